"""Records and arguments that identify() and the command line must refuse in one line
(or, where they are consistent, accept): a rate against a time column, date and
complex columns, terms outside their domain, arguments of the wrong type, time
scales out of range, records too large for the memory."""

import math
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error

import algid
from algid import _memory as memory
from algid.cli import main
from algid.errors import InputDataError, ModelError
from algid.identification._arguments import identify_bytes
from algid.models._grammar import parse_equation

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.adequacy import SECOND_ORDER, second_order  # noqa: E402
from benchmarks.synthetic_records import FRICTION_EQUATION, friction_loop  # noqa: E402

EQUATION, PARAMETERS = SECOND_ORDER


@pytest.fixture(scope="module")
def record():
    return second_order(0, duration=30.0)


@pytest.fixture(scope="module")
def reference(record):
    return algid.identify(record, EQUATION, PARAMETERS)


def one_line(info):
    text = str(info.value)
    assert "\n" not in text and text
    return text


# --------------------------------------------------------------------- time axis


def test_a_rate_that_contradicts_the_time_column_is_refused(record):
    with pytest.raises(InputDataError) as info:
        algid.identify(record, EQUATION, PARAMETERS, rate=1000.0)
    assert "rate 1000 Hz contradicts time column 't' (sampled at 100 Hz)" in one_line(info)
    with pytest.raises(InputDataError, match="contradicts"):
        algid.identify(record, EQUATION, PARAMETERS, time="t", rate=101.0)


def test_a_rate_that_agrees_with_the_time_column_is_accepted(record, reference):
    for options in ({"rate": 100.0}, {"time": "t", "rate": 100.0}, {"rate": 100.05}):
        r = algid.identify(record, EQUATION, PARAMETERS, **options)
        assert r.values == reference.values, options


@pytest.mark.parametrize("unit", ["ns", "us"])
def test_datetime64_and_timedelta64_times_become_seconds_without_losing_precision(
        record, reference, unit):
    # at an epoch of 2024 a float of seconds holds about 0.2 us: the conversion must
    # subtract the first time before it, in the column's own integer unit
    ticks = np.round(record["t"] * {"ns": 1e9, "us": 1e6}[unit]).astype(f"timedelta64[{unit}]")
    for t in (np.datetime64("2024-05-01T12:00:00", unit) + ticks,
              np.timedelta64(3600, "s").astype(f"timedelta64[{unit}]") + ticks):
        r = algid.identify(dict(record, t=t), EQUATION, PARAMETERS)
        for p, v in reference.values.items():
            assert abs(r.values[p] / v - 1) < 1e-9, (unit, p)


@pytest.mark.parametrize("rate", [True, np.bool_(True), "100", [100.0]])
def test_a_rate_that_is_not_a_number_is_refused(record, rate):
    data = {"u": record["u"], "y": record["y"]}
    with pytest.raises(InputDataError) as info:
        algid.identify(data, EQUATION, PARAMETERS, rate=rate)
    assert "rate must be a number of Hz" in one_line(info)


@pytest.mark.parametrize("rate", [1e308, 1e-308, 1e100, 1e-40])
def test_a_rate_out_of_the_time_scale_range_is_refused(record, rate):
    data = {"u": record["u"], "y": record["y"]}
    with pytest.raises(InputDataError) as info:
        algid.identify(data, EQUATION, PARAMETERS, rate=rate)
    assert f"rate {rate:g} Hz gives a sampling step" in one_line(info)


def test_a_time_column_of_an_extreme_step_is_refused(record):
    with pytest.raises(InputDataError) as info:
        algid.identify(dict(record, t=record["t"] * 1e-40), EQUATION, PARAMETERS)
    assert "time column 't' has a step of 1e-42" in one_line(info)


def test_the_time_column_may_not_be_a_signal_of_the_equation(record):
    with pytest.raises(InputDataError) as info:
        algid.identify(record, EQUATION, PARAMETERS, time="y")
    assert "time column 'y' is also a signal" in one_line(info)


# --------------------------------------------------------------------- signals


def test_complex_and_date_signals_are_refused_naming_the_column(record):
    with pytest.raises(InputDataError) as info:
        algid.identify(dict(record, u=record["u"] + 0.5j), EQUATION, PARAMETERS)
    assert "column 'u' is complex" in one_line(info)
    dates = np.datetime64("2024-01-01") + np.arange(len(record["u"])).astype("timedelta64[s]")
    with pytest.raises(InputDataError) as info:
        algid.identify(dict(record, u=dates), EQUATION, PARAMETERS)
    assert "column 'u' holds dates or durations" in one_line(info)


@pytest.mark.parametrize("equation, parameters, change, fragment", [
    ("y'' + B*y' + K*y + C*log(y) = G*u", "B K C G", None, "the term log(y) is nan"),
    ("y'' + B*y' + K*y + C*sqrt(y) = G*u", "B K C G", None, "the term sqrt(y) is nan"),
    ("y'' + B*y' + K*y + C/y = G*u", "B K C G", "zero", "is inf at t = 5 s (row 500)"),
    ("y'' + B*y' + K*y + C/t = G*u", "B K C G", None, "is inf at t = 0 s (row 0)"),
])
def test_a_term_outside_its_domain_is_refused_naming_it_and_the_time(
        record, equation, parameters, change, fragment):
    data = dict(record)
    if change == "zero":
        data["y"] = np.where(np.arange(len(data["y"])) == 500, 0.0, np.abs(data["y"]) + 1)
    with pytest.raises(InputDataError) as info:
        algid.identify(data, equation, parameters)
    text = one_line(info)
    assert fragment in text and "domain" in text
    if "log" in equation:   # the first sample where y <= 0
        first = int(np.flatnonzero(record["y"] <= 0)[0])
        assert f"(row {first})" in text


# --------------------------------------------------------------------- arguments


@pytest.mark.parametrize("options, error, fragment", [
    ({"parameters": None}, ModelError, "name the unknown parameters"),
    ({"parameters": 5}, ModelError, "parameters must be"),
    ({"equation": 5}, ModelError, "equation must be a text equation or a Model"),
    ({"name": 5}, ModelError, "name must be a string"),
    ({"window": "abc"}, InputDataError, "window must be a number of seconds, got 'abc'"),
    ({"window": True}, InputDataError, "window must be a number"),
    ({"multiplicities": 12}, InputDataError, "multiplicities must be a sequence"),
    ({"multiplicities": (8.5, 12)}, InputDataError, "multiplicity 8.5 is not an integer"),
    ({"multiplicities": (8, 99)}, InputDataError, "multiplicity 99 is not an integer"),
    ({"method": 3}, InputDataError, "unknown method 3"),
    ({"iterations": -1, "method": "iv"}, InputDataError, "iterations must be a positive"),
    ({"iterations": 1.5}, InputDataError, "iterations must be a positive"),
    ({"time": 3}, InputDataError, "time must be a column name"),
    ({"output": ["y"]}, InputDataError, "output must be a column name"),
])
def test_arguments_of_the_wrong_type_are_one_line_errors(record, options, error, fragment):
    arguments = {"equation": EQUATION, "parameters": PARAMETERS}
    arguments.update(options)
    equation, parameters = arguments.pop("equation"), arguments.pop("parameters")
    with pytest.raises(error) as info:
        algid.identify(record, equation, parameters, **arguments)
    assert fragment in one_line(info)


# --------------------------------------------------------------------- memory


def test_records_too_large_for_the_memory_are_refused_before_any_work(record, monkeypatch):
    n = len(record["y"])
    needed = n * identify_bytes(parse_equation(EQUATION, PARAMETERS))
    monkeypatch.setattr(memory, "available_memory", lambda: needed // 2)
    with pytest.raises(InputDataError) as info:
        algid.identify(record, EQUATION, PARAMETERS)
    text = one_line(info)
    assert text.startswith(f"identify: {n:.4g} samples need about") and "available" in text
    monkeypatch.setattr(memory, "available_memory", lambda: 2 * needed)
    algid.identify(record, EQUATION, PARAMETERS)


@pytest.mark.parametrize("make, equation", [
    (lambda: second_order(0, duration=600.0), SECOND_ORDER),            # 60 000 samples
    (lambda: friction_loop(0, n=30000)[0], FRICTION_EQUATION),
])
def test_the_memory_estimate_is_above_the_peak_allocation(make, equation):
    import tracemalloc

    data = make()
    algid.identify(second_order(1, duration=30.0), *SECOND_ORDER)    # warm the caches
    tracemalloc.start()
    algid.identify(data, *equation)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    n = len(next(iter(data.values())))
    assert peak < n * identify_bytes(parse_equation(*equation)), peak / n


def test_an_address_space_limit_lowers_the_memory_available():
    script = ("import resource; from algid._memory import available_memory; "
              "resource.setrlimit(resource.RLIMIT_AS, (3 * 2**30, resource.RLIM_INFINITY)); "
              "print(available_memory())")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         check=True, env={"PYTHONPATH": str(ROOT / "src"),
                                          "OPENBLAS_NUM_THREADS": "1"}).stdout
    assert 0 < int(out) < 3 * 2**30


# --------------------------------------------------------------------- command line


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def files(tmp_path_factory, record):
    folder = tmp_path_factory.mktemp("adversarial")
    rows = np.column_stack([record["t"], record["u"], record["y"]])
    timed = folder / "timed.csv"
    np.savetxt(timed, rows, delimiter=",", header="t,u,y", comments="")
    noisy = folder / "noisy.csv"
    loud = second_order(1, noise=0.05)
    np.savetxt(noisy, np.column_stack([loud["t"], loud["u"], loud["y"]]), delimiter=",",
               header="t,u,y", comments="")
    coarse = folder / "coarse.csv"    # 5 samples per period of a lightly damped mode
    t = np.arange(3000) / 10.0
    w0 = 2 * np.pi * 2.0
    u = np.sin(2 * np.pi * 0.9 * t) + np.sin(2 * np.pi * 2.3 * t)
    response = [1 / (w0 ** 2 - (2 * np.pi * f) ** 2 + 0.5j * 2 * np.pi * f) for f in (0.9, 2.3)]
    y = sum(abs(h) * np.sin(2 * np.pi * f * t + np.angle(h)) for h, f in zip(response, (0.9, 2.3)))
    np.savetxt(coarse, np.column_stack([t, u, y]), delimiter=",", header="t,u,y", comments="")
    return timed, noisy, coarse


@pytest.mark.parametrize("extra, fragments", [
    (["--rate", "1000"], ["rate 1000 Hz contradicts time column 't'"]),
    (["--rate", "1e308"], ["rate 1e+308 Hz gives a sampling step of 1e-308 s"]),
    (["--rate", "1e-308"], ["rate 1e-308 Hz gives a sampling step of 1e+308 s"]),
    (["--time", "y"], ["time column 'y' is also a signal"]),
    (["--equation", "y'' + B*y' + K*y + C*log(y) = G*u", "--parameters", "B K C G"],
     ["the term log(y) is nan at t = "]),
])
def test_identify_refuses_in_one_line(capsys, files, extra, fragments):
    arguments = ["--equation", EQUATION, "--parameters", PARAMETERS]
    if "--equation" in extra:
        arguments = []
    code, _, err = run(capsys, "identify", files[0], *arguments, *extra)
    assert_one_line_error(code, err, *fragments)


def test_identify_accepts_a_rate_that_agrees(capsys, files, reference):
    for extra in (["--rate", "100"], ["--rate", "100", "--time", "t"]):
        code, out, err = run(capsys, "identify", files[0], "--equation", EQUATION,
                             "--parameters", PARAMETERS, "--json", *extra)
        assert code == 0 and err == "", err
        assert f'"B": {reference.values["B"]!r}' in out


def test_identify_refuses_records_too_large_for_the_memory(capsys, files, monkeypatch):
    import algid.identification._arguments as arguments

    monkeypatch.setattr(arguments, "identify_bytes", lambda model: 1e15)
    code, _, err = run(capsys, "identify", files[0], "--equation", EQUATION,
                       "--parameters", PARAMETERS)
    assert_one_line_error(code, err, "identify: 3000 samples need about", " TB of memory")


@pytest.mark.parametrize("extra, fragments", [
    (["--input", "u", "--output", "u"], ["--input and --output name the same column 'u'"]),
    (["--input", "u", "--output", "t"], ["--output and --time name the same column 't'"]),
    (["--input", "u", "--output", "y", "--rate", "1000"], ["contradicts time column 't'"]),
    (["--input", "u", "--output", "y", "--rate", "1e308"], ["gives a sampling step"]),
    (["--input", "u", "--output", "y", "--rate", "1e-308"], ["gives a sampling step"]),
])
def test_estimate_refuses_in_one_line(capsys, files, extra, fragments):
    code, _, err = run(capsys, "estimate", files[0], *extra)
    assert_one_line_error(code, err, *fragments)


def test_estimate_warning_names_noise_or_resolution(capsys, files):
    _, noisy, coarse = files
    code, _, err = run(capsys, "estimate", noisy, "--input", "u", "--output", "y")
    lines = err.splitlines()
    assert code == 0 and len(lines) == 1
    level = float(lines[0].split("white noise of about ")[1].split()[0])
    assert math.isclose(level, 0.05, rel_tol=0.1) and "resample" not in lines[0]
    code, _, err = run(capsys, "estimate", coarse, "--input", "u", "--output", "y")
    lines = err.splitlines()
    assert code == 0 and len(lines) == 1
    assert "shows no noise floor" in lines[0] and "samples per period" in lines[0]


@pytest.mark.parametrize("column", ["u", "y"])
def test_integers_beyond_floating_point_are_refused_naming_the_column(record, column):
    huge = [10**400] * len(record[column])
    with pytest.raises(InputDataError) as info:
        algid.identify(dict(record, **{column: huge}), EQUATION, PARAMETERS)
    assert f"column {column!r} holds numbers too large for floating point" in one_line(info)


def test_an_unreadable_equation_is_shown_as_written():
    with pytest.raises(ModelError) as info:
        parse_equation("y'' + " + "1" * 5000 + "*y + B*y' = u", "B")
    message = one_line(info)
    assert "cannot read \"y'' + 111" in message and "__d" not in message


@pytest.mark.parametrize("name", ["if", "class", "lambda"])
def test_a_keyword_is_refused_as_a_parameter_name(name):
    with pytest.raises(ModelError) as info:
        parse_equation(f"y'' + {name}*y' + K*y = u", f"{name} K")
    assert f"parameter name {name} is a Python keyword" in one_line(info)
