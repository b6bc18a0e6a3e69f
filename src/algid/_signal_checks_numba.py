"""The checks of :func:`algid._signal_checks.check_experiment` in compiled passes (numba)."""

from __future__ import annotations

import math
from functools import cache

import numpy as np

from algid._signal_checks import check_experiment, step_tolerance

__all__ = ["check_experiment_compiled"]


@cache
def _signal_scan():
    """Compiled passes over ``t``, ``f``, ``x``: True when they pass every check of
    :func:`algid._signal_checks.check_experiment` that looks at the values."""
    import numba

    from algid._compile_notice import watch

    watch()

    # reductions in any order (vectorised); the result does not depend on the order:
    # a sum of x * 0 is NaN if and only if some x is not finite
    @numba.njit("float64(float64[::1], float64[::1], float64[::1])", cache=True, nogil=True,
                fastmath={"reassoc"})
    def nonfinite_and_excitation(t, f, x):
        nan_if_bad = 0.0
        excitation = 0.0
        for i in range(t.shape[0]):
            nan_if_bad += t[i] * 0.0 + f[i] * 0.0 + x[i] * 0.0
            excitation += abs(f[i]) + abs(x[i])
        return nan_if_bad if excitation > 0.0 else math.nan

    @numba.njit("boolean(float64[::1], float64, float64)", cache=True, nogil=True)
    def uniform(t, dt, tolerance):
        violations = 0
        for i in range(t.shape[0] - 1):
            step = t[i + 1] - t[i]
            violations += (not step > 0.0) + (abs(step - dt) > tolerance)
        return violations == 0

    def scan(t, f, x, dt, tolerance):
        return (math.isfinite(dt) and nonfinite_and_excitation(t, f, x) == 0.0
                and uniform(t, dt, tolerance))

    return scan


def check_experiment_compiled(t, f, x, *, min_samples=16, names=("t", "f", "x")):
    """:func:`algid._signal_checks.check_experiment` in two compiled passes over the data.

    Same arguments, result and errors: for float64 1-D contiguous arrays of equal
    length the values are checked by compiled loops (finite, time strictly increasing
    and uniform within :func:`~algid._signal_checks.step_tolerance`, some excitation);
    anything else, and any failure, goes to :func:`algid._signal_checks.check_experiment`,
    which raises the error that names the offending input.

    Parameters
    ----------
    t, f, x : array_like
        Time, input and output.
    min_samples : int, optional
        Smallest number of samples accepted.
    names : tuple of str, optional
        Names of ``t``, ``f`` and ``x`` in the messages.

    Returns
    -------
    t, f, x : ndarray
    dt : float
    """
    arrays = (t, f, x)
    if all(isinstance(a, np.ndarray) and not isinstance(a, np.ma.MaskedArray)
           and a.dtype == np.float64 and a.ndim == 1 and a.flags.c_contiguous
           for a in arrays):
        n = t.size
        if f.size == n and x.size == n and n >= max(int(min_samples), 2):
            dt = float((t[-1] - t[0]) / (n - 1))
            tolerance = step_tolerance(max(abs(t[0]), abs(t[-1])), dt)
            if _signal_scan()(t, f, x, dt, tolerance):
                return t, f, x, dt
    return check_experiment(t, f, x, names=names, min_samples=min_samples)
