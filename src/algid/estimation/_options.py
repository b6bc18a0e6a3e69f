"""Checks of the estimator options shared by :func:`algid.estimate` and
:class:`algid.OnlineEstimator`, and the known mass."""

from __future__ import annotations

from algid._signal_checks import integer_value, positive_number
from algid.errors import InputDataError, ModelError
from algid.signals._quadrature import check_quadrature_points

__all__ = ["DEFAULT_FILTER_ORDER", "DEFAULT_QUADRATURE_POINTS", "MAX_FILTER_ORDER",
           "integer_value", "check_filter_order",
           "check_quadrature_points", "quadrature_points_option", "known_mass",
           "channel_divisors", "with_mass_scaled"]

#: Default order ``p`` of the invariant filter ``1/s**p``.
DEFAULT_FILTER_ORDER = 2
#: Default number of points of the cumulative quadrature rule.
DEFAULT_QUADRATURE_POINTS = 8
#: Largest order ``p`` of the invariant filter ``1/s**p`` accepted.  Each order adds
#: ``n_parameters + 1`` integrators to the state (memory and work grow linearly with
#: ``p``) and multiplies the filtered denominator by about ``t**p / p!``, which pushes
#: long records towards overflow; orders 0-4 are the useful ones.
MAX_FILTER_ORDER = 32


def check_filter_order(filter_order) -> int:
    """``filter_order`` as an int, if it is an integer from 0 to :data:`MAX_FILTER_ORDER`.

    Parameters
    ----------
    filter_order : int
        Order ``p`` of the invariant filter ``1/s**p`` (an integral float such as
        ``2.0`` is accepted).

    Returns
    -------
    int
        ``filter_order`` as a Python int.

    Raises
    ------
    InputDataError
        Otherwise.
    """
    value = integer_value(filter_order)
    if value is None or not 0 <= value <= MAX_FILTER_ORDER:
        raise InputDataError(f"filter_order must be an integer from 0 to {MAX_FILTER_ORDER}, "
                             f"got {filter_order!r}")
    return value


def quadrature_points_option(quadrature_points) -> int:
    """The checked number of quadrature points of the option ``quadrature_points``.

    Parameters
    ----------
    quadrature_points : int or None
        Number of points of the rule; None means :data:`DEFAULT_QUADRATURE_POINTS`.

    Returns
    -------
    int
        The checked number of points.

    Raises
    ------
    InputDataError
        A bad value.
    """
    return check_quadrature_points(
        DEFAULT_QUADRATURE_POINTS if quadrature_points is None else quadrature_points)


def known_mass(module, mass):
    """The validated known mass, or None.

    Parameters
    ----------
    module : module
        Generated model module (declares ``MODEL``, ``PARAMETERS``, ``MASS_SCALED``).
    mass : float or None
        Known mass, or None if not given.

    Returns
    -------
    float or None
        The mass as a positive float, or None when ``mass`` is None.

    Raises
    ------
    ModelError
        If the model declares no parameter that a known mass scales (it estimates the
        mass, or has none).
    InputDataError
        If the mass is not a positive number.
    """
    if mass is None:
        return None
    if not module.MASS_SCALED:
        what = "estimates the mass" if "m" in module.PARAMETERS else "takes no known mass"
        raise ModelError(f"model {module.MODEL!r} {what}: do not give mass")
    return positive_number(mass, name="mass")


def channel_divisors(module, mass):
    """One divisor per channel, from the known mass.

    The divisor is the mass for the channels the model declares as forces
    (``MASS_DIVIDED``), 1 for the others.

    Parameters
    ----------
    module : module
        Generated model module (declares ``CHANNELS`` and ``MASS_DIVIDED``).
    mass : float or None
        Known mass, or None.

    Returns
    -------
    tuple of float or None
        One divisor per entry of ``module.CHANNELS``; None without a mass.
    """
    if mass is None:
        return None
    return tuple(mass if name in module.MASS_DIVIDED else 1.0 for name in module.CHANNELS)


def with_mass_scaled(module, estimates, mass):
    """Add the quantities a known mass scales to the estimates, in place.

    The model declares them in ``MASS_SCALED`` (e.g. ``c = B m``); nothing is added
    without a mass.

    Parameters
    ----------
    module : module
        Generated model module (declares ``MASS_SCALED``: name -> scaled parameter).
    estimates : dict
        Estimates, name -> array; modified in place.
    mass : float or None
        Known mass, or None.

    Returns
    -------
    dict
        ``estimates`` itself.
    """
    if mass is not None:
        for name, parameter in module.MASS_SCALED.items():
            estimates[name] = estimates[parameter] * mass
    return estimates
