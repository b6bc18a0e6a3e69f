"""Errata of the printed equations of Becedas et al. (WCECS 2007), Section 2.

The paper's equations (1)-(33) and its footnote on iterated integrals are transcribed
below *as printed* into SymPy objects (:data:`PRINTED`).  The transcription is data;
every verdict is computed: each entry carries a check that compares the printed form
with a first-principles computation (Newton's law and the model equations, SymPy's
Laplace transform, differentiation in ``s``) or with what the derivation engine
(:func:`algid.symbolic.derive` on the built-in model ``msd``) produces, and
equations involving iterated integrals of the signals are also evaluated on an exact
closed-form trajectory of the model.  Where an equation is wrong, the check builds the
corrected form and a one-line explanation of the difference.

Notation of the transcription: ``x(t)``, ``f(t)`` are the displacement and the input
``F/m``; ``X(s)``, ``F(s)`` their Laplace transforms (the paper writes ``x(s)``,
``f(s)``); ``x0 = x(0)``, ``x_d0 = x'(0)``; ``int^n(g)`` is
:class:`~algid.symbolic.IteratedIntegral` (the ``n``-fold integral from 0 to
``t``); ``p11, ..., q2`` name the entries of ``P`` and ``Q``; primes are derivatives
with respect to the function's own argument.
"""

from algid.symbolic._errata.notation import LowPass, PrintedFilter
from algid.symbolic._errata.reference import trajectory
from algid.symbolic._errata.report import (
                                          EquationVerdict,
                                          check_equation,
                                          errata_report,
                                          format_errata,
)
from algid.symbolic._errata.transcription import PRINTED, PrintedEquation
from algid.symbolic._printing import show

__all__ = ["EquationVerdict", "PrintedEquation", "PrintedFilter", "LowPass", "PRINTED",
           "check_equation", "errata_report", "format_errata", "show", "trajectory"]
