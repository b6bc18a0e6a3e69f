"""Hostile chunks on a stream: refused with one line, and the stream goes on as if it had
never seen them (bit for bit, with both engines)."""

import math

import numpy as np
import pytest

import algid
from algid._scaling import AMPLITUDE_BITS
from algid.errors import InputDataError

ENGINES = ["numpy", "numba"]
LIMIT = 2.0 ** (AMPLITUDE_BITS // 2)  # of msd (two parameters), in the stream's unit


@pytest.fixture(scope="module")
def record():
    t, f, x = algid.simulate("sine", duration=2.0)
    return np.asarray(t), np.asarray(f), np.asarray(x)


def _results_equal(a, b):
    for name in a.parameters:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    np.testing.assert_array_equal(a.numerical_error, b.numerical_error)


def _one_line(exc):
    message = str(exc.value)
    assert "\n" not in message
    return message


def _feed(est, t, f, x, start, stop):
    return est.update(t[start:stop], f[start:stop], x[start:stop])


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("options", [{}, {"reset_period": 0.2}, {"late_origin": True}])
@pytest.mark.parametrize("where", ["sample f", "sample x", "chunk f", "chunk -x"])
def test_an_extreme_sample_is_refused_and_leaves_the_stream_intact(record, engine, options,
                                                                  where):
    t, f, x = record
    clean = algid.OnlineEstimator(dt=1e-3, engine=engine, **options)
    hit = algid.OnlineEstimator(dt=1e-3, engine=engine, **options)
    _results_equal(_feed(clean, t, f, x, 0, 700), _feed(hit, t, f, x, 0, 700))
    magnitude = hit.state_magnitude
    kind, name = where.split()
    stop = 701 if kind == "sample" else 720
    bad_f, bad_x = f[700:stop].copy(), x[700:stop].copy()
    row = 0 if kind == "sample" else 9
    value = -1e308 if name.startswith("-") else 1e308
    (bad_f if name == "f" else bad_x)[row] = value
    with pytest.raises(InputDataError) as exc:
        if kind == "sample":  # three floats: the one-sample path
            hit.update(float(t[700]), float(bad_f[0]), float(bad_x[0]))
        else:
            hit.update(t[700:stop], bad_f, bad_x)
    message = _one_line(exc)
    assert f"signal {name.strip('-')!r} reaches {value:.10g} at stream sample {700 + row}" \
        in message
    assert "refused" in message
    assert hit.n_seen == 700 and hit.state_magnitude == magnitude
    # the same samples, good this time, then the rest: as if nothing had happened
    for start, stop in ((700, 701), (701, 950), (950, t.size)):
        last = _feed(hit, t, f, x, start, stop)
        _results_equal(_feed(clean, t, f, x, start, stop), last)
    assert math.isclose(last.final()["K"], 3.0, rel_tol=1e-6)


@pytest.mark.parametrize("engine", ENGINES)
def test_the_limit_is_relative_to_the_scale_of_the_first_chunk(record, engine):
    t, f, x = record
    # amplitudes of 1e300 are scaled into range: twice their size is no outlier ...
    big = algid.OnlineEstimator(dt=1e-3, engine=engine)
    big.update(t[:500], f[:500] * 1e300, x[:500] * 1e300)
    r = big.update(t[500:], f[500:] * 2e300, x[500:] * 2e300)  # (not the same record)
    assert np.isfinite(r.B[-1]) and np.isfinite(r.K[-1])
    # ... and after samples of 1e-300, one of 1 is beyond 2**256 of them
    small = algid.OnlineEstimator(dt=1e-3, engine=engine)
    small.update(t[:500], f[:500] * 1e-300, x[:500] * 1e-300)
    with pytest.raises(InputDataError, match="signal 'x' reaches"):
        small.update(t[500:510], f[500:510] * 1e-300, np.full(10, 1.0))


@pytest.mark.parametrize("engine", ENGINES)
def test_a_sample_at_the_limit_keeps_the_stream_finite(record, engine):
    t, f, x = record
    est = algid.OnlineEstimator(dt=1e-3, engine=engine)
    est.update(t[:500], f[:500], x[:500])          # unit amplitude: the scale is 1
    spiked = f[500:].copy()
    spiked[0] = LIMIT
    r = est.update(t[500:], spiked, x[500:])
    assert np.isfinite(est.state_magnitude)
    assert np.isfinite(r.B[1:]).all() and np.isfinite(r.K[1:]).all()


@pytest.mark.parametrize("engine", ENGINES)
def test_a_tiny_mass_is_named_and_the_first_chunk_changes_nothing(record, engine):
    t, f, x = record
    est = algid.OnlineEstimator(engine=engine, mass=1e-308)  # step taken from the stream
    with pytest.raises(InputDataError) as exc:
        est.update(t[:100], f[:100], x[:100])
    message = _one_line(exc)
    assert "mass 1e-308" in message and "signal 'f'" in message
    assert est.n_seen == 0 and est.dt is None and math.isnan(est.t_origin)


def _log_model():
    from algid.models._compiled import compile_equation
    return compile_equation("y'' + B*y' + K*log(y) = u", "B K")


@pytest.fixture(scope="module")
def log_record():
    t = np.arange(2049) / 1024.0
    return t, {"y": 2.0 + np.sin(3.0 * t), "u": np.cos(t)}


@pytest.mark.parametrize("engine", ENGINES)
@pytest.mark.parametrize("bad", [-1.0, 0.0])
def test_a_user_model_channel_outside_its_domain_is_refused(log_record, engine, bad):
    pytest.importorskip("sympy")
    module = _log_model()
    t, signals = log_record
    clean = algid.OnlineEstimator(module, rate=1024.0, engine=engine)
    hit = algid.OnlineEstimator(module, rate=1024.0, engine=engine)

    def chunk(start, stop, y=None):
        return {"y": signals["y"][start:stop] if y is None else y,
                "u": signals["u"][start:stop]}

    _results_equal(clean.update(t[:1000], signals=chunk(0, 1000)),
                   hit.update(t[:1000], signals=chunk(0, 1000)))
    y = signals["y"][1000:1010].copy()
    y[3] = bad
    with pytest.raises(InputDataError) as exc:
        hit.update(t[1000:1010], signals=chunk(1000, 1010, y))
    message = _one_line(exc)
    assert "channel 'z1' = log(y)" in message and "stream sample 1003" in message
    assert f"y = {bad:.10g}" in message
    assert ("NaN" if bad < 0 else "infinite") in message
    assert hit.n_seen == 1000
    for start, stop in ((1000, 1010), (1010, t.size)):
        _results_equal(clean.update(t[start:stop], signals=chunk(start, stop)),
                       hit.update(t[start:stop], signals=chunk(start, stop)))


def test_a_user_model_signal_or_channel_too_large_is_refused_also_in_the_warm_up():
    """A derivative inside a factor: the differentiator's state is restored too."""
    pytest.importorskip("sympy")
    from algid.models._compiled import compile_equation
    module = compile_equation("y'' + B*y' + K*y + C*sign(y')*y**3 = u", "B K C")
    t = np.arange(3000) / 1000.0
    y, u = 0.5 * np.sin(2.0 * t), np.cos(3.0 * t)
    clean = algid.OnlineEstimator(module, rate=1000.0, engine="numpy")
    hit = algid.OnlineEstimator(module, rate=1000.0, engine="numpy")
    clean.update(t[:10], signals={"y": y[:10], "u": u[:10]})
    hit.update(t[:10], signals={"y": y[:10], "u": u[:10]})
    assert hit.startup_samples > 20                    # sample 15: in the warm-up
    for row, value, what in ((5, 1e60, "signal 'y' reaches 1e+60 at stream sample 15"),
                             (25, 1e40, "y**3 reaches 1e+120 at stream sample 35")):
        bad = y[10:40].copy()
        bad[row] = value
        with pytest.raises(InputDataError) as exc:
            hit.update(t[10:40], signals={"y": bad, "u": u[10:40]})
        assert what in _one_line(exc)
        assert hit.n_seen == 10
    for start, stop in ((10, 40), (40, 3000)):
        part = {"y": y[start:stop], "u": u[start:stop]}
        _results_equal(clean.update(t[start:stop], signals=part),
                       hit.update(t[start:stop], signals=part))


@pytest.mark.parametrize("engine", ENGINES)
def test_a_huge_mass_is_refused_as_in_batch(record, engine):
    t, f, x = record
    with pytest.raises(InputDataError, match="mass 1e.308 is at most"):
        algid.estimate(t, f, x, mass=1e308, engine=engine)
    est = algid.OnlineEstimator(engine=engine, mass=1e308)
    with pytest.raises(InputDataError) as exc:
        est.update(t[:100], f[:100], x[:100])
    assert "signal 'f' divided by the mass 1e+308 is at most" in _one_line(exc)
    assert est.n_seen == 0 and est.dt is None
