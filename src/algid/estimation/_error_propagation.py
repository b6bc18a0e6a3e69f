"""The companion's estimate propagated from the estimator's own integrals, on a grid.

The numerical error (:mod:`algid.estimation._numerical_error`) compares the estimate
with a companion's: rule ``q' = q + 1`` points (``q - 1`` at the largest rule), filter
order ``p - 1``.  Run in full, the companion costs as much as the estimator.  For
``p >= 1`` its estimate can instead be formed every :data:`GRID` samples from the
estimator's integrals, once the full companion has run for :data:`SWITCH` samples
after the time origin:

- **Chains.**  The increments of the two Adams-Moulton rules differ by a backward
  difference of the integrand, whose running sum telescopes: after the start-up
  ``J' f = J f + T f + c``, ``T`` the FIR of :func:`difference_taps` and ``c`` a
  constant.  ``J`` and ``T`` commute up to constants, so to first order the companion's
  ``m``-fold integral is ``I_m + m T I_(m-1) + poly_m(t - t_s)``, where ``poly_m`` has
  the residuals of levels ``m, m - 1, ..., 1`` at the switch sample ``t_s`` as its
  Taylor coefficients.  Every kernel of the companion is so had at any sample from
  ``len(taps)`` samples of the estimator's level below it: no integration.
- **Filter.**  The companion's lanes (Cramer's numerators and denominator) are the
  algebra of its kernels.  The difference of its filter level ``k`` from the
  estimator's advances by the integral of the difference of level ``k - 1`` (the
  trapezoid over the grid: it is smooth and small) plus the telescoped ``T`` of the
  estimator's level ``k - 1`` (exact).  The companion's estimate is the ratio of the
  estimator's filter level ``p - 1`` plus that difference.

The NumPy engine captures, at every grid sample, the kernels, ``T`` of the levels below
them and of the filter levels below ``p - 1``, and filter level ``p - 1``
(:class:`Capture`), and :func:`companion_estimates` forms the companion's estimates
from them; the compiled loop (``algid/_generated/<model>_numba.py``) does the same
operations in the same order within its blocks.  ``python -m
benchmarks.error_propagation`` measures how well the result bounds the actual error,
against the full companion.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from algid.signals._quadrature import integrator_weights

__all__ = ["difference_taps", "lanes_of", "kernels_at", "Propagation", "Capture",
           "new_propagation", "start", "capture_levels", "newest_integrand",
           "companion_estimates", "GRID", "SWITCH"]

#: The companion's estimate is formed every this many samples (samples seen since the
#: origin a multiple of it).
GRID = 8
#: The full companion runs until the estimator has seen this many samples (a sample
#: where the identifiability is checked: a piece of the chunk ends there).
SWITCH = 1024


def difference_taps(points, companion_points, dt):
    """The FIR ``T`` whose running difference is that of two rules' increments.

    Parameters
    ----------
    points, companion_points : int
        Points of the estimator's rule and of the companion's.
    dt : float
        Sampling step [s] (folded into the taps, as in the integrators' weights).

    Returns
    -------
    ndarray, shape (max(points, companion_points) - 1,)
        Oldest sample first: ``T f[n] = taps @ f[n - len(taps) + 1 : n + 1]``, and
        ``T f[n] - T f[n - 1]`` is the companion's increment minus the estimator's.
    """
    ours = integrator_weights(points, dt)[0][::-1]  # by lag
    theirs = integrator_weights(companion_points, dt)[0][::-1]
    difference = np.zeros(max(points, companion_points))
    difference[:companion_points] += theirs
    difference[:points] -= ours
    running = np.cumsum(difference)  # its last value is 0: both rules integrate 1
    return running[:-1][::-1].copy()


@dataclasses.dataclass
class Propagation:
    """What the propagation carries from one grid sample to the next.

    Attributes
    ----------
    taps : ndarray
        :func:`difference_taps` of the estimator and its companion.
    kernel_levels : ndarray of int
        The level of every kernel.
    residuals : ndarray, shape (n_kernels, max level)
        ``residuals[i, j]``: the residual of level ``level_i - j`` of kernel ``i``'s
        chain at the switch, the coefficient of ``(t - t_s)**j / j!``.
    lanes : ndarray, shape (n_lanes,)
        The companion's lanes minus the estimator's at the last grid sample.
    levels : ndarray, shape (p - 1, n_lanes)
        The companion's filter levels ``1 .. p - 1`` minus the estimator's there.
    telescoped : ndarray, shape (p - 1, n_lanes)
        ``T`` of the estimator's filter levels ``0 .. p - 2`` there.
    switch : int
        Samples seen at the switch (:data:`SWITCH` when it was made).
    active : bool
        Whether the switch has passed (the full companion no longer runs).
    captured : list of Capture
        Captures of the grid samples not yet formed.
    """

    taps: np.ndarray
    kernel_levels: np.ndarray
    residuals: np.ndarray
    lanes: np.ndarray
    levels: np.ndarray
    telescoped: np.ndarray
    switch: int = SWITCH
    active: bool = False
    captured: list = dataclasses.field(default_factory=list)

    def copy(self) -> Propagation:
        """An independent copy (the captures are not carried: there are none between
        chunks)."""
        return dataclasses.replace(self, residuals=self.residuals.copy(),
                                   lanes=self.lanes.copy(), levels=self.levels.copy(),
                                   telescoped=self.telescoped.copy(), captured=[])


@dataclasses.dataclass
class Capture:
    """The estimator at some grid samples, as :func:`companion_estimates` reads it.

    Attributes
    ----------
    seen : ndarray of int, shape (g,)
        Samples seen since the origin at every grid sample.
    kernels : ndarray, shape (n_kernels, g)
        The estimator's kernels.
    below : ndarray, shape (n_kernels, g)
        ``T`` of the chain level below every kernel (0 for a kernel of level 0).
    filters : ndarray, shape (p - 1, n_lanes, g)
        ``T`` of the filter levels ``0 .. p - 2`` (level 0: the lanes).
    lanes : ndarray, shape (n_lanes, g)
        The estimator's filter level 0 (Cramer's numerators and denominator).
    top : ndarray, shape (n_lanes, g)
        The estimator's filter level ``p - 1``.
    """

    seen: np.ndarray
    kernels: np.ndarray
    below: np.ndarray
    filters: np.ndarray
    lanes: np.ndarray
    top: np.ndarray


def new_propagation(state, companion, layout):
    """The propagation of an estimator and its companion, before the switch.

    Parameters
    ----------
    state, companion : EstimatorState
        Fresh; the companion of filter order ``state.filter_order - 1``.
    layout : IntegratorLayout
        Of their model (:func:`algid.estimation._core.integrator_layout`).

    Returns
    -------
    Propagation or None
        None where it does not apply (no filter: the companion's has one level more).
    """
    if state.filter_order < 1 or companion.filter_order != state.filter_order - 1:
        return None
    levels = np.array([level for level, _ in layout.kernels], dtype=np.int64)
    n_lanes, below = layout.n_lanes, state.filter_order - 1
    return Propagation(taps=difference_taps(state.points, companion.points, state.dt),
                       kernel_levels=levels,
                       residuals=np.zeros((levels.size, max(1, int(levels.max())))),
                       lanes=np.zeros(n_lanes), levels=np.zeros((below, n_lanes)),
                       telescoped=np.zeros((below, n_lanes)), switch=SWITCH)


def lanes_of(model, kernels):
    """Cramer's numerators and denominator of the kernels (rows), shape (n_lanes, ...)."""
    P, Q = model.regressors_packed(tuple(kernels))
    numerators, denominator = model.cramer(P, Q)
    shape = np.shape(kernels[0])
    return np.array([np.broadcast_to(v, shape) for v in (*numerators, denominator)],
                    dtype=float)


def kernels_at(state, layout, newest):
    """The kernels at the state's last sample.

    Parameters
    ----------
    state : EstimatorState
    layout : IntegratorLayout
    newest : EstimatorState
        Has the channels' last values (``channel_last``, as the error's companion
        state tracks them): a kernel of level 0 is the chain's newest integrand, kept
        in the history of its first integrator, or formed from them where the chain
        has none (a signal that enters the equation unintegrated).
    """
    first = len(layout.levels[0]) if layout.levels else 0
    return np.array([(state.history[row, -1] if row < first else
                      newest_integrand(newest, layout.chains[row])) if level == 0 else
                     state.integrals[layout.level_start(level) + row]
                     for level, row in layout.kernels])


def newest_integrand(state, chain):
    """``tau**power * channel / divisor`` of a chain ``(channel, power, depth)`` at the
    state's last sample, formed as the engines form it (``tau * tau * ...`` times the
    divided sample)."""
    channel, power, _ = chain
    tau = float(state.n_seen - 1) * state.dt
    factor = 1.0
    if power:
        factor = tau
        for _ in range(power - 1):
            factor = factor * tau
    value = float(state.channel_last[channel])
    return factor * value if power else value


def start(propagation, state, companion, layout):
    """Take the differences at the switch, from the two states; the full companion
    stops there.

    Parameters
    ----------
    propagation : Propagation
        From :func:`new_propagation`; set in place and made active.
    state, companion : EstimatorState
        Both having seen ``propagation.switch`` samples.
    layout : IntegratorLayout
        Of their model.
    """
    taps = propagation.taps = difference_taps(state.points, companion.points, state.dt)
    # the history of whichever keeps len(taps) samples; the sums tap after tap, oldest
    # first (as the generated C)
    longer = state if state.points > companion.points else companion
    for i, (level, row) in enumerate(layout.kernels):
        for j in range(level):
            k = layout.level_start(level - j) + row
            propagation.residuals[i, j] = (
                companion.integrals[k] - state.integrals[k]
                - (level - j) * _grid_fir(longer.history[k], 0, 1, taps)[0])
    propagation.lanes[:] = (lanes_of(state.model, kernels_at(companion, layout, state))
                            - lanes_of(state.model, kernels_at(state, layout, state)))
    n_lanes, first = layout.n_lanes, layout.n_chain_integrators
    for k in range(propagation.levels.shape[0]):
        span = slice(first + k * n_lanes, first + (k + 1) * n_lanes)
        propagation.levels[k] = companion.integrals[span] - state.integrals[span]
        propagation.telescoped[k] = _grid_fir(longer.history[span], 0, 1, taps)[:, 0]
    propagation.active = True
    propagation.captured.clear()


def _grid_fir(padded, base, count, taps):
    """``taps @`` the samples of ``padded`` (last axis) ending at ``base + len(taps) - 1
    + GRID * j``, ``j < count``: strided views, summed tap after tap (oldest first), the
    same numbers for any number of grid samples."""
    stop = base + GRID * (count - 1) + 1
    total = padded[..., base:stop:GRID] * taps[0]
    for k in range(1, taps.size):
        total += padded[..., base + k:stop + k:GRID] * taps[k]
    return total


def capture_levels(propagation, layout, levels, lanes, filters, n0, carried):
    """Capture the grid samples of a block of the NumPy engine.

    Parameters
    ----------
    propagation : Propagation
        Active; the capture is appended to ``captured``.
    layout : IntegratorLayout
    levels : sequence of ndarray, shape (rows, carried + m)
        The chain levels ``0 .. depth``, each with the ``carried`` samples before the
        block.
    lanes : ndarray, shape (n_lanes, carried + m)
        Filter level 0.
    filters : sequence of ndarray, shape (n_lanes, carried + m)
        Filter levels ``1 .. p - 1``.
    n0 : int
        Samples seen before the block.
    carried : int
        At least ``len(taps) - 1``.
    """
    m = lanes.shape[1] - carried
    first = (-(n0 + 1)) % GRID  # block index of the first sample whose count is a multiple
    if first >= m:
        return
    count = (m - 1 - first) // GRID + 1
    taps = propagation.taps
    at = carried + first  # the first grid sample in the padded rows
    base = at - taps.size + 1  # its window's oldest sample
    stop = at + GRID * (count - 1) + 1
    kernels = np.empty((len(layout.kernels), count))
    below = np.zeros((len(layout.kernels), count))
    # the sums of every level below a kernel, all its rows at once (level 0: none)
    sums = {level: _grid_fir(levels[level - 1], base, count, taps)
            for level in {level for level, _ in layout.kernels if level}}
    for i, (level, row) in enumerate(layout.kernels):
        kernels[i] = levels[level][row, at:stop:GRID]
        if level:
            below[i] = sums[level][row]
    stack = (lanes, *filters)
    n_below = propagation.levels.shape[0]
    telescoped = np.empty((n_below, lanes.shape[0], count))
    for k in range(n_below):
        telescoped[k] = _grid_fir(stack[k], base, count, taps)
    propagation.captured.append(Capture(seen=n0 + first + 1 + GRID * np.arange(count),
                                        kernels=kernels, below=below, filters=telescoped,
                                        lanes=lanes[:, at:stop:GRID].copy(),
                                        top=stack[n_below][:, at:stop:GRID].copy()))


def companion_estimates(propagation, model, capture, dt):
    """The companion's estimates at the captured grid samples.

    Parameters
    ----------
    propagation : Propagation
        Active; advanced past the capture.
    model : module
        The generated estimator module.
    capture : Capture
    dt : float
        Sampling step [s].

    Returns
    -------
    ndarray, shape (n_parameters, g)
        NaN where the companion's denominator is zero or not finite.
    """
    since = (capture.seen - propagation.switch) * dt
    theirs = capture.kernels.copy()
    levels = propagation.kernel_levels
    theirs += levels[:, None] * capture.below
    power = np.ones_like(since)
    for j in range(propagation.residuals.shape[1]):  # the polynomials, term by term
        if j:
            power = power * since / j
        used = levels > j
        theirs[used] += propagation.residuals[used, j, None] * power
    below = lanes_of(model, theirs) - capture.lanes  # filter level 0
    previous = propagation.lanes.copy()
    propagation.lanes[:] = below[:, -1]
    for k in range(propagation.levels.shape[0]):  # filter level k + 1
        trapezoid = GRID * dt / 2.0 * (np.concatenate((previous[:, None], below[:, :-1]),
                                                      axis=1) + below)
        fir = capture.filters[k]
        steps = trapezoid + np.diff(np.concatenate((propagation.telescoped[k][:, None], fir),
                                                   axis=1), axis=1)
        propagation.telescoped[k] = fir[:, -1]
        previous = propagation.levels[k].copy()
        # summed from the carried value, left to right: the same numbers however the
        # grid samples are split into captures (chunks, blocks)
        below = np.cumsum(np.concatenate((previous[:, None], steps), axis=1), axis=1)[:, 1:]
        propagation.levels[k] = below[:, -1]
    top = capture.top + below
    denominator = top[-1]
    defined = np.isfinite(denominator) & (denominator != 0.0)
    out = np.full((top.shape[0] - 1, top.shape[1]), math.nan)
    np.divide(top[:-1], denominator, out=out, where=defined)
    return out
