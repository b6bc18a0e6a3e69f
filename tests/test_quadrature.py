"""Cumulative quadrature: exactness, convergence order, causality."""

import numpy as np
import pytest

from algid.quadrature import (QUADRATURE_ORDERS, cumulative_integral, iterated_integrals,
                              rule_weights, startup_samples)


@pytest.mark.parametrize("order", QUADRATURE_ORDERS)
def test_exact_for_polynomials_of_degree_order_minus_one(order):
    h = 0.01
    t = np.arange(40) * h
    for degree in range(order):
        y = t**degree
        exact = t ** (degree + 1) / (degree + 1)
        np.testing.assert_allclose(cumulative_integral(y, h, order=order), exact,
                                   rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("order", [2, 4, 6, 8])
def test_convergence_order(order):
    errors = []
    for n in (50, 100):
        t = np.linspace(0.0, 2.0, n + 1)
        h = t[1] - t[0]
        errors.append(np.max(np.abs(cumulative_integral(np.cos(3 * t), h, order=order)
                                    - np.sin(3 * t) / 3)))
    observed = np.log2(errors[0] / errors[1])
    assert observed == pytest.approx(order, abs=0.35)


@pytest.mark.parametrize("order", QUADRATURE_ORDERS)
def test_causal_after_startup(order):
    """Changing future samples does not change the integral from sample order-1 on."""
    rng = np.random.default_rng(1)
    y = rng.standard_normal(60)
    base = cumulative_integral(y, 0.1, order=order)
    for n in range(startup_samples(order), 59):
        z = y.copy()
        z[n + 1:] = rng.standard_normal(59 - n)
        np.testing.assert_array_equal(cumulative_integral(z, 0.1, order=order)[: n + 1],
                                      base[: n + 1])


def test_weights_sum_to_one_interval():
    for order in QUADRATURE_ORDERS:
        regular, startup = rule_weights(order)
        assert regular.sum() == pytest.approx(1.0, abs=1e-15)
        np.testing.assert_allclose(startup.sum(axis=1), 1.0, atol=1e-15)
    # the 4-point Adams-Moulton rule, as in textbooks
    np.testing.assert_allclose(rule_weights(4)[0], np.array([1, -5, 19, 9]) / 24)


def test_iterated_integrals_of_constant():
    t = np.arange(30) * 0.1
    levels = iterated_integrals(np.ones_like(t), 0.1, 3)
    np.testing.assert_allclose(levels[3], t**3 / 6, atol=1e-13)


def test_rejects_bad_order_and_short_signal():
    with pytest.raises(ValueError, match="quadrature order"):
        cumulative_integral(np.ones(10), 0.1, order=9)
    with pytest.raises(ValueError, match="too few"):
        cumulative_integral(np.ones(3), 0.1, order=6)
