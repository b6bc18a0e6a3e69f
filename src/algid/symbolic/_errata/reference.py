"""The references the errata checks compare against: the derivation of the built-in
model ``msd``, its entries of ``P`` and ``Q``, an exact trajectory, and the exact
comparisons of expressions."""

from __future__ import annotations

from functools import cache

import sympy as sp
from sympy.core.function import AppliedUndef

from algid.symbolic._builtin_models import builtin_model
from algid.symbolic._derivation import IteratedIntegral, derive
from algid.symbolic._model import LAPLACE, TIME
from algid.symbolic._realization import entries, integrate_from_zero, kernel_terms

__all__ = ["reference_derivation", "entry_labels", "entry_values", "trajectory",
           "value_on_trajectory", "is_zero", "signal_atoms", "is_constant"]

t, s = TIME, LAPLACE


@cache
def reference_derivation():
    """The derivation of the built-in model ``msd`` (cached)."""
    return derive(builtin_model("msd"))


@cache
def entry_labels():
    """Entry symbol ``p11``, ..., ``q2`` -> its kernel combination from the derivation."""
    return {sp.Symbol(name): expr for name, expr in entries(reference_derivation()).items()}


@cache
def trajectory():
    """An exact closed-form trajectory of ``x'' + B x' + K x = f``, B and K symbolic.

    ``x(t) = 1 + 2 exp(-t) - t exp(-2 t)`` (so ``x(0) = 3``, ``x'(0) = -3``) and
    ``f = x'' + B x' + K x``: an identity that holds on it for symbolic ``B``, ``K``
    holds for every value of the parameters, and the nonzero initial conditions test
    that they were eliminated.

    Returns
    -------
    dict
        ``{"x": x(t), "f": f(t)}``.
    """
    B, K = reference_derivation().parameters
    x = 1 + 2 * sp.exp(-t) - t * sp.exp(-2 * t)
    return {"x": x, "f": sp.expand(x.diff(t, 2) + B * x.diff(t) + K * x)}


@cache
def _kernel_value(signal, power, order):
    g = t**power * trajectory()[signal]
    for _ in range(order):
        g = integrate_from_zero(g)
    return g


def value_on_trajectory(expr):
    """Value on :func:`trajectory` of a kernel combination.

    Parameters
    ----------
    expr : sympy.Expr
        A linear combination of iterated integrals of the signals.

    Returns
    -------
    sympy.Expr
        A function of ``t`` (and of ``B``, ``K``).
    """
    return sp.expand(sum((c * _kernel_value(*key) for key, c in kernel_terms(expr).items()),
                         sp.Integer(0)))


@cache
def entry_values():
    return {sym: value_on_trajectory(expr) for sym, expr in entry_labels().items()}


_PROBES = (sp.Rational(7, 10), sp.Rational(13, 10), sp.Rational(29, 10))


def is_zero(expr) -> bool:
    """Whether ``expr`` vanishes identically.

    A nonzero value at a fixed probe point proves it does not (and is much faster than
    :func:`sympy.simplify` on large expressions); otherwise SymPy decides.

    Parameters
    ----------
    expr : sympy.Expr
        The expression.

    Returns
    -------
    bool
        Whether it is identically zero.
    """
    expr = sp.expand(expr)
    if expr == 0:
        return True
    symbols = sorted(expr.free_symbols, key=str)
    if not signal_atoms(expr) and not expr.has(sp.MatrixSymbol):
        for shift in range(len(_PROBES)):
            point = {sym: _PROBES[(i + shift) % len(_PROBES)] for i, sym in enumerate(symbols)}
            value = sp.N(expr.xreplace(point), 30)
            if value.is_number and abs(value) > 1e-12:
                return False
    return sp.simplify(expr) == 0


def signal_atoms(expr):
    """The signals in an expression: functions, derivatives and iterated integrals.

    Parameters
    ----------
    expr : sympy.Expr
        The expression.

    Returns
    -------
    set
        The atoms.
    """
    return expr.atoms(AppliedUndef, sp.Derivative, IteratedIntegral)


def is_constant(expr, forbidden=()) -> bool:
    """Whether an expression is free of the signals, ``s``, ``t`` and ``forbidden``.

    Parameters
    ----------
    expr : sympy.Expr
        The expression.
    forbidden : iterable of sympy.Symbol, optional
        Further symbols that must not appear.

    Returns
    -------
    bool
        Whether it is a constant.
    """
    return not signal_atoms(expr) and not (expr.free_symbols & ({s, t} | set(forbidden)))
