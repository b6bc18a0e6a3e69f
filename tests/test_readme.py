"""Every example of README.md runs as written, in order, and prints what the README shows.

The fenced blocks of README.md are read in order.  The ```python blocks run in one
namespace (matplotlib on its Agg backend), as a reader pasting them one after the other
into one interpreter; the lines of ```bash and ```console blocks that start with
``algid `` run, one after the other, in one scratch directory with the ``algid`` of this
interpreter's environment (installation lines, ``pip`` and ``./dev``, are left out).
A ```text block right after a block is that block's output: the standard output must
equal it line for line, where a line ``...`` stands for any number of lines.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT

for _module in ("control", "sympy", "matplotlib"):
    pytest.importorskip(_module, reason="the README's examples need the 'all' extra")

README = ROOT / "README.md"
ALGID = Path(sys.executable).parent / "algid"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```$", re.S | re.M)


def fenced_blocks(text):
    """``[(language, body)]`` of the fenced blocks of a Markdown text, in order."""
    return [(match.group(1), match.group(2)) for match in FENCE.finditer(text)]


def with_outputs(blocks, languages):
    """``[(body, expected output or None)]`` of the blocks in ``languages``."""
    out = []
    for k, (language, body) in enumerate(blocks):
        if language in languages:
            following = blocks[k + 1] if k + 1 < len(blocks) else ("", "")
            out.append((body, following[1] if following[0] == "text" else None))
    return out


def command_lines(body):
    """The ``algid`` command lines of a shell block (continuation lines joined)."""
    joined = re.sub(r"\\\n\s*", " ", body)
    return [line.strip() for line in joined.splitlines() if line.strip().startswith("algid ")]


def matches(actual, expected):
    """Whether the lines ``actual`` equal ``expected``, a line ``...`` matching any run."""
    pattern = "".join(r"(?:.*\n)*?" if line == "..." else re.escape(line) + r"\n"
                      for line in expected)
    return re.fullmatch(pattern, "".join(line + "\n" for line in actual)) is not None


def lines_of(text):
    return [line.rstrip() for line in text.strip("\n").splitlines()]


def check_output(actual, expected, what):
    if expected is not None:
        assert matches(lines_of(actual), lines_of(expected)), (
            f"{what} printed\n{actual}\ninstead of the README's\n{expected}")


def test_matcher_stands_for_runs_of_lines_only_where_the_readme_says_so():
    assert matches(["a", "b", "c"], ["a", "...", "c"])
    assert matches(["a", "c"], ["a", "...", "c"])
    assert not matches(["a", "b", "c"], ["a", "c"])
    assert not matches(["a", "b", "x"], ["a", "...", "c"])


def test_readme_is_short():
    assert len(README.read_text(encoding="utf-8").splitlines()) <= 150


def test_python_examples_run_in_order_and_print_what_the_readme_shows(tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    monkeypatch.chdir(tmp_path)  # anything an example writes stays out of the clone
    examples = with_outputs(fenced_blocks(README.read_text(encoding="utf-8")), {"python"})
    assert len(examples) >= 3
    namespace = {"__name__": "__readme__"}
    try:
        for number, (code, expected) in enumerate(examples, 1):
            printed = io.StringIO()
            with contextlib.redirect_stdout(printed):
                exec(compile(code, f"README.md python block {number}", "exec"),  # noqa: S102
                     namespace)
            check_output(printed.getvalue(), expected, f"python block {number}")
    finally:
        plt.close("all")


def test_command_lines_run_in_order_and_print_what_the_readme_shows(tmp_path):
    assert ALGID.exists(), f"no algid command beside {sys.executable}"
    blocks = fenced_blocks(README.read_text(encoding="utf-8"))
    examples = [(command_lines(body), expected)
                for body, expected in with_outputs(blocks, {"bash", "console"})]
    assert sum(len(lines) for lines, _ in examples) >= 4
    for lines, expected in examples:
        printed = ""
        for line in lines:
            proc = subprocess.run([str(ALGID), *shlex.split(line, comments=True)[1:]],
                                  cwd=tmp_path, capture_output=True, text=True, timeout=300,
                                  env=dict(os.environ, MPLBACKEND="Agg"))
            assert proc.returncode == 0, f"{line}\n{proc.stderr}"
            printed += proc.stdout
        if lines:
            check_output(printed, expected, " / ".join(lines))


def results_table():
    """``{first cell: last cell}`` of the README's table under ``## Results``."""
    section = README.read_text(encoding="utf-8").split("## Results", 1)[1].split("\n## ", 1)[0]
    rows = [[cell.strip() for cell in line.strip().strip("|").split("|")]
            for line in section.splitlines() if line.startswith("|")]
    return {row[0]: row[-1] for row in rows[2:]}


def scientific(value):
    """``3.5e6``: two significant digits, the README's spelling."""
    mantissa, exponent = f"{value:.1e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def test_results_table_shows_what_the_benchmark_files_hold():
    import json

    table = results_table()
    suite = json.loads((ROOT / "benchmarks" / "results.json").read_text(encoding="utf-8"))
    records = json.loads((ROOT / "benchmarks" / "identify_results.json").read_text(
        encoding="utf-8"))
    convergence = next(row["convergence_time"] for row in suite["accuracy"]["rows"]
                       if row["method"] == "algid" and row["experiment"] == "sine")
    assert table["paper's system, noise-free, 1 kHz"].startswith(f"{convergence:.3f} s")
    study = next(row for row in suite["efficiency"]["rows"] if row["method"] == "algebraic"
                 and row["input"] == "sine" and row["horizon"] == 5.0)
    assert table["paper's system, noise 0.01, 5 s"] == (
        f"{study['rmse_B'] / study['crlb_B']:.2f} / {study['rmse_K'] / study['crlb_K']:.2f}")
    silverbox = next(row for row in records["speed"] if row["record"] == "silverbox")
    assert table["Silverbox, cubic spring"] == (
        f"{1e3 * silverbox['identify_rmse']:.3f} mV (output-error fit: "
        f"{1e3 * silverbox['output_error_rmse']:.3f} mV, {silverbox['speed_ratio']:.0f}× slower)")
    batch = {row["method"]: row["throughput"] for row in suite["performance"]["batch"]}
    c_one_chunk = next(row["throughput"] for row in suite["c_speed"]["rows"]
                       if row["method"] == "c_O2_chunk_all")
    assert table["batch, 10⁷ samples, one core"] == (
        f"NumPy {scientific(batch['algid'])}, numba {scientific(batch['algid_numba'])}, "
        f"C {scientific(c_one_chunk)}")


def test_results_table_shows_the_refinement_study():
    import json

    study = json.loads((ROOT / "benchmarks" / "refinement_results.json").read_text(
        encoding="utf-8"))["white"]
    names = ("B", "K", "G", "d")
    ratios = [" ".join(f"{study[kind][p]['rmse/crlb']:.2f}" for p in names)
              for kind in ("algebraic", "refined")]
    coverage = [100 * study["refined"][p]["coverage"] for p in names]
    assert results_table()["linear plant, 30 s, 30 dB (identify)"] == (
        f"{ratios[0]} → {ratios[1]}; {min(coverage):.0f}–{max(coverage):.0f} %")


def test_results_table_shows_the_nonlinear_refinement_study():
    import json

    study = json.loads((ROOT / "benchmarks" / "nonlinear_refinement_results.json").read_text(
        encoding="utf-8"))
    ranges, coverage = [], []
    for model in ("duffing", "friction"):
        row = study[model]["white"]["reported"]
        ratios = [v["rmse/crlb"] for p, v in row.items() if p != "median_cpu_s"]
        coverage += [100 * v["coverage"] for p, v in row.items() if p != "median_cpu_s"]
        ranges.append(f"{min(ratios):.2f}–{max(ratios):.2f}")
    assert results_table()["Duffing / open-loop friction, 30 s, 30 dB (identify)"] == (
        f"{ranges[0]} / {ranges[1]}; {min(coverage):.0f}–{max(coverage):.0f} %")


def test_results_table_shows_the_algebraic_friction_estimate():
    import json

    study = json.loads((ROOT / "benchmarks" / "nonlinear_refinement_results.json").read_text(
        encoding="utf-8"))
    row = study["friction"]["white"]["algebraic"]
    names = [p for p in row if p != "median_cpu_s"]
    ratios = " ".join(f"{row[p]['rmse/crlb']:.2g}" for p in names)
    coverage = [100 * row[p]["coverage"] for p in names]
    assert results_table()["open-loop friction, 30 s, 30 dB, algebraic (`refine=False`)"] == (
        f"{ratios}; {min(coverage):.0f}–{max(coverage):.0f} %")


def test_results_table_shows_the_emps_estimates_against_the_published_values():
    import algid
    from algid import datasets

    rec = datasets.emps()
    fit = algid.identify(rec, datasets.EMPS_EQUATION, list(datasets.EMPS_PUBLISHED))
    deviations = ", ".join(f"{100 * (fit.values[p] / value - 1):+.2f}".replace("-", "−")
                           for p, value in datasets.EMPS_PUBLISHED.items())
    assert results_table()["EMPS"].startswith(deviations + " %;"), deviations


def test_results_table_shows_the_systems_study():
    import json

    study = json.loads((ROOT / "benchmarks" / "systems_results.json").read_text(
        encoding="utf-8"))
    ranges, coverage = [], []
    for name in ("two_mass", "two_mass_hidden", "dc_motor"):
        row = study[name]["reported"]
        ranges.append(f"{min(row['rmse_over_crlb']):.2f}–{max(row['rmse_over_crlb']):.2f}")
        coverage += [100 * c for c in row["coverage_2se"]]
    assert results_table()["two masses (both measured / one hidden), DC motor, 40 dB"] == (
        f"{' / '.join(ranges)}; {min(coverage):.0f}–{max(coverage):.0f} %")


def test_results_table_shows_the_weighted_algebraic_estimate():
    import json

    study = json.loads((ROOT / "benchmarks" / "window_rule_results.json").read_text(
        encoding="utf-8"))["method gls"]
    ranges, coverage = [], []
    for name in ("linear", "duffing"):
        row = next(r for r in study if r["model"] == name)["parameters"]
        ratios = [v["rmse_over_crlb"] for v in row.values()]
        coverage += [100 * v["coverage"] for v in row.values()]
        ranges.append(f"{min(ratios):.2f}–{max(ratios):.2f}")
    assert results_table()['linear / Duffing, 30 s, 30 dB, algebraic (`method="gls"`)'] == (
        f"{ranges[0]} / {ranges[1]}; {min(coverage):.0f}–{max(coverage):.0f} %")
