"""The a-posteriori numerical error of the estimates (algid.estimation._numerical_error)."""

import math
import sys

import numpy as np
import pytest
from conftest import ROOT

import algid
from algid import cli
from algid.estimation import _backends as backends
from algid.estimation._numerical_error import companion_options, relative_difference, with_companion
from algid.models._registry import load_model

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.population import Plant, exact_response  # noqa: E402

ENGINES = ["numpy"] + (["numba"] if backends.numba_available() else [])


def plant(B, K, spp, periods=5.0, sines=((1.0, 1.0, 0.3),), step=0.0, x0=0.3, v0=-0.2):
    """A plant of benchmarks/population with its sines at multiples of sqrt(K)."""
    wn = math.sqrt(K)
    sines = tuple((a * K, w * wn, p) for a, w, p in sines)
    dt = 2 * math.pi / (max(w for _, w, _ in sines) * spp)
    n = int(periods * 2 * math.pi / (min(w for _, w, _ in sines) * dt)) + 1
    return Plant(B, K, x0, v0 * wn, sines, step, dt, n, spp)


def actual_error(r, p):
    return np.maximum(abs(r.B / p.B - 1), abs(r.K / p.K - 1))


#: plants where the default estimate is poor, well or exactly right
CASES = {
    "light damping, 22 samples/period": plant(0.0421, 186.0, 22, sines=((1, 1.1, 0.3),)),
    "light damping, two sines": plant(0.02, 50.0, 30, sines=((1, 0.8, 0.1), (0.5, 1.4, 2.0))),
    "overdamped, fast pole under-resolved": plant(60.0, 1.67, 21, periods=40),
    "moderate damping, 60 samples/period": plant(1.0, 4.0, 60),
    "overdamped, long record": plant(33.0, 0.0148, 25, periods=8000),
}


@pytest.mark.parametrize("name", list(CASES))
def test_reported_error_bounds_the_actual_one(name):
    p = CASES[name]
    t, f, x = exact_response(p)
    r = algid.estimate(t, f, x)
    actual = actual_error(r, p)
    reported = r.numerical_error
    assert reported.shape == t.shape
    bounded = (actual <= 10 * reported) | (actual < 1e-10)
    assert bounded[-1], (actual[-1], reported[-1])
    # where the reported error crosses zero it may miss at a few samples
    assert np.mean(bounded[t.size // 2:]) >= 0.99


def test_reported_error_is_small_when_the_estimate_is_accurate():
    p = CASES["moderate damping, 60 samples/period"]
    r = algid.estimate(*exact_response(p))
    assert r.final_numerical_error() < 1e-6
    assert actual_error(r, p)[-1] < 1e-6


def test_reported_error_is_large_when_the_estimate_is_poor():
    p = CASES["overdamped, long record"]
    r = algid.estimate(*exact_response(p))
    assert actual_error(r, p)[-1] > 1e-3  # the case is hard ...
    assert r.final_numerical_error() > 1e-3  # ... and says so


def test_the_late_origin_skips_an_under_resolved_transient():
    p = CASES["overdamped, fast pole under-resolved"]
    t, f, x = exact_response(p)
    alone = algid.estimate(t, f, x, numerical_error=False)
    assert actual_error(alone, p)[-1] > 2e-4  # the transient at the origin spoils it
    assert actual_error(algid.estimate(t, f, x), p)[-1] > 2e-4  # the default: the same
    assert actual_error(algid.estimate(t, f, x, late_origin=True), p)[-1] < 1e-4


@pytest.mark.parametrize("engine", ENGINES)
def test_late_origin_stream_gives_the_batch_numbers(engine):
    p = CASES["overdamped, fast pole under-resolved"]
    t, f, x = exact_response(p)
    batch = algid.estimate(t, f, x, engine=engine, late_origin=True)
    dt = float((t[-1] - t[0]) / (t.size - 1))
    online = algid.OnlineEstimator(dt=dt, engine=engine, late_origin=True)
    cuts = [0, 3, 40, 64, 65, 70, 1000, t.size]
    pieces = [online.update(t[a:b], f[a:b], x[a:b]) for a, b in zip(cuts, cuts[1:])]
    for name in ("B", "K", "numerical_error"):
        np.testing.assert_array_equal(np.concatenate([getattr(r, name) for r in pieces]),
                                      getattr(batch, name))
    with pytest.raises(algid.InputDataError, match="late_origin"):
        algid.OnlineEstimator(dt=dt, reset_period=100.0, late_origin=True)
    with pytest.raises(algid.InputDataError, match="late_origin"):
        algid.estimate(t, f, x, numerical_error=False, late_origin=True)


def test_numerical_error_does_not_change_the_estimates():
    t, f, x = exact_response(CASES["light damping, two sines"])
    a = algid.estimate(t, f, x)
    b = algid.estimate(t, f, x, numerical_error=False)
    np.testing.assert_array_equal(a.B, b.B)
    np.testing.assert_array_equal(a.K, b.K)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("reset_period", [None, 0.9])
def test_stream_gives_the_batch_numerical_error_bit_for_bit(engine, reset_period):
    p = CASES["light damping, two sines"]
    t, f, x = exact_response(p)
    batch = algid.estimate(t, f, x, engine=engine)
    online = algid.OnlineEstimator(dt=p.dt, engine=engine, reset_period=reset_period)
    cuts = np.unique(np.random.default_rng(1).integers(0, t.size, 12))
    pieces = [online.update(t[a:b], f[a:b], x[a:b])
              for a, b in zip(np.r_[0, cuts], np.r_[cuts, t.size])]
    error = np.concatenate([r.numerical_error for r in pieces])
    assert error.shape == t.shape
    if reset_period is None:
        np.testing.assert_array_equal(error, batch.numerical_error)
    else:  # re-anchored: its own estimates, with their own (finite) errors
        assert np.isfinite(error[t > reset_period]).all()
        whole = algid.OnlineEstimator(dt=p.dt, engine=engine, reset_period=reset_period)
        np.testing.assert_array_equal(whole.update(t, f, x).numerical_error, error)


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("reset_period", [None, 0.05])
@pytest.mark.parametrize("constant, options, amplitude",
                         [(False, {}, 1.0), (True, {}, 1.0), (False, {"mass": 2.5}, 1.0),
                          (False, {}, 1e200), (False, {"model": "msd_mass"}, 1.0)],
                         ids=["excited", "undetermined", "mass", "scaled", "msd_mass"])
def test_one_sample_at_a_time_gives_the_whole_chunk_bit_for_bit(engine, reset_period,
                                                                  constant, options, amplitude):
    """The one-sample path (OnlineEstimator.update of floats, the steps of
    algid.estimation._numerical_error.sample_stepper) gives the estimates, numerical errors and
    state
    of one chunk, across the start-up, the identifiability checks at 64 and 128 samples
    and the restarts of re-anchoring; with a known mass, and with samples scaled."""
    t = np.arange(300) * 1e-3
    f = np.ones_like(t) if constant else np.sin(7.0 * t) + 0.3 * np.cos(23.0 * t)
    x = np.full_like(t, 0.5) if constant else 0.2 * np.sin(7.0 * t - 0.4) + 0.1 * t
    f, x = f * amplitude, x * amplitude
    whole = algid.OnlineEstimator(dt=1e-3, engine=engine, reset_period=reset_period,
                                  **options)
    ref = whole.update(t, f, x)
    for kind in ("floats", "arrays"):
        est = algid.OnlineEstimator(dt=1e-3, engine=engine, reset_period=reset_period,
                                    **options)
        pieces = [est.update(float(t[i]), float(f[i]), float(x[i])) if kind == "floats"
                  else est.update(t[i:i + 1], f[i:i + 1], x[i:i + 1])
                  for i in range(t.size)]
        for name in ref.parameters:
            np.testing.assert_array_equal(
                np.concatenate([r.estimates[name] for r in pieces]), ref.estimates[name])
        np.testing.assert_array_equal(np.concatenate([r.numerical_error for r in pieces]),
                                      ref.numerical_error)
        # (scaled, the stream's power of two comes from its first chunk: the states
        # differ by it, the estimates do not)
        for mine, theirs in zip(est._states if amplitude == 1.0 else (), whole._states):
            assert mine.n_seen == theirs.n_seen and mine.undetermined == theirs.undetermined
            assert np.array_equal(mine.channel_max, theirs.channel_max)
            assert np.array_equal(mine.channel_last, theirs.channel_last)
            np.testing.assert_array_equal(mine.recent_errors, theirs.recent_errors)
            np.testing.assert_array_equal(mine.integrals, theirs.integrals)
            np.testing.assert_array_equal(mine.companion.history, theirs.companion.history)
    if constant and reset_period is None:  # judged at 64 samples: the path marks it too
        assert np.isnan(ref.B[63:]).all() and np.isinf(ref.numerical_error[63:]).all()


@pytest.mark.parametrize("name", list(CASES))
def test_nan_before_the_first_estimate_and_honest_from_it(name):
    """The companion reports as early as the estimator (both from sample 5, by the
    early rules of :func:`algid.estimation._core.first_estimate`), and the error it gives bounds
    the actual one within 10x at every sample from the first estimate on."""
    p = CASES[name]
    r = algid.estimate(*exact_response(p))
    first = r.valid_index
    assert first == 5
    assert np.isnan(r.numerical_error[:first]).all()
    assert np.isfinite(r.numerical_error[first:]).all()
    actual = actual_error(r, p)[first:]
    assert ((actual <= 10 * r.numerical_error[first:]) | (actual < 1e-10)).all()


@pytest.mark.parametrize("engine", ENGINES)
def test_undetermined_parameters_are_nan_with_an_infinite_error_in_a_stream(engine):
    """No dynamics to see: batch refuses the record (algid.estimation._identifiability); a stream
    checks what its samples determine at 64, 128, ... samples from its origin and
    reports the undetermined parameters as NaN, with an infinite numerical error, from
    each check to the next, in any chunking."""
    t = np.arange(2000) * 1e-3
    f, x = np.ones_like(t), np.full_like(t, 0.5)
    with pytest.raises(algid.InputDataError, match="cannot determine B"):
        algid.estimate(t, f, x, engine=engine)
    whole = algid.OnlineEstimator(dt=1e-3, engine=engine).update(t, f, x)
    assert np.isnan(whole.B[63:]).all() and np.isinf(whole.numerical_error[63:]).all()
    assert np.isfinite(whole.B[5:63]).all()   # before the first check: not judged
    np.testing.assert_allclose(whole.K[5:], 2.0, rtol=1e-8)  # K = f / x: kept
    stream = algid.OnlineEstimator(dt=1e-3, engine=engine)
    cuts = [0, 1, 2, 9, 63, 64, 300, 301, 1024, 2000]
    pieces = [stream.update(t[a:b], f[a:b], x[a:b]) for a, b in zip(cuts, cuts[1:])]
    np.testing.assert_array_equal(np.concatenate([r.B for r in pieces]), whole.B)
    np.testing.assert_array_equal(np.concatenate([r.numerical_error for r in pieces]),
                                  whole.numerical_error)
    # no input on the unknown-mass model: the common scale of m, c, k is free
    sine = np.sin(3 * t)
    r = algid.OnlineEstimator("msd_mass", dt=1e-3, engine=engine).update(t, 0 * t, sine)
    for name in ("m", "c", "k"):  # (0, and so is the companion's: judged all the same)
        assert np.isnan(r.estimates[name][63:]).all()
    assert np.isinf(r.numerical_error[63:]).all()


def test_the_late_twin_does_not_replace_an_undetermined_estimate():
    t = np.arange(600) * 1e-3
    f, x = np.ones_like(t), np.full_like(t, 0.02)
    r = algid.OnlineEstimator(dt=1e-3, late_origin=True).update(t, f, x)
    assert np.isnan(r.B[63:]).all() and np.isinf(r.numerical_error[63:]).all()
    np.testing.assert_allclose(r.K[63:], 50.0, rtol=1e-8)


@pytest.mark.parametrize("quiet, undetermined_until", [(3.0, 3008), (140.0, 141312)])
def test_a_stream_that_becomes_excited_is_judged_again(quiet, undetermined_until):
    """Constant for ``quiet`` seconds at 1 kHz, then a sine: B is NaN until the first
    check after the excitation (from the next sample on), then estimated.  While B is
    undetermined the checks fall every 64th of the samples seen (at least every 64):
    after 3 s every 64 samples (the check at 3008 sees 8 excited samples), after 140 s
    every 2048 (141312), not at the next check of a determined stream (4096, 196608)."""
    t = np.arange(undetermined_until + 1700) * 1e-3
    f = np.where(t < quiet, 1.0, 1.0 + np.sin(5 * (t - quiet)))
    x = algid.simulate(f, duration=t[-1], initial_state=(1 / 3, 0.0)).x
    r = algid.OnlineEstimator(dt=1e-3).update(t, f, x)
    held = slice(63, undetermined_until)
    assert np.isnan(r.B[held]).all() and np.isinf(r.numerical_error[held]).all()
    after = slice(undetermined_until, None)
    assert np.isfinite(r.B[after]).all() and np.isfinite(r.numerical_error[after]).all()
    assert abs(r.B[-1] / 2.0 - 1) < 1e-6


@pytest.mark.parametrize("engine", ENGINES)
def test_a_quiet_start_delays_the_estimates_by_a_64th_of_it(engine):
    """5 s of zeros, then the paper's step experiment: batch and every chunking report
    NaN until the first check after the excitation (5056), then the parameters."""
    sim = algid.simulate("step", duration=3.0)
    f, x = np.r_[np.zeros(5000), sim.f], np.r_[np.zeros(5000), sim.x]
    t = np.arange(f.size) * 1e-3
    r = algid.estimate(t, f, x, engine=engine)
    assert np.isnan(r.B[:5056]).all() and np.isfinite(r.B[5056:]).all()
    assert abs(r.B[-1] / 2 - 1) <= 10 * r.numerical_error[-1] < 1e-2
    for chunk in (7, 1000):
        online = algid.OnlineEstimator(dt=1e-3, engine=engine)
        pieces = [online.update(t[i:i + chunk], f[i:i + chunk], x[i:i + chunk])
                  for i in range(0, t.size, chunk)]
        np.testing.assert_array_equal(np.concatenate([p.B for p in pieces]), r.B)
        np.testing.assert_array_equal(np.concatenate([p.numerical_error for p in pieces]),
                                      r.numerical_error)


def test_next_check():
    from algid.estimation._numerical_error import CHECK_EVERY, FIRST_CHECK, next_check
    assert (FIRST_CHECK, CHECK_EVERY) == (64, 65536)
    assert [next_check(n) for n in (0, 7, 63, 64, 65, 127, 128, 1000, 1024, 65535)] == \
        [64, 64, 64, 128, 128, 128, 256, 1024, 2048, 65536]
    assert [next_check(n) for n in (65536, 65537, 131071, 131072, 196608, 10**6)] == \
        [131072, 131072, 131072, 196608, 262144, 1048576]
    # undetermined: every 64th of the largest power of two seen, at least every 64
    assert [next_check(n, True) for n in (0, 64, 100, 4095, 4096, 65536, 10**6)] == \
        [64, 128, 128, 4096, 4160, 66560, 1007616]


def test_companion_options():
    assert companion_options(6, 2) == (7, 1)
    assert companion_options(8, 2) == (9, 1)
    assert companion_options(9, 0) == (8, 1)
    assert companion_options(2, 1) == (3, 0)


def test_relative_difference():
    est = np.array([[1.0, 2.0, np.nan, 0.0, 1.0], [4.0, 4.0, np.nan, 0.0, 1.0]])
    comp = np.array([[1.1, 2.0, np.nan, 0.0, np.nan], [4.0, 3.0, np.nan, 0.0, np.nan]])
    out = relative_difference(est, comp)
    np.testing.assert_allclose(out[:2], [0.1, 0.25])
    assert np.isnan(out[2]) and out[3] == 0.0 and out[4] == np.inf


def test_options_and_paths():
    p = CASES["moderate damping, 60 samples/period"]
    t, f, x = exact_response(p)
    assert algid.estimate(t, f, x, numerical_error=False).numerical_error is None
    for options in ({"quadrature_points": 8, "filter_order": 0},
                    {"quadrature_points": 2, "filter_order": 3},
                    {"lowpass": ([4.0], [1.0, 4.0]), "engine": "numpy"}):
        r = algid.estimate(t, f, x, **options)
        actual = actual_error(r, p)[-1]
        assert actual <= 10 * r.final_numerical_error() or actual < 1e-10, options
    assert "numerical_error" in algid.estimate(t, f, x).to_dict()


def test_user_model_has_a_numerical_error():
    from algid.models._compiled import compile_equation

    p = CASES["moderate damping, 60 samples/period"]
    t, f, x = exact_response(p)
    model = compile_equation("y'' + B*y' + K*y = G*u", "B K G")
    r = algid.estimate(t, signals={"u": f, "y": x}, model=model)
    assert r.numerical_error.shape == t.shape
    assert r.final_numerical_error() < 1e-6


def write_record(path, t, f, x):
    np.savetxt(path, np.column_stack([t, f, x]), delimiter=",", header="t,f,x", comments="")
    return str(path)


def test_cli_reports_it_and_warns_when_large(tmp_path, capsys):
    import json

    good = CASES["moderate damping, 60 samples/period"]
    assert cli.main(["estimate", write_record(tmp_path / "good.csv",
                                              *exact_response(good)), "--json"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and json.loads(out)["numerical_error"] < 1e-6
    poor = CASES["overdamped, long record"]  # about 2e-2 off
    path = write_record(tmp_path / "poor.csv", *exact_response(poor))
    assert cli.main(["estimate", path]) == 0
    out, err = capsys.readouterr()
    assert "numerical error" in out
    assert len(err.splitlines()) == 1 and err.startswith("warning:") and "numerical" in err


def test_window_maximum_is_exact_and_chunk_invariant():
    from algid.estimation._numerical_error import WINDOW, window_maximum

    rng = np.random.default_rng(3)
    raw = rng.random(200)
    raw[[0, 1, 2, 50]] = np.nan
    raw[[3, 120]] = np.inf
    whole = np.empty_like(raw)
    window_maximum(raw, np.zeros(WINDOW - 1), whole)
    finite = np.where(np.isfinite(raw), raw, 0.0)
    expected = [finite[max(0, i - WINDOW + 1):i + 1].max() for i in range(raw.size)]
    expected = np.where(np.isfinite(raw), expected, raw)
    np.testing.assert_array_equal(whole, expected)
    recent, pieces = np.zeros(WINDOW - 1), []
    for a, b in [(0, 1), (1, 7), (7, 7), (7, 40), (40, 200)]:
        out = np.empty(b - a)
        window_maximum(raw[a:b], recent, out)
        pieces.append(out)
    np.testing.assert_array_equal(np.concatenate(pieces), whole)


def test_population_quick_run_is_honest(capsys):
    from benchmarks import population

    rows = [population.run_case(p) for p in population.draw_plants(40, seed=7,
                                                                     max_samples=20000)]
    summary = population.summarise(rows)
    assert summary["honesty"]["bounded_within_10x"] == 1.0
    assert summary["honesty"]["silent_failures"] == 0
    assert population.main(["--quick", "--n", "1", "--worst", "1"]) == 0
    assert "numerical_error bounds the error" in capsys.readouterr().out


def _error_cases():
    rng = np.random.default_rng(5)
    est = rng.normal(size=(3, 300))
    comp = est * (1 + 1e-6 * rng.normal(size=est.shape))
    est[:, :4] = np.nan
    comp[:, :5] = np.nan
    est[1, 50], comp[1, 50] = 0.0, 0.0  # equal zeros: 0
    est[2, 60], comp[2, 60] = 0.0, 1e-9  # a zero estimate: inf
    comp[0, 70] = np.nan  # the companion undefined: inf
    comp[2, 80] = est[2, 80]  # equal: 0 for that parameter
    est[0, 90], comp[0, 90] = 1e-300, -1e300  # overflows to inf
    est[1, 100] = np.inf  # an infinite estimate: NaN
    comp[2, 110] = -np.inf
    est[1, 120], comp[1, 120] = -0.0, 0.0
    return est, comp


def test_scalar_numerical_error_equals_the_arrays():
    """Chunks of a few samples on the NumPy backend take a float path: same numbers."""
    from algid.estimation._numerical_error import (
        SCALAR_SAMPLES,
        WINDOW,
        _block_error,
        window_maximum,
    )

    est, comp = _error_cases()
    expected = np.empty(est.shape[1])
    window_maximum(relative_difference(est, comp), np.zeros(WINDOW - 1), expected)
    assert np.isinf(expected[[60, 70, 90]]).all() and np.isnan(expected[100])
    recent, got, at = np.zeros(WINDOW - 1), [], 0
    sizes = [1, 2, 3] * 50
    assert max(sizes) <= SCALAR_SAMPLES and sum(sizes) == est.shape[1]
    for n in sizes:
        out = np.empty(n)
        _block_error(est[:, at:at + n], comp[:, at:at + n], recent, out)
        got.append(out)
        at += n
    np.testing.assert_array_equal(np.concatenate(got), expected)
    none = np.empty(1)
    _block_error(np.empty((0, 1)), np.empty((0, 1)), np.zeros(WINDOW - 1), none)
    assert np.isnan(none[0])


@pytest.mark.skipif(len(ENGINES) < 2, reason="needs numba")
def test_compiled_numerical_error_equals_numpy():
    from algid.estimation._numerical_error import WINDOW, window_maximum
    from algid.estimation._numerical_error_numba import block_error as numerical_error

    est, comp = _error_cases()
    expected = np.empty(300)
    window_maximum(relative_difference(est, comp), np.zeros(WINDOW - 1), expected)
    for cuts in ([300], [7, 293], [100, 100, 100]):
        recent, got, at = np.zeros(WINDOW - 1), [], 0
        for n in cuts:
            out = np.empty(n)
            numerical_error(est[:, at:at + n], comp[:, at:at + n], recent, out)
            got.append(out)
            at += n
        np.testing.assert_array_equal(np.concatenate(got), expected)
    # one sample at a time, as the one-sample step of the generated loops computes it
    from algid.estimation._numerical_error_numba import sample_error
    recent, got = np.zeros(WINDOW - 1), np.empty(300)
    for j in range(300):
        sample_error(est[:, j:j + 1], comp[:, j:j + 1], recent, got[j:j + 1])
    np.testing.assert_array_equal(got, expected)


@pytest.mark.skipif(len(ENGINES) < 2, reason="needs numba")
def test_compiled_channel_extent_equals_numpy():
    from algid.estimation._numerical_error import _track_channels
    from algid.estimation._numerical_error_numba import sample_extent, track_extent

    rng = np.random.default_rng(5)
    from algid.estimation import _core as core

    state = with_companion(core.new_state(load_model("msd"), points=8, filter_order=2,
                                          dt=1e-3, divisors=np.array([3.0, 1.0])))
    compiled = state.copy()
    for size in (1, 5, 300, 2):
        rows = tuple(rng.standard_normal(size) * 10.0 ** rng.integers(-3, 3)
                     for _ in range(2))
        _track_channels(state, rows)
        for c, row in enumerate(rows):
            track_extent(row, compiled.divisors.item(c), c, compiled.channel_max,
                         compiled.channel_last)
        np.testing.assert_array_equal(compiled.channel_max, state.channel_max)
        np.testing.assert_array_equal(compiled.channel_last, state.channel_last)
    for value in (-40.0, 2.5, -0.0, 1e3):  # one sample as a number, as the pair step does
        _track_channels(state, (np.array([value]), np.array([-value])))
        for c, v in enumerate((value, -value)):
            sample_extent(v, compiled.divisors.item(c), c, compiled.channel_max,
                          compiled.channel_last)
        np.testing.assert_array_equal(compiled.channel_max, state.channel_max)
        np.testing.assert_array_equal(compiled.channel_last, state.channel_last)


@pytest.mark.skipif(len(ENGINES) < 2, reason="needs numba")
@pytest.mark.parametrize("name", ["light damping, two sines",
                                  "overdamped, fast pole under-resolved"])
def test_engines_agree_on_the_numerical_error(name):
    t, f, x = exact_response(CASES[name])
    a, b = (algid.estimate(t, f, x, engine=e) for e in ("numpy", "numba"))
    np.testing.assert_array_equal(a.numerical_error, b.numerical_error)
    np.testing.assert_array_equal(a.B, b.B)
