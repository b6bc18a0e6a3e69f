"""The differentiator's taps built once and applied by a correlation: the same numbers as
the direct computation (taps rebuilt for every window, a sum over taps per sample)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from algid.signals import _differentiation as differentiation
from algid.signals._differentiation import CausalDifferentiator, algebraic_derivative


def direct_taps(steps, n, kappa, mu, N, at):
    """The taps of one window built from scratch: the previous implementation."""
    u = np.arange(steps + 1) / steps
    quadrature = np.full(steps + 1, 1.0 / steps)
    quadrature[[0, -1]] *= 0.5
    taps = quadrature * differentiation._kernel(u, n, kappa, mu, N, at)
    degree = min(max(N, n + 1) + 2, steps - 2)
    if degree < 0:
        return taps
    nodes, weights = np.polynomial.legendre.leggauss(64)
    x = 0.5 * (nodes + 1.0)
    basis_nodes = np.polynomial.legendre.legvander(nodes, degree)
    moments = (0.5 * weights * differentiation._kernel(x, n, kappa, mu, N, at)) @ basis_nodes
    basis = np.polynomial.legendre.legvander(2.0 * u - 1.0, degree)
    correction = np.linalg.lstsq(basis.T, moments - basis.T @ taps, rcond=None)[0]
    return taps + correction


def direct_derivative(y, dt, steps, n, kappa, mu, N, causal):
    """Every sample's estimate as its own window times its own taps."""
    T = steps * dt
    out = np.full(len(y), np.nan)
    if causal:
        taps = (-1.0) ** n * direct_taps(steps, n, kappa, mu, N, 0.0) / T ** n
        for i in range(steps, len(y)):
            out[i] = sum(taps[j] * y[i - j] for j in range(steps + 1))
        return out
    centre = int(round(differentiation._centre(n, kappa, mu) * steps))
    for i in range(len(y)):
        start = min(max(i - centre, 0), len(y) - 1 - steps)
        at = (i - start) / steps
        order = N if start == i - centre else max(N, n + 1)
        out[i] = direct_taps(steps, n, kappa, mu, order, at) @ y[start:start + steps + 1]
    return out / T ** n


def signals(n_samples=400, dt=1e-3):
    t = np.arange(n_samples) * dt
    rng = np.random.default_rng(7)
    return {
        "sine and noise": np.sin(2 * np.pi * 3 * t) + 1e-3 * rng.standard_normal(n_samples),
        "chirp": np.cos(2 * np.pi * (1 + 20 * t) * t),
        "random walk": np.cumsum(rng.standard_normal(n_samples)),
    }


SETTINGS = [  # derivative, kappa, mu, truncation, window steps, causal
    (1, 2, 2, 1, 20, False),     # the default
    (2, 1, 3, 3, 24, False),
    (0, 4, 4, 1, 100, False),
    (3, 2, 2, 3, 30, False),
    (1, 2, 2, 1, 100, True),
    (2, 0, 3, 3, 17, True),
]


@pytest.mark.parametrize("n, kappa, mu, N, steps, causal", SETTINGS)
def test_same_numbers_as_the_direct_computation(n, kappa, mu, N, steps, causal):
    dt = 1e-3
    for name, y in signals(dt=dt).items():
        fast = algebraic_derivative(y, dt, derivative=n, kappa=kappa, mu=mu, truncation=N,
                                    window=steps * dt, causal=causal)
        whole_steps = differentiation._window_steps(steps * dt, dt, causal, n, kappa, mu)
        reference = direct_derivative(y, dt, whole_steps, n, kappa, mu, N, causal)
        assert np.array_equal(np.isnan(fast), np.isnan(reference)), name
        defined = ~np.isnan(reference)
        scale = np.max(np.abs(reference[defined]))
        assert np.max(np.abs(fast[defined] - reference[defined])) <= 1e-12 * scale, name


def test_taps_are_built_once_and_read_only():
    differentiation._uniform_taps.cache_clear()
    differentiation._edge_taps.cache_clear()
    y = signals()["chirp"]
    first = algebraic_derivative(y, 1e-3, window=0.05)
    second = algebraic_derivative(y, 1e-3, window=0.05)
    np.testing.assert_array_equal(first, second)
    assert differentiation._uniform_taps.cache_info().hits == 1
    assert differentiation._edge_taps.cache_info().hits == 1
    taps = differentiation._uniform_taps(50, 1, 2, 2, 1, 0.5)
    with pytest.raises(ValueError, match="read-only"):
        taps[0] = 1.0


def test_chunked_stream_still_gives_the_whole_record_bit_for_bit():
    y = signals()["random walk"]
    whole = algebraic_derivative(y, 1e-3, window=0.03, causal=True)
    stream = CausalDifferentiator(1e-3, window=0.03)
    cuts = [0, 1, 7, 31, 32, 150, 151, 400]
    chunks = [stream.update(y[a:b]) for a, b in zip(cuts[:-1], cuts[1:])]
    np.testing.assert_array_equal(np.concatenate(chunks), whole)
    assert math.isnan(whole[29]) and not math.isnan(whole[30])
