"""Notation of the transcription: the low-pass filter of (32), (33), the printed
time-varying filters (26)-(31) and the footnote's nested integrals."""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from algid.symbolic._model import TIME
from algid.symbolic._printing import show

__all__ = ["LowPass", "PrintedFilter", "PHI", "nested_integral"]

t = TIME


class LowPass(sp.Function):
    """``F(s)[e]``: the invariant low-pass filter of (32), (33) applied to ``e``.

    The paper writes the filter in the frequency domain and its argument in the time
    domain; Remark 2.1 takes ``F(s) = 1/s**p``, that is ``p``-fold integration from 0.

    Parameters
    ----------
    *args : sympy.Expr
        The filtered expression ``e``.
    """

    nargs = 1

    def _sympystr(self, printer):
        return f"F(s)[{printer._print(self.args[0])}]"


@dataclass(frozen=True)
class PrintedFilter:
    """A time-varying filter as printed in (26)-(31).

    Attributes
    ----------
    output : str
        The printed name of the entry it realises (``p11``, ``q11``, ...).
    expression : sympy.Expr
        The output line, in the states and the signals.
    equations : tuple
        ``(state, right-hand side)`` pairs, one per printed state equation.
    where : tuple
        ``(state, entry name)`` pairs of the printed remarks "where state = entry".
    renamed : tuple
        ``(printed state, read as)``: a state symbol the reading renames.
    """

    output: str
    expression: sp.Expr
    equations: tuple
    where: tuple = ()
    renamed: tuple = ()

    def text(self) -> str:
        """The filter as one line: output, state equations and "where" remarks.

        Returns
        -------
        str
            The lines joined by ``"; "``.
        """
        lines = [f"{self.output}(t) = {show(self.expression)}"]
        lines += [f"{z}' = {show(rhs)}" for z, rhs in self.equations]
        lines += [f"where {z} = {name}" for z, name in self.where]
        return "; ".join(lines)


def nested_integral(phi, n):
    """The footnote's iterated integral, as printed.

    ``int_0^t int_0^sigma1 ... int_0^sigma(n-1) phi(sigma_n) dsigma_n ... dsigma_1``.

    Parameters
    ----------
    phi : sympy.FunctionClass
        The integrand.
    n : int
        Number of integrals.

    Returns
    -------
    sympy.Integral
        Unevaluated nested integrals.
    """
    sig = sp.symbols(f"sigma1:{n + 1}")
    expr = phi(sig[-1])
    for i in range(n - 1, -1, -1):
        upper = t if i == 0 else sig[i - 1]
        expr = sp.Integral(expr, (sig[i], 0, upper))
    return expr


#: The test function of the footnote's integrals.
PHI = sp.Function("phi")
