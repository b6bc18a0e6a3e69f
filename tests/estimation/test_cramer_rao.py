"""Tests of the sensitivities, the Cramér–Rao bound and the efficiency study (algid.estimation).

The Monte Carlo comparison of the bound with the efficient (refined) estimator is in
tests/test_refine.py.
"""

import numpy as np
import pytest
from msd_reference import analytic_response

from algid.errors import InputDataError
from algid.estimation._cramer_rao import covariance_from_sensitivities, crlb, fisher_information
from algid.estimation._sensitivity import SENSITIVITY_PARAMETERS, output_sensitivities

EPS = np.finfo(float).eps
TRUE = dict(B=2.0, K=3.0, x0=0.05, v0=-0.1)


def _reference_x(kind, B, K, x0, v0, duration=2.0):
    """Closed-form response (tests/msd_reference.py, independent of algid)."""
    return analytic_response(kind, B=B, K=K, x0=x0, v0=v0, duration=duration)[2]


@pytest.mark.parametrize("kind", ["step", "sine"])
def test_model_output_is_exact(kind):
    # Step: the constant input is interpolated exactly, so the response is exact up to
    # round-off.  Sine: the interpolation error is O(h**6) ~ 1e-18.  Reference: the
    # closed-form solution of tests/msd_reference.py.
    t, f, x = analytic_response(kind, duration=1.0, x0=0.3, v0=-0.7)
    xhat, _ = output_sensitivities(t, f, B=2.0, K=3.0, x0=0.3, v0=-0.7)
    assert np.max(np.abs(xhat - x)) <= 1e3 * EPS * np.max(np.abs(x))


@pytest.mark.parametrize("kind", ["step", "sine"])
def test_sensitivities_match_finite_differences(kind):
    # Central differences of the closed-form response (independent code).
    # Their truncation error is O(e**2): with steps e and e/2 the error of the finer
    # one is a third of the difference between the two, so that difference (plus the
    # round-off floor eps * |x| / e) bounds it.
    t = np.arange(2001) * 1e-3
    f = np.ones_like(t) if kind == "step" else np.sin(t)
    _, S = output_sensitivities(t, f, **TRUE)
    for j, name in enumerate(SENSITIVITY_PARAMETERS):
        fd = []
        for e in (1e-3, 5e-4):
            plus, minus = dict(TRUE), dict(TRUE)
            plus[name] += e
            minus[name] -= e
            fd.append((_reference_x(kind, **plus) - _reference_x(kind, **minus)) / (2 * e))
        bound = np.max(np.abs(fd[0] - fd[1])) + 1e3 * EPS / 5e-4
        assert np.max(np.abs(fd[1] - S[:, j])) <= bound, name
        assert np.max(np.abs(S[:, j])) > 1e3 * bound  # the check is not vacuous


def test_bound_matches_a_finite_difference_fisher_matrix():
    # CRLB from a Jacobian of central differences (e = 1e-5: relative error ~1e-9 in
    # the Jacobian, hence in the bound, well inside 1e-6).
    t = np.arange(2501) * 1e-3
    f = np.ones_like(t)
    columns = []
    for name in SENSITIVITY_PARAMETERS:
        plus, minus = dict(TRUE), dict(TRUE)
        plus[name] += 1e-5
        minus[name] -= 1e-5
        columns.append((_reference_x("step", duration=2.5, **plus)
                        - _reference_x("step", duration=2.5, **minus)) / 2e-5)
    J = np.column_stack(columns)
    std_fd = np.sqrt(np.diag(np.linalg.inv(J.T @ J))) * 0.01
    bound = crlb(t, f, noise_std=0.01, **TRUE)
    for j, name in enumerate(SENSITIVITY_PARAMETERS):
        assert bound[name] == pytest.approx(std_fd[j], rel=1e-6)


def test_fisher_information_and_covariance_agree():
    t = np.arange(3001) * 1e-3
    f = np.sin(t)
    fim = fisher_information(t, f, noise_std=0.02, **TRUE)
    bound = crlb(t, f, noise_std=0.02, **TRUE)
    std = np.sqrt(np.diag(np.linalg.inv(fim)))
    for j, name in enumerate(SENSITIVITY_PARAMETERS):
        assert bound[name] == pytest.approx(std[j], rel=1e-8)


def test_bound_scales_with_noise_horizon_and_mass():
    t = np.arange(5001) * 1e-3
    f = np.ones_like(t)
    base = crlb(t, f, B=2.0, K=3.0, noise_std=0.01)
    # linear in the noise level
    double = crlb(t, f, B=2.0, K=3.0, noise_std=0.02)
    assert double["B"] == pytest.approx(2 * base["B"], rel=1e-12)
    # horizon = the record cut there
    cut = crlb(t[:2501], f[:2501], B=2.0, K=3.0, noise_std=0.01)
    assert crlb(t, f, B=2.0, K=3.0, noise_std=0.01, horizon=2.5) == cut
    # more data never lowers the information: the bound decreases with the horizon
    b1 = crlb(t, f, B=2.0, K=3.0, noise_std=0.01, horizon=1.0)
    assert base["B"] < cut["B"] < b1["B"] and base["K"] < cut["K"] < b1["K"]
    # with a mass: f is the force, c = B m and k = K m
    m = 2.5
    with_mass = crlb(t, m * f, B=2.0, K=3.0, noise_std=0.01, mass=m)
    assert with_mass["B"] == pytest.approx(base["B"], rel=1e-12)
    assert with_mass["c"] == pytest.approx(m * base["B"], rel=1e-12)
    assert with_mass["k"] == pytest.approx(m * base["K"], rel=1e-12)


def test_free_response_is_informative_without_input():
    # zero input but a non-zero initial state still identifies B and K
    t = np.arange(3001) * 1e-3
    bound = crlb(t, np.zeros_like(t), B=2.0, K=3.0, x0=0.1, v0=0.0, noise_std=0.01)
    assert np.isfinite(bound["B"]) and bound["B"] > 0


@pytest.mark.parametrize("kwargs,fragment", [
    (dict(noise_std=0.0), "noise_std"),
    (dict(noise_std=-1.0), "noise_std"),
    (dict(noise_std=0.01, horizon=-1.0), "horizon"),
    (dict(noise_std=0.01, horizon=0.003), "horizon"),
    (dict(noise_std=0.01, mass=0.0), "mass"),
])
def test_bad_options_are_rejected(kwargs, fragment):
    t = np.arange(1001) * 1e-3
    with pytest.raises(InputDataError, match=fragment):
        crlb(t, np.ones_like(t), B=2.0, K=3.0, **kwargs)


def test_unidentifiable_data_are_rejected():
    t = np.arange(1001) * 1e-3
    with pytest.raises(InputDataError, match="does not depend on B"):
        crlb(t, np.zeros_like(t), B=2.0, K=3.0, noise_std=0.01)
    with pytest.raises(InputDataError, match="linearly dependent"):
        covariance_from_sensitivities(np.column_stack([t, 2 * t]), 1.0)


def test_study_rows_are_consistent():
    from algid.estimation._efficiency import crlb_study, format_study

    rows = crlb_study(n_runs=3, horizons=(0.5, 1.0), inputs=("sine",), seed=5)
    assert [(r["horizon"], r["method"]) for r in rows] == [
        (0.5, "algebraic"), (0.5, "refined"), (1.0, "algebraic"), (1.0, "refined")]
    t = np.arange(1001) * 1e-3
    bound = crlb(t, np.sin(t), B=2.0, K=3.0, noise_std=0.01)
    for r in rows:
        assert r["n_valid"] == 3
        assert r["ratio_B"] == pytest.approx(r["rmse_B"] / r["crlb_B"], rel=1e-12)
        if r["horizon"] == 1.0:
            assert r["crlb_B"] == pytest.approx(bound["B"], rel=1e-12)
    table = format_study(rows)
    assert len(table.splitlines()) == 2 + len(rows)
