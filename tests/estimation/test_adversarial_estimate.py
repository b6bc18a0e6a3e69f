"""Hostile input to ``algid.estimate``, ``algid.simulate`` and their commands: one
``AlgidError`` line naming the real cause (exit 2 on the command line), never a
traceback, a hang or a silently wrong number."""

import warnings

import numpy as np
import pytest
from conftest import assert_one_line_error

import algid
from algid.cli import main
from algid.errors import AlgidError, InputDataError


def run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def sine():
    return algid.simulate("sine", duration=2.0)


def write_csv(path, t, f, x, header="t,f,x"):
    rows = "\n".join(f"{a!r},{b!r},{c!r}" for a, b, c in zip(t.tolist(), f.tolist(),
                                                               x.tolist()))
    path.write_text(f"{header}\n{rows}\n")
    return path


def one_line(exc_info):
    message = str(exc_info.value)
    assert "\n" not in message and "Traceback" not in message
    return message


# ----------------------------------------------------------------- amplitudes


@pytest.mark.parametrize("signal", ["f", "x"])
def test_an_outlier_of_1e308_is_named_in_batch(sine, signal, capsys, tmp_path):
    f, x = sine.f.copy(), sine.x.copy()
    (f if signal == "f" else x)[1000] = 1e308
    other = "x" if signal == "f" else "f"
    for engine in ("numpy", "numba"):
        with pytest.raises(InputDataError) as exc:
            algid.estimate(sine.t, f, x, engine=engine)
        message = one_line(exc)
        assert f"signal {other!r} is at most" in message
        assert f"1e+308 of {signal!r} (row 1000)" in message
    code, _, err = run(capsys, "estimate", str(write_csv(tmp_path / "d.csv", sine.t, f, x)))
    assert_one_line_error(code, err, "1e+308", "row 1000")


@pytest.mark.parametrize("scale", [1e-310, 1e-315])
def test_subnormal_amplitudes_are_rescaled(sine, scale, capsys, tmp_path):
    """Signals below 2**-1022 (subnormal) are brought up by 2**1023, the largest power
    of two (a scale that overflowed was an OverflowError traceback)."""
    f, x = sine.f * scale, sine.x * scale
    reference = algid.estimate(sine.t, sine.f, sine.x)
    r = algid.estimate(sine.t, f, x)
    # subnormal samples keep fewer bits: relative steps of 2**-1074 / scale (5e-14,
    # 5e-9); the estimates move by less (measured 2e-14, 3e-9)
    assert abs(r.B[-1] / reference.B[-1] - 1) < 2.0**-1074 / scale
    streamed = algid.OnlineEstimator(rate=1000.0).update(sine.t, f, x)
    np.testing.assert_array_equal(streamed.B, r.B)
    code, out, _ = run(capsys, "estimate", str(write_csv(tmp_path / "d.csv", sine.t, f, x)))
    assert code == 0 and "B" in out


@pytest.mark.parametrize("mass, words", [(1e-308, "reaches 1e+308"),
                                         (1e308, "is at most 1e-308"),
                                         (1e-300, "beyond 2**256"),
                                         (1e300, "below 2**-256"),
                                         # the quotient overflows: no raw warning, no inf
                                         (1e-320, "reaches 1 / 9.99989e-321 (beyond")])
def test_an_extreme_mass_is_named(sine, mass, words, capsys, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow on the way
        with pytest.raises(InputDataError) as exc:
            algid.estimate(sine.t, sine.f, sine.x, mass=mass)
    message = one_line(exc)
    assert f"signal 'f' divided by the mass {mass:g}" in message and words in message
    assert "express the time" not in message
    path = write_csv(tmp_path / "d.csv", sine.t, sine.f, sine.x)
    code, _, err = run(capsys, "estimate", str(path), "--mass", repr(mass))
    assert_one_line_error(code, err, "divided by the mass")


@pytest.mark.parametrize("scale", [1e-40, 1e30])
def test_time_units_out_of_range_are_refused_instead_of_nan(sine, scale):
    with pytest.raises(InputDataError, match="express the time in other units"):
        algid.estimate(sine.t * scale, sine.f, sine.x)


@pytest.mark.parametrize("scale", [1e-20, 1e-34, 1e-38, 1e-60])
def test_a_record_in_extreme_time_units_is_estimated_or_refused(sine, scale):
    """The same record with the time in units of ``1/scale`` s (the force rescaled to
    match): B and K scale with it, or a one-line refusal.  At 1e-34 to 1e-42 Cramer's
    denominator underflowed to 0 and every estimate was NaN, silently; at 1e-60 the
    kernels underflowed and the refusal blamed an unexcited K."""
    t, f = sine.t * scale, sine.f / scale**2
    if scale >= 1e-20:
        r = algid.estimate(t, f, sine.x)
        assert abs(r.B[-1] * scale / sine_true_B(sine) - 1) < 1e-9
        return
    with pytest.raises(InputDataError, match="express the time in other units") as info:
        algid.estimate(t, f, sine.x)
    assert "not excited" not in one_line(info)


def test_the_command_line_takes_the_apis_shortest_record_and_names_the_file(
        sine, capsys, tmp_path):
    short = write_csv(tmp_path / "short.csv", sine.t[:12], sine.f[:12], sine.x[:12])
    algid.estimate(sine.t[:12], sine.f[:12], sine.x[:12])  # the API takes 12 samples
    code, out, _ = run(capsys, "estimate", str(short))
    assert code == 0 and "B" in out  # (the command line asked for 16)
    t = sine.t
    flat = write_csv(tmp_path / "flat.csv", t, np.ones_like(t), np.full_like(t, 0.5))
    code, _, err = run(capsys, "estimate", str(flat))
    assert_one_line_error(code, err, f"{flat}: the data cannot determine B")


def test_float32_times_are_named_as_the_cause_of_uneven_steps(sine):
    t = np.arange(5001, dtype=np.float32) * np.float32(1e-3)
    with pytest.raises(InputDataError, match="float32 values round the steps unevenly"):
        algid.estimate(t, np.sin(3 * t), np.cos(3 * t))


def test_signals_of_scales_no_common_unit_serves_are_refused(sine):
    """An output 1e-120 times the input's scale, in a model that fits it (``c*u``):
    Cramer's numerator of c underflowed to exactly 0 and c came back 0.0 with an error
    of 1e-12; now a refusal naming the spread of the channels."""
    pytest.importorskip("sympy")
    from algid.models._compiled import compile_equation
    model = compile_equation("y'' + a*y' + b*y = c*u", "a b c")
    scale = 1e-120
    with pytest.raises(InputDataError, match="units closer to one another .*differ by a"):
        algid.estimate(sine.t, signals={"u": sine.f, "y": sine.x * scale}, model=model)
    r = algid.estimate(sine.t, signals={"u": sine.f, "y": sine.x * 1e-100}, model=model)
    assert abs(r.final()["c"] / 1e-100 - 1.0) < 1e-9  # (y'' + 2 y' + 3 y = 1e-100 f)


def sine_true_B(sine):
    return algid.estimate(sine.t, sine.f, sine.x).B[-1]


# ----------------------------------------------------------------- user models


@pytest.fixture(scope="module")
def log_model():
    pytest.importorskip("sympy")
    from algid.models._compiled import compile_equation
    return compile_equation("y'' + B*y' + K*log(y) = u", "B K")


def test_a_user_model_given_f_and_x_says_it_needs_signals(log_model, sine):
    with pytest.raises(InputDataError) as exc:
        algid.estimate(sine.t, sine.f, sine.x, model=log_model)
    message = one_line(exc)
    assert "reads the signals y, u" in message and "signals=" in message


def test_a_nan_channel_is_named_with_its_expression(log_model):
    t = np.arange(2000) / 1000.0
    y, u = 2.0 + np.sin(3.0 * t), np.cos(t)
    y[1000] = -1.0
    with pytest.raises(InputDataError) as exc:
        algid.estimate(t, signals={"y": y, "u": u}, model=log_model)
    message = one_line(exc)
    assert "channel 'z1' = log(y) is NaN at row 1000 (y = -1" in message
    assert "express the time" not in message


def test_a_derivative_window_beyond_the_record_or_memory_is_refused():
    pytest.importorskip("sympy")
    from algid.models._compiled import compile_equation
    module = compile_equation("M*q'' + Fv*q' + Fc*tanh(q'/0.2) = F", "M Fv Fc")
    t = np.arange(2000) / 1000.0
    signals = {"q": np.sin(t), "F": np.cos(t)}
    for differentiator in ("centred", "causal"):
        with pytest.raises(InputDataError, match="derivative_window 1e.09 s is longer than "
                                                 "the record"):
            algid.estimate(t, signals=signals, model=module, derivative_window=1e9,
                           differentiator=differentiator)
    with pytest.raises(InputDataError, match="derivative_window must be a positive number"):
        algid.estimate(t, signals=signals, model=module, derivative_window="1")
    for window, words in ((1e9, "of memory"), (1e300, "more than 2\\*\\*53")):
        with pytest.raises(InputDataError, match=f"derivative_window: .*{words}"):
            algid.OnlineEstimator(module, dt=1e-3, derivative_window=window)
    with pytest.raises(InputDataError, match="derivative_window must be a positive number"):
        algid.OnlineEstimator(dt=1e-3, derivative_window="1")


# ----------------------------------------------------------------- types


@pytest.mark.parametrize("call", [
    lambda s: algid.estimate("abc", s.f, s.x),
    lambda s: algid.estimate(None, s.f, s.x),
    lambda s: algid.estimate(s.t, s.f.astype(str), s.x),
    lambda s: algid.estimate(s.t, np.array([None] * s.t.size), s.x),
    lambda s: algid.estimate(s.t, np.stack([s.f, s.f]), s.x),
    lambda s: algid.estimate(s.t, s.f > 0, s.x),
    lambda s: algid.estimate(s.t, s.f, s.x, numerical_error="no"),
    lambda s: algid.estimate(s.t, s.f, s.x, mass="1"),
    lambda s: algid.estimate(s.t, s.f, s.x, filter_order=None),
    lambda s: algid.OnlineEstimator(dt="0.001"),
    lambda s: algid.OnlineEstimator(reset_period=True),
    lambda s: algid.OnlineEstimator().update("a", "b", "c"),
    lambda s: algid.OnlineEstimator().update(s.t[:5], np.stack([s.f[:5]] * 2), s.x[:5]),
    lambda s: algid.simulate(m="1"),
    lambda s: algid.simulate(duration=None),
    lambda s: algid.simulate(noise_std=0.1, seed="abc"),
    lambda s: algid.simulate(noise_std=0.1, seed=-1),
    lambda s: algid.simulate(noise_std=0.1, seed=1.5),
    lambda s: algid.simulate(noise_std=0.1, seed=True),
])
def test_arguments_of_the_wrong_type_give_one_line(sine, call):
    with pytest.raises(AlgidError) as exc:
        call(sine)
    one_line(exc)


def test_a_string_signal_is_named_as_such(sine):
    with pytest.raises(InputDataError, match=r"time 't' is a str \('abc'\): give one 1-D array"):
        algid.estimate("abc", sine.f, sine.x)


# ----------------------------------------------------------------- simulate


@pytest.mark.parametrize("options, words", [
    ({"m": 1e-308}, "k/m, c/m or 1/m overflows"),
    ({"c": 1e308}, "x_true is not finite"),
    ({"noise_std": 1e308}, "simulated x is not finite"),
    ({"inputs": "sine", "frequency": 1e308}, "frequency=1e+308"),
])
def test_simulations_out_of_range_are_refused(options, words, capsys, tmp_path):
    with pytest.raises(InputDataError) as exc:
        algid.simulate(**options)
    assert words in one_line(exc)


@pytest.mark.parametrize("argv, words", [
    (["--mass", "1e-308"], "overflows"),
    (["--damping", "1e308"], "not finite"),
    (["--noise-std", "1e308"], "not finite"),
    (["--rate", "1e308"], "memory"),
    (["--duration", "1e-300"], "at least 2 samples"),
    (["--duration", "nan"], "not a finite number"),
    (["--rate", "-1"], "must be positive"),
])
def test_extreme_simulate_options_give_one_line(argv, words, capsys, tmp_path):
    code, _, err = run(capsys, "simulate", *argv, "--out", str(tmp_path / "o.csv"))
    assert_one_line_error(code, err, words)
    assert not (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("name", ["o.mat", "o", "o.csv.gz"])
def test_simulate_writes_only_to_a_csv_name(name, capsys, tmp_path):
    """CSV text under a name that estimate reads as another format (or not at all)."""
    code, _, err = run(capsys, "simulate", "--out", str(tmp_path / name))
    assert_one_line_error(code, err, "name the file .csv or .txt")
    assert not (tmp_path / name).exists()


def test_negative_numbers_with_an_exponent_are_values(capsys, tmp_path):
    out = tmp_path / "o.csv"
    code, _, err = run(capsys, "simulate", "--v0", "-1e-3", "--amplitude", "-2.5e0",
                       "--out", str(out))
    assert code == 0 and err == ""
    r = algid.simulate(amplitude=-2.5, initial_state=(0.0, -1e-3))
    np.testing.assert_allclose(np.loadtxt(out, delimiter=",", skiprows=1)[:, 2], r.x,
                               rtol=1e-15, atol=1e-18)


# ----------------------------------------------------------------- the warning's cause


def test_the_same_column_as_input_and_output_is_refused(sine, capsys, tmp_path):
    path = write_csv(tmp_path / "d.csv", sine.t, sine.f, sine.x)
    code, _, err = run(capsys, "estimate", str(path), "--input", "x", "--output", "x")
    assert_one_line_error(code, err, "--input and --output name the same column 'x'")


def test_the_large_error_warning_names_the_sampling_only_when_it_is_the_cause(
        capsys, tmp_path):
    coarse = algid.simulate("step", c=0.5, k=400.0, duration=5.0, rate=40.0)
    noisy = algid.simulate("step", noise_std=0.01, seed=1)
    records = {"coarse": (coarse.t, coarse.f, coarse.x),
               "noisy": (noisy.t, noisy.f, noisy.x),
               "no input": (noisy.t, 0.0 * noisy.f, noisy.x_true)}
    for name, (t, f, x) in records.items():
        path = write_csv(tmp_path / f"{name.replace(' ', '_')}.csv", t, f, x)
        code, _, err = run(capsys, "estimate", str(path))
        assert code == 0 and len(err.splitlines()) == 1, err
        assert err.startswith("warning: ") and "numerical error" in err
        assert ("resample faster" in err) == (name == "coarse"), err
        if name != "coarse":
            assert "does not come from the sampling" in err


@pytest.mark.parametrize("scale", [1e300, 1e-300])
def test_the_warnings_cause_does_not_depend_on_the_units(scale, capsys, tmp_path):
    """The noise level in units of the largest sample: at 1e300 the squares overflowed
    (raw RuntimeWarnings, "noise of about nan"), at 1e-300 they underflowed (another
    cause named)."""
    noisy = algid.simulate("step", noise_std=0.01, seed=1)
    lines = []
    for factor in (1.0, scale):
        path = write_csv(tmp_path / "d.csv", noisy.t, noisy.f * factor, noisy.x * factor)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            code, _, err = run(capsys, "estimate", str(path))
        assert code == 0 and len(err.splitlines()) == 1, err
        lines.append(err.replace(str(path), "d.csv"))
    assert lines[1] == lines[0] and "white noise of about" in lines[0]


# ----------------------------------------------------------------- model simulation


@pytest.mark.parametrize("change, words", [
    ({"parameters": {"B": None}}, "parameter 'B' must be a real number, got None"),
    ({"parameters": {"B": "1"}}, "parameter 'B' must be a real number"),
    ({"parameters": {"G": 1e308}, "scale": 10.0}, "known terms"),
    ({"time": "abc"}, "time is a str ('abc')"),
    ({"inputs": "list"}, "inputs must be a mapping"),
    ({"inputs": {"u": "abc"}}, "input 'u' is a str ('abc')"),
    ({"spike": 1e308}, "too large to interpolate"),
    ({"spike": 1e308, "interpolation": "cubic"}, "too large to interpolate"),
    ({"initial_state": "ab"}, "initial_state must be numbers"),
    ({"method": "XYZ"}, "method must be one of"),
    ({"rtol": -1.0}, "rtol must be a positive number"),
    ({"method": "RK4", "substeps": "4"}, "substeps must be a positive integer"),
    ({"method": "RK4", "substeps": 10**12}, "of memory"),
])
def test_simulate_model_refuses_bad_arguments_in_one_line(change, words):
    from algid.models._grammar import parse_equation
    from algid.simulation._model import simulate_model
    model = parse_equation("y'' + B*y' + K*y = G*u", "B K G")
    t = np.arange(200) / 100.0
    u = np.sin(t) * change.pop("scale", 1.0)
    if "spike" in change:
        u[-1] = change.pop("spike")
    parameters = {"B": 1.0, "K": 4.0, "G": 1.0, **change.pop("parameters", {})}
    inputs = change.pop("inputs", {"u": u})
    inputs = [u] if inputs == "list" else inputs
    with pytest.raises(AlgidError) as exc:
        simulate_model(model, parameters, change.pop("time", t), inputs, **change)
    assert words in one_line(exc)


def test_a_rate_too_small_for_the_times_is_named(sine, capsys, tmp_path):
    path = write_csv(tmp_path / "d.csv", sine.t, sine.f, sine.x)
    code, _, err = run(capsys, "estimate", str(path), "--rate", "1e-308")
    assert_one_line_error(code, err, "rate 1e-308 Hz")
