"""Modulating kernels: the s-domain derivation, the modulating-function form, the
generated table, and the accuracy of sampled window integrals."""

import numpy as np
import pytest
import sympy as sp

from algid._generated.modulating import MAX_MULTIPLICITY, TERM_KERNELS
from algid.identification._window_kernels import (
    term_kernel,
    uniform_window_integrals,
    window_integrals,
)
from algid.symbolic._modulating import (
    T,
    tau,
    term_kernel_from_laplace,
    term_kernel_from_modulating_function,
    u,
    unit_term_kernel,
)


@pytest.mark.parametrize("a", [1, 2, 4])
def test_laplace_steps_equal_the_modulating_function_derivatives(a):
    for k in range(a + 1):
        laplace = term_kernel_from_laplace(a, k)
        assert sp.expand(laplace - term_kernel_from_modulating_function(a, k)) == 0
        # and the normalised unit-window kernel is the same polynomial, rescaled:
        # proportional coefficients in tau
        unit = unit_term_kernel(a, k).subs(u, tau / T)
        assert not sp.cancel(laplace / unit).has(tau)


def test_kernel_vanishes_to_order_a_minus_k_at_both_ends():
    a = 4
    for k in range(a):
        kernel = unit_term_kernel(a, k)
        for j in range(a - k):
            d = sp.diff(kernel, u, j)
            assert d.subs(u, 0) == 0 and d.subs(u, 1) == 0


def test_generated_table_matches_the_derivation():
    assert MAX_MULTIPLICITY >= 8
    points = [sp.Rational(i, 13) for i in range(14)]
    for (a, k) in TERM_KERNELS:
        poly = sp.Poly(unit_term_kernel(a, k), u)
        exact = np.array([float(poly.eval(p)) for p in points])
        values = term_kernel(a, k, np.array([float(p) for p in points]))
        scale = np.max(np.abs(exact))
        np.testing.assert_allclose(values, exact, rtol=0, atol=1e-12 * scale)
    # the kernel of D^0 has unit integral
    for a in range(1, MAX_MULTIPLICITY + 1):
        assert sp.Poly(unit_term_kernel(a, 0), u).integrate().eval(1) == 1


def test_integration_by_parts_holds_on_samples_at_eight_per_period():
    """A derivative moves onto the kernel: integral of psi * z'' equals the
    kernel of D^2 against z, for a window starting anywhere."""
    omega, rate = 2 * np.pi, 8.0
    t = np.arange(0, 10, 1 / rate)
    z = np.sin(omega * t + 0.3)
    zdd = -omega ** 2 * z
    errors = {}
    for a, length in ((3, 16), (5, 16), (8, 16), (10, 24)):
        lhs = uniform_window_integrals(zdd, 1 / rate, length, a, 0)
        rhs = uniform_window_integrals(z, 1 / rate, length, a, 2)
        errors[a] = np.max(np.abs(lhs - rhs)) / np.max(np.abs(lhs))
    # a smoother kernel has less spectrum at the sampling rate (measured: 5e-2, 5e-4,
    # 1.3e-5, 7e-8)
    assert errors[3] > errors[5] > errors[8] > errors[10]
    assert errors[5] < 1e-3 and errors[8] < 3e-5 and errors[10] < 2e-7


def test_non_uniform_grid_matches_the_uniform_one_on_uniform_times():
    rng = np.random.default_rng(0)
    t = np.arange(200) * 0.01
    z = rng.standard_normal(200)
    a = uniform_window_integrals(z, 0.01, 21, 4, 1, stride=3)
    b = window_integrals(z, t, 21, 4, 1, stride=3)
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9)


def test_kernel_outside_the_table_is_a_model_error():
    from algid.errors import ModelError
    with pytest.raises(ModelError, match="multiplicity"):
        term_kernel(2, 3, [0.5])
