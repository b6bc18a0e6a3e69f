"""The algebraic differentiator: generated kernels against the derivation, accuracy."""

from __future__ import annotations

import math

import numpy as np
import pytest

from algid._generated.differentiator_kernels import KERNELS
from algid.errors import InputDataError
from algid.signals._differentiation import (
    algebraic_derivative,
    differentiator_delay,
    differentiator_response,
)

sp = pytest.importorskip("sympy", reason="needs the 'derive' extra")
from algid.symbolic._differentiator import differentiator_kernel, jacobi_kernel, u  # noqa: E402

SAMPLE = [(1, 2, 2, 1), (1, 0, 0, 1), (0, 3, 1, 2), (2, 1, 4, 3), (3, 6, 6, 5),
          (1, 4, 4, 3), (2, 0, 6, 2), (5, 2, 3, 7)]


@pytest.mark.parametrize("key", SAMPLE)
def test_generated_table_matches_the_derivation(key):
    n, kappa, mu, N = key
    h = differentiator_kernel(n, kappa, mu, N)
    q = sp.Poly(sp.cancel(h / (u ** kappa * (1 - u) ** mu)), u).all_coeffs()[::-1]
    table = KERNELS[key]
    assert len(table) == len(q)
    for value, exact in zip(table, q):
        assert value == pytest.approx(float(exact), rel=1e-15, abs=1e-15 * max(map(abs, table)))


@pytest.mark.parametrize("n,kappa,mu", [(0, 0, 0), (1, 0, 0), (1, 2, 2), (1, 1, 3),
                                        (2, 3, 0), (3, 2, 5)])
def test_minimal_kernel_is_the_jacobi_kernel(n, kappa, mu):
    assert sp.expand(differentiator_kernel(n, kappa, mu) - jacobi_kernel(n, kappa, mu)) == 0


@pytest.mark.parametrize("n,kappa,mu,N", [(1, 1, 1, 1), (1, 2, 0, 3), (2, 1, 2, 4), (0, 2, 2, 2)])
def test_kernel_is_exact_up_to_the_truncation_order(n, kappa, mu, N):
    """T**-n int h(u) y(uT) du = y^(n)(0) for y = t**k/k!, k <= N, and not for k = N+1."""
    h = differentiator_kernel(n, kappa, mu, N)
    moments = [sp.integrate(h * u ** k / sp.factorial(k), (u, 0, 1)) for k in range(N + 2)]
    assert moments[:N + 1] == [1 if k == n else 0 for k in range(N + 1)]
    assert moments[N + 1] != 0


def _polynomial(t, degree):
    coefficients = np.array([0.3, -1.1, 0.7, 2.0, -0.4, 0.9])[:degree + 1]
    return np.polynomial.polynomial.polyval(t, coefficients), coefficients


@pytest.mark.parametrize("n", [0, 1, 2, 3])
@pytest.mark.parametrize("options,exact_degree", [
    ({}, "n+1"), ({"kappa": 1, "mu": 3}, "n+1"), ({"truncation": "n+2"}, "n+2"),
    ({"causal": True, "truncation": "n+1"}, "n+1"), ({"causal": True, "truncation": "n+2"}, "n+2")])
def test_exact_on_polynomials_uniform(n, options, exact_degree):
    dt = 1e-3
    t = np.arange(0.0, 0.2, dt)
    options = {key: (n + int(value[-1]) if isinstance(value, str) else value)
               for key, value in options.items()}
    degree = n + int(exact_degree[-1])
    y, c = _polynomial(t, degree)
    truth = np.polynomial.polynomial.polyval(t, np.polynomial.polynomial.polyder(c, n))
    estimate = algebraic_derivative(y, dt, derivative=n, window=0.02, **options)
    valid = ~np.isnan(estimate)
    scale = np.max(np.abs(truth)) + 1.0
    # centred: only the interior is exact to degree n+1 (the ends are re-expanded to n+1)
    assert np.max(np.abs(estimate - truth)[valid]) < 1e-8 * scale * 0.02 ** -n
    assert valid.sum() >= len(t) - 21


def test_minimal_causal_estimate_lags_by_the_documented_delay():
    dt, window = 1e-3, 0.03
    t = np.arange(0.0, 0.3, dt)
    for kappa, mu in ((2, 2), (1, 4), (3, 0)):
        delay = differentiator_delay(window, kappa=kappa, mu=mu)
        assert delay == pytest.approx(window * (kappa + 2) / (kappa + mu + 4))
        estimate = algebraic_derivative(t ** 2, dt, window=window, kappa=kappa, mu=mu,
                                        causal=True)
        valid = ~np.isnan(estimate)
        np.testing.assert_allclose(estimate[valid], 2 * (t[valid] - delay), atol=1e-10)
        assert np.all(np.isnan(estimate[:30]))


@pytest.mark.parametrize("steps_per_period", [40, 15, 9])
@pytest.mark.parametrize("window_steps", [10, 20, 40])
def test_sine_error_is_the_documented_bandwidth(steps_per_period, window_steps):
    """Interior error of the centred estimate = 1 - Phi(2 pi f T), up to the sampling.

    The sampling error (the sum of samples against the integral) is what Poisson
    summation predicts: the kernel's spectrum at the sampling rate, smaller for smoother
    kernels and longer windows.  Measured: at most 1.1e-4 (kappa = 2) and 7e-6
    (kappa = 4) at 15 samples per period, 5.6e-4 and 4.4e-5 at 9 samples per period,
    with 10-step windows, of the derivative's amplitude.
    """
    dt = 1e-3
    f = 1.0 / (steps_per_period * dt)
    t = np.arange(0.0, 1.0, dt)
    y = np.sin(2 * np.pi * f * t + 0.3)
    truth = 2 * np.pi * f * np.cos(2 * np.pi * f * t + 0.3)
    amplitude = 2 * np.pi * f
    inner = slice(window_steps, -window_steps)
    residuals = {}
    for kappa in (2, 4):
        estimate = algebraic_derivative(y, dt, window=window_steps * dt, kappa=kappa, mu=kappa)
        gain = differentiator_response(f, window_steps * dt, kappa=kappa, mu=kappa)
        assert abs(gain.imag) < 1e-12
        residuals[kappa] = np.max(np.abs(estimate - gain.real * truth)[inner]) / amplitude
        # the continuous estimator's error, 1 - Phi, explains the measured one
        error = np.max(np.abs(estimate - truth)[inner]) / amplitude
        expected = abs(1 - gain.real) * np.max(np.abs(truth[inner])) / amplitude
        assert abs(error - expected) <= residuals[kappa] + 1e-12
    bound = 1e-3 if steps_per_period == 9 else 2e-4 if steps_per_period == 15 else 1e-5
    assert residuals[2] < bound
    assert residuals[4] < residuals[2] / 5
    # small-fT formula of the module docstring (a = b = kappa + n + 1 = 4 for kappa 2)
    if window_steps / steps_per_period < 0.3:
        a = b = 4
        gain = differentiator_response(f, window_steps * dt).real
        approx = (2 * np.pi * f * window_steps * dt) ** 2 * a * b / (2 * (a + b) ** 2 * (a + b + 1))
        assert 1 - gain == pytest.approx(approx, rel=0.05)


def test_cutoff_of_the_default_settings():
    window = 0.02
    response = differentiator_response(0.782 / window, window)
    assert abs(response) == pytest.approx(1 / math.sqrt(2), abs=2e-3)
    causal = differentiator_response(0.782 / window, window, causal=True)
    assert abs(causal) == pytest.approx(abs(response), rel=1e-12)


def test_non_uniform_grid():
    rng = np.random.default_rng(1)
    t = np.arange(600) * 1e-3 + rng.uniform(-3e-4, 3e-4, 600)
    y, c = _polynomial(t, 3)
    truth = np.polynomial.polynomial.polyval(t, np.polynomial.polynomial.polyder(c, 1))
    estimate = algebraic_derivative(y, time=t, window=0.02, truncation=3)
    np.testing.assert_allclose(estimate, truth, atol=1e-9)
    # sines: the interior follows the continuous response as on a uniform grid
    f = 25.0
    estimate = algebraic_derivative(np.sin(2 * np.pi * f * t), time=t, window=0.02)
    truth = 2 * np.pi * f * np.cos(2 * np.pi * f * t)
    gain = differentiator_response(f, 0.02).real
    # (measured 1.0e-4 of the amplitude at 40 samples per period, jitter 30 % of a step)
    assert np.max(np.abs(estimate - gain * truth)[15:-15]) / (2 * np.pi * f) < 3e-4
    # a gap wider than the window leaves windows without samples: a clear error
    holes = np.r_[t[:200], t[260:]]
    with pytest.raises(InputDataError, match=r"gap between t = 0\.19.* longer than 0\.25"):
        algebraic_derivative(np.sin(holes), time=holes, window=0.02)


def test_default_call_used_by_identify():
    dt = 1e-3
    t = np.arange(0.0, 2.0, dt)
    v = algebraic_derivative(np.sin(2 * np.pi * t), dt, derivative=1)
    assert v.shape == t.shape and np.all(np.isfinite(v))
    error = np.abs(v - 2 * np.pi * np.cos(2 * np.pi * t)) / (2 * np.pi)
    # interior: 1 - Phi = (2 pi f T)**2 a b / (2 (a+b)**2 (a+b+1)) = 2.2e-4 at f T = 0.02;
    # the first and last 10 samples are extrapolated (exact to degree 2 only): 1.8e-3
    predicted = (2 * np.pi * 0.02) ** 2 * 16 / (2 * 64 * 9)
    assert np.max(error[10:-10]) == pytest.approx(predicted, rel=0.01)
    assert np.max(error) < 3e-3


@pytest.mark.parametrize("call,match", [
    (lambda y: algebraic_derivative(y), "exactly one of dt"),
    (lambda y: algebraic_derivative(y, 1e-3, time=np.arange(100.0)), "exactly one of dt"),
    (lambda y: algebraic_derivative(y, -1.0), "dt must be"),
    (lambda y: algebraic_derivative(y, 1e-3, kappa=9), "kappa must be an integer in 0..6"),
    (lambda y: algebraic_derivative(y, 1e-3, derivative=4), "derivative must be"),
    (lambda y: algebraic_derivative(y, 1e-3, truncation=5), "truncation must be"),
    (lambda y: algebraic_derivative(y, 1e-3, window=1.0), "shorter than one window"),
    (lambda y: algebraic_derivative(np.r_[y[:-1], np.nan], 1e-3), "finite"),
    (lambda y: algebraic_derivative(y, time=np.zeros(100)), "strictly increasing"),
])
def test_bad_input_is_a_clear_error(call, match):
    with pytest.raises(InputDataError, match=match):
        call(np.linspace(0.0, 1.0, 100))
