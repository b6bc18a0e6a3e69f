"""Derivation of the algebraic numerical differentiator (Mboup, Join and Fliess).

On a window ``[0, T]`` the signal is its truncated Taylor expansion about 0,
``y_N(t) = sum_{i<=N} a_i t**i / i!`` with ``a_i = y^(i)(0)``, whose Laplace transform is
``Y(s) = sum_i a_i / s**(i+1)``.  The annihilator

    Pi = s**-(N+1+mu) * d^(n+kappa)/ds^(n+kappa) * s**-1 * d^(N-n)/ds^(N-n) * s**(N+1)

keeps only ``a_n`` (the n-th derivative) on the right-hand side:

- ``s**(N+1) Y = sum_i a_i s**(N-i)`` is a polynomial in ``s``;
- ``d^(N-n)/ds^(N-n)`` removes the ``a_i`` with ``i > n``;
- ``s**-1`` then leaves ``a_n`` alone on ``1/s`` and a polynomial of degree ``n - 1``
  that ``d^(n+kappa)/ds^(n+kappa)`` removes;
- ``s**-(N+1+mu)`` leaves only negative powers of ``s``, i.e. integrals.

Back in the time domain with the operator table (``d^k/ds^k`` -> multiplication by
``(-t)**k``, ``s**-j`` -> ``j``-fold integral from 0, written as the Cauchy formula
``int_0^T (T - tau)**(j-1)/(j-1)! (.) dtau``), the left-hand side is an integral of
``y`` against a polynomial kernel and the right-hand side a multiple of ``a_n``.  In the
window's unit time ``u = tau / T``:

    y^(n)(0) = T**-n * int_0^1 h(u) y(u T) du,

exact when ``y`` is a polynomial of degree ``N``.  ``h`` always has the factor
``u**kappa (1 - u)**mu``; for ``N = n`` (the minimal estimator) it is the Jacobi kernel
``h(u) = c u**kappa (1-u)**mu P_n^(mu, kappa)(2u - 1)`` (Rodrigues' formula), i.e. up to
a constant the n-th derivative of ``u**(kappa+n) (1-u)**(mu+n)``.

This module needs SymPy; the runtime (:mod:`algid.signals._differentiation`) uses the table that
``python -m derivation`` writes from it into ``algid/_generated/``.
"""

from __future__ import annotations

import sympy as sp

__all__ = ["differentiator_kernel", "jacobi_kernel", "kernel_table_source",
           "TABLE_DERIVATIVES", "TABLE_KAPPA", "TABLE_MU", "TABLE_EXTRA_ORDERS"]

u = sp.Symbol("u", nonnegative=True)

#: The range of the generated table: derivative orders n, kernel exponents kappa and
#: mu, and truncation orders N = n + extra.
TABLE_DERIVATIVES = range(0, 6)
TABLE_KAPPA = range(0, 7)
TABLE_MU = range(0, 7)
TABLE_EXTRA_ORDERS = range(0, 3)


def _check(derivative, kappa, mu, truncation):
    for name, value in (("derivative", derivative), ("kappa", kappa), ("mu", mu)):
        if int(value) != value or value < 0:
            raise ValueError(f"{name} must be a non-negative integer, got {value!r}")
    if int(truncation) != truncation or truncation < derivative:
        raise ValueError(f"truncation must be an integer >= derivative, got {truncation!r}")


def differentiator_kernel(derivative, kappa, mu, truncation=None):
    """The kernel ``h(u)`` of the n-th derivative, derived by annihilation.

    Parameters
    ----------
    derivative : int
        ``n``, the order of the derivative estimated at ``u = 0``.
    kappa, mu : int
        The extra ``d/ds`` and ``1/s`` factors of the annihilator; ``h`` vanishes like
        ``u**kappa`` at 0 and like ``(1 - u)**mu`` at 1.
    truncation : int, optional
        ``N >= n``, the order of the Taylor expansion the estimate is exact for
        (default ``n``: the minimal estimator).

    Returns
    -------
    sympy.Expr
        A polynomial in the module's symbol ``u`` with rational coefficients such that
        ``y^(n)(0) = T**-n * int_0^1 h(u) y(u T) du`` for every polynomial ``y`` of
        degree ``N``.
    """
    n, N = int(derivative), int(derivative if truncation is None else truncation)
    _check(n, kappa, mu, N)
    # An operator term c * s**p * d^k/ds^k is the key (p, k) of a dict of exact
    # coefficients; the annihilator is built right to left with Leibniz' rule.
    operator = {(N + 1, 0): sp.Integer(1)}                 # s**(N+1)
    operator = _differentiate(operator, N - n)              # d^(N-n)/ds^(N-n)
    operator = _shift(operator, -1)                         # 1/s
    operator = _differentiate(operator, n + kappa)          # d^(n+kappa)/ds^(n+kappa)
    operator = _shift(operator, -(N + 1 + mu))              # s**-(N+1+mu)
    # Right-hand side: the operator on the Taylor model sum_i a_i s**-(i+1) leaves
    # c * a_n * s**-p alone (checked: every other a_i cancels).
    coefficient, power = _on_taylor_model(operator, n, N)
    # Time domain at t = T: s**-j -> int_0^T (T - tau)**(j-1)/(j-1)! (.) dtau and
    # d^k/ds^k -> (-tau)**k; the right-hand side a_n c s**-p -> a_n c T**(p-1)/(p-1)!.
    # With tau = u T each term carries T**(j+k) and y(u T) carries T**n a_n: the
    # equation is homogeneous (j + k + n = p - 1 for every term), so T = 1 loses nothing.
    kernel = sp.Poly(0, u, domain="QQ")
    one_minus_u, minus_u = sp.Poly(1 - u, u, domain="QQ"), sp.Poly(-u, u, domain="QQ")
    for (p, k), c in operator.items():
        j = -p
        if j < 1:
            raise RuntimeError(f"the annihilator left a non-integral term s**{p}")
        if j + k + n != power - 1:
            raise RuntimeError("the annihilated equation is not homogeneous in T")
        kernel += one_minus_u ** (j - 1) * minus_u ** k * (c / sp.factorial(j - 1))
    scale = coefficient / sp.factorial(power - 1)
    # y^(n)(0) * T**n = int_0^1 h(u) y(u T) du
    return (kernel * (1 / scale)).as_expr()


def _shift(operator, m):
    """``s**m`` times the operator."""
    return {(p + m, k): c for (p, k), c in operator.items()}


def _differentiate(operator, times):
    """``d^times/ds^times`` composed after the operator (Leibniz' rule)."""
    for _ in range(times):
        result = {}
        for (p, k), c in operator.items():
            # d/ds (s**p Y^(k)) = p s**(p-1) Y^(k) + s**p Y^(k+1)
            if p != 0:
                result[(p - 1, k)] = result.get((p - 1, k), 0) + c * p
            result[(p, k + 1)] = result.get((p, k + 1), 0) + c
        operator = {key: c for key, c in result.items() if c != 0}
    return operator


def _on_taylor_model(operator, n, N):
    """``(c, p)``: the operator on ``sum_{i<=N} a_i s**-(i+1)`` equals ``c a_n s**-p``."""
    found = None
    for i in range(N + 1):
        powers = {}
        for (p, k), c in operator.items():
            # d^k/ds^k s**-(i+1) = (-(i+1)) (-(i+2)) ... (-(i+k)) s**-(i+1+k)
            value = c * sp.ff(-(i + 1), k)
            key = p - (i + 1) - k
            powers[key] = powers.get(key, 0) + value
        powers = {key: value for key, value in powers.items() if value != 0}
        if i != n and powers:
            raise RuntimeError(f"the annihilator leaves the Taylor coefficient a_{i}")
        if i == n:
            if len(powers) != 1:
                raise RuntimeError("the annihilator does not leave a_n on one power of s")
            ((key, value),) = powers.items()
            found = (value, -key)
    return found


def jacobi_kernel(derivative, kappa, mu):
    """The minimal kernel in Jacobi form, ``c u**kappa (1-u)**mu P_n^(mu,kappa)(2u-1)``.

    The constant ``c`` makes ``int_0^1 h(u) u**n / n! du = 1`` (exactness on ``t**n``).

    Parameters
    ----------
    derivative : int
        Order ``n`` of the derivative estimated.
    kappa, mu : int
        Multiplicities of the kernel's zeros at ``u = 0`` and ``u = 1``.

    Returns
    -------
    sympy.Expr
        The kernel as a polynomial in ``u`` on the unit window.
    """
    n = int(derivative)
    _check(n, kappa, mu, n)
    shape = u ** kappa * (1 - u) ** mu * sp.jacobi(n, mu, kappa, 2 * u - 1)
    norm = sp.integrate(sp.expand(shape * u ** n / sp.factorial(n)), (u, 0, 1))
    return sp.expand(shape / norm)


def _factored(h, kappa, mu):
    """Coefficients of ``q`` (lowest power first) with ``h = u**kappa (1-u)**mu q(u)``."""
    quotient, remainder = sp.div(sp.Poly(h, u), sp.Poly(u ** kappa * (1 - u) ** mu, u))
    if not remainder.is_zero:
        raise RuntimeError(f"kernel lacks the factor u**{kappa} (1-u)**{mu}")
    return [sp.Rational(c) for c in reversed(quotient.all_coeffs())]


def kernel_table_source():
    """Text of ``algid/_generated/differentiator_kernels.py``: the kernel table.

    Returns
    -------
    str
    """
    lines = [
        '"""Kernels of the algebraic differentiator (Mboup, Join and Fliess).',
        "",
        "Generated by `python -m derivation` (algid.symbolic._differentiator); do not edit",
        "by hand.  Change the derivation and run `python -m derivation` from the",
        "repository root.",
        "",
        "KERNELS[(n, kappa, mu, N)] = (q_0, q_1, ...): the kernel of the n-th derivative,",
        "exact on polynomials of degree N, is",
        "    h(u) = u**kappa * (1 - u)**mu * (q_0 + q_1 u + q_2 u**2 + ...),  0 <= u <= 1,",
        "and y^(n)(0) = T**-n * int_0^1 h(u) y(u T) du on the window [0, T].",
        '"""',
        "",
        f"DERIVATIVES = range({TABLE_DERIVATIVES.start}, {TABLE_DERIVATIVES.stop})",
        f"KAPPA = range({TABLE_KAPPA.start}, {TABLE_KAPPA.stop})",
        f"MU = range({TABLE_MU.start}, {TABLE_MU.stop})",
        f"EXTRA_ORDERS = range({TABLE_EXTRA_ORDERS.start}, {TABLE_EXTRA_ORDERS.stop})",
        "",
        "KERNELS = {",
    ]
    for n in TABLE_DERIVATIVES:
        for kappa in TABLE_KAPPA:
            for mu in TABLE_MU:
                for extra in TABLE_EXTRA_ORDERS:
                    q = _factored(differentiator_kernel(n, kappa, mu, n + extra), kappa, mu)
                    values = ", ".join(repr(float(c)) for c in q)
                    lines.append(f"    ({n}, {kappa}, {mu}, {n + extra}): ({values},),")
    lines.append("}")
    return "\n".join(lines) + "\n"
