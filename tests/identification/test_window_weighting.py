"""The windows weighted by their noise (``method="gls"``): the band of the inverse, the
whitened equations' noise against the map from noise samples built impulse by impulse,
and the estimate on noisy records against the Cramér–Rao bound."""

import numpy as np
import pytest
from benchmarks.synthetic_records import CUBIC_EQUATION, cubic_spring
from scipy.linalg import cholesky_banded

import algid
from algid.errors import ModelError

LINEAR = ("y'' + B*y' + K*y = G*u + d", "B K G d")


def test_inverse_band_is_the_band_of_the_inverse():
    from algid.identification._window_weighting import inverse_band

    rng = np.random.default_rng(0)
    n, k = 40, 3
    X = np.zeros((n, n + k))
    for i in range(n):   # rows overlapping k + 1 columns: a banded Gram matrix
        X[i, i:i + k + 1] = rng.standard_normal(k + 1)
    S = X @ X.T
    band = np.array([np.append(np.diag(S, -d), np.zeros(d)) for d in range(k + 1)])
    Z = inverse_band(cholesky_banded(band, lower=True))
    inverse = np.linalg.inv(S)
    for d in range(k + 1):
        np.testing.assert_allclose(Z[d, :n - d], np.diag(inverse, -d), rtol=1e-9,
                                   atol=1e-12 * np.abs(inverse).max())


@pytest.mark.parametrize("uniform, linear", [(True, False), (False, False), (True, True)])
def test_whitened_noise_is_that_of_the_noise_map(uniform, linear):
    """``Q = sum_ij tr(M_i^T S^-1 M_j)`` with ``M_c`` the map from output noise samples to
    column ``c`` of the equations (first order; a cubic term, so that every window
    weighs its noise differently, or the linear model, whose windows all weigh it
    alike) and ``S = M_e M_e^T`` that of the equation error; and
    ``theta_bar^T Q theta_bar`` is the number of windows (the whitened errors have unit
    variance)."""
    from algid.identification._records import prepare_records
    from algid.identification._window_basis import WindowBasis
    from algid.identification._window_problem import (
        ProblemCache,
        WindowProblem,
        window_stride,
    )
    from algid.identification._window_weighting import WhitenedEquations
    from algid.models._grammar import parse_equation

    record, truth = cubic_spring(3, n=160)
    record = dict(record, y=10.0 * record["y"])
    if not uniform:
        jitter = np.random.default_rng(1).uniform(-0.1, 0.1, 160) / 80.0
        record = dict(record, t=np.asarray(record["t"]) + jitter)
    model = parse_equation(*(LINEAR if linear else CUBIC_EQUATION))
    segments, step, _ = prepare_records(record, model.signals, time="t", min_length=16)
    problem = WindowProblem(model, segments, step)
    assert problem.uniform_noise == linear
    length, a = 24, 8
    stride = window_stride(length)
    A, b, ids = problem.rows(length, a)
    basis = WindowBasis(A, b)
    theta_bar = np.append([truth.get(p, 1.0) * 1.1 for p in model.parameters], -1.0)
    whitened = WhitenedEquations(problem, length, a, theta_bar, basis, ids, stride)

    bound = problem.noise_bound()
    h = 1e-6
    maps = []
    for n in range(len(segments[0])):
        rows = []
        for sign in (1, -1):
            seg = segments[0]
            saved = seg.values[model.output]
            shifted = saved.copy()
            shifted[n] += sign * h * problem.output_unit
            seg.values[model.output] = shifted
            problem.cache = ProblemCache(noise_bound=bound)
            A1, b1, _ = problem.rows(length, a)
            seg.values[model.output] = saved
            rows.append(np.column_stack([A1, b1]))
        maps.append((rows[0] - rows[1]) / (2 * h))
    problem.cache = ProblemCache()
    M = np.stack(maps, axis=2)                    # windows x (p + 1) x samples
    p = A.shape[1]
    full = np.zeros((p + 1, p + 1))   # [A | b] -> the basis, written out here
    full[:p, :p] = np.linalg.inv(basis.R[:p, :p]) / 2.0 ** basis.shifts[:, None]
    full[p, p] = 2.0 ** -basis.b_shift
    assert np.array_equal(full, basis.change)
    Mb = np.einsum("wcn,cd->wdn", M, full)        # in the basis
    error = np.einsum("wdn,d->wn", M, theta_bar) * full[p, p]
    S_inv = np.linalg.inv(error @ error.T)
    expected = np.einsum("wdn,wv,ven->de", Mb, S_inv, Mb)
    np.testing.assert_allclose(whitened.noise, expected, rtol=1e-5,
                               atol=1e-8 * np.abs(expected).max())
    theta_basis = np.linalg.solve(full, theta_bar * full[p, p])
    assert theta_basis[p] == pytest.approx(-1.0)
    assert theta_basis @ whitened.noise @ theta_basis == pytest.approx(len(ids), rel=1e-5)


def test_gls_on_a_noise_free_record_and_the_record_in_memory():
    record, truth = cubic_spring(0, n=4000, noise=0.0)
    r = algid.identify(record, *CUBIC_EQUATION, method="gls", refine=False)
    assert r.method == "gls" and r.warnings == []   # (the quadrature is no misfit)
    for p, v in truth.items():   # (the record's own misfit: RK4 and the quadrature)
        assert abs(r.values[p] - v) <= 2 * (r.stderr[p] + r.numerical_error[p]), p
        assert abs(r.values[p] - v) <= 1e-4 * max(1.0, abs(v)), p
    with pytest.raises(ModelError, match="gls"):
        algid.identify(record, *CUBIC_EQUATION, method="gls", chunk=1000)


def test_gls_is_nearer_the_bound_with_honest_errors():
    """Twelve noisy records of the hardening spring at the same window: the weighted
    estimate's spread is below that of least squares for every parameter, by at least
    a third for the stiffnesses; its reported errors cover the truth."""
    errors = {"bc": [], "gls": []}
    z = []
    for seed in range(12):
        record, truth = cubic_spring(seed, n=4000, noise=0.01)
        for method in errors:
            r = algid.identify(record, *CUBIC_EQUATION, method=method, window=0.6,
                               refine=False)
            error = np.array([r.values[p] - truth[p] for p in truth])
            errors[method].append(error)
            if method == "gls":
                z.append(error / np.array([r.stderr[p] for p in truth]))
    spread = {m: np.sqrt(np.mean(np.square(e), axis=0)) for m, e in errors.items()}
    assert np.all(spread["gls"] < spread["bc"]), spread
    assert np.all(spread["gls"][1:3] < 0.67 * spread["bc"][1:3]), spread
    assert np.all(np.sqrt(np.mean(np.square(z), axis=0)) < 1.6), np.square(z).mean(0)


def test_gls_on_a_wrong_model_reports_the_unweighted_estimate():
    """The hardening spring's record with the linear model: the weighted estimate is far
    from the unweighted one (the misfit, not noise, is what the weighting weighs), and
    identify says so and returns what method "bc" returns."""
    record, _ = cubic_spring(0, n=4000, noise=0.01)
    r = algid.identify(record, *LINEAR, method="gls", refine=False)
    assert r.method == "bc"
    assert any("method='gls'" in line and "standard deviations" in line
               for line in r.warnings), r.warnings
    plain = algid.identify(record, *LINEAR, refine=False)   # its own window, bit for bit
    assert r.values == plain.values and r.window == plain.window
    assert r.warnings == plain.warnings + r.warnings[-1:]
    right = algid.identify(record, *CUBIC_EQUATION, method="gls", refine=False)
    assert right.method == "gls" and not any("method=" in w for w in right.warnings)


@pytest.mark.parametrize("equation", ["M*q'' + Fv*q' + Fc*sign(q') = F",
                                      "M*q'' + Fv*abs(q')*q' + Fc*q = F"])
def test_gls_refuses_sign_and_derivatives_inside_nonlinear_factors(equation):
    t = np.arange(2000) / 100.0
    record = {"t": t, "F": np.sin(t), "q": np.cos(t)}
    with pytest.raises(ModelError, match="method='gls'.*use method='bc'"):
        algid.identify(record, equation, "M Fv Fc", method="gls")
