"""The companion's estimate propagated on a grid (algid.estimation._error_propagation).

What ``algid.estimate`` reports past the switch (``PROPAGATE``; the fixture makes sure
of it): both engines and every chunking give the same numbers, they are those of the
study in ``benchmarks.error_propagation``, and the error so formed is as honest as the
full companion's (``PROPAGATE`` off).  The generated C's equality with it is tested in
``tests/symbolic/test_codegen_c.py``.
"""

import sys

import numpy as np
import pytest
from conftest import ROOT

import algid
import algid.estimation._numerical_error as numerical_error
from algid.estimation import _backends as backends
from algid.estimation._error_propagation import GRID, SWITCH, difference_taps
from algid.signals._quadrature import integrator_weights

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.error_propagation import propagated_error  # noqa: E402
from benchmarks.population import draw_plants, exact_response  # noqa: E402
from estimation.test_numerical_error import actual_error, plant  # noqa: E402

ENGINES = ["numpy"] + (["numba"] if backends.numba_available() else [])
#: light damping, two sines, 30 samples per period: 40 periods (about 2100 samples)
LONG = plant(0.02, 50.0, 30, sines=((1, 0.8, 0.1), (0.5, 1.4, 2.0)), periods=40)


@pytest.fixture
def propagated(monkeypatch):
    monkeypatch.setattr(numerical_error, "PROPAGATE", True)


def _increments(f, points, dt):
    """The rule's increment at every sample from ``points - 1`` on (oldest first)."""
    weights = integrator_weights(points, dt)[0]
    return np.correlate(f, weights, mode="valid")


@pytest.mark.parametrize("points, companion_points", [(8, 9), (4, 5), (9, 8)])
def test_the_rules_differ_by_a_telescoped_fir(points, companion_points):
    """Past both rules' start-up, the companion's increment minus the estimator's is
    ``T f[n] - T f[n - 1]``: their running sums differ by ``T f`` and a constant."""
    dt = 1e-3
    f = np.random.default_rng(3).standard_normal(300)
    taps = difference_taps(points, companion_points, dt)
    first = max(points, companion_points) - 1  # the first sample both rules reach
    ours = _increments(f, points, dt)[first - points + 1:]
    theirs = _increments(f, companion_points, dt)[first - companion_points + 1:]
    telescoped = np.correlate(f, taps, mode="valid")[first - taps.size + 1:]
    np.testing.assert_allclose(theirs[1:] - ours[1:], np.diff(telescoped),
                               rtol=0, atol=1e-15)


@pytest.mark.parametrize("engine", ENGINES)
def test_streams_and_engines_give_the_same_numbers(propagated, engine):
    p = LONG
    t, f, x = exact_response(p)
    assert t.size > SWITCH + 4 * GRID
    batch = algid.estimate(t, f, x, engine=engine)
    reference = algid.estimate(t, f, x, engine="numpy")
    np.testing.assert_array_equal(batch.numerical_error, reference.numerical_error)
    for chunk in (1, 7, 1000):
        online = algid.OnlineEstimator(dt=p.dt, engine=engine)
        error = np.concatenate([online.update(t[i:i + chunk], f[i:i + chunk],
                                              x[i:i + chunk]).numerical_error
                                for i in range(0, t.size, chunk)])
        np.testing.assert_array_equal(error, batch.numerical_error)


def test_the_full_companion_runs_until_the_switch(propagated, monkeypatch):
    p = LONG
    t, f, x = exact_response(p)
    on = algid.estimate(t, f, x, engine="numpy")
    monkeypatch.setattr(numerical_error, "PROPAGATE", False)
    full = algid.estimate(t, f, x, engine="numpy")
    np.testing.assert_array_equal(on.B, full.B)  # the estimates are not touched
    np.testing.assert_array_equal(on.numerical_error[:SWITCH], full.numerical_error[:SWITCH])
    assert not np.array_equal(on.numerical_error, full.numerical_error)


def test_it_is_the_study(propagated):
    """The engines' numbers at the final sample are the study's (formed there in one
    block, from the same arrays)."""
    p = LONG
    t, f, x = exact_response(p)
    error, estimates = propagated_error(t, f, x)
    r = algid.estimate(t, f, x, engine="numpy")
    assert r.numerical_error[-1] == pytest.approx(error, rel=1e-12)
    assert (r.B[-1], r.K[-1]) == tuple(estimates)


def test_it_is_as_honest_as_the_full_companion(propagated, monkeypatch):
    """On the population's records long enough to switch: the reported error bounds the
    actual one within 10x (or that is below 1e-10), as the full companion's does, and
    the two agree in size."""
    plants = [p for p in draw_plants(120, seed=0) if p.n > SWITCH + 4 * GRID][:25]
    assert len(plants) == 25
    ratios = []
    for p in plants:
        t, f, x = exact_response(p)
        r = algid.estimate(t, f, x)
        actual = actual_error(r, p)[-1]
        reported = r.numerical_error[-1]
        assert actual <= 10 * reported or actual < 1e-10, (p, actual, reported)
        monkeypatch.setattr(numerical_error, "PROPAGATE", False)
        ratios.append(reported / algid.estimate(t, f, x).numerical_error[-1])
        monkeypatch.setattr(numerical_error, "PROPAGATE", True)
    assert 0.5 < np.median(ratios) < 2.0
    assert np.min(ratios) > 0.05 and np.max(ratios) < 20.0


@pytest.mark.parametrize("m", [4, 9, 15, 16, 40, 301])
@pytest.mark.parametrize("phase", [0, 3, 7])
def test_the_grid_window_gives_the_full_windows_numbers(m, phase):
    """The window past the switch read at the grid samples only (``_grid_error``) gives
    the numbers of the full window over estimates that stand in for the companion's off
    the grid: with NaN and inf estimates, a NaN companion, zeros, and values before the
    block (as the full companion leaves them at the switch)."""
    rng = np.random.default_rng(m * 8 + phase)
    estimates = rng.standard_normal((2, m))
    columns = np.arange(phase, m, GRID)
    companion = estimates[:, columns] * (1 + 1e-3 * rng.standard_normal((2, columns.size)))
    special = rng.choice(m, size=max(1, m // 6), replace=False)
    estimates[0, special[::3]] = np.nan
    estimates[1, special[1::3]] = np.inf
    estimates[:, special[2::3]] = 0.0
    if columns.size > 1:
        companion[1, 1] = np.nan
        companion[:, 0] = estimates[:, columns[0]]  # equal: a difference of 0
    other = estimates.copy()
    other[:, columns] = companion
    recent = rng.uniform(0, 1e-3, numerical_error.WINDOW - 1)
    recent[rng.choice(recent.size, 4)] = 0.0
    full_recent, grid_recent = recent.copy(), recent.copy()
    full, grid = np.empty(m), np.empty(m)
    numerical_error.window_maximum(numerical_error.relative_difference(estimates, other),
                                   full_recent, full)
    numerical_error._grid_error(estimates, phase, companion, grid_recent, grid)
    np.testing.assert_array_equal(grid, full)
    np.testing.assert_array_equal(grid_recent, full_recent)
    assert np.isnan(grid).any() and np.isfinite(grid).any()


@pytest.mark.parametrize("order, filter_order", [(1, 1), (2, 1), (2, 2), (3, 2)])
def test_a_signal_that_enters_unintegrated_switches_too(propagated, monkeypatch, order,
                                                        filter_order):
    """``y^(order) = a*u``: the ``t**order * y`` term has no integrator (level 0), so at
    the switch its kernel is formed from the channels' last values; both engines and
    every chunking agree, and the error is the full companion's past the switch (a
    wrong kernel there skews it: 37x at order 3)."""
    from algid.models import compile_equation
    model = compile_equation("y" + "'" * order + " = a*u", "a")
    w, a = 150.0, 2.0  # 42 samples per period: the quadrature error shows
    t = np.arange(1500) * 1e-3
    u = np.sin(w * t) + 0.3  # y: a times its order-fold antiderivative (exact)
    y = a * (np.sin(w * t - order * np.pi / 2) / w**order + 0.3 * t**order
             / np.prod(np.arange(1, order + 1)))
    signals = {"u": u, "y": y}
    batch = {engine: algid.estimate(t, signals=signals, model=model,
                                    filter_order=filter_order, engine=engine)
             for engine in ENGINES}
    r = batch["numpy"]
    for other in batch.values():
        np.testing.assert_array_equal(other.numerical_error, r.numerical_error)
        np.testing.assert_array_equal(other.estimates["a"], r.estimates["a"])
    online = algid.OnlineEstimator(model=model, dt=1e-3, filter_order=filter_order)
    streamed = np.concatenate([online.update(t[i:i + 7], signals={
        "u": u[i:i + 7], "y": y[i:i + 7]}).numerical_error for i in range(0, t.size, 7)])
    np.testing.assert_array_equal(streamed, r.numerical_error)
    actual = abs(r.estimates["a"][-1] / a - 1.0)
    assert actual <= 10 * r.numerical_error[-1] or actual < 1e-10
    monkeypatch.setattr(numerical_error, "PROPAGATE", False)
    full = algid.estimate(t, signals=signals, model=model, filter_order=filter_order)
    ratio = r.numerical_error[SWITCH:] / full.numerical_error[SWITCH:]
    assert 0.7 < np.median(ratio) < 1.2 and 0.3 < ratio.min() and ratio.max() < 2.0
