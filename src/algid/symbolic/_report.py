"""The derivation written out step by step, as a student would read it.

:func:`derivation_report` renders a :class:`~algid.symbolic.Derivation` as
plain text, as a LaTeX document or as Markdown with ``$$`` display maths.  Every display
equation is a single line of maths that matplotlib's mathtext can also render (no
matrix environments), which the tests check.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from algid.errors import ModelError
from algid.symbolic._builtin_models import builtin_model
from algid.symbolic._derivation import EXPANDED_CRAMER_MAX, Derivation, derive
from algid.symbolic._model import LinearODEModel

__all__ = ["Step", "derivation_steps", "derivation_report", "FORMATS"]

#: Output formats of :func:`derivation_report`.
FORMATS = ("text", "latex", "markdown")


@dataclass(frozen=True)
class Step:
    """One step of the derivation: a heading, an explanation and display equations.

    Parameters
    ----------
    title : str
        The heading.
    text : str
        The explanation.
    equations : tuple
        ``(lhs, rhs)`` pairs of SymPy objects (or ``(None, expr)`` for an expression
        shown alone).
    """

    title: str
    text: str
    equations: tuple


def _ic_names(d: Derivation):
    names = {}
    for sym in d.initial_conditions:
        base, _, rest = sym.name[:-1].partition("_")  # x0 -> x, x_d0 -> x, d
        order = rest.count("d") if rest else 0
        names[sym] = (base, order)
    return names


def _latex(expr, d: Derivation) -> str:
    names = {}
    for sym, (base, order) in _ic_names(d).items():
        names[sym] = (rf"\dot{{{base}}}(0)" if order == 1 else
                      rf"\ddot{{{base}}}(0)" if order == 2 else
                      f"{base}^{{({order})}}(0)" if order else f"{base}(0)")
    return sp.latex(expr, symbol_names=names)


def _text(expr, d: Derivation) -> str:
    subs = {sym: sp.Symbol(f"{base}{chr(39) * order}(0)")
            for sym, (base, order) in _ic_names(d).items()}
    return sp.sstr(expr.xreplace(subs) if hasattr(expr, "xreplace") else expr)


def derivation_steps(d: Derivation) -> list:
    """The derivation as a list of steps.

    Parameters
    ----------
    d : Derivation
        The derivation.

    Returns
    -------
    list of Step
        In reading order.
    """
    model = d.model
    X, _ = d.transforms
    params = ", ".join(str(p) for p in model.parameters)
    ode = model.ode()
    steps = [Step("Model",
                  f"A linear model with unknown parameters {params}; the input {model.input} "
                  f"and the output {model.output} are measured.",
                  ((ode.lhs, ode.rhs),)),
             Step("Laplace transform",
                  "Transform with the initial conditions kept as unknown symbols "
                  f"({', '.join(_text(c, d) for c in d.initial_conditions)}).",
                  ((d.laplace, sp.Integer(0)),))]
    n = d.n_derivatives
    for i in range(1, n + 1):
        left = d.differentiated[i].free_symbols & set(d.initial_conditions)
        note = ("The initial conditions are gone: the estimator does not depend on them."
                if not left else
                f"Still present: {', '.join(_text(c, d) for c in sorted(left, key=str))}.")
        steps.append(Step(f"Derivative {i} with respect to s",
                          f"Differentiate with respect to s ({i} of {n}); "
                          "a polynomial of degree "
                          f"{n - 1} in s (the initial conditions) vanishes after {n}. {note}",
                          ((d.differentiated[i], sp.Integer(0)),)))
    steps.append(Step(f"Multiplication by s^-{d.s_power}",
                      "Positive powers of s are derivatives in time; multiplying by "
                      f"s^-{d.s_power} leaves only integrations.",
                      ((d.multiplied, sp.Integer(0)),)))
    table = (f"Operator table: d^k/ds^k {X} maps to (-t)^k {model.output}(t), and s^-k to the "
             "k-fold integral from 0 to t (written int^(k)); no inverse Laplace transform "
             "is needed.")
    steps.append(Step("Back to the time domain", table, ((d.time_equations[0], sp.Integer(0)),)))
    if len(d.time_equations) > 1:
        steps.append(Step("More equations",
                          f"{len(model.parameters)} unknowns need {len(model.parameters)} "
                          "equations: "
                          "integrate the equation again (multiply by 1/s).",
                          tuple((e, sp.Integer(0)) for e in d.time_equations[1:])))
    Ps, Qs = d.entry_symbols()
    eqs = []
    for i in range(d.P.shape[0]):
        lhs = sum(Ps[i, j] * p for j, p in enumerate(model.parameters))
        eqs.append((lhs, Qs[i]))
    entries = tuple((Ps[i, j], d.P[i, j]) for i in range(d.P.shape[0]) for j in range(d.P.shape[1]))
    entries += tuple((Qs[i], d.Q[i]) for i in range(d.Q.shape[0]))
    steps.append(Step("Linear system P theta = Q",
                      "Each equation is linear in the unknowns; P and Q are filtered signals "
                      "computed on-line from the measurements.", tuple(eqs) + entries))
    if d.P.shape[0] == d.P.shape[1] and d.P.shape[0] > EXPANDED_CRAMER_MAX:
        # the expanded determinants would have n! products: named, not written out
        den = sp.Symbol("det(P)")
        nums = [sp.Symbol(f"det(P_{j + 1})") for j in range(d.P.shape[1])]
        steps.append(Step("Solution",
                          "Cramer's rule: P_j is P with its column j replaced by Q (the "
                          "generated code computes the determinants from shared minors); "
                          "the estimate is defined wherever det P is not zero.",
                          tuple((p, num / den) for p, num in zip(model.parameters, nums))))
    elif d.P.shape[0] == d.P.shape[1]:
        nums, den = d.cramer()
        steps.append(Step("Solution",
                          "Cramer's rule; the estimate is defined wherever det P is not zero: "
                          "for every small t > 0, and afterwards except at isolated instants "
                          "where det P crosses zero.  The same low-pass filter (for example "
                          "1/s^p) may be applied to each numerator and to the denominator "
                          "without changing the quotient.",
                          tuple((p, num / den) for p, num in zip(model.parameters, nums))))
    return steps


def _render_text(steps, d):
    out = [f"Algebraic estimator of model {d.model.name!r}: {d.model.equation_text()}", ""]
    for k, step in enumerate(steps, 1):
        out += [f"{k}. {step.title}", f"   {step.text}"]
        for lhs, rhs in step.equations:
            out.append(f"     {_text(lhs, d)} = {_text(rhs, d)}")
        out.append("")
    return "\n".join(out)


def _display_latex(lhs, rhs, d):
    return f"{_latex(lhs, d)} = {_latex(rhs, d)}"


def _escape(text):
    return (text.replace("\\", r"\textbackslash{}").replace("_", r"\_").replace("^", r"\^{}")
            .replace("&", r"\&").replace("%", r"\%").replace("#", r"\#"))


def _render_latex(steps, d):
    out = [r"\documentclass{article}", r"\usepackage{amsmath}", r"\allowdisplaybreaks",
           r"\begin{document}",
           rf"\section*{{Algebraic estimator of model \texttt{{{_escape(d.model.name)}}}}}"]
    for step in steps:
        out.append(rf"\subsection*{{{_escape(step.title)}}}")
        out.append(_escape(step.text))
        for lhs, rhs in step.equations:
            out += [r"\begin{multline*}", _display_latex(lhs, rhs, d), r"\end{multline*}"]
    out.append(r"\end{document}")
    return "\n".join(out) + "\n"


def _render_markdown(steps, d):
    out = [f"# Algebraic estimator of model `{d.model.name}`", ""]
    for k, step in enumerate(steps, 1):
        out += [f"## {k}. {step.title}", "", step.text, ""]
        for lhs, rhs in step.equations:
            out += ["$$", _display_latex(lhs, rhs, d), "$$", ""]
    return "\n".join(out)


def display_equations(model, fmt="latex"):
    """Every display equation of the report as a LaTeX string (for checking rendering)."""
    d = derive(_as_model(model))
    return [_display_latex(lhs, rhs, d) for step in derivation_steps(d)
            for lhs, rhs in step.equations]


def _as_model(model):
    if isinstance(model, LinearODEModel):
        return model
    if isinstance(model, Derivation):
        return model.model
    return builtin_model(model)


def derivation_report(model="msd", fmt="text") -> str:
    """The derivation of ``model``'s estimator, step by step.

    Parameters
    ----------
    model : str, LinearODEModel or Derivation
        A built-in model name (``"msd"``, ``"msd_mass"``), or a user's model.
    fmt : {"text", "latex", "markdown"}
        Plain text, a complete LaTeX document, or Markdown with ``$$`` maths.

    Returns
    -------
    str

    Examples
    --------
    >>> from algid.symbolic import derivation_report
    >>> print(derivation_report("msd").splitlines()[0])
    Algebraic estimator of model 'msd': x'' + B*x' + K*x = f
    >>> derivation_report("msd", fmt="markdown").splitlines()[0]
    '# Algebraic estimator of model `msd`'
    """
    if fmt not in FORMATS:
        raise ModelError(f"unknown format {fmt!r} (known: {', '.join(FORMATS)})")
    d = model if isinstance(model, Derivation) else derive(_as_model(model))
    steps = derivation_steps(d)
    render = {"text": _render_text, "latex": _render_latex, "markdown": _render_markdown}[fmt]
    return render(steps, d)
