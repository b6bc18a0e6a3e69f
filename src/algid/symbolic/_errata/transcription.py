"""The paper's equations (1)-(33) and its footnote, transcribed as printed.

:data:`PRINTED` is data: each :class:`PrintedEquation` holds the printed form (SymPy
objects), the check that judges it and, where the PDF extraction was ambiguous, how it
was read.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache

import sympy as sp

from algid.symbolic._derivation import IteratedIntegral
from algid.symbolic._errata.checks import (
    check_against,
    check_cramer,
    check_definitions,
    check_differentiated,
    check_filtered,
    check_footnote,
    check_forces,
    check_identity,
    check_laplace,
    check_mass_relation,
    check_matrix_form,
    check_multiplied,
    check_transfer,
    msd_equation,
    msd_mass_equation,
    time_equation_check,
)
from algid.symbolic._errata.filter_checks import check_filter
from algid.symbolic._errata.notation import PHI, LowPass, PrintedFilter, nested_integral
from algid.symbolic._model import LAPLACE, TIME

__all__ = ["PrintedEquation", "PRINTED"]

t, s = TIME, LAPLACE
I = IteratedIntegral  # noqa: E741 - the integral operator, as in the paper


@dataclass(frozen=True)
class PrintedEquation:
    """One printed equation and the check that judges it.

    Attributes
    ----------
    number : str
        The paper's equation number (``"14"``) or ``"footnote 1"``.
    printed : object
        The transcription: a tuple of sides (``a = b = c``), a tuple of such tuples, or
        a :class:`PrintedFilter`.
    check : callable
        ``check(printed, filters) -> (correct, corrected, explanation)``; ``filters``
        are the printed filters (26)-(31) of the table, for their cross references.
    reading : str
        How an ambiguous extraction of the PDF was read (empty when unambiguous).
    """

    number: str
    printed: object
    check: Callable = field(compare=False, repr=False)
    reading: str = ""

    def evaluate(self, table=None):
        """Run the check of this equation.

        Parameters
        ----------
        table : tuple of PrintedEquation, optional
            The transcription the cross references point into (default :data:`PRINTED`).

        Returns
        -------
        tuple
            ``(correct, corrected, explanation)``: a bool, the corrected form as an object
            (``None`` when correct), and a one-line explanation.
        """
        table = PRINTED if table is None else table
        filters = tuple(e.printed for e in table if isinstance(e.printed, PrintedFilter))
        return _outcome(self.check, self.printed, filters)


@lru_cache(maxsize=512)
def _outcome(check, printed, filters):
    """The checks are pure functions of the printed form (and of the printed filters)."""
    return check(printed, filters)


def _table():
    B, K = sp.symbols("B K")
    m, c, k = sp.symbols("m c k")
    x, f = sp.Function("x")(t), sp.Function("f")(t)
    Force = sp.Function("F")(t)
    X, F = sp.Function("X")(s), sp.Function("F")(s)
    x0, xd0 = sp.symbols("x0 x_d0")
    F_s, F_d, sum_F, v, a, G = sp.symbols("F_s F_d sum_F v a G")
    p11, p12, p21, p22, q1, q2 = sp.symbols("p11 p12 p21 p22 q1 q2")
    th, V = sp.Function("theta_m")(t), sp.Function("V")(t)
    xd, xdd = sp.Derivative(x, t), sp.Derivative(x, (t, 2))

    def D2(e):
        return sp.Derivative(e, (s, 2))

    def Ds(e, n=1):
        return sp.Derivative(e, (s, n))

    def states(names):
        return sp.symbols(names)

    x1, x2, x3 = states("x1 x2 x3")
    y1, y2, y3 = states("y1 y2 y3")
    z1, z2, z3 = states("z1 z2 z3")
    xi1, xi2, xi3, xi4 = states("xi1 xi2 xi3 xi4")
    rho1, rho2, rho3, rho4 = states("rho1 rho2 rho3 rho4")
    psi1, psi2, psi3, psi4 = states("psi1 psi2 psi3 psi4")
    den = p11 * p22 - p12 * p21
    Pm = sp.Matrix([[p11, p12], [p21, p22]])
    E = PrintedEquation
    return (
        E("1", ((F_s, -k * x),), check_forces),
        E("2", ((F_d, -c * v, -c * xd, -c * xd),), check_forces,
          "the dot and dx/dt notations are both x'(t); v is the velocity x'(t)"),
        E("3", ((sum_F, m * a, m * xdd, m * xdd),), check_forces,
          "a is the acceleration x''(t); sum_F is the sum of the forces on the mass, "
          "F + F_s + F_d"),
        E("4", ((m * xdd + c * xd + k * x, Force),),
          check_against(msd_mass_equation, "the model m x'' + c x' + k x = F (msd_mass)")),
        E("5", ((xdd + c / m * xd + k / m * x, Force / m),),
          check_against(msd_mass_equation, "the model m x'' + c x' + k x = F (msd_mass)")),
        E("6", ((xdd + B * xd + K * x, f),),
          check_against(msd_equation, "the model x'' + B x' + K x = f (msd)")),
        E("7", ((G, X / F, 1 / (s**2 + B * s + K)),), check_transfer,
          "the paper's x(s), f(s) are X(s), F(s) here"),
        E("8", ((k, K * m),), check_mass_relation),
        E("9", ((c, B * m),), check_mass_relation),
        E("10", ((s**2 * X - s * x0 - xd0 + B * (s * X - x0) + K * X, F),), check_laplace,
          "x(0), x'(0) are x0, x_d0"),
        E("11", ((D2(s**2 * X) + B * D2(s**2 * X), D2(F - K * X)),), check_differentiated),
        E("12", ((D2(s**2 * X), 2 * X + 4 * s * Ds(X) + s**2 * Ds(X, 2)),), check_identity),
        E("13", ((D2(s * X), 2 * Ds(X) + s * Ds(X, 2)),), check_identity),
        E("14", ((B * (2 * s**-2 * Ds(X) + s**-1 * Ds(X, 2)) + K * s**-2 * Ds(X, 2),
                  s**-2 * Ds(F, 2) - 2 * s**-2 - 4 * s**-1),), check_multiplied,
          "the right side is printed '- 2s^-2 - 4s^-1' with no x(s) or dx/ds"),
        E("15", ((B * p11 - K * p12, -q1),), time_equation_check(rows=(0,))),
        E("16", ((p11, -2 * I(t * x, 2) + I(t**2 * x, 1)),), check_definitions),
        E("17", ((p12, I(t**2 * x, 2)),), check_definitions),
        E("18", ((q1, I(t**2 * f - 2 * x, 2) + 4 * I(t * x, 1) - t**2 * x),), check_definitions),
        E("19", ((sp.MatMul(sp.MatrixSymbol("P", 2, 2), sp.MatrixSymbol("X", 2, 1)),
                  sp.MatrixSymbol("Q", 2, 1)),), check_matrix_form,
          "X is the column of the unknowns (B, K)"),
        E("20", ((sp.MatMul(sp.ImmutableMatrix(Pm), sp.ImmutableMatrix([B, K])),
                  sp.ImmutableMatrix([q1, q2])),), time_equation_check(rows=(0, 1))),
        E("21", ((p21, I(p11, 1), -2 * I(t * x, 3) + I(t**2 * x, 2)),), check_definitions,
          "p21 = int p11 is the sentence before (21)"),
        E("22", ((p22, I(p12, 1)), (p12, I(t**2 * x, 3))), check_definitions,
          "p22 = int p12 is the sentence before (21); the numbered line reads "
          "'p12(t) = int^(3) t^2 x'"),
        E("23", ((q2, I(q1, 1), I(t**2 * f - 2 * x, 3) + 4 * I(t * x, 2) - I(t**2 * x, 1)),),
          check_definitions,
          "q2 = int q1 is the sentence before (21); the stray ')' at the end of (23) is dropped"),
        E("24", ((K, (-p21 * q1 + p11 * q2) / den),), check_cramer),
        E("25", ((B, (p22 * q1 - p12 * q2) / den),), check_cramer),
        E("26", PrintedFilter("p11", x1, ((x1, -t**3 * th + x2), (x2, 6 * t**2 * th + x3),
                                          (x3, -6 * t * th))), check_filter),
        E("27", PrintedFilter("p12", y1, ((y1, y2), (y2, t**3 * V + y3), (y3, -3 * t**2 * V))),
          check_filter),
        E("28", PrintedFilter("q11", t**3 * th + z1,
                              ((z1, -9 * t**2 * th + z2), (z2, 18 * t * th + z3),
                               (x3, -6 * th)), renamed=((x3, z3),)), check_filter,
          "the output line is extracted as 'q11(t) = t3θm(t)z1', read as t^3 theta_m + z1 "
          "(a product would not be a linear filter); the last line is printed as x3' (x3 is "
          "a state of (26)) and read as z3'; q11 is the paper's name of q1"),
        E("29", PrintedFilter("p21", xi1, ((xi1, xi2), (xi2, -t**3 * th + xi3),
                                           (xi3, 6 * t**2 * th + xi4), (xi4, -6 * t * th)),
                              where=((xi2, "p11"),)), check_filter),
        E("30", PrintedFilter("p22", rho1, ((rho1, rho2), (rho2, rho3), (rho3, t**3 * V + rho4),
                                            (rho4, -3 * t**2 * V)),
                              where=((rho2, "p12"),)), check_filter),
        E("31", PrintedFilter("q21", psi1, ((psi1, t**3 * th + psi2), (psi2, -9 * t**2 * th + psi3),
                                            (psi3, 18 * t * th + psi4), (psi4, -6 * th)),
                              where=((psi2, "q11"),)), check_filter,
          "q21 is the paper's name of q2"),
        E("32", ((K, LowPass(-p21 * q1 + p11 * q2) / LowPass(den)),), check_filtered,
          "F(s)[.] is the filter F(s) = 1/s^p of Remark 2.1 applied to a time signal"),
        E("33", ((B, LowPass(p22 * q1 - p12 * q2) / LowPass(den)),), check_filtered,
          "F(s)[.] is the filter F(s) = 1/s^p of Remark 2.1 applied to a time signal"),
        E("footnote 1", tuple((I(PHI(t), n), nested_integral(PHI, n)) for n in (1, 2, 3))
          + ((I(PHI(t), 1), sp.Integral(PHI(sp.Symbol("sigma")), (sp.Symbol("sigma"), 0, t))),),
          check_footnote,
          "the general n-fold formula is transcribed for n = 1, 2, 3"),
    )


#: The printed equations of Section 2, in the paper's order.
PRINTED = _table()
