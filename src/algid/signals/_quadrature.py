"""Cumulative quadrature for uniformly sampled signals, usable on-line.

The algebraic estimate is exact in continuous time, but ``det P(t)`` grows from zero
like a high power of ``t``, so at early times the estimate amplifies the error of the
numerical integrals enormously.  The plain trapezoid (2 points) needs hundreds of
samples to bring the paper's system within 0.1 %; the Adams-Moulton rules below reach
the same accuracy within a few (``algid paper`` measures both).

Rule of ``q`` points (``points=q``; 6 by default in these functions, while the
estimators default to 8, see :func:`algid.estimation._core.first_estimate`): the integral over
``[t[n-1], t[n]]`` is that of the polynomial interpolating ``y[n-q+1], ..., y[n]``, so it
uses the current and past samples only (causal).  For the first ``q - 2`` intervals
there are not enough past samples; they use the polynomial through ``y[0], ...,
y[q-1]`` instead.  That start-up is the only look-ahead: every value from sample
``q - 1`` on is causal, and an on-line estimator reports its first value once sample
``q - 1`` has arrived (:data:`startup_samples`).  ``points=2`` is the trapezoid rule.

The rules are exact for polynomials of degree ``q - 1``; the error of the cumulative
integral of a smooth signal is ``O(dt**q)``.
"""

from __future__ import annotations

from fractions import Fraction
from functools import cache

import numpy as np

from algid._signal_checks import integer_value
from algid.errors import InputDataError

__all__ = ["check_quadrature_points", "cumulative_integral", "iterated_integrals",
           "startup_samples", "rule_weights",
           "integrator_weights", "advance_integrators", "integrate_padded", "QUADRATURE_POINTS"]

#: Numbers of points of the rule that are offered.
QUADRATURE_POINTS = (2, 3, 4, 5, 6, 7, 8, 9)

def _check_points(points):
    if isinstance(points, bool) or points not in QUADRATURE_POINTS:
        raise ValueError(f"quadrature points {points!r} is not one of {QUADRATURE_POINTS}")


def startup_samples(points: int) -> int:
    """Number of samples the rule of ``points`` points needs before it is causal.

    The estimate at sample ``n`` can be reported once sample ``max(n, points - 1)`` has
    arrived; samples ``0 .. points - 2`` are the start-up.

    Parameters
    ----------
    points : int
        Number of points of the rule, one of :data:`QUADRATURE_POINTS`.

    Returns
    -------
    int
        ``points - 1``.
    """
    _check_points(points)
    return points - 1


def _poly_mul(a, b):
    out = [Fraction(0)] * (len(a) + len(b) - 1)
    for i, ai in enumerate(a):
        for j, bj in enumerate(b):
            out[i + j] += ai * bj
    return out


@cache
def _interval_weights(nodes: tuple, lo: int, hi: int) -> tuple:
    """Exact weights ``w`` with ``int_lo^hi p(u) du = sum w_i p(nodes_i)`` for polynomials
    ``p`` of degree ``len(nodes) - 1`` (integration of the Lagrange basis)."""
    weights = []
    for i, ui in enumerate(nodes):
        poly = [Fraction(1)]  # coefficients, lowest degree first
        for j, uj in enumerate(nodes):
            if j != i:
                poly = _poly_mul(poly, [Fraction(-uj, ui - uj), Fraction(1, ui - uj)])
        weights.append(sum(c * (Fraction(hi) ** (d + 1) - Fraction(lo) ** (d + 1)) / (d + 1)
                           for d, c in enumerate(poly)))
    return tuple(weights)


def rule_weights(points: int):
    """Weights of the rule of ``points`` points, in units of the step ``dt``.

    Parameters
    ----------
    points : int
        Number of points of the rule (one of :data:`QUADRATURE_POINTS`).

    Returns
    -------
    regular : ndarray, shape (points,)
        ``int_{t[n-1]}^{t[n]} y = dt * regular @ y[n-points+1 : n+1]`` for
        ``n >= points - 1``.
    startup : ndarray, shape (points - 2, points)
        Row ``j - 1`` integrates over ``[t[j-1], t[j]]`` from ``y[0 : points]``, for
        ``j = 1 .. points - 2``.
    """
    _check_points(points)
    nodes = tuple(range(points))
    regular = np.array([float(w) for w in _interval_weights(nodes, points - 2, points - 1)])
    startup = np.array([[float(w) for w in _interval_weights(nodes, j - 1, j)]
                        for j in range(1, points - 1)]).reshape(points - 2, points)
    return regular, startup


def integrator_weights(points: int, dt: float):
    """The weights every integrator of the estimator uses, with the step folded in.

    Parameters
    ----------
    points : int
        Number of points of the rule.
    dt : float
        Sampling step [s].

    Returns
    -------
    regular : ndarray, shape (points,)
        ``dt * regular`` of :func:`rule_weights`, oldest sample first: the increment
        over ``[t[n-1], t[n]]`` is ``regular @ y[n-points+1 : n+1]``.
    startup : ndarray, shape (points - 2, points)
        ``dt * startup``, for the first ``points - 2`` intervals.
    """
    regular, startup = rule_weights(points)
    return regular * dt, startup * dt


def _nested_sum(columns, weights):
    """``((c[0] w[0] + c[1] w[1]) + ...)``: left to right, oldest sample first."""
    acc = columns[0] * weights[0]
    for column, weight in zip(columns[1:], weights[1:]):
        acc = acc + column * weight
    return acc


def integrate_padded(padded, integrals, weights, out):
    """Integrate with the regular rule: the core step of every integrator.

    ``out[r, i] = integrals[r] + inc[r, 0] + ... + inc[r, i]``, summed left to right,
    where ``inc[r, i]`` is the increment over the interval ending at sample ``i``,
    ``weights @ padded[r, i : i + points]`` summed oldest sample first (the order of
    ``numpy.correlate`` and of the compiled backend).  The running sums of two
    integrators are formed in one pass, as the real and imaginary parts of a complex
    cumulative sum (the same additions, in the same order).

    Parameters
    ----------
    padded : ndarray, shape (rows, points - 1 + m)
        The last ``points - 1`` integrand samples before the chunk, then the ``m``
        samples of the chunk.
    integrals : ndarray, shape (rows,)
        Integrals up to the sample before the chunk; updated in place to the last.
    weights : ndarray, shape (points,)
        From :func:`integrator_weights`.
    out : ndarray, shape (rows, m)
        Receives the integrals at every sample of the chunk.
    """
    rows, total = padded.shape
    m = total - (weights.size - 1)
    if m <= 0:
        return
    increments = np.empty((m, rows + rows % 2))  # two integrators per complex column
    for r in range(rows):
        increments[:, r] = np.correlate(padded[r], weights, mode="valid")
    if rows % 2:
        increments[:, rows] = 0.0
    increments[0, :rows] += integrals
    pairs = increments.view(np.complex128)
    np.cumsum(pairs, axis=0, out=pairs)
    out[...] = increments[:, :rows].T
    integrals[...] = increments[-1, :rows]


def advance_integrators(samples, integrals, history, weights, startup=None):
    """Integrate a chunk of samples with integrators that carry their state.

    Parameters
    ----------
    samples : ndarray, shape (rows, m)
        Integrand of every integrator over the chunk.
    integrals : ndarray, shape (rows,)
        Integral up to the sample before the chunk; updated in place.
    history : ndarray, shape (rows, points - 1)
        The integrand samples before the chunk, oldest first; updated in place.
    weights : ndarray, shape (points,)
        From :func:`integrator_weights`.
    startup : ndarray, shape (points - 2, points), optional
        Given at the time origin (``samples[:, 0]`` is sample 0, ``m >= points``): the
        first ``points - 2`` intervals take the start-up rule, and ``integrals`` and
        ``history`` are ignored on entry.

    Returns
    -------
    ndarray, shape (rows, m)
        The integrals at every sample of the chunk (0 at sample 0 from the origin).
    """
    rows, m = samples.shape
    width = weights.size - 1
    out = np.empty((rows, m))
    if startup is None:
        padded = np.concatenate((history, samples), axis=1)
        integrate_padded(padded, integrals, weights, out)
    else:
        out[:, 0] = 0.0
        head = samples[:, :width + 1].T  # the first `points` samples, as columns
        for j in range(1, width):
            out[:, j] = out[:, j - 1] + _nested_sum(head, startup[j - 1])
        integrals[...] = out[:, width - 1]
        padded = samples
        integrate_padded(padded, integrals, weights, out[:, width:])
    history[...] = padded[:, padded.shape[1] - width:]
    return out


def cumulative_integral(y, dt: float, *, points: int = 6) -> np.ndarray:
    """Cumulative integral ``I[n] = int_{t[0]}^{t[n]} y``, with ``I[0] = 0``.

    Parameters
    ----------
    y : array_like, shape (n,)
        Samples on a uniform grid of step ``dt``; ``n >= points``.
    dt : float
        Sampling step.
    points : int, optional
        Number of points of the rule (2 = trapezoid).  Default 6.

    Returns
    -------
    ndarray, shape (n,)

    Examples
    --------
    >>> import numpy as np
    >>> from algid.signals import cumulative_integral
    >>> t = np.linspace(0.0, 1.0, 11)
    >>> area = cumulative_integral(t**2, 0.1)    # t**3 / 3, exact for a polynomial
    >>> float(area[0]), round(float(area[-1]), 12)
    (0.0, 0.333333333333)
    """
    y = np.asarray(y, dtype=float)
    n = y.shape[-1]
    weights, startup = integrator_weights(points, dt)
    if n < points:
        raise ValueError(f"{n} samples are too few for a rule of {points} points")
    rows = y.reshape(1, n)
    return advance_integrators(rows, np.zeros(1), np.zeros((1, points - 1)), weights,
                               startup)[0]


def iterated_integrals(y, dt: float, depth: int, *, points: int = 6) -> list:
    """``[y, int y, int int y, ...]``: the iterated integrals of ``y`` up to ``depth``.

    Each level integrates the previous one with :func:`cumulative_integral`, as the
    integrator chain of the time-varying state-space realisation does.

    Parameters
    ----------
    y : array_like, shape (n,)
        Samples on a uniform grid of step ``dt``.
    dt : float
        Sampling step.
    depth : int
        Number of integrations.
    points : int, optional
        Number of points of the rule.  Default 6.

    Returns
    -------
    list of ndarray

    Examples
    --------
    >>> import numpy as np
    >>> from algid.signals import iterated_integrals
    >>> levels = iterated_integrals(np.ones(11), 0.1, 2)    # 1, t, t**2 / 2
    >>> [round(float(level[-1]), 12) for level in levels]
    [1.0, 1.0, 0.5]
    """
    levels = [np.asarray(y, dtype=float)]
    for _ in range(depth):
        levels.append(cumulative_integral(levels[-1], dt, points=points))
    return levels


def check_quadrature_points(points, *, name="quadrature_points") -> int:
    """``points`` as an int, if it is one of :data:`QUADRATURE_POINTS`.

    Parameters
    ----------
    points : int
        Number of points of the cumulative quadrature rule (an integral float such as
        ``6.0`` is accepted).
    name : str, optional
        Name of the option, used in the error message.

    Returns
    -------
    int
        ``points`` as a Python int.

    Raises
    ------
    InputDataError
        Otherwise; the message names the option ``name``.
    """
    value = integer_value(points)
    if value not in QUADRATURE_POINTS:
        raise InputDataError(f"{name} must be one of {QUADRATURE_POINTS}, got {points!r}")
    return value
