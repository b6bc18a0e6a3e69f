"""Tests of ``algid.paper`` (reproduction of the paper's Section 3) and ``algid paper``."""

import json
import math
import sys

import matplotlib

matplotlib.use("Agg")

import matplotlib.image  # noqa: E402
import pytest  # noqa: E402
from conftest import assert_one_line_error
from scipy.stats import t as student_t  # noqa: E402

from algid import paper  # noqa: E402
from algid.cli import main  # noqa: E402
from algid.errors import AlgidError  # noqa: E402

#: Reduced workload: 5 noise realisations (seeds 0..4) for the statistics, and a
#: shown realisation with a seed outside them, so that its error is independent of
#: the RMSE it is compared with.
N_SEEDS = 5
SHOWN_SEED = N_SEEDS
RATES = (1000.0, 10000.0)


@pytest.fixture(scope="module")
def reproduction(tmp_path_factory):
    out = tmp_path_factory.mktemp("paper") / "figures"  # created by reproduce
    return paper.reproduce(out, seed=SHOWN_SEED, n_seeds=N_SEEDS, rates=RATES,
                           filter_orders=(0, 1, 2), noisy_rates=(1000.0,))


def test_figures_are_valid_pngs(reproduction):
    assert set(reproduction.figures) == {f"fig{i}" for i in range(3, 10)}
    for key, path in reproduction.figures.items():
        assert path.parent == reproduction.out
        assert path.name == paper.FIGURE_FILES[key]
        image = matplotlib.image.imread(path)
        assert image.ndim == 3 and image.shape[2] in (3, 4)
        assert image.shape[0] > 200 and image.shape[1] > 300
        assert image.std() > 0.01  # not a blank canvas


def test_summary_json_matches_and_has_all_parts(reproduction):
    written = json.loads((reproduction.out / "summary.json").read_text(encoding="utf-8"))
    assert written == json.loads(reproduction.to_json())
    assert set(written) == {"system", "settings", "experiments", "quadrature_vs_rate",
                            "filter_order_noise", "rate_noise", "figures", "runtime_s"}
    assert set(written["experiments"]) == {e.name for e in paper.EXPERIMENTS}
    assert written["settings"]["seed"] == SHOWN_SEED
    assert written["settings"]["n_seeds"] == N_SEEDS
    assert written["figures"] == {k: p.name for k, p in reproduction.figures.items()}
    for entry in written["experiments"].values():
        assert {"paper", "toolkit", "paper_style"} <= set(entry)
        for key in ("t_1pct", "t_0.1pct", "t_1pct_B", "t_1pct_K", "final",
                    "final_rel_error", "t_valid"):
            assert key in entry["toolkit"] and key in entry["paper_style"]
        if entry["noise_std"] > 0:
            assert entry["seed"] == SHOWN_SEED
            for key in ("toolkit_seeds", "paper_style_seeds"):
                stats = entry[key]
                assert stats["n"] == N_SEEDS and stats["seeds"] == [0, N_SEEDS - 1]
                assert {"median_t_1pct", "reached_1pct", "rmse", "mean"} <= set(stats)
    # the printed table can be rebuilt from the file alone
    text = paper.format_summary(written)
    for e in paper.EXPERIMENTS:
        assert f"{e.claim_time:g} s" in text
    assert "paper-style" in text and "Why the numbers differ" in text


@pytest.mark.parametrize("name", ["step", "sine"])
def test_noise_free_exact_and_faster_than_paper(reproduction, name):
    entry = reproduction.summary["experiments"][name]
    tool = entry["toolkit"]
    # exact in continuous time; the 6-point rule leaves round-off only (~1e-14)
    assert max(abs(v) for v in tool["final_rel_error"].values()) <= 1e-6
    # the paper's claim (good estimates at 0.04 s step / 0.06 s sine) is met at 0.1 %
    claim = entry["paper"]["t_good"]
    assert tool["t_0.1pct"] is not None and tool["t_0.1pct"] <= claim
    assert tool["t_1pct"] <= tool["t_0.1pct"]
    assert tool["t_valid"] <= tool["t_1pct"]


@pytest.mark.parametrize("name", ["step", "sine"])
def test_trapezoid_converges_as_h_squared(reproduction, name):
    rows = {r["rate"]: r for r in reproduction.summary["quadrature_vs_rate"]
            if r["input"] == name and r["quadrature_order"] == 2}
    slow, fast = rows[RATES[0]], rows[RATES[1]]
    err = [max(abs(v) for v in r["final_rel_error"].values()) for r in (slow, fast)]
    # global error O(h**2): ten times the rate, a hundred times smaller (+-factor 2)
    assert 50 <= err[0] / err[1] <= 200
    # and the early, ill-conditioned phase is shorter with the smaller step
    assert fast["t_1pct"] < slow["t_1pct"]
    # the paper-style row is the trapezoid at the rate of the figures
    assert reproduction.summary["experiments"][name]["paper_style"]["t_1pct"] == slow["t_1pct"]


@pytest.mark.parametrize("name", ["step_noise", "sine_noise"])
def test_noisy_final_estimates_within_measured_spread(reproduction, name):
    entry = reproduction.summary["experiments"][name]
    stats = entry["toolkit_seeds"]
    # To first order the final estimate is a linear function of the Gaussian noise, so
    # its error e is N(b, sigma**2) with a bias b of order noise**2 (negligible).  The
    # RMSE s over N independent seeds then gives e / s ~ Student t with N degrees of
    # freedom; the shown seed is not among them.  Bound at two-sided probability 1e-3.
    factor = student_t.ppf(1 - 0.5e-3, N_SEEDS)
    for param, err in entry["toolkit"]["final_rel_error"].items():
        assert 0 < stats["rmse"][param]
        assert abs(err) <= factor * stats["rmse"][param], (param, err, stats["rmse"])
    # the estimates settle within 1 % before the end for most realisations
    assert stats["median_t_1pct"] is not None
    assert stats["median_t_1pct"] <= paper.DURATION


def test_filter_reduces_noise(reproduction):
    rows = {(r["input"], r["filter_order"]): r
            for r in reproduction.summary["filter_order_noise"]}
    for inp in ("step", "sine"):
        assert rows[(inp, 0)]["rmse"]["B"] > rows[(inp, 2)]["rmse"]["B"]
    # the toolkit row of the study is the same computation as the seed statistics
    step = reproduction.summary["experiments"]["step_noise"]["toolkit_seeds"]
    assert rows[("step", paper.TOOLKIT["filter_order"])]["rmse"] == step["rmse"]


def test_bad_out_and_options(tmp_path):
    afile = tmp_path / "file.txt"
    afile.write_text("x", encoding="utf-8")
    with pytest.raises(AlgidError, match="not a directory"):
        paper.reproduce(afile)
    with pytest.raises(AlgidError, match="n_seeds"):
        paper.reproduce(None, n_seeds=0)
    with pytest.raises(AlgidError, match="seed"):
        paper.reproduce(None, seed=-1)
    with pytest.raises(AlgidError, match="unknown experiment"):
        paper.simulate_experiment("ramp")


def run(capsys, *argv):
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_cli_json(tmp_path, capsys):
    out = tmp_path / "figs"
    code, stdout, stderr = run(capsys, "paper", "--out", out, "--json", "--seed", 3,
                               "--n-seeds", 2)
    assert code == 0, stderr
    summary = json.loads(stdout)
    assert summary["settings"]["seed"] == 3 and summary["settings"]["n_seeds"] == 2
    assert json.loads((out / "summary.json").read_text(encoding="utf-8")) == summary
    assert sorted(p.name for p in out.glob("*.png")) == sorted(paper.FIGURE_FILES.values())
    for name in ("step", "sine"):
        errors = summary["experiments"][name]["toolkit"]["final_rel_error"]
        assert max(abs(v) for v in errors.values()) <= 1e-6


def test_cli_out_is_a_file(tmp_path, capsys):
    afile = tmp_path / "summary.txt"
    afile.write_text("", encoding="utf-8")
    code, stdout, stderr = run(capsys, "paper", "--out", afile)
    assert_one_line_error(code, stderr, str(afile), "not a directory")
    assert stdout == ""


def test_cli_bad_n_seeds(tmp_path, capsys):
    code, _, stderr = run(capsys, "paper", "--out", tmp_path, "--n-seeds", 0)
    assert_one_line_error(code, stderr, "--n-seeds")


def test_cli_without_matplotlib(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import now fails
    code, stdout, stderr = run(capsys, "paper", "--out", tmp_path / "x")
    assert_one_line_error(code, stderr, "matplotlib")
    assert not (tmp_path / "x").exists()


def test_convergence_helpers():
    # accuracy() on a hand-made result: B enters the 1 % band at 0.3 s and stays
    import numpy as np

    from algid.estimation._result import EstimationResult

    t = np.linspace(0.0, 1.0, 11)
    B = np.where(t < 0.25, 3.0, 2.01)
    K = np.full_like(t, 3.0)
    r = EstimationResult(t=t, estimates={"B": B, "K": K}, model="msd", filter_order=0,
                         quadrature_points=2)
    acc = paper.accuracy(r)
    assert acc["t_1pct_B"] == pytest.approx(0.3) and acc["t_1pct_K"] == 0.0
    assert acc["t_1pct"] == pytest.approx(0.3)
    assert math.isnan(acc["t_0.1pct"])  # B ends 0.5 % off
    assert acc["final_rel_error"]["B"] == pytest.approx(0.005)
