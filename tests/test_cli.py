"""Tests of the ``algid`` command line (run in-process through ``algid.cli.main``)."""

import importlib.util
import json
import subprocess
import sys
import types
from importlib.metadata import entry_points
from pathlib import Path

import numpy as np
import pytest
import scipy.io
from conftest import assert_one_line_error

import algid
from algid._signal_checks import check_experiment
from algid.cli import main
from algid.errors import InputDataError, ModelError


def run(capsys, *argv):
    code = main([str(arg) for arg in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def signals(n=200, h=1e-3):
    t = np.arange(n) * h
    f = np.ones(n)
    x = 1.5 * t**2
    return t, f, x


def write_csv(path, columns, header=None):
    names = list(columns) if header is None else header
    rows = zip(*(np.asarray(v).tolist() for v in columns.values()))
    lines = [",".join(names)] + [",".join(repr(v) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


@pytest.fixture
def good_csv(tmp_path):
    t, f, x = signals()
    return write_csv(tmp_path / "data.csv", {"t": t, "f": f, "x": x})


def install_module(monkeypatch, name, **attributes):
    """Put a stand-in module under ``algid.<name>`` for the duration of a test."""
    module = types.ModuleType(f"algid.{name}")
    for key, value in attributes.items():
        setattr(module, key, value)
    monkeypatch.setitem(sys.modules, f"algid.{name}", module)
    monkeypatch.setattr(algid, name, module, raising=False)
    return module


def ensure_dependency(monkeypatch, name):
    """Let a command's dependency check pass even where the package is not installed."""
    if name not in sys.modules and importlib.util.find_spec(name) is None:
        monkeypatch.setitem(sys.modules, name, types.ModuleType(name))


class FakeResult:
    def __init__(self, t, estimates, model, filter_order):
        self._estimates = estimates
        self.parameters = tuple(estimates)
        self.t_valid = float(t[3])
        self.n_samples = len(t)
        self.model = model
        self.filter_order = filter_order

    def final(self):
        return dict(self._estimates)


@pytest.fixture
def fake_estimator(monkeypatch):
    """Replace ``algid.estimation._batch`` by a stand-in that records its calls."""
    calls = []

    def estimate(t, f, x, *, model="msd", filter_order=2, mass=None):
        calls.append({"t": t, "f": f, "x": x, "model": model, "filter_order": filter_order,
                      "mass": mass})
        if model not in ("msd", "msd_mass"):
            raise ModelError(f"unknown model {model!r} (known: msd, msd_mass)")
        t, f, x, _ = check_experiment(t, f, x)
        estimates = {"B": 2.0, "K": float("nan")}
        if mass is not None:
            estimates.update(c=2.0 * mass, k=float("nan"))
        return FakeResult(t, estimates, model, filter_order)

    install_module(monkeypatch, "estimation._batch", estimate=estimate)
    return calls


# ------------------------------------------------------------------ basics


def test_version(capsys):
    code, out, _ = run(capsys, "--version")
    assert code == 0
    assert out.strip().startswith("algid ")


def test_no_command_is_usage_error(capsys):
    code, _, err = run(capsys)
    assert code == 2
    assert err.count("\n") == 1 and "COMMAND" in err and "--help" in err


@pytest.mark.parametrize(
    "argv",
    [
        ["estimate"],
        ["estimate", "d.csv", "--bogus"],
        ["estimate", "d.csv", "--rate", "-1"],
        ["estimate", "d.csv", "--rate", "100", "--time", "t"],
        ["estimate", "d.csv", "--filter-order", "two"],
        ["simulate"],
        ["simulate", "--out", "s.csv", "--input", "ramp"],
        ["derive", "--format", "pdf"],
    ],
)
def test_usage_errors_exit_2(capsys, argv):
    code, _, err = run(capsys, *argv)
    assert code == 2
    assert "Traceback" not in err


def test_console_script_is_declared():
    scripts = entry_points(group="console_scripts")
    assert any(ep.name == "algid" and ep.value == "algid.cli:main" for ep in scripts)


def test_python_m_algid_exit_code(tmp_path):
    missing = tmp_path / "missing.csv"
    proc = subprocess.run(
        [sys.executable, "-m", "algid", "estimate", str(missing)],
        capture_output=True, text=True, timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert proc.stderr.splitlines() == [f"algid: error: {missing}: file not found"]


# ---------------------------------------------------------- estimate: bad input


def _nan(tmp_path):
    t, f, x = signals()
    x[17] = np.nan
    path = write_csv(tmp_path / "data.csv", {"t": t, "f": f, "x": x})
    return path, ["signal 'x' has NaN at row 17"]


def _inf(tmp_path):
    t, f, x = signals()
    f[9] = np.inf
    path = write_csv(tmp_path / "data.csv", {"t": t, "f": f, "x": x})
    return path, ["signal 'f' has inf at row 9"]


def _lengths(tmp_path):
    t, f, x = signals()
    path = tmp_path / "data.mat"
    scipy.io.savemat(path, {"t": t, "f": f, "x": x[:-1]})
    return path, ["different lengths", "x: 199"]


def _not_increasing(tmp_path):
    t, f, x = signals()
    t[50] = t[49]
    return write_csv(tmp_path / "data.csv", {"t": t, "f": f, "x": x}), [
        "does not increase at row 50"]


def _too_few(tmp_path):
    t, f, x = signals(n=5)
    return write_csv(tmp_path / "data.csv", {"t": t, "f": f, "x": x}), ["only 5 samples"]


def _missing_column(tmp_path):
    t, f, x = signals()
    return write_csv(tmp_path / "data.csv", {"t": t, "f": f, "y": x}), [
        "column 'x' not found (columns: t, f, y)"]


def _non_numeric(tmp_path):
    path = tmp_path / "data.csv"
    path.write_text("t,f,x\n0,1,0\n0.001,1,oops\n", encoding="utf-8")
    return path, ["column 'x', line 3: 'oops' is not a number"]


def _empty(tmp_path):
    path = tmp_path / "data.csv"
    path.write_text("", encoding="utf-8")
    return path, ["file is empty"]


def _header_only(tmp_path):
    path = tmp_path / "data.csv"
    path.write_text("t,f,x\n", encoding="utf-8")
    return path, ["no data rows after the header"]


def _no_excitation(tmp_path):
    t, _, _ = signals()
    zero = np.zeros_like(t)
    return write_csv(tmp_path / "data.csv", {"t": t, "f": zero, "x": zero}), [
        "no excitation: input 'f' and output 'x' are both zero"]


def _non_uniform(tmp_path):
    t, f, x = signals()
    t[120:] += 0.4e-3
    return write_csv(tmp_path / "data.csv", {"t": t, "f": f, "x": x}), [
        "not uniformly sampled", "resample first"]


def _unknown_extension(tmp_path):
    path = tmp_path / "data.xlsx"
    path.write_text("t,f,x\n", encoding="utf-8")
    return path, ["unknown file type (extension '.xlsx')"]


def _missing_file(tmp_path):
    return tmp_path / "nothing.csv", ["file not found"]


BAD_INPUTS = {
    "nan": _nan,
    "inf": _inf,
    "different-lengths": _lengths,
    "time-not-increasing": _not_increasing,
    "too-few-samples": _too_few,
    "missing-column": _missing_column,
    "non-numeric": _non_numeric,
    "empty-file": _empty,
    "header-only": _header_only,
    "no-excitation": _no_excitation,
    "non-uniform": _non_uniform,
    "unknown-extension": _unknown_extension,
    "missing-file": _missing_file,
}


@pytest.mark.parametrize("case", list(BAD_INPUTS))
def test_estimate_bad_input_is_one_line_exit_2(capsys, tmp_path, case):
    path, fragments = BAD_INPUTS[case](tmp_path)
    code, out, err = run(capsys, "estimate", path)
    assert out == ""
    assert_one_line_error(code, err, f"algid: error: {path}: ", *fragments)


def test_estimate_bad_input_names_renamed_columns(capsys, tmp_path):
    t, f, x = signals()
    x[30] = np.nan
    path = write_csv(tmp_path / "sb.csv", {"V1": f, "V2": x})
    code, _, err = run(capsys, "estimate", path, "--input", "V1", "--output", "V2",
                       "--rate", 1000)
    assert_one_line_error(code, err, "signal 'V2' has NaN at row 30")


def test_estimate_missing_time_column_suggests_rate(capsys, tmp_path):
    t, f, x = signals()
    path = write_csv(tmp_path / "sb.csv", {"V1": f, "V2": x})
    code, _, err = run(capsys, "estimate", path, "--input", "V1", "--output", "V2")
    assert_one_line_error(code, err, "time column 't' not found", "--rate")


def test_estimate_error_from_estimator_is_one_line(capsys, good_csv, fake_estimator):
    code, out, err = run(capsys, "estimate", good_csv, "--model", "nope")
    assert out == ""
    assert_one_line_error(code, err, "unknown model 'nope'")


# -------------------------------------------------------- estimate: success


def test_estimate_table_with_fake(capsys, good_csv, fake_estimator):
    code, out, err = run(capsys, "estimate", good_csv)
    assert (code, err) == (0, "")
    call, = fake_estimator
    assert call["model"] == "msd"
    assert call["mass"] is None
    assert call["filter_order"] == 2  # not passed: the estimator's default applies
    np.testing.assert_array_equal(call["x"], signals()[2])
    assert "parameter" in out and "estimate" in out
    lines = out.splitlines()
    assert any(line.split() == ["B", "2"] for line in lines)
    assert any(line.split() == ["K", "nan"] for line in lines)
    assert "valid from t = 0.003 s" in out


def test_estimate_passes_options(capsys, good_csv, fake_estimator):
    code, out, _ = run(capsys, "estimate", good_csv, "--mass", 2.5, "--filter-order", 3,
                       "--model", "msd")
    assert code == 0
    call, = fake_estimator
    assert call["mass"] == 2.5 and call["filter_order"] == 3 and call["model"] == "msd"
    assert any(line.split() == ["c", "5"] for line in out.splitlines())


def test_estimate_json_nan_becomes_null(capsys, good_csv, fake_estimator):
    code, out, _ = run(capsys, "estimate", good_csv, "--json", "--mass", 2)
    assert code == 0
    assert len(out.strip().splitlines()) == 1
    data = json.loads(out)
    assert data == {"B": 2.0, "K": None, "c": 4.0, "k": None, "t_valid": 0.003,
                    "n_samples": 200, "numerical_error": None}


def test_estimate_silverbox_style_with_rate(capsys, tmp_path, fake_estimator):
    _, f, x = signals()
    path = tmp_path / "SNLS80mV.csv"
    body = "".join(f"{a!r},{b!r},\n" for a, b in zip(f.tolist(), x.tolist()))
    path.write_text('"V1","V2",\n' + body, encoding="utf-8")
    code, out, _ = run(capsys, "estimate", path, "--input", "V1", "--output", "V2",
                       "--rate", 500, "--json")
    assert code == 0
    call, = fake_estimator
    np.testing.assert_allclose(call["t"], np.arange(200) / 500)
    np.testing.assert_array_equal(call["f"], f)
    assert json.loads(out)["n_samples"] == 200


def test_estimate_mat_file(capsys, tmp_path, fake_estimator):
    t, f, x = signals()
    path = tmp_path / "exp.mat"
    scipy.io.savemat(path, {"time": t[:, None], "u": f[:, None], "y": x[:, None]})
    code, _, _ = run(capsys, "estimate", path, "--time", "time", "--input", "u",
                     "--output", "y")
    assert code == 0
    np.testing.assert_array_equal(fake_estimator[0]["x"], x)


def test_estimate_with_real_estimator(capsys, tmp_path):
    pytest.importorskip("algid.estimation._batch")
    n, h = 3001, 1e-3
    t = np.arange(n) * h
    # closed-form step response of x'' + 2 x' + 3 x = 1 from rest
    w = np.sqrt(2.0)
    x = (1 - np.exp(-t) * (np.cos(w * t) + np.sin(w * t) / w)) / 3
    path = write_csv(tmp_path / "step.csv", {"t": t, "f": np.ones(n), "x": x})
    code, out, err = run(capsys, "estimate", path, "--json")
    assert (code, err) == (0, "")
    data = json.loads(out)
    assert data["B"] == pytest.approx(2.0, rel=1e-3)
    assert data["K"] == pytest.approx(3.0, rel=1e-3)
    assert data["n_samples"] == n


# ------------------------------------------------------------------ simulate


class FakeSimulation:
    def __init__(self, n):
        self.t = np.arange(n) / 10.0
        self.f = np.ones(n)
        self.x = np.zeros(n)

    def to_csv(self, path):
        Path(path).write_text("t,f,x\n", encoding="utf-8")
        return Path(path)


@pytest.fixture
def fake_simulation(monkeypatch):
    calls = []

    def simulate(inputs="step", **kwargs):
        calls.append((inputs, kwargs))
        return FakeSimulation(11)

    ensure_dependency(monkeypatch, "control")
    install_module(monkeypatch, "simulation", simulate=simulate)
    return calls


def test_simulate_defaults_with_fake(capsys, tmp_path, fake_simulation):
    out_path = tmp_path / "sim.csv"
    code, out, err = run(capsys, "simulate", "--out", out_path)
    assert (code, err) == (0, "")
    (inputs, kwargs), = fake_simulation
    assert inputs == "step"
    assert kwargs == dict(m=1.0, c=2.0, k=3.0, duration=5.0, rate=1000.0, amplitude=1.0,
                          frequency=1.0, initial_state=(0.0, 0.0), noise_std=0.0, seed=None)
    assert out_path.exists()
    assert len(out.splitlines()) == 1
    assert f"wrote 11 samples to {out_path}" in out


def test_simulate_options_with_fake(capsys, tmp_path, fake_simulation):
    code, _, _ = run(capsys, "simulate", "--input", "sine", "--amplitude", 2,
                     "--frequency", 3, "--mass", 4, "--damping", 5, "--stiffness", 6,
                     "--duration", 7, "--rate", 80, "--x0", 0.1, "--v0", -0.2,
                     "--noise-std", 0.01, "--seed", 42, "--out", tmp_path / "s.csv")
    assert code == 0
    (inputs, kwargs), = fake_simulation
    assert inputs == "sine"
    assert kwargs == dict(m=4.0, c=5.0, k=6.0, duration=7.0, rate=80.0, amplitude=2.0,
                          frequency=3.0, initial_state=(0.1, -0.2), noise_std=0.01, seed=42)


def test_simulate_unwritable_output(capsys, tmp_path, fake_simulation):
    target = tmp_path / "no" / "such" / "dir" / "s.csv"
    code, _, err = run(capsys, "simulate", "--out", target)
    assert_one_line_error(code, err, f"{target}: cannot write file")


def test_simulate_without_control(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "control", None)
    code, _, err = run(capsys, "simulate", "--out", tmp_path / "s.csv")
    assert_one_line_error(
        code, err, "algid simulate needs python-control: pip install 'algid[simulate]'")


def test_simulate_bad_parameter_from_simulation(capsys, tmp_path, monkeypatch):
    def simulate(inputs, **kwargs):
        raise InputDataError("stiffness k must be finite, got nan")

    ensure_dependency(monkeypatch, "control")
    install_module(monkeypatch, "simulation", simulate=simulate)
    code, _, err = run(capsys, "simulate", "--out", tmp_path / "s.csv")
    assert_one_line_error(code, err, "stiffness k must be finite")


def test_simulate_then_estimate_real(capsys, tmp_path):
    pytest.importorskip("algid.simulation")
    pytest.importorskip("algid.estimation._batch")
    path = tmp_path / "sim.csv"
    code, out, _ = run(capsys, "simulate", "--out", path, "--duration", 3)
    assert code == 0 and str(path) in out
    code, out, err = run(capsys, "estimate", path, "--json")
    assert (code, err) == (0, "")
    data = json.loads(out)
    assert data["B"] == pytest.approx(2.0, rel=1e-3)
    assert data["K"] == pytest.approx(3.0, rel=1e-3)
    assert data["n_samples"] == 3001


# -------------------------------------------------------------------- derive


def test_derive_with_fake(capsys, monkeypatch):
    calls = []

    def derivation_report(model_name, fmt):
        calls.append((model_name, fmt))
        return f"report of {model_name} as {fmt}\n"

    ensure_dependency(monkeypatch, "sympy")
    install_module(monkeypatch, "symbolic", derivation_report=derivation_report)
    code, out, _ = run(capsys, "derive")
    assert code == 0
    assert out == "report of msd as text\n"
    code, out, _ = run(capsys, "derive", "--model", "msd_mass", "--format", "latex")
    assert code == 0
    assert calls == [("msd", "text"), ("msd_mass", "latex")]


def test_derive_unknown_model_is_one_line(capsys, monkeypatch):
    def derivation_report(model_name, fmt):
        raise ModelError(f"unknown model {model_name!r} (known: msd, msd_mass)")

    ensure_dependency(monkeypatch, "sympy")
    install_module(monkeypatch, "symbolic", derivation_report=derivation_report)
    code, _, err = run(capsys, "derive", "--model", "spring")
    assert_one_line_error(code, err, "unknown model 'spring'")


def test_derive_without_sympy(capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "sympy", None)
    code, out, err = run(capsys, "derive")
    assert out == ""
    assert_one_line_error(code, err, "algid derive needs SymPy: pip install 'algid[derive]'")


# ------------------------------------------------------------------ datasets


def test_identify_reads_a_gzip_csv(capsys, tmp_path):
    import gzip

    t = np.arange(3000) * 1e-3
    u = np.sin(7 * t) + np.sin(31 * t)
    # y'' + 4 y' + 100 y = 100 u, simulated finely enough for 5 significant digits
    from algid.models._grammar import parse_equation
    from algid.simulation._model import simulate_model

    model = parse_equation("y'' + B*y' + K*y = G*u", "B K G")
    y = simulate_model(model, {"B": 4.0, "K": 100.0, "G": 100.0}, t, {"u": u}, rtol=1e-11)
    plain = write_csv(tmp_path / "run.csv", {"t": t, "u": u, "y": y})
    packed = tmp_path / "run.csv.gz"
    packed.write_bytes(gzip.compress(plain.read_bytes()))
    answers = []
    for path in (plain, packed):
        code, out, err = run(capsys, "identify", path, "--equation", "y'' + B*y' + K*y = G*u",
                             "--parameters", "B K G", "--json")
        assert code == 0, err
        answers.append(json.loads(out))
    assert answers[0] == answers[1]
    assert abs(answers[1]["K"] / 100 - 1) < 1e-3


def test_datasets_list_names_each_record_its_files_and_citation(capsys):
    code, out, err = run(capsys, "datasets", "list")
    assert code == 0 and err == ""
    assert out.startswith("silverbox: silverbox.csv") and "\nemps: emps_estimation.csv" in out
    assert out.count("cite: ") == 2 and "Janot" in out and "Wigren" in out


def test_datasets_export_then_identify_reads_the_files_directly(capsys, tmp_path):
    code, out, err = run(capsys, "datasets", "export", "emps", tmp_path / "records")
    assert code == 0, err
    assert out.splitlines() == [f"wrote {tmp_path / 'records' / name}"
                                for name in ("emps_estimation.csv", "emps_validation.csv")]
    equation = "M*qm'' + Fv*qm' + Fc*sign(qm') + off = F"
    code, out, err = run(capsys, "identify", tmp_path / "records" / "emps_estimation.csv",
                         "--equation", equation, "--parameters", "M Fv Fc off", "--json")
    assert code == 0, err
    # the exported values are exact: the same estimate as from the record in Python
    record = algid.datasets.emps("estimation")
    expected = algid.identify({"t": record.t, "qm": record.qm, "F": record.F}, equation,
                              "M Fv Fc off")
    assert {p: json.loads(out)[p] for p in expected.values} == expected.values


@pytest.mark.parametrize("argv, expected", [
    (["datasets"], "the following arguments are required: ACTION"),
    (["datasets", "export", "nope", "d"], "invalid choice: 'nope'"),
    (["datasets", "export", "emps"], "the following arguments are required: DIR"),
])
def test_datasets_usage_errors_are_one_line(capsys, argv, expected):
    code, _, err = run(capsys, *argv)
    assert_one_line_error(code, err, "datasets", expected)


def test_datasets_export_into_an_unwritable_place_is_one_line(capsys, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    code, _, err = run(capsys, "datasets", "export", "emps", blocker / "sub")
    assert_one_line_error(code, err, "cannot write")


def test_a_coefficient_that_overflows_is_one_line(capsys, tmp_path):
    t = np.arange(0, 5, 0.01)
    u = np.sin(t) + np.sin(3.7 * t)
    y = np.cos(t) + 0.1 * np.sin(5 * t)
    path = tmp_path / "record.csv"
    np.savetxt(path, np.column_stack([t, u, y]), delimiter=",", header="t,u,y", comments="")
    code, out, err = run(capsys, "identify", path, "--equation", "y'' + B*y' + K*y = 1e200*u",
                         "--parameters", "B K")
    assert_one_line_error(code, err, "overflows floating point")


def test_paper_bounds_the_number_of_seeds(capsys, tmp_path):
    from algid.paper._reproduction import MAX_SEEDS

    out = tmp_path / "figures"
    code, _, err = run(capsys, "paper", "--out", out, "--n-seeds", 1_000_000_000)
    assert_one_line_error(code, err, f"n_seeds must be an integer from 1 to {MAX_SEEDS}")
    assert not out.exists()
