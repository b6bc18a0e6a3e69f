"""The numerical error (:mod:`algid.estimation._numerical_error`), compiled; needs numba.

:func:`block_error` serves the compiled backend (:mod:`algid.estimation._core_numba`);
:func:`sample_error` the one-sample step of the generated loops
(``advance_sample_pair`` in ``algid/_generated/<model>_numba.py``), which call it
within their own compiled code.  Both give the numbers of
:func:`algid.estimation._numerical_error.relative_difference` followed by
:func:`algid.estimation._numerical_error.window_maximum`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from algid._compile_notice import watch

watch()   # a line on stderr while numba compiles these for more than a second

__all__ = ["block_error", "sample_error", "larger_relative", "track_extent",
           "sample_extent"]


# x / 0: inf or NaN, no exception; inlined into their callers (a call per sample costs
# as much as the rest of the error), as selects (the block's loops vectorise)
@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _relative(a, b):  # pragma: no cover - compiled
    """``|a - b| / |a|``; for a finite ``a`` where that is NaN (0 / 0: ``a = b = 0``, or
    ``b`` NaN: the data do not determine it), 0 if ``a == b``, else inf."""
    rel = abs(a - b) / abs(a)
    equal = 0.0 if a == b else np.inf
    return equal if (rel != rel and abs(a) < np.inf) else rel


@numba.njit(cache=True, nogil=True, inline="always")
def _larger(raw, rel):  # pragma: no cover - compiled
    """The larger of two relative differences, NaN if either is NaN."""
    return np.nan if (rel != rel or raw != raw) else max(raw, rel)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def larger_relative(raw, a, b):  # pragma: no cover - compiled
    """The larger of ``raw`` and the relative difference of ``a`` and ``b`` (NaN if
    either is NaN), compiled with this module's error model: for the generated loops,
    whose own raises on a division by zero."""
    return _larger(raw, _relative(a, b))


@numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _raw_error(estimates, companion, j):  # pragma: no cover - compiled
    """The largest relative difference over the parameters at sample ``j``."""
    raw = 0.0 if estimates.shape[0] else np.nan
    for i in range(estimates.shape[0]):
        raw = _larger(raw, _relative(estimates[i, j], companion[i, j]))
    return raw


@numba.njit(cache=True, nogil=True, error_model="numpy")
def block_error(estimates, companion, recent, out):  # pragma: no cover - compiled
    """The numerical error of a block.

    Parameters
    ----------
    estimates, companion : ndarray, shape (n_parameters, m)
        The estimates and the companion's.
    recent : ndarray, shape (WINDOW - 1,)
        The finite raw values before the block; updated in place.
    out : ndarray, shape (m,)
        Receives the numerical error.
    """
    n_parameters, m = estimates.shape
    width = recent.shape[0]
    level = np.empty(width + m)
    level[:width] = recent
    # the raw error (_raw_error's numbers) into out, parameter by parameter over every
    # sample: the loops vectorise
    first = 0.0 if n_parameters else np.nan
    for j in range(m):
        out[j] = first
    for i in range(n_parameters):
        for j in range(m):
            out[j] = _larger(out[j], _relative(estimates[i, j], companion[i, j]))
    for j in range(m):
        raw = out[j]
        level[width + j] = raw if abs(raw) < np.inf else 0.0  # finite
    for k in range(width):   # a loop: a slice assignment compiles an error path
        recent[k] = level[m + k]
    # the largest over the last width + 1 samples: maxima of 2, 4, 8, ... samples (the
    # window is a power of two), each pass reading the previous one's values ahead
    span = 1
    while span <= width:
        for k in range(width + m - span):
            level[k] = max(level[k], level[k + span])  # (no NaN here) branch-free
        span *= 2
    for j in range(m):
        if abs(out[j]) < np.inf:
            out[j] = level[j]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def sample_error(estimates, companion, recent, out):  # pragma: no cover - compiled
    """:func:`block_error` of one sample, without a working array.

    Parameters
    ----------
    estimates, companion : ndarray, shape (n_parameters, 1)
    recent : ndarray, shape (WINDOW - 1,)
        Updated in place.
    out : ndarray, shape (1,)
    """
    raw = _raw_error(estimates, companion, 0)
    finite = math.isfinite(raw)
    value = raw if finite else 0.0
    largest = value
    width = recent.shape[0]
    for i in range(width):
        if recent[i] > largest:
            largest = recent[i]
    if width:
        for i in range(width - 1):
            recent[i] = recent[i + 1]
        recent[width - 1] = value
    out[0] = largest if finite else raw


@numba.njit(cache=True, nogil=True)
def track_extent(row, divisor, c, channel_max, channel_last):  # pragma: no cover - compiled
    """The extent of channel ``c`` over a block: its largest absolute value divided by
    ``divisor`` into ``channel_max[c]`` if larger, its last value so divided into
    ``channel_last[c]`` (as :func:`algid.estimation._numerical_error.advance_with_error` tracks it).

    Parameters
    ----------
    row : ndarray, shape (m,)
        The block's samples of the channel (finite, ``m >= 1``).
    divisor : float
    c : int
    channel_max, channel_last : ndarray
        Updated in place.
    """
    largest = 0.0
    for value in row:
        if abs(value) > largest:
            largest = abs(value)
    _record_extent(largest / divisor, row[row.shape[0] - 1] / divisor, c, channel_max,
                   channel_last)


@numba.njit(cache=True, nogil=True)
def sample_extent(value, divisor, c, channel_max, channel_last):  # pragma: no cover
    """:func:`track_extent` of one sample given as a number (the one-sample step of the
    generated loops calls it).

    Parameters
    ----------
    value : float
    divisor : float
    c : int
    channel_max, channel_last : ndarray
        Updated in place.
    """
    newest = value / divisor
    _record_extent(abs(newest), newest, c, channel_max, channel_last)


@numba.njit(cache=True, nogil=True, inline="always")
def _record_extent(size, newest, c, channel_max, channel_last):  # pragma: no cover
    """The extent rule: the largest size so far, the newest value."""
    if size > channel_max[c]:
        channel_max[c] = size
    channel_last[c] = newest
