"""``algid identify``: output, --json keys, exit codes and one-line errors."""

import json
import sys

import numpy as np
import pytest
from conftest import ROOT, assert_one_line_error
from scipy.io import savemat

from algid.cli import main

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.synthetic_records import LINEAR_EQUATION, linear_offsets  # noqa: E402


def run(capsys, *argv):
    code = main([str(arg) for arg in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def record_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("identify")
    record, truth = linear_offsets(0, n=2000)
    csv = folder / "run.csv"
    rows = np.column_stack([record["t"], record["u"], record["y"]])
    np.savetxt(csv, rows, delimiter=",", header="t,u,y", comments="")
    no_time = folder / "no_time.csv"
    np.savetxt(no_time, rows[:, 1:], delimiter=",", header="u,y", comments="")
    second, _ = linear_offsets(1, n=2000)
    mat = folder / "run2.mat"
    savemat(mat, {"t": second["t"] + 100, "u": second["u"], "y": second["y"]})
    return csv, no_time, mat, truth


def test_json_has_a_key_per_parameter_stderr_window_samples_and_warnings(capsys,
                                                                         record_files):
    csv, _, mat, truth = record_files
    # (8 samples per period: the default keeps the algebraic estimate, whose numerical
    # error is honest there; --refine refines anyway)
    code, out, err = run(capsys, "identify", csv, mat, "--equation", LINEAR_EQUATION[0],
                         "--parameters", LINEAR_EQUATION[1], "--json", "--refine")
    assert code == 0, err
    payload = json.loads(out)
    assert set(payload) == {"B", "K", "G", "d", "stderr", "numerical_error", "window",
                            "n_samples", "warnings", "estimate", "algebraic"}
    assert payload["warnings"] == [] and err == ""   # the right model
    # a linear model: refined by output error, the algebraic kept
    assert payload["estimate"] == "refined"
    assert set(payload["numerical_error"]) == {"B", "K", "G", "d"}
    algebraic = payload["algebraic"]
    assert set(algebraic) == {"values", "stderr", "numerical_error"}
    assert set(payload["stderr"]) == set(algebraic["numerical_error"]) == {"B", "K", "G", "d"}
    assert all(v > 0 for v in algebraic["numerical_error"].values())
    assert payload["n_samples"] == 4000 and 0 < payload["window"] < 1
    for p in truth:
        assert abs(payload[p] - truth[p]) < 5 * payload["stderr"][p]
        assert abs(algebraic["values"][p] - truth[p]) < 5 * algebraic["stderr"][p]
    for flag in ("--no-refine", None):
        code, out, err = run(capsys, "identify", csv, mat, "--equation", LINEAR_EQUATION[0],
                             "--parameters", LINEAR_EQUATION[1], "--json",
                             *([flag] if flag else []))
        plain = json.loads(out)
        assert code == 0 and plain["estimate"] == "algebraic"
        assert {p: plain[p] for p in truth} == algebraic["values"]
        assert plain["numerical_error"] == algebraic["numerical_error"]


def test_text_output_and_rate_and_window(capsys, record_files):
    _, no_time, _, _ = record_files
    code, out, err = run(capsys, "identify", no_time, "--equation", LINEAR_EQUATION[0],
                         "--parameters", LINEAR_EQUATION[1], "--rate", 80, "--window", 0.2)
    assert code == 0, err
    assert "window 0.2 s" in out and "std. error" in out and out.count("\n") == 7
    assert "numerical" in out.splitlines()[2]


@pytest.mark.parametrize("extra, fragments", [
    (["--parameters", "B K G stderr", "--equation", "y'' + B*y' + K*y = G*u + stderr"],
     ["'stderr' is reserved"]),
    (["--parameters", "B K", "--equation", "y'' + B*K*y = u"], ["multiplied together"]),
    (["--parameters", "B K", "--equation", "y'' + B*y' + K*y = z"], ["'z' not found"]),
    # a parameter left out of --parameters is read as a signal: the error says so
    (["--parameters", "B K G", "--equation", "y'' + B*y' + K*y = G*u + d"],
     ["'d' not found", "if 'd' is an unknown, add it to --parameters"]),
    (["--parameters", "B K", "--equation", "y'' + B*y' + K*y = u", "--window", "1000"],
     ["longer than"]),
])
def test_bad_input_exits_2_with_one_line(capsys, record_files, extra, fragments):
    csv = record_files[0]
    code, _, err = run(capsys, "identify", csv, *extra)
    assert_one_line_error(code, err, *fragments)


def test_missing_file_and_missing_time(capsys, record_files, tmp_path):
    code, _, err = run(capsys, "identify", tmp_path / "none.csv", "--equation",
                       LINEAR_EQUATION[0], "--parameters", LINEAR_EQUATION[1])
    assert_one_line_error(code, err, "file not found")
    code, _, err = run(capsys, "identify", record_files[1], "--equation",
                       LINEAR_EQUATION[0], "--parameters", LINEAR_EQUATION[1])
    assert_one_line_error(code, err, "no time column")
    code, _, err = run(capsys, "identify", record_files[0], "--equation",
                       LINEAR_EQUATION[0], "--parameters", LINEAR_EQUATION[1], "--rate", "-3")
    assert code == 2


def test_standard_input_is_one_record(capsys, record_files, monkeypatch):
    import io

    csv = record_files[0]
    options = ["--equation", LINEAR_EQUATION[0], "--parameters", LINEAR_EQUATION[1],
               "--json", "--no-refine"]
    _, from_file, _ = run(capsys, "identify", csv, *options)
    monkeypatch.setattr("sys.stdin", io.StringIO(csv.read_text()))
    code, out, err = run(capsys, "identify", "-", *options)
    assert code == 0, err
    assert json.loads(out) == json.loads(from_file)
    monkeypatch.setattr("sys.stdin", io.StringIO(""))
    code, out, err = run(capsys, "identify", "-", *options)
    assert_one_line_error(code, err, "standard input: input is empty")
    code, out, err = run(capsys, "identify", "-", csv, *options)
    assert_one_line_error(code, err, "- (standard input) is one record")


def test_a_refusal_with_json_is_also_a_json_object(capsys, record_files, tmp_path):
    code, out, err = run(capsys, "identify", tmp_path / "none.csv", "--equation",
                         LINEAR_EQUATION[0], "--parameters", LINEAR_EQUATION[1], "--json")
    assert_one_line_error(code, err, "file not found")
    assert json.loads(out) == {"error": err.strip().removeprefix("algid: error: ")}
    code, out, err = run(capsys, "identify", tmp_path / "none.csv", "--equation",
                         LINEAR_EQUATION[0], "--parameters", LINEAR_EQUATION[1])
    assert code == 2 and out == ""   # without --json, nothing on stdout


def test_out_writes_the_result_as_a_one_row_table(capsys, record_files, tmp_path):
    pd = pytest.importorskip("pandas")
    csv = record_files[0]
    code, out, err = run(capsys, "identify", csv, "--equation", LINEAR_EQUATION[0],
                         "--parameters", LINEAR_EQUATION[1], "--no-refine", "--out",
                         tmp_path / "result.csv")
    assert code == 0, err
    table = pd.read_csv(tmp_path / "result.csv", index_col="source")
    assert list(table.index) == [str(csv)] and table.loc[str(csv), "estimate"] == "algebraic"
    assert list(table.columns[:4]) == ["B", "K", "G", "d"]
