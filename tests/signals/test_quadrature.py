"""Cumulative quadrature: exactness, convergence order, causality."""

import numpy as np
import pytest

from algid.signals._quadrature import (QUADRATURE_POINTS, advance_integrators, cumulative_integral,
                              integrator_weights, iterated_integrals, rule_weights,
                              startup_samples)


@pytest.mark.parametrize("points", QUADRATURE_POINTS)
def test_exact_for_polynomials_of_degree_points_minus_one(points):
    h = 0.01
    t = np.arange(40) * h
    for degree in range(points):
        y = t**degree
        exact = t ** (degree + 1) / (degree + 1)
        np.testing.assert_allclose(cumulative_integral(y, h, points=points), exact,
                                   rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("points", [2, 4, 6, 8])
def test_convergence_order(points):
    errors = []
    for n in (50, 100):
        t = np.linspace(0.0, 2.0, n + 1)
        h = t[1] - t[0]
        errors.append(np.max(np.abs(cumulative_integral(np.cos(3 * t), h, points=points)
                                    - np.sin(3 * t) / 3)))
    observed = np.log2(errors[0] / errors[1])
    assert observed == pytest.approx(points, abs=0.35)


@pytest.mark.parametrize("points", QUADRATURE_POINTS)
def test_causal_after_startup(points):
    """Changing future samples does not change the integral from sample points-1 on."""
    rng = np.random.default_rng(1)
    y = rng.standard_normal(60)
    base = cumulative_integral(y, 0.1, points=points)
    for n in range(startup_samples(points), 59):
        z = y.copy()
        z[n + 1:] = rng.standard_normal(59 - n)
        np.testing.assert_array_equal(cumulative_integral(z, 0.1, points=points)[: n + 1],
                                      base[: n + 1])


def test_weights_sum_to_one_interval():
    for points in QUADRATURE_POINTS:
        regular, startup = rule_weights(points)
        assert regular.sum() == pytest.approx(1.0, abs=1e-15)
        np.testing.assert_allclose(startup.sum(axis=1), 1.0, atol=1e-15)
    # the 4-point Adams-Moulton rule, as in textbooks
    np.testing.assert_allclose(rule_weights(4)[0], np.array([1, -5, 19, 9]) / 24)


def test_iterated_integrals_of_constant():
    t = np.arange(30) * 0.1
    levels = iterated_integrals(np.ones_like(t), 0.1, 3)
    np.testing.assert_allclose(levels[3], t**3 / 6, atol=1e-13)


def test_rejects_bad_points_and_short_signal():
    with pytest.raises(ValueError, match="quadrature points"):
        cumulative_integral(np.ones(10), 0.1, points=10)
    with pytest.raises(ValueError, match="too few"):
        cumulative_integral(np.ones(3), 0.1, points=6)



@pytest.mark.parametrize("points", [2, 3, 6, 8])
def test_integrators_continue_bit_for_bit_across_chunks(points):
    """The carried state (integral and last points - 1 samples) continues a chunked
    integration exactly as one pass, whatever the chunk sizes (also shorter than the
    history), for several integrators at once (paired in the complex running sum)."""
    rng = np.random.default_rng(points)
    samples = rng.standard_normal((3, 200))
    weights, startup = integrator_weights(points, 0.01)
    whole = advance_integrators(samples, np.zeros(3), np.zeros((3, points - 1)), weights,
                                startup)
    integrals, history = np.zeros(3), np.zeros((3, points - 1))
    pieces = [advance_integrators(samples[:, :points], integrals, history, weights, startup)]
    start = points
    for size in (1, 2, 7, 0, 50):
        pieces.append(advance_integrators(samples[:, start:start + size], integrals, history,
                                          weights))
        start += size
    pieces.append(advance_integrators(samples[:, start:], integrals, history, weights))
    np.testing.assert_array_equal(np.concatenate(pieces, axis=1), whole)
    np.testing.assert_array_equal(history, samples[:, 200 - (points - 1):])
    assert integrals.tolist() == whole[:, -1].tolist()
