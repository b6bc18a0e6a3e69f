"""Modulating kernels of the algebraic method on a window, derived with SymPy.

On a window ``[t0, t0 + T]`` with local time ``tau = t - t0``, a term ``D^k z`` of a
model has the Laplace form ``s^k Z(s) - sum_{i<k} s^(k-1-i) z^(i)(0)``: a polynomial
of degree ``k - 1`` in ``s`` carries the unknown initial conditions.  The algebraic
method applies

1. ``d^a/ds^a`` (``a >= k``): it annihilates that polynomial;
2. ``s^(-N)`` with ``N = a + 1``: only integrations remain;
3. the inverse transform at ``tau = T`` with the operator table
   ``d^j/ds^j <-> multiplication by (-tau)^j`` and
   ``s^(-m) <-> integral of (T - tau)^(m-1)/(m-1)!`` (Cauchy's repeated integral).

Expanding ``d^a/ds^a (s^k Z)`` by Leibniz's rule gives ``D^k z`` as one integral of a
polynomial *term kernel* times the plain signal ``z``, with no boundary value left:

    sum_j C(a, j) k!/(k-j)! (T-tau)^(N-1-k+j)/(N-1-k+j)! (-tau)^(a-j).

The same result read in the time domain: ``d^a/ds^a`` then ``s^(-N)`` integrate
``z^(k)`` against ``phi(tau) = (-1)^a tau^a (T - tau)^a / a!``, which vanishes to
order ``a`` at both ends; integrating by parts ``k`` times moves the derivative onto
``phi``: the term kernel equals ``(-1)^k phi^(k)``.  :func:`term_kernel_from_laplace`
follows the s-domain steps, :func:`term_kernel_from_modulating_function` the time
domain, and the tests check that they agree.

The runtime table (:func:`kernel_table`) uses the unit window ``u = tau/T`` and the
*kernel multiplicity* ``a``, normalised so that ``psi_a(u) = u^a (1-u)^a / B(a+1, a+1)``
has unit integral; the term kernel of ``D^k`` is ``(-1)^k psi_a^(k)(u)``, and on a
window of length ``T`` it is scaled by ``T^(-k)``.  Each kernel is stored as Chebyshev
coefficients in ``x = 2u - 1`` (exact rationals here), which evaluate without the
cancellation of monomial coefficients at high multiplicity.
"""

from __future__ import annotations

from fractions import Fraction
from functools import cache

import sympy as sp

__all__ = ["term_kernel_from_laplace", "term_kernel_from_modulating_function",
           "unit_term_kernel", "chebyshev_coefficients", "kernel_table",
           "MAX_MULTIPLICITY", "table_module_source"]

#: Largest kernel multiplicity in the generated table.
MAX_MULTIPLICITY = 12

tau, T, u, x, s = sp.symbols("tau T u x s", positive=True)


def term_kernel_from_laplace(multiplicity: int, derivative: int):
    """Kernel of ``D^k z`` on ``[0, T]`` from the s-domain steps.

    Parameters
    ----------
    multiplicity : int
        ``a``: order of ``d/ds`` (must be ``>= derivative``).
    derivative : int
        ``k``: order of the time derivative of the term.

    Returns
    -------
    sympy.Expr
        Polynomial in ``tau`` (and ``T``) such that the transformed term at ``T`` is
        ``integral_0^T kernel(tau) z(tau) dtau``.
    """
    a, k = multiplicity, derivative
    if a < k:
        raise ValueError("the multiplicity must be at least the derivative order")
    n_int = a + 1
    Z = sp.Function("Z")(s)
    ics = sp.symbols(f"z0:{max(k, 1)}")
    laplace = s ** k * Z - sum(s ** (k - 1 - i) * ics[i] for i in range(k))
    transformed = sp.expand(sp.diff(laplace, s, a) * s ** (-n_int))
    # the initial conditions are annihilated
    assert all(not transformed.has(c) for c in ics[:k])
    # d^j Z/ds^j -> symbol D_j, then read each coefficient as a polynomial in r = 1/s
    derivative_symbols = sp.symbols(f"D0:{a + 1}")
    replaced = transformed.subs({sp.Derivative(Z, (s, j)): derivative_symbols[j]
                                 for j in range(a, 0, -1)}).subs(Z, derivative_symbols[0])
    r = sp.Symbol("r", positive=True)
    kernel = sp.Integer(0)
    for j, symbol in enumerate(derivative_symbols):
        in_r = sp.Poly(sp.expand(replaced.coeff(symbol).subs(s, 1 / r)), r)
        for (m,), coefficient in in_r.terms():
            if coefficient == 0:
                continue
            # s^(-m) <-> integral of (T - tau)^(m-1)/(m-1)!, m >= 1: no boundary value
            assert m >= 1, "a non-negative power of s would need a boundary value"
            kernel += coefficient * (T - tau) ** (m - 1) / sp.factorial(m - 1) * (-tau) ** j
    return sp.expand(kernel)


def term_kernel_from_modulating_function(multiplicity: int, derivative: int):
    """Return ``(-1)^k phi^(k)(tau)`` with ``phi = (-1)^a tau^a (T - tau)^a / a!``.

    Parameters
    ----------
    multiplicity : int
        ``a``.
    derivative : int
        ``k``.

    Returns
    -------
    sympy.Expr
    """
    a, k = multiplicity, derivative
    phi = (-1) ** a * tau ** a * (T - tau) ** a / sp.factorial(a)
    return sp.expand((-1) ** k * sp.diff(phi, tau, k))


def _unit_term_kernel_poly(a, k):
    # 1/B(a+1, a+1) = (2a+1)!/(a!)^2
    norm = sp.factorial(2 * a + 1) / sp.factorial(a) ** 2
    psi = sp.Poly(u, u, domain=sp.QQ) ** a * sp.Poly(1 - u, u, domain=sp.QQ) ** a * norm
    return psi.diff((u, k)) * (-1) ** k


def unit_term_kernel(multiplicity: int, derivative: int):
    """Return the normalised term kernel ``(-1)^k psi_a^(k)(u)`` on the unit window.

    Parameters
    ----------
    multiplicity : int
        ``a``.
    derivative : int
        ``k``.

    Returns
    -------
    sympy.Expr
        A polynomial in ``u``.
    """
    return _unit_term_kernel_poly(multiplicity, derivative).as_expr()


@cache
def _chebyshev(degree):
    """Integer coefficients (ascending) of T_degree(x)."""
    if degree < 2:
        return (1,) if degree == 0 else (0, 1)
    previous, current = _chebyshev(degree - 2), _chebyshev(degree - 1)
    out = [0] * (degree + 1)
    for i, c in enumerate(current):
        out[i + 1] += 2 * c
    for i, c in enumerate(previous):
        out[i] -= c
    return tuple(out)


def chebyshev_coefficients(polynomial_in_u):
    """Exact Chebyshev coefficients (ascending) of a polynomial in ``u``, in ``x = 2u-1``.

    Exact rational arithmetic (:class:`fractions.Fraction`) on the coefficients.

    Parameters
    ----------
    polynomial_in_u : sympy.Expr or sympy.Poly
        Polynomial in ``u`` with rational coefficients.

    Returns
    -------
    list of sympy.Rational
    """
    in_u = polynomial_in_u if isinstance(polynomial_in_u, sp.Poly) else sp.Poly(
        polynomial_in_u, u, domain=sp.QQ)
    # u = (x + 1)/2, by Horner's rule on ascending coefficient lists in x
    in_x = [Fraction(0)]
    for c in in_u.all_coeffs():
        c = sp.Rational(c)
        shifted = [Fraction(0)] + in_x
        in_x = [(shifted[i] + (in_x[i] if i < len(in_x) else 0)) / 2
                for i in range(len(shifted))]
        in_x[0] += Fraction(int(c.p), int(c.q))
    while len(in_x) > 1 and in_x[-1] == 0:
        in_x.pop()
    result = [Fraction(0)] * len(in_x)
    # peel off the leading term: T_d has leading coefficient 2^(d-1) (1 for d = 0)
    for d in range(len(in_x) - 1, -1, -1):
        c = in_x[d] / (2 ** (d - 1) if d > 0 else 1)
        result[d] = c
        for i, t in enumerate(_chebyshev(d)):
            in_x[i] -= c * t
    return [sp.Rational(c.numerator, c.denominator) for c in result]


def kernel_table(max_multiplicity: int = MAX_MULTIPLICITY):
    """Kernel table ``{(a, k): exact Chebyshev coefficients}``, ``0 <= k <= a <= max``.

    Parameters
    ----------
    max_multiplicity : int
        Largest multiplicity ``a``.

    Returns
    -------
    dict
    """
    return {(a, k): chebyshev_coefficients(_unit_term_kernel_poly(a, k))
            for a in range(1, max_multiplicity + 1) for k in range(a + 1)}


def table_module_source(header: str, max_multiplicity: int = MAX_MULTIPLICITY) -> str:
    """Source of ``algid/_generated/modulating.py``: the runtime kernel table.

    Parameters
    ----------
    header : str
        The generated-code notice.
    max_multiplicity : int
        Largest multiplicity ``a``.

    Returns
    -------
    str
    """
    lines = ['"""Term kernels of the modulating-function form of the algebraic method.', "",
             "TERM_KERNELS[(a, k)] holds the Chebyshev coefficients (ascending, in",
             "x = 2u - 1 on the unit window u in [0, 1]) of the kernel (-1)^k psi_a^(k)(u),",
             "psi_a(u) = u^a (1 - u)^a / B(a + 1, a + 1), that multiplies the plain signal z",
             "of a term D^k z (a: kernel multiplicity, k: derivative order).", "",
             header, '"""', "",
             f"MAX_MULTIPLICITY = {max_multiplicity}", "", "TERM_KERNELS = {"]
    for (a, k), coefficients in kernel_table(max_multiplicity).items():
        values = ", ".join(repr(float(c)) for c in coefficients)
        lines.append(f"    ({a}, {k}): ({values},),")
    lines += ["}", ""]
    return "\n".join(lines)
