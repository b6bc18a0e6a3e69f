"""The checks of the printed time-varying filters (26)-(31).

Each printed filter is integrated back to its integral form and compared with the entry
of ``P`` or ``Q`` it claims to realise; the corrected form is the realisation of that
entry (:func:`algid.symbolic._realization.realize`).
"""

from __future__ import annotations

from functools import cache

import sympy as sp

from algid.symbolic._errata.reference import entry_labels, reference_derivation
from algid.symbolic._model import LAPLACE, TIME
from algid.symbolic._printing import show
from algid.symbolic._realization import (
    from_kernel_terms,
    kernel_terms,
    realize,
    same_integral_form,
    solve_state_equations,
    undefined_states,
)

__all__ = ["check_filter"]

t, s = TIME, LAPLACE


# ------------------------------------------------ checks: the filters (26)-(31)


def _capital(name):
    return name[0].upper() + name[1:]


def _laplace_form(expr):
    """Map a kernel combination back to ``s``: ``int^k(t^p u)`` -> ``s^-k (-d/ds)^p U(s)``."""
    total = sp.Integer(0)
    for (sig, p, k), c in kernel_terms(expr).items():
        U = sp.Function(_capital(sig))(s)
        total += c * s**(-k) * (-1)**p * (U if p == 0 else sp.Derivative(U, (s, p)))
    return total


def _describe_laplace(expr):
    """``expr`` in the ``s`` domain as a sum of ``c s^j d^n/ds^n[s^m U(s)]``, one per signal."""
    total = sp.Integer(0)
    terms = kernel_terms(expr)
    for sig in sorted({key[0] for key in terms}):
        L = _laplace_form(from_kernel_terms({k: v for k, v in terms.items() if k[0] == sig}))
        U = sp.Function(_capital(sig))(s)
        top = max(key[1] for key in terms if key[0] == sig) + 1
        dummies = {sp.Derivative(U, (s, j)): sp.Dummy() for j in range(1, top + 1)}
        dummies[U] = sp.Dummy()
        found = None
        for n in range(1, top + 1):
            for m in range(n + 1):
                cand = sp.expand(sp.diff(s**m * U, s, n))
                ratio = sp.cancel(L.xreplace(dummies) / cand.xreplace(dummies))
                coeff, power = ratio.as_coeff_exponent(s)
                if not (ratio.free_symbols - {s}) and not coeff.has(s) and coeff != 0:
                    found = coeff * s**power * sp.Derivative(s**m * U, (s, n))
                    break
            if found is not None:
                break
        total += found if found is not None else L
    return total


_PAPER_NAMES = {"q11": "q1", "q21": "q2"}  # the paper's names of q1, q2 in (28), (31)


@cache
def _realization():
    real = realize(reference_derivation(), layout="entries")
    if not real.check():  # pragma: no cover - guarded by the tests of realization
        raise AssertionError("the realisation does not reproduce P and Q")
    return real


def _printed_filter_form(flt):
    """Integral form of a printed filter's output and states (after the reading)."""
    eqs = dict(flt.equations)
    renames = dict(flt.renamed)
    eqs = {renames.get(z, z): rhs for z, rhs in eqs.items()}
    return solve_state_equations(eqs, {flt.output: flt.expression})


def check_filter(printed, filters):
    """Check a printed filter (26)-(31) against the entry it claims to realise.

    Parameters
    ----------
    printed : PrintedFilter
        The printed filter.
    filters : tuple of PrintedFilter
        All printed filters, for the "where" remarks.

    Returns
    -------
    tuple
        ``(correct, corrected, explanation)``; the corrected form is the realisation
        of the entry.
    """
    flt = printed
    model = reference_derivation().model
    name = _PAPER_NAMES.get(flt.output, flt.output)
    target = entry_labels()[sp.Symbol(name)]
    issues = []
    missing = undefined_states(dict(flt.equations), {flt.output: flt.expression})
    if missing:
        renames = dict(flt.renamed)
        read = "; ".join(f"the line {z}' is read as {renames[z]}'" for z in renames)
        issues.append(f"no equation for {', '.join(map(str, missing))} ({read})")
    form = _printed_filter_form(flt)
    out = form[flt.output]
    used = sorted({key[0] for key in kernel_terms(out)})
    ours = [model.output, model.input]
    foreign = [u for u in used if u not in ours]
    # where-remarks: a state equal to another printed filter's output
    printed_filters = {other.output: other for other in filters}
    for z, other in flt.where:
        if other not in printed_filters:
            issues.append(f"'where {z} = {other}' names no printed filter")
            continue
        value = _printed_filter_form(printed_filters[other])[other]
        if not same_integral_form(form[z], value):
            issues.append(f"'where {z} = {other}' does not hold: {z} = {show(form[z])}, "
                          f"{other} = {show(value)}")
    same = not foreign and same_integral_form(out, target)
    corrected = _realization().format([name])
    if same and not issues:
        return True, None, f"realises {name} = {show(target)}"
    texts = []
    if foreign:
        # every signal of the printed filters that this model does not have
        alien = sorted({key[0] for other in filters
                        for key in kernel_terms(_printed_filter_form(other)[other.output])}
                       - set(ours), key=str.lower)
        texts.append("a filter of another model ((26)-(31) use "
                     f"{', '.join(f'{u}(t)' for u in alien)}"
                     + (", a DC motor's angle and voltage," if set(alien) == {"theta_m", "V"}
                        else "")
                     + " not x(t), f(t))")
    if not same_integral_form(out.xreplace(_signal_reading()), target):
        texts.append(f"it computes {show(out)} = {show(_describe_laplace(out))}, not "
                     f"{name} = {show(target)} = {show(_describe_laplace(target))} (not even "
                     "with theta_m read as x, V as f)")
    texts += issues
    return False, corrected, "; ".join(texts)


@cache
def _signal_reading():
    """The printed filters' signals read as this model's: the measured angle theta_m as
    the measured output x, the voltage V as the input f (the most favourable reading)."""
    model = reference_derivation().model
    return {sp.Function("theta_m")(t): model.output_function,
            sp.Function("V")(t): model.input_function}
