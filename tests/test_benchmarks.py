"""Tests of the benchmark suite (benchmarks/): its smallest run and its baselines."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT, exact_response

import algid
from algid.simulation import simulate

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks import baselines as bl  # noqa: E402
from benchmarks.run import SECTIONS  # noqa: E402

TRUE = {"B": 2.0, "K": 3.0}
IC = (0.1, -0.2)


# --------------------------------------------------------------------------------------
# the smallest run of the whole suite, through its command line
# --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "results.json"
    proc = subprocess.run([sys.executable, "-m", "benchmarks", "--smoke", "--out", str(out)],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(out.read_text()), proc.stdout


def test_smoke_run_writes_every_section(smoke):
    results, stdout = smoke
    assert set(SECTIONS) | {"meta", "targets"} <= set(results)
    assert results["meta"]["mode"] == "smoke"
    assert results["meta"]["sections"] == list(SECTIONS)
    for heading in ("### 1.", "### 2.", "### 3.", "### 4.", "### 5.", "### 6.", "### 7.",
                    "### Targets"):
        assert heading in stdout
    names = {t["name"] for t in results["targets"]}
    assert names - {"c_speed"} == {"convergence", "efficiency", "long_stream", "tracking",
                                   "numpy_speed", "error_speed", "error_cost", "error_stream"}
    for t in results["targets"]:
        assert set(t) == {"name", "description", "limit", "measured", "met", "detail"}


def test_smoke_accuracy(smoke):
    acc = smoke[0]["accuracy"]
    rows = {(r["method"], r["experiment"]): r for r in acc["rows"]}
    experiments = {"step", "sine", "step_ic", "sine_ic"}
    assert {e for _, e in rows} == experiments
    for e in experiments:
        # the toolkit is exact up to round-off, whatever the initial state
        assert max(rows["algid", e]["error_B"], rows["algid", e]["error_K"]) < 1e-9
        # the output-error fit is the exact model: only the first-order hold of a
        # smooth input (O(h**2)) limits it
        assert max(rows["oe_nls", e]["error_B"], rows["oe_nls", e]["error_K"]) < 1e-6
        # online methods report a convergence time, batch methods none
        assert rows["svf_ls", e]["convergence_time"] is None
        assert rows["algid", e]["convergence_time"] is not None
        assert acc["naive_vs_algid_trapezoid"][e] < 1e-8
    for e in ("step_ic", "sine_ic"):  # the SVF bias is the predicted transient bias
        for k in TRUE:
            measured = rows["svf_ls", e][f"final_{k}"] - TRUE[k]
            predicted = acc["svf_predicted_bias"][e][k]
            assert measured == pytest.approx(predicted, rel=1e-3, abs=1e-5)
    for e in ("step", "sine"):  # from rest the filter has no transient to miss
        assert max(rows["svf_ls", e]["error_B"], rows["svf_ls", e]["error_K"]) < 1e-5


def test_smoke_efficiency(smoke):
    eff = smoke[0]["efficiency"]
    methods = {r["method"] for r in eff["rows"]}
    assert {"svf_ls", "svf_rls", "oe_nls", "algid_trap_p0", "algid_trap_p1"} <= methods
    if eff["study"].startswith("algid."):
        assert {"algebraic", "refined"} <= methods
        # the baselines ran on the study's records: its RMSE is reproduced exactly
        for diff in eff["same_data_check"].values():
            assert diff < 1e-12
    for r in eff["rows"]:
        assert r["crlb_B"] > 0 and r["crlb_K"] > 0
        assert r["n_valid"] <= r["n_runs"]
        # an RMSE exists exactly when some run gave an estimate, and the efficiency
        # column is the RMSE over the bound
        assert (r["rmse_B"] is None) == (r["n_valid"] == 0)
        if r["rmse_B"] is not None:
            assert r["ratio_B"] == pytest.approx(r["rmse_B"] / r["crlb_B"], rel=1e-12)


def test_smoke_performance(smoke):
    perf = smoke[0]["performance"]
    rows = {r["method"]: r for r in perf["batch"] if "not_available" not in r}
    assert rows["naive_numpy"]["throughput_ratio"] == pytest.approx(1.0)
    reference = perf["reference"]
    for r in rows.values():
        assert r["throughput"] == pytest.approx(r["n_samples"] / r["time"], rel=1e-12)
        ratio = r["throughput"] / reference["throughput"]
        assert r["throughput_ratio"] == pytest.approx(ratio, rel=1e-12)
        assert r["memory_ratio"] > 0  # a peak of zero bytes would be a broken measurement
    chunks = {(r["method"], r["chunk"]) for r in perf["streaming"] if "chunk" in r}
    assert ("svf_rls", 1) in chunks and ("svf_rls", 1000) in chunks
    for r in perf["streaming"]:
        if "not_available" not in r:
            ratio = r["cost_per_sample"] / reference["cost_per_sample"]
            assert r["cost_ratio"] == pytest.approx(ratio, rel=1e-12)


def test_smoke_long_stream_and_tracking(smoke):
    results = smoke[0]
    ls, tr = results["long_stream"], results["tracking"]
    if "not_available" in ls:
        pytest.skip(ls["not_available"])
    reset = next(r for r in ls["rows"] if r["method"] == "online_reset")
    assert reset["n_samples"] == ls["n_samples"]
    assert reset["n_undefined"] == 0
    assert max(reset["max_rel_error"].values()) < 1e-3
    from algid.estimation._online import TRACKING_RESET_PERIOD

    # noise-free, a change is followed once the reported window starts after it: at the
    # latest one period later (with a persistently exciting input)
    for r in tr["rows"]:
        if r["method"] == "online_reset" and r["input"] == "sine":
            assert r["tracking_time"] is not None
            assert 0 < r["tracking_time"] <= TRACKING_RESET_PERIOD + 1e-9


def test_only_rejects_unknown_section():
    proc = subprocess.run([sys.executable, "-m", "benchmarks", "--smoke", "--only", "speed",
                           "--out", "-"], cwd=ROOT, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2
    assert "unknown section" in proc.stderr


# --------------------------------------------------------------------------------------
# the baselines
# --------------------------------------------------------------------------------------


def test_state_variable_filter_step_response():
    lam, h = 5.0, 1e-3
    t = np.arange(3001) * h
    z, _ = bl.StateVariableFilter(lam, h).apply(np.ones_like(t))
    lt = lam * t
    e = np.exp(-lt)
    exact = [1 - e * (1 + lt + lt**2 / 2), lam * e * lt**2 / 2, lam**2 * e * (lt - lt**2 / 2)]
    # a step is piecewise linear: the discretisation is exact; the triple pole at
    # exp(-lam h) amplifies round-off by about 1 / (lam h)**3 = 8e6
    for k in range(3):
        np.testing.assert_allclose(z[k], exact[k], rtol=0, atol=1e-8 * lam**k)


def test_state_variable_filter_chunks_equal_whole():
    svf = bl.StateVariableFilter(5.0, 1e-3)
    u = np.sin(np.arange(2000) * 1e-3)
    whole, _ = svf.apply(u)
    parts, states = [], None
    for i in range(0, u.size, 333):
        z, states = svf.apply(u[i:i + 333], states)
        parts.append(z)
    np.testing.assert_allclose(np.concatenate(parts, axis=1), whole, rtol=0, atol=1e-15)


def test_naive_algebraic_is_the_trapezoid_estimator():
    t, f, x = exact_response("sine", duration=2.0, x0=IC[0], v0=IC[1])
    for p in (0, 1):
        B, K = bl.naive_algebraic(t, f, x, filter_order=p)
        r = algid.estimate(t, f, x, quadrature_points=2, filter_order=p)
        # the same arithmetic in another order: round-off, magnified by the conditioning
        # of P (det P ~ t**k at early times; it also passes near zero later)
        np.testing.assert_allclose(B[10:], r.B[10:], rtol=1e-6)
        np.testing.assert_allclose(K[10:], r.K[10:], rtol=1e-6)


def test_rls_information_form_equals_covariance_form_and_chunking():
    t, f, x = exact_response("step", duration=1.0, x0=IC[0], v0=IC[1])
    phi, y = bl.svf_regressors(t, f, x)
    reference = bl.rls_covariance_form(phi, y)
    B, K = bl.svf_rls(t, f, x)
    np.testing.assert_allclose(B[50:], reference[50:, 0], rtol=1e-9)
    np.testing.assert_allclose(K[50:], reference[50:, 1], rtol=1e-9)
    rls = bl.SVFRecursiveLeastSquares()
    outs = [rls.update(t[0], f[0], x[0])]  # a first chunk of one sample
    for i in range(1, t.size, 97):
        outs.append(rls.update(t[i:i + 97], f[i:i + 97], x[i:i + 97]))
    B2 = np.concatenate([o[0] for o in outs])
    assert math.isnan(B2[0])
    np.testing.assert_allclose(B2[50:], B[50:], rtol=1e-12)


def test_svf_bias_is_the_predicted_transient_bias():
    sim = simulate("step", duration=5.0, initial_state=IC)
    fit = bl.svf_least_squares(sim.t, sim.f, sim.x)
    predicted = bl.svf_transient_bias(sim.t, sim.f, sim.x_true, B=2.0, K=3.0, x0=IC[0],
                                      v0=IC[1])
    assert abs(predicted["B"]) > 0.1  # a large bias: 10 % of B
    assert fit.B - 2.0 == pytest.approx(predicted["B"], rel=1e-5)
    assert fit.K - 3.0 == pytest.approx(predicted["K"], rel=1e-3)


def test_output_error_model_is_exact_for_a_step():
    sim = simulate("step", duration=3.0, initial_state=IC)
    x = bl.OutputErrorModel(sim.t, sim.f).response([2.0, 3.0, *IC])
    # exact up to round-off, which the poles at exp(-(1 +- 1.4j) h) near 1 amplify by
    # about 1 / (B h)**2 = 2.5e5 in the recursion of lfilter
    np.testing.assert_allclose(x, sim.x_true, rtol=0, atol=1e-10)


@pytest.mark.parametrize("kind", ["step", "sine"])
def test_output_error_nls_recovers_the_parameters(kind):
    sim = simulate(kind, duration=5.0, initial_state=IC)
    fit = bl.output_error_nls(sim.t, sim.f, sim.x)
    assert fit.extra["success"]
    # exact for a step; for a sine the first-order hold of the input is O(h**2)
    tol = 1e-9 if kind == "step" else 1e-6
    assert fit.B == pytest.approx(2.0, rel=tol)
    assert fit.K == pytest.approx(3.0, rel=tol)
    assert fit.extra["x0"] == pytest.approx(IC[0], rel=tol)
    assert fit.extra["v0"] == pytest.approx(IC[1], rel=tol)


def test_smoke_c_speed(smoke):
    cs = smoke[0]["c_speed"]
    if "not_available" in cs:
        pytest.skip(cs["not_available"])
    assert cs["compiler_warnings"] == {"O2": "", "O2_native": ""}
    rows = {r["method"]: r for r in cs["rows"] if "not_available" not in r}
    assert rows["naive_numpy"]["throughput_ratio"] == pytest.approx(1.0)
    for build in ("O2", "O2_native"):
        assert set(cs["c_ns_per_sample"][build]) == {"1", "1000", "all"}
        assert all(v > 0 for v in cs["c_ns_per_sample"][build].values())
        assert cs["fraction_of_cumsum"][build] > 0
    # the timed C estimator computes the batch estimate (chunks of 1, 1000, all alike),
    # and its numerical error
    assert cs["max_rel_diff_c_numpy"] <= 1e-10
    assert cs["max_error_diff_c_numpy"] <= 1e-10


def test_smoke_error_cost(smoke):
    ec = smoke[0]["error_cost"]
    assert ec["runs"] == 1 and [s["n_samples"] for s in ec["sizes"]] == [2000, 10000]
    for size in ec["sizes"]:
        assert len(size["naive_rates"]) == 1 and size["naive_rates"][0] > 0
        for engine in ec["engines"]:
            r = size[engine]
            # the ratios are those of the times of the (one) run
            times = size["times"]
            assert r["speed"] == pytest.approx(times["naive"][0] / times[engine][0])
            assert r["error_cost"] == pytest.approx(times[engine][0] /
                                                    times[f"{engine}_alone"][0])


def test_error_propagation_study_follows_the_companion():
    """The grid propagation of benchmarks.error_propagation: its error at the final
    sample of an under-resolved plant (actual error 4e-8) is the companion's within a
    factor 1.5 and bounds the actual error; the study's estimates are estimate's."""
    from benchmarks.error_propagation import difference_taps, propagated_error
    from benchmarks.population import draw_plants
    from benchmarks.population import exact_response as plant_response

    taps = difference_taps(8, 9, 1.0)
    assert taps.size == 8  # a backward difference of order 7: kills cubics
    assert abs(taps @ np.arange(8.0) ** 3) < 1e-12
    plant = draw_plants(60, 0)[54]
    t, f, x = plant_response(plant)
    result = algid.estimate(t, f, x)
    actual = max(abs(result.B[-1] / plant.B - 1.0), abs(result.K[-1] / plant.K - 1.0))
    propagated, estimates = propagated_error(t, f, x)
    companion = result.numerical_error[-1]
    assert actual > 1e-9 and actual <= 10 * propagated
    assert companion / 1.5 < propagated < 1.5 * companion
    np.testing.assert_allclose(estimates, [result.B[-1], result.K[-1]], rtol=1e-12)
    with pytest.raises(ValueError, match="longer record"):
        propagated_error(t[:500], f[:500], x[:500])
