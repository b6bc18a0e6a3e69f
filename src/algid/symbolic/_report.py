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
from algid.models._model import Model
from algid.models._system import SystemModel
from algid.symbolic._builtin_models import builtin_model
from algid.symbolic._channels import ChannelModel
from algid.symbolic._derivation import EXPANDED_CRAMER_MAX, Derivation, derive
from algid.symbolic._model import TIME, LinearODEModel
from algid.symbolic._system_derivation import SystemDerivation

__all__ = ["Step", "derivation_steps", "system_steps", "derivation_report", "FORMATS"]

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
    """Each initial condition's signal and derivative order, from the names the
    derivation gives them (``x0``, ``x_d0``, ``x_dd0``), matched against its channels
    (a signal may have ``_`` in its name)."""
    spelled = {f"{channel}{'_' + 'd' * k if k else ''}0": (channel, k)
               for channel in d.model.channels for k in range(d.model.order + 1)}
    return {sym: spelled[sym.name] for sym in d.initial_conditions}


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


def _channel_model_step(model, params):
    """The "Model" step of an equation in several signals (a ChannelModel)."""
    lhs = sp.Add(*(coefficient * (sp.Function(channel)(TIME).diff(TIME, derivative)
                                  if derivative else sp.Function(channel)(TIME))
                   for coefficient, channel, derivative in model.channel_terms()))
    measured = ", ".join(model.model.signals)
    text = (f"An equation linear in its unknown parameters {params}, written with every term "
            f"on the left; the signals {measured} are measured")
    factors = model.factor_texts()
    if factors:
        text += " (" + ", ".join(f"{channel} stands for {factor}"
                                 for channel, factor in factors.items()) + ")"
    return Step("Model", text + ".", ((lhs, sp.Integer(0)),))


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
    if hasattr(model, "ode"):
        ode = model.ode()
        first = Step("Model",
                     f"A linear model with unknown parameters {params}; the input "
                     f"{model.input} and the output {model.output} are measured.",
                     ((ode.lhs, ode.rhs),))
        table = (f"Operator table: d^k/ds^k {X} maps to (-t)^k {model.output}(t), and s^-k "
                 "to the k-fold integral from 0 to t (written int^(k)); no inverse Laplace "
                 "transform is needed.")
    else:
        first = _channel_model_step(model, params)
        table = ("Operator table: d^k/ds^k of a signal's transform Z(s) maps to (-t)^k z(t), "
                 "and s^-k to the k-fold integral from 0 to t (written int^(k)); no "
                 "inverse Laplace transform is needed.")
    steps = [first,
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
    if all(q == 0 for q in d.Q):
        steps.append(Step("No known term",
                          "Every term has an unknown parameter, so Q = 0: P theta = 0 fixes "
                          "only the ratios of the parameters (theta = 0 solves it).  In a "
                          "system, a parameter this equation shares with another one fixes "
                          "the scale.", ()))
    elif d.P.shape[0] == d.P.shape[1] and d.P.shape[0] > EXPANDED_CRAMER_MAX:
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


def _render_text(title, sections):
    out = [title, ""]
    for heading, prefix, steps, d in sections:
        if heading:
            out += [heading, ""]
        for k, step in enumerate(steps, 1):
            out += [f"{prefix}{k}. {step.title}", f"   {step.text}"]
            for lhs, rhs in step.equations:
                out.append(f"     {_text(lhs, d)} = {_text(rhs, d)}")
            out.append("")
    return "\n".join(out)


def _display_latex(lhs, rhs, d):
    return f"{_latex(lhs, d)} = {_latex(rhs, d)}"


def _escape(text):
    return (text.replace("\\", r"\textbackslash{}").replace("_", r"\_").replace("^", r"\^{}")
            .replace("&", r"\&").replace("%", r"\%").replace("#", r"\#")
            .replace("<", r"\textless{}").replace(">", r"\textgreater{}"))


def _render_latex(title, sections):
    out = [r"\documentclass{article}", r"\usepackage{amsmath}", r"\allowdisplaybreaks",
           r"\begin{document}", rf"\section*{{{title}}}"]
    for heading, _, steps, d in sections:
        if heading:
            out.append(rf"\subsection*{{{_escape(heading)}}}")
        for step in steps:
            out.append(rf"\{'sub' if heading else ''}subsection*{{{_escape(step.title)}}}")
            out.append(_escape(step.text))
            for lhs, rhs in step.equations:
                out += [r"\begin{multline*}", _display_latex(lhs, rhs, d), r"\end{multline*}"]
    out.append(r"\end{document}")
    return "\n".join(out) + "\n"


def _render_markdown(title, sections):
    out = [f"# {title}", ""]
    for heading, prefix, steps, d in sections:
        if heading:
            out += [f"## {heading}", ""]
        for k, step in enumerate(steps, 1):
            # (y**3 and _x in the text are no emphasis)
            text = step.text.replace("*", r"\*").replace("_", r"\_")
            out += [f"{'###' if heading else '##'} {prefix}{k}. {step.title}", "", text, ""]
            for lhs, rhs in step.equations:
                out += ["$$", _display_latex(lhs, rhs, d), "$$", ""]
    return "\n".join(out)


def _titles(d, fmt):
    """The report's title of one equation's derivation, per format."""
    if fmt == "text":
        return f"Algebraic estimator of model {d.model.name!r}: {d.model.equation_text()}"
    if fmt == "latex":
        return rf"Algebraic estimator of model \texttt{{{_escape(d.model.name)}}}"
    return f"Algebraic estimator of model `{d.model.name}`"


def system_steps(sd: SystemDerivation) -> list:
    """The steps that join a system's equations: the stacked linear system and its
    solution.

    Parameters
    ----------
    sd : SystemDerivation

    Returns
    -------
    list of Step
    """
    rows = []
    for e, i in sd.rows:
        model, number = sd.equations[e].model, sd.numbers[e]
        lhs = sp.Add(*(sp.Symbol(f"p{number}_{i}_{j}") * p
                       for j, p in enumerate(model.parameters)))
        rows.append((lhs, sp.Symbol(f"q{number}_{i}")))
    n, p = sd.P.shape
    shared = [str(q) for q in sd.parameters
              if sum(q in d.model.parameters for d in sd.equations) > 1]
    text = (f"Every equation's rows in the system's unknowns "
            f"{', '.join(map(str, sd.parameters))} (pE_I_J and qE_I: the entries of "
            f"equation E's P and Q): {_count(n, 'equation')} in {_count(p, 'unknown')}")
    if shared:
        text += (f"; {', '.join(shared)} {'appear' if len(shared) > 1 else 'appears'} in "
                 f"several equations, which ties them.")
    else:
        text += ": no parameter is shared, so each equation is solved on its own."
    if sd.skipped:
        text += (f"  Without unknowns, and left out: {'; '.join(sd.skipped)}.")
    steps = [Step("Stacked linear system P theta = Q", text, tuple(rows))]
    if n == p:
        solve = ("As many equations as unknowns: Cramer's rule on the stacked P, as for one "
                 "equation, wherever det P is not zero.")
        if len(sd.equations) == 1:
            solve = "One equation with unknowns: solved as on its own (above)."
    else:
        solve = (f"More equations ({n}) than unknowns ({p}): least squares, theta minimising "
                 f"the weighted sum of squared residuals, (P^T W P) theta = P^T W Q.  "
                 f"algid.identify stacks these rows over many windows, weights each equation "
                 f"by the inverse rms of its residuals, and removes the bias of every "
                 f"output's noise (Koopmans' estimator).")
    if any(all(q == 0 for q in d.Q) for d in sd.equations):
        solve += ("  An equation without a known term contributes only through the "
                  "parameters it shares: they fix its scale.")
    steps.append(Step("Solution", solve, ()))
    return steps


def _count(n, noun):
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _system_sections(sd: SystemDerivation, fmt):
    count = len(sd.system.equations)
    quote = (lambda text: f"`{text}`") if fmt == "markdown" else (lambda text: text)
    sections = [(f"Equation {number} of {count}: {quote(d.model.equation_text())}",
                 f"{number}.", derivation_steps(d), d)
                for number, d in zip(sd.numbers, sd.equations)]
    sections.append(("The system", "S.", system_steps(sd), sd.equations[0]))
    equations = "; ".join(m.equation for m in sd.system.equations)
    title = {"text": f"Algebraic estimator of the system {sd.system.name!r}: {equations}",
             "latex": rf"Algebraic estimator of the system "
                      rf"\texttt{{{_escape(sd.system.name)}}}",
             "markdown": f"Algebraic estimator of the system `{sd.system.name}`"}[fmt]
    return title, sections


def display_equations(model, fmt="latex"):
    """Every display equation of the report as a LaTeX string (for checking rendering)."""
    if isinstance(model, SystemModel):
        _, sections = _system_sections(derive(model), "latex")
    else:
        d = derive(_as_model(model))
        sections = [(None, "", derivation_steps(d), d)]
    return [_display_latex(lhs, rhs, d) for _, _, steps, d in sections for step in steps
            for lhs, rhs in step.equations]


def _as_model(model):
    if isinstance(model, (LinearODEModel, ChannelModel)):
        return model
    if isinstance(model, Model):
        return ChannelModel(model)
    if isinstance(model, Derivation):
        return model.model
    if not isinstance(model, str):
        raise ModelError(f"a report takes a built-in model's name, a model, a derivation or "
                         f"a system (algid.models.parse_system), got {type(model).__name__}")
    return builtin_model(model)


def derivation_report(model="msd", fmt="text") -> str:
    """The derivation of ``model``'s estimator, step by step.

    Parameters
    ----------
    model : str, LinearODEModel, Model, Derivation, SystemModel or SystemDerivation
        A built-in model name (``"msd"``, ``"msd_mass"``), a user's model (also one
        from :func:`algid.models.parse_equation`, in several signals), or a system
        of equations (:func:`algid.models.parse_system`): each equation's derivation,
        then their stacked linear system.
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
    render = {"text": _render_text, "latex": _render_latex, "markdown": _render_markdown}[fmt]
    if isinstance(model, SystemModel):
        model = derive(model)
    if isinstance(model, SystemDerivation):
        return render(*_system_sections(model, fmt))
    d = model if isinstance(model, Derivation) else derive(_as_model(model))
    return render(_titles(d, fmt), [(None, "", derivation_steps(d), d)])
