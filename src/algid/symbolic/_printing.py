"""Plain-text printing of SymPy expressions, as the derivation reports show them.

:func:`show` renders an equation, a chain of equal sides ``a = b = c`` or several
relations; :class:`TextPrinter` writes derivatives of a function in its own argument
with primes (``X''(s)``) and other derivatives as ``d^2/ds^2[...]``.
:func:`double_constants` prepares an expression for the code printers: every constant
a double.
"""

from __future__ import annotations

import math

import sympy as sp
from sympy.core.function import AppliedUndef
from sympy.printing.str import StrPrinter

from algid.errors import ModelError

__all__ = ["TextPrinter", "show", "double_constants"]


def _is_constant(expr):
    return expr.is_number and not (expr.is_Rational or expr.is_Float)


def _as_double(expr):
    value = complex(sp.N(expr, 30))
    if value.imag != 0 or not math.isfinite(value.real):
        raise ModelError(f"the constant {expr} of the estimator is not a finite real double")
    return sp.Float(value.real)


def double_constants(expr):
    """``expr`` with every constant a finite double, for the code printers.

    A constant that is not a rational nor a float (``pi``, ``sqrt(2)``, ``exp(1)``) is
    replaced by its nearest double, so that no printer writes a name or macro for it
    (``M_PI`` is not C99, ``pi`` not a NumPy name); a complex or non-finite constant is
    refused.

    Parameters
    ----------
    expr : sympy.Expr

    Returns
    -------
    sympy.Expr

    Raises
    ------
    ModelError
        A constant that is complex or beyond the range of a double.

    Examples
    --------
    >>> import sympy as sp
    >>> double_constants(sp.pi * sp.Symbol("x"))
    3.14159265358979*x
    """
    expr = sp.Integer(expr) if isinstance(expr, int) else expr
    if expr.has(sp.I, sp.zoo, sp.oo, -sp.oo, sp.nan):
        raise ModelError(f"the estimator has a constant that is not a finite real double "
                         f"in {str(expr)[:60]}")
    if any(_is_constant(a) for a in sp.preorder_traversal(expr)):
        expr = expr.replace(_is_constant, _as_double)
    for number in expr.atoms(sp.Rational, sp.Float):
        try:
            finite = math.isfinite(float(number))
        except OverflowError:
            finite = False
        if not finite:
            raise ModelError(f"the constant {str(number)[:30]} of the estimator is beyond "
                             f"the range of a double")
    return expr


class TextPrinter(StrPrinter):
    """Plain-text SymPy printer with primes for derivatives.

    ``X''(s)`` for derivatives of a function in its own argument, ``d^2/ds^2[...]`` for
    derivatives of compound expressions, ``[a, b; c, d]`` for matrices.

    Parameters
    ----------
    settings : dict, optional
        Settings of :class:`sympy.printing.str.StrPrinter`.
    """

    def _print_Derivative(self, expr):
        (var, n), *rest = expr.variable_count
        inner = expr.expr
        if not rest and isinstance(inner, AppliedUndef) and inner.args == (var,) and n <= 3:
            return f"{inner.func.__name__}{chr(39) * n}({self._print(var)})"
        order = "" if n == 1 else f"^{n}"
        return f"d{order}/d{self._print(var)}{order}[{self._print(inner)}]"

    def _print_ImmutableDenseMatrix(self, expr):
        return "[" + "; ".join(", ".join(self._print(e) for e in expr.row(i))
                               for i in range(expr.rows)) + "]"

    _print_MutableDenseMatrix = _print_ImmutableDenseMatrix


def show(obj) -> str:
    """Text form of an expression, an equation or several relations.

    Parameters
    ----------
    obj : sympy.Basic, tuple, str or None
        A tuple of expressions is a chain ``a = b = c``; a tuple of such tuples is
        several relations (joined by ``;``); strings pass through, ``None`` is empty,
        and an object with a ``text()`` method (a printed filter) renders itself.

    Returns
    -------
    str
        The text form.

    Examples
    --------
    >>> import sympy as sp
    >>> s = sp.Symbol("s")
    >>> X = sp.Function("X")(s)
    >>> show((sp.Derivative(X, (s, 2)), 2 * X))
    "X''(s) = 2*X(s)"
    """
    if obj is None:
        return ""
    if isinstance(obj, str):
        return obj
    if callable(getattr(obj, "text", None)):  # a printed filter renders itself
        return obj.text()
    if isinstance(obj, tuple):
        if obj and all(isinstance(o, tuple) for o in obj):
            return "; ".join(show(o) for o in obj)
        return " = ".join(show(o) for o in obj)
    return TextPrinter().doprint(obj)
