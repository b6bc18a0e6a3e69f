"""The a-posteriori numerical error of the algebraic estimate.

The estimate is exact in continuous time.  On noise-free samples what separates it from
the parameters is numerical: the error of the quadrature (large where a signal is
under-resolved: a fast transient, or few samples per period of a lightly damped mode),
amplified by the conditioning of ``P(t)`` and of the filtered denominator, and
round-off, which grows with the weights ``t**k`` over long records.

Every estimator carries a *companion*: the same estimator with a quadrature rule of one
point more (one less at the largest rule) and an invariant filter of one order less
(order 1 without a filter) (:func:`companion_options`).  Both estimates are exact in
continuous time, so on noise-free data they differ only by their numerical errors.
These come from different rules and filters and do not cancel: the relative difference
of the two estimates, the largest over the parameters, estimates the error of the
estimate, as the difference of an embedded Runge-Kutta pair does
(:func:`relative_difference`).  Where the two errors happen to cross, their
difference dips: the reported error is the largest difference over the last
:data:`WINDOW` samples (:func:`window_maximum`).  Where the signals are resolved the
companion's rule is the more accurate and the difference is the error itself; where they are not (an
under-resolved transient at the time origin), no rule is accurate, but the error then
depends strongly on the filter and the companion's differs.  How well the reported
error bounds the actual one is measured by ``python -m benchmarks.population``.

The companion is advanced with the estimator, on the same samples, so the numerical
error of a stream is that of the batch estimate, bit for bit.  Past
:data:`~algid.estimation._error_propagation.SWITCH` samples it is no longer run but
propagated from the estimator's own integrals (:mod:`algid.estimation._error_propagation`):
the error then adds a third to a half of the estimator's time.  With noise, the two
filters pass the noise differently: the difference then also holds part of the noise's
effect.

Data that do not determine a parameter (a constant output leaves ``B`` free) make the
estimate round-off divided by round-off.  At the checks of :func:`next_check` (the
same samples however a stream is cut) the test of
:mod:`algid.estimation._identifiability` runs on the state, if the numerical error is
above :data:`JUDGED_ABOVE` or an estimate is 0; until the next check, the parameters
it finds undetermined are NaN and the numerical error is infinite.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np

import algid.estimation._core as core
from algid.estimation._backends import require_backend
from algid.estimation._core_numpy import advance_sample as numpy_sample
from algid.estimation._core_numpy import sample_step_is_exact
from algid.estimation._error_propagation import GRID, companion_estimates, new_propagation
from algid.estimation._error_propagation import start as start_propagation
from algid.estimation._identifiability import undetermined_in_stream
from algid.signals._quadrature import QUADRATURE_POINTS

__all__ = ["companion_options", "with_companion", "advance_with_error", "advance_rows_with_error",
           "sample_stepper",
           "relative_difference", "window_maximum", "next_check", "WINDOW", "FIRST_CHECK",
           "CHECK_EVERY", "RECHECK_SHARE", "JUDGED_ABOVE"]


def companion_options(points: int, filter_order: int) -> tuple:
    """Quadrature points and filter order of the companion estimator.

    Parameters
    ----------
    points : int
        Points of the estimator's quadrature rule.
    filter_order : int
        Order of its invariant filter ``1/s**p``.

    Returns
    -------
    tuple of int
        ``(points + 1, filter_order - 1)``; ``points - 1`` for the largest rule and
        order 1 for ``filter_order = 0``.
    """
    points = int(points)
    filter_order = int(filter_order)
    other_points = points + 1 if points < max(QUADRATURE_POINTS) else points - 1
    return other_points, filter_order - 1 if filter_order > 0 else 1


def with_companion(state: core.EstimatorState) -> core.EstimatorState:
    """Give a fresh state its companion (:func:`companion_options`).

    Parameters
    ----------
    state : EstimatorState
        From :func:`algid.estimation._core.new_state`, with no sample seen yet.

    Returns
    -------
    EstimatorState
        ``state``, whose ``companion`` is set.
    """
    points, filter_order = companion_options(state.points, state.filter_order)
    state.companion = core.new_state(state.model, points=points, filter_order=filter_order,
                                     dt=state.dt, divisors=state.divisors)
    state.recent_errors = np.zeros(WINDOW - 1)
    state.propagation = new_propagation(
        state, state.companion, core.integrator_layout(state.model)) if PROPAGATE else None
    if state.propagation is not None and next_check(state.propagation.switch - 1) != \
            state.propagation.switch:
        raise ValueError("the switch of the propagation must be a checked sample count")
    state.channel_max = np.zeros(len(state.divisors))  # for the identifiability checks
    state.channel_last = np.zeros(len(state.divisors))
    return state


#: The reported error is the largest relative difference over this many samples (a
#: power of two).
WINDOW = 16
#: Whether the companion's estimate is propagated from the estimator's integrals after
#: :data:`algid.estimation._error_propagation.SWITCH` samples (both engines and the
#: generated C, with the same numbers); off: the full companion throughout.
PROPAGATE = True


def window_maximum(raw, recent, out):
    """Largest finite value of ``raw`` over the last :data:`WINDOW` samples.

    Parameters
    ----------
    raw : ndarray, shape (m,)
        Relative differences of a chunk (:func:`relative_difference`).
    recent : ndarray, shape (WINDOW - 1,)
        The finite values of the samples before the chunk (0 for NaN or inf, and
        before the origin); updated in place.
    out : ndarray, shape (m,)
        Receives the maximum at every sample; NaN and inf of ``raw`` are kept as they
        are (the maximum is exact: the result does not depend on the chunks).
    """
    finite = np.isfinite(raw)
    width = recent.size
    level = np.concatenate((recent, np.where(finite, raw, 0.0)))
    if level.size > width:
        recent[...] = level[level.size - width:]
    else:
        recent[...] = level[:width]
    span = 1
    while span < WINDOW:  # windows of 2, 4, 8, ... samples
        level = np.maximum(level[span:], level[:-span])
        span *= 2
    out[...] = np.where(finite, level[level.size - raw.size:], raw)


def relative_difference(estimates, companion, out=None):
    """Relative difference of two estimates, the largest over the parameters.

    Parameters
    ----------
    estimates, companion : ndarray, shape (n_parameters, m)
        The estimates and the companion's.
    out : ndarray, shape (m,), optional
        Float64 array to write into.

    Returns
    -------
    ndarray, shape (m,)
        ``max_i |estimates[i] - companion[i]| / |estimates[i]|``: 0 where they are
        equal, NaN where an estimate is NaN, inf where the estimate is defined and the
        companion's is not (the data do not determine it).
    """
    estimates = np.asarray(estimates, dtype=float)
    companion = np.asarray(companion, dtype=float)
    if out is None:
        out = np.empty(estimates.shape[1])
    if estimates.shape[0] == 0:
        out.fill(np.nan)
        return out
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        rel = np.subtract(estimates, companion)
        np.abs(rel, out=rel)
        rel /= np.abs(estimates)
    undefined = np.isnan(rel)
    if undefined.any():  # 0 / 0 (equal estimates), or a finite estimate and a NaN companion
        defined = undefined & np.isfinite(estimates)
        rel[defined] = np.where(estimates[defined] == companion[defined], 0.0, np.inf)
    np.max(rel, axis=0, out=out)
    return out


#: Samples per block of :func:`advance_with_error` (its scratch arrays stay small).
BLOCK = 65536


def _as_rows(channels):
    """The chunk as float64 rows of one length, or None (the core then says why not)."""
    if type(channels) is tuple and all(type(c) is np.ndarray and c.dtype == np.float64
                                       and c.ndim == 1 and c.flags.c_contiguous
                                       for c in channels):
        return channels if channels and all(c.shape == channels[0].shape
                                            for c in channels) else None
    try:
        rows = tuple(np.ascontiguousarray(c, dtype=np.float64) for c in channels)
    except (TypeError, ValueError):
        return None
    if not rows or any(r.ndim != 1 or r.shape != rows[0].shape for r in rows):
        return None
    return rows


def advance_with_error(state, channels, *, backend="numpy", out=None, error_out=None):
    """:func:`algid.estimation._core.advance`, with the numerical error of every estimate.

    The estimator and its companion advance block by block over the chunk (the numbers
    do not depend on the blocks, as they do not on the chunks).

    Parameters
    ----------
    state : EstimatorState
        With its companion (:func:`with_companion`); both advance in place.
    channels : array_like or sequence of arrays
        The chunk (see :func:`algid.estimation._core.advance`).
    backend : {"numpy", "numba"}, optional
        Backend of the estimator and its companion.  Default ``"numpy"``.
    out : ndarray, shape (n_parameters, m), optional
        Float64 array to write the estimates into.
    error_out : ndarray, shape (m,), optional
        Float64 array to write the numerical error into.

    Returns
    -------
    estimates : ndarray, shape (n_parameters, m)
    numerical_error : ndarray, shape (m,)
        Estimated relative error of the estimates at every sample, the largest over the
        parameters (:func:`relative_difference`).
    state : EstimatorState
        The same object, advanced past the chunk.
    """
    companion = state.companion
    if companion is None:
        raise ValueError("the state has no companion: see with_companion")
    companion.dt = state.dt  # a stream may learn its step after the state was made
    rows = _as_rows(channels)
    if rows is None or len(rows) != len(state.model.CHANNELS):
        core.advance(state, channels, backend=backend, out=out)  # raises InputDataError
        rows = tuple(np.asarray(c, dtype=np.float64) for c in channels)
    m = rows[0].size
    out = core.output_array(out, (len(state.model.PARAMETERS), m))
    error_out = core.output_array(error_out, (m,), "error_out")
    if not m:
        return out, error_out, state
    check = next_check(state.n_seen, bool(state.undetermined))
    if m <= BLOCK and state.n_seen + m < check:  # one piece (every small chunk of a
        _piece(state, rows, backend, out, error_out)  # stream): no slicing
        return out, error_out, state
    scratch = np.empty((out.shape[0], min(m, BLOCK)))
    start = 0
    while start < m:
        stop = min(m, start + BLOCK, start + check - state.n_seen)
        _piece(state, tuple(r[start:stop] for r in rows), backend, out[:, start:stop],
               error_out[start:stop], scratch[:, :stop - start])
        propagation = state.propagation
        if propagation is not None and not propagation.active and \
                state.n_seen == propagation.switch:  # (the switch is one of the checks)
            start_propagation(propagation, state, state.companion,
                              core.integrator_layout(state.model))
        if state.n_seen == check:
            # judged where the estimate is in doubt: an undetermined parameter, round-off
            # over round-off, has an error of order one, or is 0 with its companion
            last = out[:, stop - 1]
            doubt = not (error_out[stop - 1] <= JUDGED_ABOVE and np.all(last != 0.0))
            verdict = undetermined_in_stream(state) if doubt else ()
            if verdict is not None:
                state.undetermined = verdict
                if verdict:  # from the checked sample on
                    _mark_undetermined(state, out[:, stop - 1:stop],
                                       error_out[stop - 1:stop])
            check = next_check(state.n_seen, bool(state.undetermined))
        start = stop
    return out, error_out, state


def advance_rows_with_error(state, rows, out, error_out, backend="numpy"):
    """:func:`advance_with_error` on a chunk known to be well formed (no checks).

    For a stream, whose chunks are checked before (:class:`algid.OnlineEstimator`): a
    chunk of one sample past the start-up, with no identifiability check due, takes a
    shorter path (fewer Python operations; the same numbers).

    Parameters
    ----------
    state : EstimatorState
        With its companion (:func:`with_companion`); both advance in place.
    rows : tuple of ndarray
        One C-contiguous float64 1-D array per channel, all of one length ``m``, in the
        model's ``CHANNELS`` order.
    out : ndarray, shape (n_parameters, m)
        Float64 array the estimates are written into.
    error_out : ndarray, shape (m,)
        Float64 array the numerical error is written into.
    backend : {"numpy", "numba"}, optional
        Default ``"numpy"``.

    Returns
    -------
    out, error_out : ndarray
        The arrays given.
    """
    if error_out.shape[0] == 1:
        step = state.__dict__.get("_sample_step")
        if step is None or step[0] != state.dt or step[1] != backend:
            step = state._sample_step = (state.dt, backend, sample_stepper(state, backend))
        ready, advance, buffer = step[2]
        values = tuple(row.item(0) for row in rows)
        if ready():
            advance(values, out, error_out)
            return out, error_out
        if buffer(values, out, error_out):
            return out, error_out
    advance_with_error(state, rows, backend=backend, out=out, error_out=error_out)
    return out, error_out


def sample_stepper(state, backend="numpy"):
    """One sample of a stream given as numbers: estimator, companion, numerical error.

    :func:`advance_with_error` of one sample, with the arrays bound.

    Parameters
    ----------
    state : EstimatorState
        With its companion (:func:`with_companion`).  The step holds its ``dt``: make a
        new one if ``state.dt`` changes.
    backend : {"numpy", "numba"}, optional
        Default ``"numpy"``.  On ``"numba"`` the sample is one compiled call
        (:func:`algid.estimation._core_numba.bound_sample_pair`).

    Returns
    -------
    ready : callable
        ``ready() -> bool``: whether the next sample can take ``advance``: False in the
        start-up, where an identifiability check is due (:func:`next_check`), and with
        NumPy where its per-sample step is not exact here
        (:func:`algid.estimation._core_numpy.sample_step_is_exact`); take
        :func:`advance_with_error` there.
    advance : callable
        ``advance(values, out, error_out)``: ``values`` the sample of every channel as
        floats (checked, in the model's ``CHANNELS`` order), ``out`` a float64 array of
        shape ``(n_parameters, 1)``, ``error_out`` one of shape ``(1,)``.
    buffer : callable
        ``buffer(values, out, error_out) -> bool``: a sample of the start-up that gives
        no estimate yet, for an estimator without the early estimates (a re-anchored
        one, :meth:`algid.estimation._core.EstimatorState.restart`): kept for the integration from
        the origin, NaN into ``out`` and ``error_out``.  False, and nothing done,
        elsewhere.
    """
    companion = state.companion
    companion.dt = state.dt
    first = max(state.points, companion.points)
    if backend == "numba":
        from algid.estimation._core_numba import bound_sample as core_numba_sample
        from algid.estimation._core_numba import bound_sample_pair
        pair, arguments = bound_sample_pair(state)
        dt = state.dt

        alone = core_numba_sample(state)
        recent = state.recent_errors

        def advance(values, out, error_out):  # (the hottest path of a stream)
            if state.propagation is not None and state.propagation.active:
                alone(*values, out, state.n_seen)  # (ready: not a grid sample)
                _sample_errors(out, out, recent, error_out)  # the estimate stands in
                _track_values(state, values)
            else:
                pair(*values, state.n_seen, dt, *arguments, out, error_out)
                companion.n_seen += 1
            state.n_seen += 1
            if state.undetermined:
                _mark_undetermined(state, out, error_out)
    else:
        require_backend(backend)  # the backend is known
        if not sample_step_is_exact():
            first = math.inf
        layout = core.integrator_layout(state.model)
        other = np.empty((len(state.model.PARAMETERS), 1))
        recent = state.recent_errors

        def advance(values, out, error_out):
            numpy_sample(state, layout, values, out)
            if state.propagation is not None and state.propagation.active:
                _sample_errors(out, out, recent, error_out)  # (ready: not a grid sample)
            else:
                numpy_sample(companion, layout, values, other)
                _sample_errors(out, other, recent, error_out)
            _track_values(state, values)
            if state.undetermined:
                _mark_undetermined(state, out, error_out)

    span = [0, 0]  # from span[0] to span[1] - 1 samples seen, one more needs no check

    def ready():
        seen = state.n_seen
        if span[0] <= seen < span[1]:
            return True
        check = next_check(seen, bool(state.undetermined))
        if seen < first or seen + 1 >= check:
            return False
        last = check - 1
        propagation = state.propagation
        if propagation is not None and seen + 1 >= propagation.switch:
            if not propagation.active or (seen + 1) % GRID == 0:
                return False  # a grid sample: the engine captures it
            last = min(last, seen + (-(seen + 1)) % GRID)
        span[:] = seen, last
        return True

    # in the start-up both estimates are NaN: the raw error is NaN and 0 joins the
    # recent values (algid.estimation._core.advance_rows buffers the samples up to sample q - 1)
    last_buffered = min(state.points, companion.points) - 2
    recent = state.recent_errors

    def buffer(values, out, error_out):
        seen = state.n_seen
        if state.early or companion.early or seen > last_buffered or \
                companion.n_seen != seen or \
                seen + 1 >= next_check(seen, bool(state.undetermined)):
            return False
        state.startup[:, seen] = values
        companion.startup[:, seen] = values
        state.n_seen = companion.n_seen = seen + 1
        recent[:-1] = recent[1:]
        recent[-1] = 0.0
        _track_values(state, values)
        out.fill(math.nan)
        error_out.fill(math.nan)
        return True
    return ready, advance, buffer


#: Whether the samples determine the parameters is judged when the estimator has seen
#: a power of two of samples, from this one on (:func:`next_check`) up to
#: :data:`CHECK_EVERY`, then every :data:`CHECK_EVERY` samples; each verdict holds until
#: the next (so that it does not depend on how a stream is cut into chunks).
FIRST_CHECK = 64
#: The longest interval between two checks: a stream that becomes excited late is
#: judged again within this many samples (doubling intervals alone would wait as long
#: as the stream is old).  Checks split a batch into pieces: every 4096 samples cost
#: about a fifth of the NumPy backend's throughput, every 65536 nothing measurable (a
#: batch is advanced in pieces of that size anyway).
CHECK_EVERY = 65536
#: While a parameter is undetermined, it is judged again every this share of the
#: samples seen (:func:`next_check`; a check costs about 0.1 ms).
RECHECK_SHARE = 64
#: ... where the numerical error is above this (or not finite), or an estimate is 0;
#: otherwise the estimate is taken as determined without the test (which costs about
#: 0.1 ms: so that noisy streams, and estimators re-anchored every few tens of samples,
#: are not slowed down).
JUDGED_ABOVE = 0.1


def next_check(n_seen, undetermined=False):
    """The first sample count above ``n_seen`` at which the identifiability is checked.

    Powers of two from :data:`FIRST_CHECK` to :data:`CHECK_EVERY`, then the multiples
    of :data:`CHECK_EVERY`.  While a parameter is undetermined, more often: the
    multiples of :data:`RECHECK_SHARE` of the largest power of two up to ``n_seen``
    (at least :data:`FIRST_CHECK`), so that a stream excited only after a quiet start
    reports estimates within a 64th of its age, not up to :data:`CHECK_EVERY`
    samples later.

    Parameters
    ----------
    n_seen : int
        Samples seen since the time origin.
    undetermined : bool, optional
        Whether the last check left a parameter undetermined.

    Returns
    -------
    int
    """
    n_seen = int(n_seen)
    if undetermined and n_seen >= FIRST_CHECK:
        every = max(FIRST_CHECK, (1 << (n_seen.bit_length() - 1)) // RECHECK_SHARE)
        return min(next_check(n_seen), (n_seen // every + 1) * every)
    if n_seen >= CHECK_EVERY:
        return (n_seen // CHECK_EVERY + 1) * CHECK_EVERY
    return max(FIRST_CHECK, 1 << n_seen.bit_length())


def _piece(state, rows, backend, out, error_out, scratch=None):
    """Estimator, companion and numerical error over a piece with no check inside."""
    if state.propagation is not None and state.propagation.active:
        _propagated_piece(state, rows, backend, out, error_out)
        return
    core.advance_rows(state, rows, out, backend)  # rows and out checked by the caller
    other = core.advance_rows(state.companion, rows,
                              np.empty(out.shape) if scratch is None else scratch, backend)
    if backend == "numba":
        block_error = _compiled()[0]
        block_error(out, other, state.recent_errors, error_out)
        _track_channels_compiled(state, rows)
    else:
        _block_error(out, other, state.recent_errors, error_out)
        _track_channels(state, rows)
    if state.undetermined:
        _mark_undetermined(state, out, error_out)


def _propagated_piece(state, rows, backend, out, error_out):
    """:func:`_piece` past the switch: the estimator alone, and the companion's estimates
    propagated at the grid samples (:mod:`algid.estimation._error_propagation`); the
    estimates stand for them elsewhere (a relative difference of 0, NaN where the
    estimate is NaN), and the window carries the grid samples' differences."""
    propagation = state.propagation
    if backend == "numba":  # the compiled loop writes the error itself
        from algid.estimation._core_numba import advance as numba_advance
        numba_advance(state, core.integrator_layout(state.model), rows, out,
                      error_out=error_out)
        _track_channels_compiled(state, rows)
    else:
        first_grid = (-(state.n_seen + 1)) % GRID  # the chunk's first grid sample
        core.advance_rows(state, rows, out, backend)  # the engine captures the grid samples
        companion = np.concatenate(
            [companion_estimates(propagation, state.model, capture, state.dt)
             for capture in propagation.captured] or [out[:, :0]], axis=1)
        propagation.captured.clear()
        if out.shape[1] <= SCALAR_SAMPLES:
            other = out.copy()
            other[:, first_grid::GRID] = companion
            _sample_errors(out, other, state.recent_errors, error_out)
        else:
            _grid_error(out, first_grid, companion, state.recent_errors, error_out)
        _track_channels(state, rows)
    if state.undetermined:
        _mark_undetermined(state, out, error_out)


def _track_channels(state, rows):
    """The channels' extent (largest absolute value, newest), for the checks."""
    largest, last, divisors = state.channel_max, state.channel_last, state.divisors
    for c, row in enumerate(rows):
        divisor = divisors.item(c)
        newest = row.item(-1) / divisor
        size = abs(newest) if row.size == 1 else max(row.max(), -row.min()) / divisor
        if size > largest[c]:
            largest[c] = size
        last[c] = newest


def _track_channels_compiled(state, rows):
    """:func:`_track_channels` compiled (one pass over each row)."""
    track_extent = _compiled()[1]
    for c, row in enumerate(rows):
        track_extent(row, state.divisors.item(c), c, state.channel_max, state.channel_last)


def _track_values(state, values):
    """:func:`_track_channels` of one sample given as numbers."""
    largest, last, divisors = state.channel_max, state.channel_last, state.divisors
    for c, value in enumerate(values):
        newest = value / divisors.item(c)
        if abs(newest) > largest[c]:
            largest[c] = abs(newest)
        last[c] = newest


def _mark_undetermined(state, out, error_out):
    """NaN for the parameters the data leave undetermined, an infinite error."""
    out[list(state.undetermined)] = np.nan
    error_out[...] = np.inf


#: Chunks of at most this many samples take the scalar path of the NumPy backend
#: (:func:`_sample_errors`: the same numbers, without the arrays' per-call cost).
SCALAR_SAMPLES = 3


def _sample_errors(estimates, other, recent, out):
    """:func:`relative_difference` then :func:`window_maximum`, one sample at a time in
    floats: the same numbers (IEEE division, ``abs`` and ``max`` round alike)."""
    rows = estimates.tolist()
    others = other.tolist()
    held = recent.tolist()
    for j in range(len(out)):
        raw = 0.0 if rows else math.nan
        for row, companion in zip(rows, others):
            a, b = row[j], companion[j]
            if a == 0.0:  # 0 / 0 where they are equal, else inf (the NumPy path's rule)
                rel = 0.0 if b == 0.0 else math.inf
            elif not math.isfinite(a):
                rel = math.nan
            else:
                rel = abs(a - b) / abs(a)
                if rel != rel:  # the companion is NaN: the data do not determine it
                    rel = math.inf
            if rel != rel or raw != raw:
                raw = math.nan
            elif rel > raw:
                raw = rel
        finite = math.isfinite(raw)
        largest = max(held) if held else 0.0
        value = raw if finite else 0.0
        out[j] = max(largest, value) if finite else raw
        held = held[1:] + [value] if held else held
    recent[:] = held


def _grid_error(estimates, first, companion, recent, out):
    """:func:`_block_error` of a block past the switch, where the companion's estimates
    are the estimates' but at the grid samples (every :data:`GRID`-th from ``first``).

    The same numbers without a pass over every sample for each window span: off the
    grid the relative difference is 0 (NaN where an estimate is not finite), so a
    window's largest value is that of its two grid samples, and for the first
    ``WINDOW - 1`` samples also that of the values before the block still in it.

    Parameters
    ----------
    estimates : ndarray, shape (n_parameters, m)
    first : int
        The block's first grid sample.
    companion : ndarray, shape (n_parameters, g)
        The companion's estimates at the block's grid samples, ``first``, ``first +
        GRID``, ...
    recent : ndarray, shape (WINDOW - 1,)
        Updated in place (:func:`window_maximum`).
    out : ndarray, shape (m,)
    """
    m, width = out.size, recent.size
    columns = slice(first, m, GRID)  # (a view: strided, not gathered)
    on_grid = relative_difference(estimates[:, columns], companion)
    level = np.where(np.isfinite(on_grid), on_grid, 0.0)
    # the largest of a sample's window within the block: from each grid sample on, its
    # value and that of the one before it
    out[:first] = 0.0
    if first < m:
        pair = level.copy()
        np.maximum(pair[1:], level[:-1], out=pair[1:])
        out[first:] = np.repeat(pair, GRID)[:m - first]
    head = min(width, m)
    before = np.maximum.accumulate(recent[::-1])[::-1]  # recent[i:]'s largest
    np.maximum(out[:head], before[:head], out=out[:head])
    # NaN where an estimate is not finite (its relative difference), the grid
    # samples' own value where that is not finite
    for row in estimates:
        np.copyto(out, np.nan, where=~np.isfinite(row))
    if not estimates.shape[0]:
        out.fill(np.nan)  # no parameter: no relative difference
    grid = out[columns]
    np.copyto(grid, on_grid, where=~np.isfinite(on_grid))
    tail = np.zeros(head)  # the last samples' values, for the next block
    at = np.arange(first, m, GRID)
    late = at >= m - head
    tail[at[late] - (m - head)] = level[late]
    recent[...] = np.concatenate((recent, tail))[head:]


@cache
def _compiled():
    """The compiled block error and channel extent (``_numerical_error_numba``)."""
    from algid.estimation._numerical_error_numba import block_error, track_extent
    return block_error, track_extent


def _block_error(estimates, other, recent, out):
    """The numerical error of a block into ``out``, with NumPy (in floats for a few
    samples: the same numbers)."""
    if out.size <= SCALAR_SAMPLES:
        _sample_errors(estimates, other, recent, out)
    else:
        window_maximum(relative_difference(estimates, other), recent, out)
