"""Plain-text printing of SymPy expressions, as the derivation reports show them.

:func:`show` renders an equation, a chain of equal sides ``a = b = c`` or several
relations; :class:`TextPrinter` writes derivatives of a function in its own argument
with primes (``X''(s)``) and other derivatives as ``d^2/ds^2[...]``.
"""

from __future__ import annotations

from sympy.core.function import AppliedUndef
from sympy.printing.str import StrPrinter

__all__ = ["TextPrinter", "show"]


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
