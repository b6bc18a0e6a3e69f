"""The NumPy backend of the estimator core (:mod:`algid.estimation._core`).

Every level of integrators forms its increments with one :func:`numpy.correlate` over
all its rows (the rows of a level sit one after another in one flat buffer, each
preceded by its carried samples, so that the outputs that straddle two rows are simply
not read) and its running sums with one cumulative sum along the rows.  A long chunk is
processed in blocks of :data:`BLOCK` samples, whose working arrays stay in the
processor's cache; the result does not depend on the block size (a block is a chunk,
and chunks do not change the numbers).

Chunks of at most :data:`SMALL_CHUNK` samples (one sample per call, say) take a
per-sample step instead: the products of the carried samples and the weights for
every integrator at once, then the sums in Python floats.  It performs the operations
of :func:`numpy.correlate` (``s = 0; s += d[i] * w[i]``, oldest sample first, no fused
multiply-add) and of the cumulative sum in the same order, so it gives the same
numbers bit for bit; :func:`sample_step_is_exact` checks this on the running platform
once, and the step is used only where it holds.
"""

from __future__ import annotations

import dis
import math
from functools import cache, lru_cache

import numpy as np

from algid.estimation._error_propagation import GRID, capture_levels
from algid.signals._quadrature import integrator_weights

__all__ = ["advance", "advance_sample", "sample_step_is_exact", "BLOCK", "SMALL_CHUNK"]

#: Samples per block of the NumPy backend.
BLOCK = 32768
#: Chunks of at most this many samples take the per-sample step (when it is exact).
SMALL_CHUNK = 3


@lru_cache(maxsize=64)
def _weights(points, dt):
    regular, startup = integrator_weights(points, dt)
    return regular, startup, regular[:-1].copy(), float(regular[-1])


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


def _solve(state, kernels, lanes):
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


class _Level:
    """The samples of one level: ``rows`` rows of ``width`` carried samples then ``m``
    new ones, in one flat buffer with ``width`` spare zeros at the end."""

    __slots__ = ("flat", "padded", "samples", "carried", "newest")

    def __init__(self, rows, width, m):
        span = width + m
        self.flat = np.zeros(rows * span + width)
        self.padded = self.flat[:rows * span].reshape(rows, span)
        self.samples = self.padded[:, width:]
        self.carried = self.padded[:, :width]  # the samples before the chunk
        self.newest = self.padded[:, m:]  # the last `width` samples: carried to the next


class _Work:
    """Working arrays of :func:`_block` for chunks of ``m`` samples, with their views
    into the state (kept with the state for small chunks, which repeat)."""

    def __init__(self, state, layout, m):
        width = state.points - 1
        sizes, starts = _level_blocks(layout)
        self.m = m
        self.integrals, self.history = state.integrals, state.history
        level = _Level(len(layout.chains), width, m)
        self.levels = [level]
        self.steps = []  # (driving level, rows, integrals, history, driven samples)
        for depth, size in enumerate(sizes, start=1):
            start, stop = starts[depth - 1], starts[depth]
            following = _Level(size, width, m)
            self.steps.append((level, size, state.integrals[start:stop],
                               state.history[start:stop], following.samples))
            self.levels.append(following)
            level = following
        self.kernels = tuple(self.levels[depth].samples[row] for depth, row in layout.kernels)
        self.lanes = lanes = _Level(layout.n_lanes, width, m)
        self.filter_levels = []  # filter levels 0 .. p - 1
        start = starts[-1]
        for _ in range(state.filter_order):
            self.filter_levels.append(lanes)
            stop = start + layout.n_lanes
            integrated = _Level(layout.n_lanes, width, m)
            self.steps.append((lanes, layout.n_lanes, state.integrals[start:stop],
                               state.history[start:stop], integrated.samples))
            lanes = integrated
            start = stop
        self.result = lanes.samples


def _work(state, layout, m):
    """The working arrays for a chunk of ``m`` samples (reused for small chunks)."""
    work = getattr(state, "_numpy_work", None)
    if work is not None and work.m == m and work.integrals is state.integrals \
            and work.history is state.history:
        return work
    work = state._numpy_work = _Work(state, layout, m)
    return work


#: Chunks of at most this many samples keep their working arrays with the state (longer
#: ones keep them only while the chunk is processed, block after block).
REUSED_WORK = 4096


def _integrate(level, rows, weights, integrals, target, startup=None):
    """Integrate the first ``rows`` rows of ``level`` into ``target`` (rows, m).

    ``inc[r, i] = weights @ padded[r, i : i + points]`` (one correlate over the flat
    buffer: output ``r * span + i`` is that window), then ``target[r] = integrals[r] +
    inc[r, 0] + ... + inc[r, i]`` summed left to right.  With ``startup`` the samples
    start at the time origin: the first increment is 0 and the next ``points - 2`` take
    the start-up rule (each ``((s[0] a[0] + s[1] a[1]) + ...)``, as
    :func:`algid.signals._quadrature.advance_integrators`); ``integrals`` are then ignored.
    """
    m = target.shape[1]
    span = level.padded.shape[1]
    width = span - m
    inc = np.correlate(level.flat[:rows * span + width], weights,
                       mode="valid").reshape(rows, span)[:, :m]
    if startup is None:
        inc[:, 0] += integrals
    else:
        inc[:, 0] = 0.0
        if width > 1:  # all start-up increments of all rows at once, in the rule's order
            products = level.samples[:rows, None, :width + 1] * startup
            np.add.accumulate(products, axis=2, out=products)  # left to right
            inc[:, 1:width] = products[:, :, width]
    inc.cumsum(axis=1, out=target)
    integrals[...] = target[:, m - 1]


def _block(state, layout, channels, out, from_origin):
    """Estimates of one block into ``out``; the state advances past it."""
    m = channels[0].size
    weights, startup, _, _ = _weights(state.points, state.dt)
    startup = startup if from_origin else None
    work = _work(state, layout, m)
    _integrands(state, layout, channels, 0 if from_origin else state.n_seen,
                work.levels[0].samples)
    chain_steps = len(work.levels) - 1
    for i, (level, rows, integrals, history, target) in enumerate(work.steps):
        if i == chain_steps:
            _solve(state, work.kernels, work.lanes.samples)
        if from_origin:
            level.carried[:rows] = 0.0
        else:
            level.carried[:rows] = history
        _integrate(level, rows, weights, integrals, target, startup)
        history[...] = level.newest[:rows]
    if len(work.steps) == chain_steps:  # no filter
        _solve(state, work.kernels, work.lanes.samples)
    _divide(work.result, out)
    propagation = state.propagation
    if propagation is not None and propagation.active:  # (never from the origin)
        capture_levels(propagation, layout, [level.padded for level in work.levels],
                       work.lanes.padded, [level.padded for level in work.filter_levels[1:]],
                       state.n_seen, state.points - 1)
    if from_origin:
        out[:, :state.points - 1] = np.nan
        state.n_seen = m
    else:
        state.n_seen += m


# ------------------------------------------------------------------ the per-sample step

#: Byte codes of plain arithmetic on locals: the generated algebra may run on floats
#: only if it uses nothing else (no power, division or call, which Python floats and
#: NumPy arrays might round differently or refuse).
_PLAIN = {"RESUME", "NOP", "LOAD_FAST", "LOAD_FAST_CHECK", "LOAD_FAST_LOAD_FAST",
          "STORE_FAST", "STORE_FAST_STORE_FAST", "STORE_FAST_LOAD_FAST", "LOAD_CONST",
          "RETURN_VALUE", "RETURN_CONST", "BUILD_TUPLE", "UNPACK_SEQUENCE", "BINARY_SUBSCR",
          "UNARY_NEGATIVE", "COPY", "SWAP", "POP_TOP", "CACHE", "BINARY_ADD",
          "BINARY_SUBTRACT", "BINARY_MULTIPLY"}
_PLAIN_OPS = {"+", "-", "*", "+=", "-=", "*="}


def _plain_arithmetic(function) -> bool:
    for instruction in dis.get_instructions(function):
        if instruction.opname == "BINARY_OP":
            if instruction.argrepr not in _PLAIN_OPS:
                return False
        elif instruction.opname not in _PLAIN:
            return False
    return True


@cache
def _algebra_on_floats(module) -> bool:
    """Whether the generated algebra of ``module`` gives, on floats, the numbers it
    gives on arrays (true when it is made of ``+``, ``-`` and ``*`` only)."""
    return _plain_arithmetic(module.regressors_packed) and _plain_arithmetic(module.cramer)


@cache
def sample_step_is_exact() -> bool:
    """Whether the per-sample step gives the numbers of :func:`numpy.correlate` here.

    :func:`numpy.correlate` of a short kernel sums ``s = 0; s += d[i] * w[i]`` oldest
    sample first; a build that fuses the multiply and the add would differ.  Checked on
    random samples spanning many magnitudes, for every number of points.

    Returns
    -------
    bool
        True if every checked increment is equal bit for bit.
    """
    from algid.signals._quadrature import QUADRATURE_POINTS
    rng = np.random.default_rng(20240611)
    for points in QUADRATURE_POINTS:
        weights = rng.standard_normal(points) * 10.0 ** rng.integers(-8, 8, points)
        samples = rng.standard_normal(400) * 10.0 ** rng.integers(-30, 30, 400)
        samples[::7] = -0.0
        expected = np.correlate(samples, weights, mode="valid")
        products = np.lib.stride_tricks.sliding_window_view(samples, points)[:, :-1] \
            * weights[:-1]
        w_last = float(weights[-1])
        for i, (row, newest) in enumerate(zip(products.tolist(),
                                              samples[points - 1:].tolist())):
            s = 0.0
            for p in row:
                s += p
            if (s + newest * w_last) != expected[i] or \
                    math.copysign(1.0, s + newest * w_last) != math.copysign(1.0, expected[i]):
                return False
    return True


@cache
def _sample_plan(layout, filter_order):
    """Where every integrator of the per-sample step takes its newest sample from.

    Values are numbered: level 0 of the chains, then the chain integrators in state
    order; for the filter, the numerators and the denominator, then the filter
    integrators.  Returns the chain drivers, a getter of the kernels and the filter
    drivers.
    """
    n_chains = len(layout.chains)
    starts = [layout.level_start(level) for level in range(1, len(layout.levels) + 1)]
    chain_drivers = []
    for level, rows in enumerate(layout.levels, start=1):
        for r in range(len(rows)):
            chain_drivers.append(r if level == 1 else n_chains + starts[level - 2] + r)
    kernel_values = [row if level == 0 else n_chains + starts[level - 1] + row
                     for level, row in layout.kernels]
    lanes = layout.n_lanes
    filter_drivers = [r if level == 0 else lanes + (level - 1) * lanes + r
                      for level in range(filter_order) for r in range(lanes)]
    return chain_drivers, kernel_values, filter_drivers


def _sample_fixed(state, layout):
    """What :func:`_sample_steps` takes from ``state`` and its layout, kept with the
    state while its step and arrays stay: the step, the weights, the plan, the
    divisors, and the working array with its views and those of the history."""
    _, _, carried_weights, w_last = _weights(state.points, state.dt)
    history = state.history
    # products[:, 0] = 0, then the carried samples times their weights: the running
    # sums along a row are correlate's sums over the carried samples
    products = np.zeros((history.shape[0], history.shape[1] + 1))
    return (state.dt, state.integrals, history, carried_weights, w_last,
            *_sample_plan(layout, state.filter_order), _algebra_on_floats(state.model),
            tuple((channel, power) for channel, power, _ in layout.chains),
            state.divisors.tolist(), products, products[:, 1:], products[:, -1],
            history[:, :-1], history[:, 1:], history[:, -1])


def advance_sample(state, layout, values, out):
    """Estimates of one sample given as numbers, into ``out``.

    The sample continues the stream, past the start-up.  The per-sample step, without
    making arrays of the sample: the numbers of :func:`advance` where
    :func:`sample_step_is_exact` (call :func:`advance` where not).

    Parameters
    ----------
    state : EstimatorState
        Past its start-up; advanced in place.
    layout : IntegratorLayout
        Layout of the state's model (:func:`algid.estimation._core.integrator_layout`).
    values : sequence of float
        The sample of every channel, in the model's ``CHANNELS`` order.
    out : ndarray, shape (n_parameters, 1)
        Float64 array the estimates are written into.
    """
    _sample_columns(state, layout, [[value] for value in values], out)


def _sample_steps(state, layout, channels, out):
    """Estimates of a few samples, one at a time, into ``out`` (the state is past the
    start-up): the arithmetic of :func:`_block`, in the same order."""
    _sample_columns(state, layout, [row.tolist() for row in channels], out)


def _sample_columns(state, layout, columns, out):
    """:func:`_sample_steps` of the channels given as lists of floats."""
    model = state.model
    integrals, history = state.integrals, state.history
    fixed = state.__dict__.get("_numpy_sample")
    if fixed is None or fixed[0] != state.dt or fixed[1] is not integrals \
            or fixed[2] is not history:
        fixed = state._numpy_sample = _sample_fixed(state, layout)
    (dt, _, _, carried_weights, w_last, chain_drivers, kernel_values, filter_drivers,
     on_floats, chains, divisors, products, weighted, last, older, newer,
     newest_column) = fixed
    n_chain = len(chain_drivers)
    n_parameters = layout.n_lanes - 1
    for j in range(len(columns[0])):
        np.multiply(history, carried_weights, out=weighted)
        np.add.accumulate(products, axis=1, out=products)
        carried = last.tolist()  # (column 0 stays 0)
        sums = integrals.tolist()
        tau = (state.n_seen + j) * dt
        signals = [column[j] if d == 1.0 else column[j] / d
                   for column, d in zip(columns, divisors)]
        values = []
        for channel, power in chains:
            if power == 0:
                values.append(signals[channel])
            else:
                factor = tau
                for _ in range(power - 1):
                    factor = factor * tau
                values.append(factor * signals[channel])
        newest = []
        for k, driver in enumerate(chain_drivers):
            sample = values[driver]
            newest.append(sample)
            sums[k] = total = sums[k] + (carried[k] + sample * w_last)
            values.append(total)
        kernels = tuple([values[i] for i in kernel_values])
        if not on_floats:
            kernels = tuple(np.array([value]) for value in kernels)
        P, Q = model.regressors_packed(kernels)
        numerators, denominator = model.cramer(P, Q)
        lanes = [float(value if on_floats else np.asarray(value).reshape(-1)[0])
                 for value in (*numerators, denominator)]
        for k, driver in enumerate(filter_drivers, start=n_chain):
            sample = lanes[driver]
            newest.append(sample)
            sums[k] = total = sums[k] + (carried[k] + sample * w_last)
            lanes.append(total)
        denominator = lanes[-1]
        if denominator == 0.0 or not math.isfinite(denominator):
            out[:, j] = math.nan
        else:
            first = len(lanes) - n_parameters - 1
            for r in range(n_parameters):
                out[r, j] = lanes[first + r] / denominator
        integrals[:] = sums
        older[...] = newer
        newest_column[...] = newest
    state.n_seen += len(columns[0])


def _captures(state, m):
    """Whether the next ``m`` samples hold a grid sample the error propagation
    captures (:mod:`algid.estimation._error_propagation`; the blocks do)."""
    propagation = state.propagation
    return propagation is not None and propagation.active and \
        (state.n_seen + m) // GRID > state.n_seen // GRID


def advance(state, layout, channels, out, *, from_origin=False):
    """Estimates of a chunk into ``out``, block by block.

    The chunk continues the stream, or with ``from_origin`` it holds the first samples
    after the time origin (at least ``points`` of them; the estimates of samples
    ``0 .. points - 2`` are NaN).

    Parameters
    ----------
    state : EstimatorState
        The state (:func:`algid.estimation._core.new_state`); advanced in place.
    layout : IntegratorLayout
        Layout of the state's model (:func:`algid.estimation._core.integrator_layout`).
    channels : tuple of ndarray
        The chunk: one float64 1-D array per channel, all of length ``m``, in the
        model's ``CHANNELS`` order.
    out : ndarray, shape (n_parameters, m)
        Float64 array the estimates are written into.
    from_origin : bool, optional
        The chunk starts at the time origin (the state holds no sample yet).
    """
    m = channels[0].size
    if not from_origin and m <= SMALL_CHUNK and sample_step_is_exact() and \
            not _captures(state, m):
        _sample_steps(state, layout, channels, out)
        return
    first = True
    for start in range(0, m, BLOCK):
        stop = min(m, start + BLOCK)
        _block(state, layout, tuple(c[start:stop] for c in channels), out[:, start:stop],
               from_origin and first)
        first = False
    if min(m, BLOCK) > REUSED_WORK:
        del state._numpy_work
