"""A second time origin, a few samples after the first.

The estimate does not depend on the initial conditions, but its numerical error does
depend on what happens just after the origin: a transient faster than the sampling (the
fast pole of an overdamped plant, a few samples long) is integrated with an error of
order one that stays in the integrals for the rest of the record.  An estimator whose
origin is :data:`LATE_ORIGIN` samples later never sees it.

Beside the estimator from the first sample runs its twin from sample
:data:`LATE_ORIGIN`; at every sample where the twin's numerical error
(:mod:`algid.estimation._numerical_error`) is ``MARGIN`` (3) times smaller, the twin's estimate is
reported, with its error.  (The margin keeps noisy estimates, whose numerical error also
holds part of the noise, from switching on a coin toss.)  The choice is made sample by
sample from numbers that do not depend on how the stream is cut, so a stream gives the
batch estimate bit for bit.  It doubles the cost again, and ``python -m
benchmarks.population --late-origin`` measures what it changes.  It is an option
(``late_origin=True`` of :func:`algid.estimate` and :class:`algid.OnlineEstimator`): by
default the estimate is that of the method from the first sample.
"""

from __future__ import annotations

import numpy as np

import algid.estimation._core as core
from algid.estimation._numerical_error import BLOCK, advance_with_error, with_companion

__all__ = ["LATE_ORIGIN", "late_twin", "advance_best"]

#: The twin's origin, in samples after the first sample.
LATE_ORIGIN = 64
#: The twin's estimate is reported where its numerical error is this many times smaller.
MARGIN = 3.0


def late_twin(state: core.EstimatorState) -> core.EstimatorState:
    """A fresh state with the options of ``state``, and its companion.

    Parameters
    ----------
    state : EstimatorState
        The estimator from the first sample.

    Returns
    -------
    EstimatorState
        Its twin, to be advanced from sample :data:`LATE_ORIGIN` on.
    """
    return with_companion(core.new_state(state.model, points=state.points,
                                         filter_order=state.filter_order, dt=state.dt,
                                         divisors=state.divisors))


def advance_best(state, twin, channels, *, backend="numpy", out=None, error_out=None):
    """Estimates of a chunk, from the origin or from the twin's where that is better.

    Parameters
    ----------
    state : EstimatorState
        The estimator from the first sample, with its companion; never restarted.
    twin : EstimatorState
        From :func:`late_twin`; it starts at sample :data:`LATE_ORIGIN` of the stream.
    channels : sequence of arrays
        The chunk (see :func:`algid.estimation._core.advance`).
    backend : {"numpy", "numba"}, optional
        Default ``"numpy"``.
    out : ndarray, shape (n_parameters, m), optional
        Float64 array to write the estimates into.
    error_out : ndarray, shape (m,), optional
        Float64 array to write their numerical error into.

    Returns
    -------
    estimates : ndarray, shape (n_parameters, m)
    numerical_error : ndarray, shape (m,)
    """
    n_before = state.n_seen
    twin.dt = state.dt
    estimates, error, _ = advance_with_error(state, channels, backend=backend, out=out,
                                             error_out=error_out)
    m = estimates.shape[1]
    skip = min(m, max(0, LATE_ORIGIN - n_before))
    if skip == m:
        return estimates, error
    rows = tuple(np.asarray(c, dtype=np.float64)[skip:] for c in channels)
    late = np.empty((estimates.shape[0], min(m - skip, BLOCK)))
    late_error = np.empty(late.shape[1])
    for start in range(0, m - skip, BLOCK):
        stop = min(m - skip, start + BLOCK)
        n = stop - start
        advance_with_error(twin, tuple(r[start:stop] for r in rows), backend=backend,
                           out=late[:, :n], error_out=late_error[:n])
        ours = error[skip + start:skip + stop]
        # (not where the data were found not to determine a parameter: NaN, inf error)
        judged = np.isinf(ours) & np.isnan(estimates[:, skip + start:skip + stop]).any(axis=0)
        better = np.flatnonzero((MARGIN * late_error[:n] < ours) & ~judged)
        if better.size:
            estimates[:, skip + start + better] = late[:, better]
            error[skip + start + better] = late_error[better]
    return estimates, error
