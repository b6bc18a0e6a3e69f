"""A cheaper numerical error: the companion's difference propagated on a grid (a study).

Run from the repository root: ``python -m benchmarks.error_propagation [--n 400]
[--seed 0]``.  :func:`algid.estimate` computes this propagation (its engines form the
same numbers within their loops, :mod:`algid.estimation._error_propagation`); the full
companion, which costs about as much as the estimator itself, runs only with
``algid.estimation._numerical_error.PROPAGATE`` off.  This module evaluates, on the
plants of :mod:`benchmarks.population`, whether the companion's estimate formed from the
estimator's own integrals every :data:`GRID` samples is as honest as the full one, and
forms it apart, in one block, as a check of the engines.

The design, for an estimator of rule ``q`` and filter order ``p >= 1`` whose companion
has rule ``q' = q + 1`` (``q - 1`` at the largest rule) and filter order ``p - 1``:

- **Rule, chains.**  The Adams-Moulton increments of ``q'`` and ``q`` points differ by
  a multiple of a backward difference of order ``max(q, q') - 1`` of the integrand,
  whose running sum telescopes: after the start-up, ``J' f = J f + T f + c`` exactly,
  with ``T`` an FIR of ``max(q, q') - 1`` taps (:func:`difference_taps`) and ``c`` a
  constant.  ``J`` and ``T`` commute up to constants, so to first order the
  companion's ``m``-fold integral of a chain is ``I_m + m T I_(m-1) + poly_m(t)``:
  ``I_m`` the estimator's, ``T`` applied to the estimator's level below, and a
  polynomial of degree ``m - 1`` whose coefficients are the residuals of levels
  ``1 .. m`` at the switch sample.  No integration: every kernel of the companion is
  had at any sample from ``max(q, q') - 1`` samples of the level below it.
- **Filter.**  The companion's lanes (Cramer's numerators and denominator) are the
  algebra of its kernels; their difference from the estimator's is nonlinear, so the
  difference of each companion filter level is integrated on the grid by the
  trapezoid, plus the telescoped ``T`` of the estimator's level below, which is exact.
  The companion's filter level ``p - 1`` is the estimator's own plus that difference.
- **Start.**  The full companion runs for the first :data:`SWITCH` samples after the
  origin (the start-up, where the identities do not hold yet, and short records); at
  that sample the residuals and differences are read from the two states (``T`` of
  the level below from the history of whichever rule keeps more samples).
- **Grid.**  From then on the companion's estimate, and the relative difference, exist
  every :data:`GRID` samples; the reported error is the largest over the last
  :data:`algid.estimation._numerical_error.WINDOW` samples (two grid points).

Reported, for the error at the final sample of every plant: the three criteria of
:mod:`benchmarks.population` (bounded within 10x, silent failures, reported at most
1e-6 among the plants whose actual error is below 1e-6) for the companion and for the
propagation, and the ratio of the two on the records longer than the switch.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import time

import numpy as np

import algid
import algid.estimation._core as core
import algid.estimation._core_numpy as core_numpy
import algid.estimation._numerical_error as numerical_error
from algid.estimation._error_propagation import GRID, SWITCH, difference_taps, kernels_at, lanes_of
from algid.estimation._numerical_error import WINDOW, relative_difference, with_companion
from algid.models._registry import load_model

__all__ = ["difference_taps", "propagated_error", "compare", "main", "GRID", "SWITCH"]

def _fir_at(padded, row, ends, taps):
    """``taps @`` the samples of ``padded[row]`` ending at every index of ``ends``."""
    width = taps.size
    total = np.zeros(ends.size)
    for k, tap in enumerate(taps):  # strided views: one pass per tap
        total += tap * padded[row][ends - width + 1 + k]
    return total


def propagated_error(t, f, x, *, points=8, filter_order=2, model="msd"):
    """The propagated numerical error at the final sample of a record.

    Parameters
    ----------
    t, f, x : ndarray
        A uniformly sampled record of more than ``SWITCH + 2 * GRID`` samples.
    points, filter_order : int, optional
        The estimator's options (``filter_order >= 1``).
    model : str, optional

    Returns
    -------
    error : float
        The largest relative difference between the estimate and the propagated
        companion's at the grid samples among the last ``WINDOW``.
    estimates : ndarray, shape (n_parameters,)
        The estimate at the final sample (for a check against :func:`algid.estimate`).
    """
    module = load_model(model)
    layout = core.integrator_layout(module)
    dt = float((t[-1] - t[0]) / (t.size - 1))
    n = t.size
    if filter_order < 1 or n <= SWITCH + 2 * GRID:
        raise ValueError("the propagation needs filter_order >= 1 and a longer record")
    state = with_companion(core.new_state(module, points=points, filter_order=filter_order,
                                          dt=dt))
    companion = state.companion
    rows = (np.ascontiguousarray(f, dtype=float), np.ascontiguousarray(x, dtype=float))
    n_parameters = len(module.PARAMETERS)
    for s in (state, companion):
        core.advance_rows(s, tuple(r[:SWITCH] for r in rows), np.empty((n_parameters, SWITCH)))
    state.channel_last[:] = [r[SWITCH - 1] for r in rows]  # (divisors 1)
    taps = difference_taps(points, companion.points, dt)
    longer = state if points > companion.points else companion
    # residuals of every chain integrator at the switch
    residual = {}
    for level in range(1, len(layout.levels) + 1):
        for row in range(len(layout.levels[level - 1])):
            i = layout.level_start(level) + row
            residual[level, row] = (companion.integrals[i] - state.integrals[i]
                                    - level * (longer.history[i] @ taps))
    n_lanes, first_filter = layout.n_lanes, layout.n_chain_integrators
    lane_difference = (lanes_of(module, kernels_at(companion, layout, state))
                       - lanes_of(module, kernels_at(state, layout, state)))
    filters = [slice(first_filter + k * n_lanes, first_filter + (k + 1) * n_lanes)
               for k in range(filter_order - 1)]
    level_difference = [companion.integrals[s] - state.integrals[s] for s in filters]
    telescoped = [longer.history[s] @ taps for s in filters]
    # the estimator alone over the rest, in one block whose levels stay readable
    m = n - SWITCH
    rest = np.empty((n_parameters, m))
    core_numpy._block(state, layout, tuple(r[SWITCH:] for r in rows), rest, False)
    work = state._numpy_work
    carried = points - 1
    grid = np.arange(SWITCH + GRID, n + 1, GRID)  # samples seen at the grid points
    index = grid - 1 - SWITCH  # in the block
    ends = carried + index  # in the levels' padded rows
    since = (grid - SWITCH) * dt
    ours, theirs = [], []
    for level, row in layout.kernels:
        value = work.levels[level].samples[row][index]
        ours.append(value)
        if level == 0:
            theirs.append(value)
            continue
        correction = level * _fir_at(work.levels[level - 1].padded, row, ends, taps)
        for j in range(level):
            correction += residual[level - j, row] * since**j / math.factorial(j)
        theirs.append(value + correction)
    below = np.concatenate([lane_difference[:, None],
                            lanes_of(module, theirs) - lanes_of(module, ours)], axis=1)
    chain_steps = len(work.levels) - 1
    for k in range(1, filter_order):
        driving = work.steps[chain_steps + k - 1][0]  # the estimator's filter level k - 1
        fir = np.stack([_fir_at(driving.padded, lane, ends, taps) for lane in range(n_lanes)])
        fir = np.concatenate([telescoped[k - 1][:, None], fir], axis=1)
        steps = GRID * dt / 2 * (below[:, :-1] + below[:, 1:]) + np.diff(fir, axis=1)
        below = np.concatenate([level_difference[k - 1][:, None],
                                level_difference[k - 1][:, None] + np.cumsum(steps, axis=1)],
                               axis=1)
    top = (work.lanes.samples if filter_order == 1 else
           work.steps[chain_steps + filter_order - 1][0].samples)[:, index] + below[:, 1:]
    with np.errstate(divide="ignore", invalid="ignore"):
        theirs_estimates = top[:-1] / top[-1]
    raw = relative_difference(rest[:, index], theirs_estimates)
    return float(np.max(raw[grid > n - WINDOW])), rest[:, -1].copy()


@contextlib.contextmanager
def _full_companion():
    """:func:`algid.estimate` with the full companion throughout (no propagation)."""
    propagate = numerical_error.PROPAGATE
    numerical_error.PROPAGATE = False
    try:
        yield
    finally:
        numerical_error.PROPAGATE = propagate


def compare(n_plants=400, seed=0):
    """The companion's and the propagated error at the final sample of every plant.

    Parameters
    ----------
    n_plants, seed : int, optional
        The plants of :func:`benchmarks.population.draw_plants`.

    Returns
    -------
    dict
        ``error``, ``companion``, ``propagated`` (arrays, one value per plant),
        ``samples`` (record lengths) and ``estimate_difference`` (the largest relative
        difference between the final estimates of the study's run, whose blocks differ,
        and those of :func:`algid.estimate`).
    """
    from benchmarks.population import draw_plants, exact_response
    error, companion, propagated, samples, difference = [], [], [], [], 0.0
    for plant in draw_plants(n_plants, seed):
        t, f, x = exact_response(plant)
        with _full_companion():
            result = algid.estimate(t, f, x)
        final = np.array([result.B[-1], result.K[-1]])
        actual = float(np.max(np.abs(final / np.array([plant.B, plant.K]) - 1.0)))
        error.append(actual if np.isfinite(actual) else math.inf)
        companion.append(float(result.numerical_error[-1]))
        if t.size > SWITCH + 2 * GRID:
            value, estimates = propagated_error(t, f, x)
            difference = max(difference, float(np.max(np.abs(estimates / final - 1.0))))
        else:  # the full companion runs over the whole record
            value = companion[-1]
        propagated.append(value)
        samples.append(t.size)
    return {"error": np.array(error), "companion": np.array(companion),
            "propagated": np.array(propagated), "samples": np.array(samples),
            "estimate_difference": difference}


def _criteria(error, reported):
    accurate = error < 1e-6
    return {"bounded": float(np.mean((error <= 10 * reported) | (error < 1e-10))),
            "silent": int(np.sum((error > 1e-3) & ~(reported > 1e-4))),
            "at_most_1e-6": float(np.mean(reported[accurate] <= 1e-6)),
            "accurate": int(accurate.sum())}


def main(argv=None):
    """Print the comparison (see the module's docstring)."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.error_propagation")
    parser.add_argument("--n", type=int, default=400)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    start = time.perf_counter()
    result = compare(args.n, args.seed)
    print(f"{args.n} plants, seed {args.seed}, {time.perf_counter() - start:.0f} s; "
          f"grid {GRID}, switch {SWITCH}")
    print("| error | bounded within 10x | silent | reported <= 1e-6 (of plants < 1e-6) |")
    print("|---|---|---|---|")
    for name in ("companion", "propagated"):
        c = _criteria(result["error"], result[name])
        print(f"| {name} | {100 * c['bounded']:.2f} % | {c['silent']} | "
              f"{100 * c['at_most_1e-6']:.1f} % (of {c['accurate']}) |")
    long_ = result["samples"] > SWITCH + 2 * GRID
    if long_.any():
        ratio = result["propagated"][long_] / result["companion"][long_]
        print(f"{long_.sum()} records longer than the switch: propagated / companion "
              f"min {np.min(ratio):.3g}, median {np.median(ratio):.3g}, "
              f"max {np.max(ratio):.3g}")
    print(f"final estimates of the study's run against algid.estimate's: largest relative "
          f"difference {result['estimate_difference']:.2g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
