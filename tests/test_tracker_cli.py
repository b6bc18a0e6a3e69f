"""The ``algid track`` command line."""

import io
import json
import os
import pathlib
import selectors
import subprocess
import sys

import numpy as np
import pytest
from benchmarks.synthetic_records import linear_offsets

from algid.cli import main
from algid.identification._tracker import Tracker

EQUATION, PARAMETERS = "y'' + B*y' + K*y = G*u + d", "B K G d"
SRC = pathlib.Path(__file__).resolve().parents[1] / "src"


def write_record(path, n=900):
    record, _ = linear_offsets(0, n=n)
    np.savetxt(path, np.column_stack([record["t"], record["u"], record["y"]]), delimiter=",",
               header="t,u,y", comments="")
    return record


def test_file_json_equals_the_tracker(tmp_path, capsys):
    record = write_record(tmp_path / "lin.csv")
    code = main(["track", str(tmp_path / "lin.csv"), "--equation", EQUATION, "--parameters",
                 PARAMETERS, "--window", "0.1875", "--half-life", "3", "--chunk", "77",
                 "--every", "1", "--json"])
    assert code == 0
    payload = json.loads(capsys.readouterr().out)
    assert set(payload) == {"t", "B", "K", "G", "d", "stderr", "alarms", "window", "half_life"}
    expected = Tracker(EQUATION, PARAMETERS, time="t", window=0.1875, half_life=3.0,
                       every=1.0).update(record)
    # and the end of the stream (its last line was the last multiple of --every)
    end = Tracker(EQUATION, PARAMETERS, time="t", window=0.1875, half_life=3.0).update(record)
    assert end.t[-1] > expected.t[-1]
    assert payload["t"] == expected.t.tolist() + [end.t[-1]]
    assert payload["K"][:-1] == [None if np.isnan(k) else k for k in expected["K"]]
    assert payload["K"][-1] == end["K"][-1]
    assert payload["stderr"]["K"][-1] == end.stderr[-1, 1]
    assert payload["half_life"] == 3.0 and abs(payload["window"] - 0.1875) < 1e-12


def test_bad_input_one_line_exit_2(tmp_path, capsys):
    write_record(tmp_path / "lin.csv", n=100)
    for argv in (["track", str(tmp_path / "none.csv")],
                 ["track", str(tmp_path / "lin.csv"), "--parameters", "B K G t"],
                 ["track", str(tmp_path / "lin.csv"), "--parameters", PARAMETERS,
                  "--window", "-1"],
                 ["track", str(tmp_path / "lin.csv"), "--parameters", "B K G d Q"],
                 # no window completes: the header alone, exit 0, before
                 ["track", str(tmp_path / "lin.csv"), "--parameters", PARAMETERS,
                  "--window", "1000"]):
        code = main(argv[:2] + ["--equation", EQUATION] + (argv[2:] or
                                                           ["--parameters", PARAMETERS]))
        err = capsys.readouterr().err
        assert code == 2
        assert err.count("\n") == 1 and err.startswith("algid: error:")
    # two equations: refused, not the last one tracked
    code = main(["track", str(tmp_path / "lin.csv"), "--equation", EQUATION, "--equation",
                 EQUATION, "--parameters", PARAMETERS])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "--equation was given 2 times" in err


@pytest.mark.parametrize("text, words", [("t,u,y\n", "standard input: no samples"),
                                         ("t,u,y\n0,1,2\n0.0125,1,2\n", "no window")])
def test_standard_input_that_ends_before_a_report(monkeypatch, capsys, text, words):
    monkeypatch.setattr(sys, "stdin", io.StringIO(text))
    code = main(["track", "-", "--equation", EQUATION, "--parameters", PARAMETERS,
                 "--window", "0.1875"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and words in err


def test_standard_input_live(tmp_path):
    """Reports come while the stream is still open; a malformed row is skipped."""
    record, _ = linear_offsets(0, n=900)
    rows = [f"{float(t)!r},{float(u)!r},{float(y)!r}\n"
            for t, u, y in zip(record["t"], record["u"], record["y"])]
    env = dict(os.environ, PYTHONPATH=str(SRC), OPENBLAS_NUM_THREADS="1")
    process = subprocess.Popen(
        [sys.executable, "-m", "algid", "track", "-", "--equation", EQUATION,
         "--parameters", PARAMETERS, "--window", "0.1875", "--every", "1", "--json"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        bufsize=1, env=env)
    try:
        process.stdin.write("t,u,y\n" + "".join(rows[:500]) + "oops,1\n")
        process.stdin.flush()
        selector = selectors.DefaultSelector()
        selector.register(process.stdout, selectors.EVENT_READ)
        assert selector.select(timeout=60), "no report while the stream is open"
        first = json.loads(process.stdout.readline())
        assert set(first) == {"t", "B", "K", "G", "d", "stderr", "alarms"}
        process.stdin.write("".join(rows[500:]))
        process.stdin.close()
        rest = [json.loads(line) for line in process.stdout.read().splitlines()]
        err = process.stderr.read()
        assert process.wait(timeout=60) == 0
    finally:
        process.kill()
    assert err.count("\n") == 1 and "row 502 skipped" in err
    # the skipped row left the state intact: the same reports as the clean stream
    clean = {k: np.array([float(r.split(",")[i]) for r in rows]) for i, k in
             enumerate(("t", "u", "y"))}
    expected = Tracker(EQUATION, PARAMETERS, time="t", window=0.1875, every=1.0).update(clean)
    end = Tracker(EQUATION, PARAMETERS, time="t", window=0.1875).update(clean)
    reports = [first] + rest
    assert [r["t"] for r in reports] == expected.t.tolist() + [end.t[-1]]   # and the end
    assert reports[-2]["K"] == expected["K"][-1] and reports[-1]["K"] == end["K"][-1]


def _live_rows(n=400):
    record, _ = linear_offsets(0, n=n)
    return record, "".join(f"{float(t)!r},{float(u)!r},{float(y)!r}\n"
                           for t, u, y in zip(record["t"], record["u"], record["y"]))


def test_standard_input_with_a_rate_checks_the_time_column(monkeypatch, capsys):
    """--rate beside a time column that contradicts it: refused as in a file (the live
    stream dropped the column: estimates off by the rates' ratio, exit 0)."""
    record, rows = _live_rows()
    rate = 1.0 / float(np.median(np.diff(record["t"])))
    monkeypatch.setattr(sys, "stdin", io.StringIO("t,u,y\n" + rows))
    code = main(["track", "-", "--equation", EQUATION, "--parameters", PARAMETERS,
                 "--window", "0.1875", "--rate", str(rate * 2)])
    captured = capsys.readouterr()
    assert code == 2 and captured.err.count("\n") == 1
    assert "contradicts time column 't'" in captured.err
    # the right rate: the same reports as with the column
    outputs = []
    for extra in (["--rate", repr(rate)], []):
        monkeypatch.setattr(sys, "stdin", io.StringIO("t,u,y\n" + rows))
        assert main(["track", "-", "--equation", EQUATION, "--parameters", PARAMETERS,
                     "--window", "0.1875", "--json"] + extra) == 0
        outputs.append([json.loads(line)["K"] for line in
                        capsys.readouterr().out.splitlines()])
    with_rate, with_column = (np.array(o, dtype=float) for o in outputs)  # (None: NaN)
    assert np.isfinite(with_rate).sum() > 10
    assert np.allclose(with_rate, with_column, rtol=1e-9, equal_nan=True)


def test_standard_input_with_a_byte_order_mark(monkeypatch, capsys):
    """A UTF-8 BOM before the header was 'no time column'."""
    _, rows = _live_rows()
    monkeypatch.setattr(sys, "stdin", io.StringIO("\ufefft,u,y\n" + rows))
    assert main(["track", "-", "--equation", EQUATION, "--parameters", PARAMETERS,
                 "--window", "0.1875", "--json"]) == 0
    assert capsys.readouterr().out.strip()


def test_standard_input_refuses_a_window_its_rate_cannot_hold(monkeypatch, capsys):
    """A window too short at the stream's rate was a warning per row, every row skipped."""
    _, rows = _live_rows()
    monkeypatch.setattr(sys, "stdin", io.StringIO("t,u,y\n" + rows))
    code = main(["track", "-", "--equation", EQUATION, "--parameters", PARAMETERS,
                 "--window", "0.05"])
    captured = capsys.readouterr()
    assert code == 2 and captured.err.count("\n") == 1
    assert "is shorter than the kernels" in captured.err


def test_standard_input_that_ends_in_the_window_s_warmup(monkeypatch, capsys):
    """12 s of a 1 Hz mode: the warm-up's span would double to 16 s (its window near the
    longest that 8 s allow); at the end of standard input the window of 8 s is kept and
    the reports come out (nothing came out, 'no window could be chosen')."""
    from benchmarks.window_rule_study import LINEAR, simulate

    t, u, y = simulate(LINEAR, rate=100.0, duration=12.0)
    y = y + 10 ** -1.5 * np.std(y) * np.random.default_rng(0).standard_normal(len(t))
    rows = "".join(f"{a!r},{b!r},{c!r}\n" for a, b, c in zip(t.tolist(), u.tolist(),
                                                              y.tolist()))
    monkeypatch.setattr(sys, "stdin", io.StringIO("t,u,y\n" + rows))
    assert main(["track", "-", "--equation", LINEAR["equation"], "--parameters",
                 LINEAR["parameters"], "--every", "1", "--json"]) == 0
    reports = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    tracker = Tracker(LINEAR["equation"], LINEAR["parameters"], time="t")
    end = tracker.update({"t": t, "u": u, "y": y}, last=True)
    assert tracker.window > 0.5 and reports[-1]["t"] == end.t[-1]
    assert [reports[-1][p] for p in ("B", "K", "G", "d")] == end.values[-1].tolist()
