"""Model output and its sensitivities to the parameters and the initial conditions.

For ``x'' + B x' + K x = u`` with state ``z = (x, v)``, ``A = [[0, 1], [-K, -B]]``,
the sensitivities ``z_B = dz/dB`` and ``z_K = dz/dK`` obey

    z_B' = A z_B - (0, v),    z_K' = A z_K - (0, x),    z_B(0) = z_K(0) = 0,

and ``z_x0 = dz/dx0``, ``z_v0 = dz/dv0`` are free responses from ``(1, 0)`` and
``(0, 1)``.  Plant and sensitivities form one linear time-invariant system of ten
states driven by ``u``, integrated exactly between samples for the input interpolated
as by the cumulative quadrature rule (:func:`algid.signals.lti_response`): exact up to
round-off for a constant input, ``O(h**q)`` for a smooth one.  The time origin is the
first sample; ``x0`` and ``v0`` are the state there.  NumPy and SciPy only.
"""

from __future__ import annotations

import numpy as np

from algid._signal_checks import as_signal, check_experiment
from algid.errors import InputDataError
from algid.signals._filters import lti_response

__all__ = ["output_sensitivities", "check_input", "SENSITIVITY_PARAMETERS"]

#: Order of the columns of the sensitivity matrix.
SENSITIVITY_PARAMETERS = ("B", "K", "x0", "v0")


def check_input(t, f, *, horizon=None, order=6):
    """Check a sampled input and cut it at ``horizon``.

    Parameters
    ----------
    t, f : array_like
        Uniformly spaced sample times and input samples.
    horizon : float, optional
        Keep the samples with ``t - t[0] <= horizon`` (all if None).
    order : int, optional
        Points of the interpolation rule; at least that many samples are needed.

    Returns
    -------
    t, f : ndarray
        The (cut) signals.
    h : float
        Sampling step.

    Raises
    ------
    InputDataError
        Unusable signals (see :func:`algid._signal_checks.check_experiment`), a horizon that
        is not a positive number, or fewer than ``max(order, 8)`` samples up to it.
    """
    t = as_signal(t, name="t")
    f = as_signal(f, name="f")
    if t.size != f.size:
        raise InputDataError(f"signals have different lengths: 't' has {t.size}, "
                             f"'f' has {f.size}")
    # the output is not needed here: check the time axis with a placeholder output
    t, f, _, h = check_experiment(t, f, np.ones_like(t), min_samples=max(order, 8))
    if horizon is not None:
        try:
            horizon = float(horizon)
        except (TypeError, ValueError):
            raise InputDataError(f"horizon must be a number of seconds, got {horizon!r}") \
                from None
        if not np.isfinite(horizon) or horizon <= 0:
            raise InputDataError(f"horizon must be a positive number of seconds, "
                                 f"got {horizon!r}")
        n = int(np.floor(horizon / h + 1e-6)) + 1
        if n < max(order, 8):
            raise InputDataError(f"horizon {horizon!r} s holds only {min(n, t.size)} "
                                 f"samples; at least {max(order, 8)} are needed")
        t, f = t[:n], f[:n]
    return t, f, h


def output_sensitivities(t, f, *, B, K, x0=0.0, v0=0.0, order=6):
    """Model output ``x`` and its sensitivities at the samples.

    Parameters
    ----------
    t : array_like, shape (N,)
        Uniformly spaced sample times [s]; the initial state is at ``t[0]``.
    f : array_like, shape (N,)
        Input ``u`` of ``x'' + B x' + K x = u`` (force per unit mass).
    B, K : float
        Model parameters.
    x0, v0 : float, optional
        Displacement and velocity at ``t[0]``.  Default 0.
    order : int, optional
        Points of the input interpolation (as the quadrature rule; 2 = first-order
        hold).  Default 6.

    Returns
    -------
    x : ndarray, shape (N,)
        Model output.
    S : ndarray, shape (N, 4)
        ``dx/dB, dx/dK, dx/dx0, dx/dv0`` (columns in :data:`SENSITIVITY_PARAMETERS`).

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(2001) * 1e-3
    >>> x, S = output_sensitivities(t, np.ones_like(t), B=2.0, K=3.0)
    >>> round(float(x[-1]), 6), S.shape
    (0.366424, (2001, 4))
    """
    t, f, h = check_input(t, f, order=order)
    B, K, x0, v0 = (float(val) for val in (B, K, x0, v0))
    a = np.array([[0.0, 1.0], [-K, -B]])
    M = np.zeros((10, 10))
    for block in range(5):
        M[2 * block:2 * block + 2, 2 * block:2 * block + 2] = a
    M[3, 1] = -1.0  # v_B' = ... - v
    M[5, 0] = -1.0  # v_K' = ... - x
    b = np.zeros(10)
    b[1] = 1.0
    z0 = np.zeros(10)
    z0[0], z0[1] = x0, v0
    z0[6] = 1.0  # d(x, v)/dx0 at t0
    z0[9] = 1.0  # d(x, v)/dv0 at t0
    z = lti_response(M, b, f, h, initial_state=z0, points=order)
    return z[:, 0], z[:, [2, 4, 6, 8]]
