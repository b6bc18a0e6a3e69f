"""The NumPy backend of the estimator core (:mod:`algid.core`).

Every integrator forms its increments with :func:`numpy.correlate` and its running
sum with a cumulative sum, two integrators per complex cumulative sum
(:func:`algid.quadrature.integrate_padded`).  A long chunk is processed in blocks of
:data:`BLOCK` samples, whose working arrays stay in the processor's cache; the result
does not depend on the block size (a block is a chunk, and chunks do not change the
numbers).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from algid.quadrature import advance_integrators, integrate_padded, integrator_weights

__all__ = ["advance", "advance_from_origin", "BLOCK"]

#: Samples per block of the NumPy backend.
BLOCK = 32768


@lru_cache(maxsize=64)
def _weights(points, dt):
    return integrator_weights(points, dt)


def _integrands(state, layout, channels, n0, out):
    """Level 0 of every chain, ``tau**power * channel / divisor``, into ``out``
    (shape (chains, m))."""
    m = out.shape[1]
    values = []
    for c, row in enumerate(channels):
        divisor = state.divisors[c]
        values.append(row if divisor == 1.0 else row / divisor)
    tau = (n0 + np.arange(m)) * state.dt
    powers = {1: tau}
    for i, (channel, power, _) in enumerate(layout.chains):
        if power == 0:
            out[i] = values[channel]
            continue
        for k in range(2, power + 1):  # tau * tau * ...: the product the compiled loop forms
            if k not in powers:
                powers[k] = powers[k - 1] * tau
        np.multiply(powers[power], values[channel], out=out[i])


def _solve(state, layout, kernels, lanes, out):
    """``P``, ``Q``, Cramer's rule into ``lanes`` (numerators, then the denominator)."""
    P, Q = state.model.regressors_packed(kernels)
    numerators, denominator = state.model.cramer(P, Q)
    for r, values in enumerate((*numerators, denominator)):
        lanes[r] = values  # broadcasts a constant


def _divide(lanes, out):
    """``numerator / denominator``, NaN where the denominator is zero or not finite."""
    denominator = lanes[-1]
    defined = np.isfinite(denominator)
    defined &= denominator != 0.0
    np.divide(lanes[:-1], denominator, out=out, where=defined)
    if not defined.all():
        out[:, ~defined] = np.nan


def advance_from_origin(state, layout, channels, out):
    """Estimates of the first ``points`` samples after the time origin.

    They are integrated with the start-up rule; ``state`` holds no sample yet.  The
    estimates written into ``out`` are NaN but the last.

    Parameters
    ----------
    state : EstimatorState
        The state (:func:`algid.core.new_state`); advanced in place.
    layout : IntegratorLayout
        Layout of the state's model (:func:`algid.core.integrator_layout`).
    channels : tuple of ndarray
        The chunk: one float64 1-D array per channel, all of length ``m``, in the
        model's ``CHANNELS`` order.
    out : ndarray, shape (n_parameters, m)
        Float64 array the estimates are written into.
    """
    m = channels[0].size
    weights, startup = _weights(state.points, state.dt)
    integrals, history = state.integrals, state.history
    levels = [np.empty((len(layout.chains), m))]
    _integrands(state, layout, channels, 0, levels[0])
    start = 0
    for rows in layout.levels:
        stop = start + len(rows)
        levels.append(advance_integrators(levels[-1][:len(rows)], integrals[start:stop],
                                          history[start:stop], weights, startup))
        start = stop
    lanes = np.empty((layout.n_lanes, m))
    _solve(state, layout, tuple(levels[level][row] for level, row in layout.kernels), lanes,
           out)
    for _ in range(state.filter_order):
        stop = start + layout.n_lanes
        lanes = advance_integrators(lanes, integrals[start:stop], history[start:stop],
                                    weights, startup)
        start = stop
    _divide(lanes, out)
    out[:, :state.points - 1] = np.nan
    state.n_seen = m


_BLOCKS = {}


def _level_blocks(layout):
    """Rows per chain level, and the first integrator of every level and of the filter
    (computed once per layout; layouts live as long as their module)."""
    blocks = _BLOCKS.get(id(layout))
    if blocks is None or blocks[0] is not layout:
        sizes = [len(rows) for rows in layout.levels]
        starts = [layout.level_start(level) for level in range(1, len(sizes) + 2)]
        blocks = _BLOCKS[id(layout)] = (layout, sizes, starts)
    return blocks[1], blocks[2]


def _padded(history_rows, rows, width, m):
    """A level's buffer: the history of the integrators it drives, then ``m`` samples."""
    buffer = np.empty((rows, width + m))
    buffer[:history_rows.shape[0], :width] = history_rows
    return buffer


def _block(state, layout, channels, out):
    """Estimates of one block into ``out``; the state advances past it."""
    m = channels[0].size
    weights, _ = _weights(state.points, state.dt)
    width = state.points - 1
    integrals, history = state.integrals, state.history
    sizes, starts = _level_blocks(layout)
    # buffers[l][:, width:] holds level l of the chains; buffers[l][:, :width] the
    # history of the integrators of level l + 1, which it drives
    buffers = []
    for level in range(len(sizes) + 1):
        driven = history[starts[level]:starts[level + 1]] if level < len(sizes) else history[:0]
        rows = len(layout.chains) if level == 0 else sizes[level - 1]
        buffers.append(_padded(driven, rows, width, m))
    _integrands(state, layout, channels, state.n_seen, buffers[0][:, width:])
    for level, size in enumerate(sizes, start=1):
        start, stop = starts[level - 1], starts[level]
        drive = buffers[level - 1][:size]
        integrate_padded(drive, integrals[start:stop], weights, buffers[level][:, width:])
        history[start:stop] = drive[:, m:]
    kernels = tuple(buffers[level][row, width:] for level, row in layout.kernels)
    start = starts[-1]
    lanes = _padded(history[start:start + layout.n_lanes], layout.n_lanes, width, m)
    _solve(state, layout, kernels, lanes[:, width:], out)
    for level in range(state.filter_order):
        stop = start + layout.n_lanes
        following = history[stop:stop + layout.n_lanes] \
            if level + 1 < state.filter_order else history[:0]
        integrated = _padded(following, layout.n_lanes, width, m)
        integrate_padded(lanes, integrals[start:stop], weights, integrated[:, width:])
        history[start:stop] = lanes[:, m:]
        lanes = integrated
        start = stop
    _divide(lanes[:, width:], out)
    state.n_seen += m


def advance(state, layout, channels, out, *, from_origin=False):
    """Estimates of a chunk into ``out``, block by block.

    The chunk continues the stream, or with ``from_origin`` it holds the first
    ``points`` samples after the time origin (:func:`advance_from_origin`).

    Parameters
    ----------
    state : EstimatorState
        The state (:func:`algid.core.new_state`); advanced in place.
    layout : IntegratorLayout
        Layout of the state's model (:func:`algid.core.integrator_layout`).
    channels : tuple of ndarray
        The chunk: one float64 1-D array per channel, all of length ``m``, in the
        model's ``CHANNELS`` order.
    out : ndarray, shape (n_parameters, m)
        Float64 array the estimates are written into.
    from_origin : bool, optional
        The chunk starts at the time origin (the state holds no sample yet).
    """
    if from_origin:
        advance_from_origin(state, layout, channels, out)
        return
    m = channels[0].size
    for start in range(0, m, BLOCK):
        stop = min(m, start + BLOCK)
        _block(state, layout, tuple(c[start:stop] for c in channels), out[:, start:stop])
