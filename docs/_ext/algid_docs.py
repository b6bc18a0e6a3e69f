"""Sphinx extension of the algid documentation: what the pages show is computed.

Directives
----------
``algid-derivation``
    The derivation step by step, parsed from ``algid derive --format latex`` (that is,
    :func:`algid.symbolic.derivation_report` with ``fmt="latex"``) of a built-in model
    (``:model:``) or of an equation (``:equation:``, ``:parameters:``, ``:signals:``).
``algid-errata``
    The verdict on each printed equation of the paper, and the corrected forms, rendered
    from the SymPy objects that the errata checks compute (what ``algid errata`` prints).
``algid-exercise-solution``
    A solution written in the page (rows of ``P`` and ``Q``), checked against the
    derivation engine: a solution that disagrees fails the build.
``algid-benchmarks``
    The tables of a benchmark results file (``benchmarks.report.markdown``, and those
    of ``benchmarks.identify_speed`` and ``benchmarks.adequacy``).

Events
------
``config-inited`` writes the API pages (one per public module, from ``__all__``) and
executes the notebooks into ``examples/`` (:mod:`algid_notebooks`);
``missing-reference`` resolves a re-exported name (``algid.estimate``) or a short name
(``EstimationResult``) to the one page that documents the object;
``doctree-resolved`` keeps each number of a result table on one line.
"""

from __future__ import annotations

import importlib
import inspect
import json
import pkgutil
import re
from pathlib import Path

from docutils import nodes
from docutils.parsers.rst import Directive, directives
from sphinx.errors import ExtensionError
from sphinx.util import logging

logger = logging.getLogger(__name__)

DOCS = Path(__file__).resolve().parents[1]
ROOT = DOCS.parent

#: Modules that are not API: the command line (its own page, from the parser),
#: generated code and ``python -m algid``; the same as tests/test_docstrings.py.
SKIPPED_MODULES = ("algid.cli", "algid.__main__", "algid._generated")


# --------------------------------------------------------------------------- the API
def public_modules():
    """``algid`` and every module below it without a leading underscore in its name."""
    import algid

    names = ["algid"]
    for info in pkgutil.walk_packages(algid.__path__, "algid."):
        parts = info.name.split(".")
        if any(p.startswith("_") for p in parts) or info.name.startswith(SKIPPED_MODULES):
            continue
        names.append(info.name)
    return names


def public_names():
    """``{module: [names of its __all__]}`` for every public module."""
    out = {}
    for modname in public_modules():
        module = importlib.import_module(modname)
        out[modname] = [n for n in getattr(module, "__all__", ())]
    return out


def home_of(modname, name, table):
    """The module whose page documents ``modname.name``.

    A function or class is documented where it is defined (its ``__module__``) when
    that module is public and exports it; anything else in the deepest public module
    that exports the same object (constants are documented with ``#:`` comments where
    they are defined).
    """
    obj = getattr(importlib.import_module(modname), name)
    defined = getattr(obj, "__module__", None) if (inspect.isclass(obj)
                                                   or inspect.isfunction(obj)) else None
    if defined in table and name in table[defined]:
        return defined
    holders = [m for m, names in table.items() if name in names
               and getattr(importlib.import_module(m), name, None) is obj]
    return max(holders, key=lambda m: (m.count("."), len(m)))


def _write_if_changed(path: Path, text: str):
    if not path.exists() or path.read_text(encoding="utf-8") != text:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")


def write_api_pages(app):
    """One page per public module under ``api/``; record the alias of every name."""
    table = public_names()
    api = DOCS / "api"
    aliases = {}
    toc = []
    for modname, names in table.items():
        own, elsewhere = [], []
        dunders = [n for n in names if n.startswith("__")]
        for name in names:
            if name in dunders:
                continue
            home = home_of(modname, name, table)
            if home == modname:
                own.append(name)
            else:
                elsewhere.append(f"{home}.{name}")
                aliases[f"{modname}.{name}"] = f"{home}.{name}"
        lines = [modname, "=" * len(modname), "", f".. automodule:: {modname}",
                 "   :no-members:", "", f".. currentmodule:: {modname}", ""]
        if own:
            lines += ["Defined here", "-" * 12, "", ".. autosummary::",
                      "   :toctree: generated", "   :nosignatures:", ""]
            lines += [f"   {name}" for name in own] + [""]
        if elsewhere:
            lines += ["Exported here, documented where defined", "-" * 39, "",
                      ".. autosummary::", "   :nosignatures:", ""]
            # autosummary resolves names relative to the current module
            lines += [f"   ~{path.removeprefix(modname + '.')}" for path in elsewhere] + [""]
        for name in dunders:
            value = getattr(importlib.import_module(modname), name)
            lines += [f".. py:data:: {name}", f"   :value: {value!r}", "",
                      f"   ``{modname}.{name}``.", ""]
        if not names:
            lines += ["This module exports no names (no ``__all__``).", ""]
        _write_if_changed(api / f"{modname}.rst", "\n".join(lines))
        toc.append(modname)
    index = ["API reference", "=============", "",
             "Every name in ``algid.__all__`` and in the ``__all__`` of each public module,",
             "from its docstring.  A name exported by several modules is documented once,",
             "in the module that defines it; the others link there.", "",
             ".. toctree::", "   :maxdepth: 1", ""]
    index += [f"   {m}" for m in toc]
    _write_if_changed(api / "index.rst", "\n".join(index) + "\n")
    for stale in api.glob("*.rst"):
        if stale.stem not in toc and stale.name != "index.rst":
            stale.unlink()
    documented = {f"{m}.{name}" for m, names in table.items() for name in names
                  if home_of(m, name, table) == m}
    for stale in (api / "generated").glob("*.rst"):  # pages of names gone or moved
        if stale.stem not in documented:
            stale.unlink()
    app.config.algid_aliases = aliases
    return aliases


def _import_path(path):
    """The object a dotted path names (``None`` when it names nothing importable).

    Attributes win over submodules of the same name (``sympy.simplify`` is the
    function, as ``from sympy import simplify`` gives it).
    """
    parts = path.split(".")
    try:
        obj = importlib.import_module(parts[0])
        for i, attr in enumerate(parts[1:], 2):
            obj = (getattr(obj, attr) if hasattr(obj, attr)
                   else importlib.import_module(".".join(parts[:i])))
    except ImportError:
        return None
    return obj


def _documented_class_of(domain, name):
    """``name``'s parent when that is a documented class that has the attribute.

    A dataclass field or an attribute listed in a class's Attributes section has no
    entry of its own: a reference to it goes to the class.
    """
    parent, _, attr = name.rpartition(".")
    entry = domain.objects.get(parent)
    if entry is None or entry.objtype not in ("class", "exception"):
        return None
    from numpydoc.docscrape import NumpyDocString

    cls = _import_path(parent)
    fields = set(getattr(cls, "__dataclass_fields__", ())) | set(
        getattr(cls, "__annotations__", ()))
    for item in NumpyDocString(inspect.getdoc(cls) or "")["Attributes"]:
        fields.update(n.strip() for n in item.name.split(","))
    try:  # a constructor argument kept under its own name, documented with it
        fields.update(inspect.signature(cls).parameters)
    except (TypeError, ValueError):
        pass
    return parent if attr in fields or hasattr(cls, attr) else None


def resolve_alias(app, env, node, contnode):
    """Resolve a Python name that has no entry of its own.

    In order: a name re-exported elsewhere (``algid.estimate``) goes to the page that
    documents the object; a short name (``EstimationResult``, ``Model.method``) to the
    one documented algid object it ends with; an attribute without an entry (a dataclass
    field) to its class; an external name spelt by where it is exported
    (``sympy.Symbol``) to the inventory entry of where it is defined.
    """
    if node.get("refdomain") != "py":
        return None
    aliases = getattr(app.config, "algid_aliases", {})
    domain = env.get_domain("py")
    target = node["reftarget"]
    modname, classname = node.get("py:module"), node.get("py:class")
    candidates = [f"{prefix}.{target}" for prefix in filter(None, [
        modname and classname and f"{modname}.{classname}", modname])] + [target]

    def resolve(name):
        return domain.resolve_xref(env, node["refdoc"], app.builder, node["reftype"],
                                   name, node, contnode)

    for cand in candidates:
        for alias, home in aliases.items():  # algid.X -> algid.mod.X, algid.X.attr too
            if cand == alias or cand.startswith(alias + "."):
                cand = home + cand[len(alias):]
                break
        if cand in domain.objects:
            return resolve(cand)
    matches = sorted({name for name in domain.objects
                      if name.startswith("algid.") and name.endswith("." + target)})
    if len(matches) == 1:
        return resolve(matches[0])
    if node["reftype"] in ("attr", "meth", "obj"):
        for cand in candidates + [m for m in domain.objects if m.endswith("." + target)]:
            parent = _documented_class_of(domain, cand)
            if parent is not None:
                ref = domain.resolve_xref(env, node["refdoc"], app.builder, "class", parent,
                                          node, contnode)
                if ref is not None:
                    return ref
    if not target.startswith("algid"):
        obj = _import_path(target)
        module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
        if module and qualname and f"{module}.{qualname}" != target:
            from sphinx.ext import intersphinx

            retry = node.deepcopy()
            retry["reftarget"] = f"{module}.{qualname}"
            return intersphinx.missing_reference(app, env, retry, contnode)
    return None


# -------------------------------------------------------------------- the notebooks
def execute_notebooks(app):
    """Executed notebooks in ``examples/`` (reused when up to date)."""
    import algid_notebooks

    outcome = algid_notebooks.execute_all(
        DOCS / "examples", quick=app.config.algid_notebooks_quick,
        log=lambda line: logger.info(f"[notebooks] {line}"))
    failed = {name: exc for name, exc in outcome.items() if isinstance(exc, Exception)}
    if failed:
        raise ExtensionError("notebooks failed: " + "; ".join(
            f"{name}: {str(exc).strip().splitlines()[-1] if str(exc).strip() else exc!r}"
            for name, exc in failed.items()))


def on_config_inited(app, config):
    # before Sphinx looks for the source files, so that these pages are found
    write_api_pages(app)
    execute_notebooks(app)


# --------------------------------------------------------------------- derivation
def _math(latex, env):
    node = nodes.math_block(latex, latex, nowrap=False, number=None, label=None,
                            docname=env.docname)
    return node


def _unescape(text):
    return (text.replace(r"\^{}", "^").replace(r"\_", "_").replace(r"\&", "&")
            .replace(r"\%", "%").replace(r"\#", "#"))


def parse_latex_report(latex):
    """``[(title, text, [equations])]`` from a ``derivation_report(..., "latex")``."""
    body = latex.split(r"\begin{document}", 1)[1].split(r"\end{document}", 1)[0]
    steps = []
    for chunk in re.split(r"\\subsection\*\{", body)[1:]:
        title, rest = chunk.split("}\n", 1)
        equations = re.findall(r"\\begin\{multline\*\}\n(.*?)\n\\end\{multline\*\}", rest,
                               flags=re.S)
        text = re.sub(r"\\begin\{multline\*\}.*?\\end\{multline\*\}", "", rest,
                      flags=re.S).strip()
        steps.append((_unescape(title), _unescape(text), equations))
    return steps


class DerivationDirective(Directive):
    """The derivation of a model's estimator, from ``derivation_report(model, "latex")``."""

    option_spec = {"model": directives.unchanged, "equation": directives.unchanged,
                   "parameters": directives.unchanged, "signals": directives.unchanged,
                   "last": directives.positive_int}

    def run(self):
        from algid.symbolic import LinearODEModel, derivation_report

        env = self.state.document.settings.env
        model = self.options.get("model", "msd")
        if "equation" in self.options:
            signals = self.options.get("signals", "f x").split()
            model = LinearODEModel.from_equation(
                self.options["equation"], parameters=self.options["parameters"].split(),
                input=signals[0], output=signals[1], name="custom")
        steps = parse_latex_report(derivation_report(model, "latex"))
        first = len(steps) - self.options.get("last", len(steps))  # :last: N, the last N
        out = []
        for number, (title, text, equations) in enumerate(steps, 1):
            if number <= first:
                continue
            out.append(nodes.rubric("", f"{number}. {title}"))
            if text:
                out.append(nodes.paragraph("", text))
            out += [_math(eq, env) for eq in equations]
        return out


# ------------------------------------------------------------------------- errata
def latex_of(obj):
    """LaTeX lines of a printed form: a chain ``a = b``, several relations, a filter."""
    import sympy as sp

    if obj is None:
        return []
    if isinstance(obj, str):
        return [rf"\text{{{obj}}}"]
    if hasattr(obj, "expression") and hasattr(obj, "equations"):  # PrintedFilter
        lines = [rf"{obj.output}(t) = {sp.latex(obj.expression)}"]
        lines += [rf"\dot{{{sp.latex(z)}}} = {sp.latex(rhs)}" for z, rhs in obj.equations]
        lines += [rf"\text{{where }} {sp.latex(z)} = \text{{{name}}}" for z, name in obj.where]
        return lines
    if isinstance(obj, tuple):
        if obj and all(isinstance(o, tuple) for o in obj):
            return [line for o in obj for line in latex_of(o)]
        return [" = ".join(latex_of(o)[0] if isinstance(o, (str, tuple)) else sp.latex(o)
                           for o in obj)]
    return [sp.latex(obj)]


class ErrataDirective(Directive):
    """The errata of the paper, computed by :mod:`algid.symbolic._errata`."""

    option_spec = {}

    def run(self):
        from algid.symbolic._errata import PRINTED

        env = self.state.document.settings.env
        verdicts = [(entry, *entry.evaluate(PRINTED)) for entry in PRINTED]
        wrong = [v for v in verdicts if not v[1]]
        summary = nodes.paragraph("", f"{len(wrong)} of {len(verdicts)} printed equations "
                                      "are wrong (computed at build time).")
        table = nodes.table()
        group = nodes.tgroup(cols=3)
        table += group
        for width in (12, 10, 78):
            group += nodes.colspec(colwidth=width)
        head = nodes.thead()
        group += head
        head += self._row(["equation", "verdict", "what was checked"])
        body = nodes.tbody()
        group += body
        for entry, correct, _, explanation in verdicts:
            body += self._row([f"({entry.number})", "OK" if correct else "wrong",
                               explanation])
        out = [summary, table, nodes.rubric("", "The wrong equations, printed and corrected")]
        for entry, _, corrected, explanation in wrong:
            out.append(nodes.paragraph("", f"({entry.number}) as printed:"))
            out += [_math(line, env) for line in latex_of(entry.printed)]
            if isinstance(corrected, str):  # a realisation, written as state equations
                out.append(nodes.paragraph("", "corrected:"))
                out.append(nodes.literal_block(corrected, corrected))
            elif corrected is not None:
                out.append(nodes.paragraph("", "corrected:"))
                out += [_math(line, env) for line in latex_of(corrected)]
            out.append(nodes.paragraph("", explanation))
            if entry.reading:
                out.append(nodes.paragraph("", f"Reading of the extraction: {entry.reading}"))
        return out

    @staticmethod
    def _row(cells):
        row = nodes.row()
        for cell in cells:
            entry = nodes.entry()
            entry += nodes.paragraph("", str(cell))
            row += entry
        return row



# ------------------------------------------------------------------ sympy objects
class SympyDirective(Directive):
    """Display equations computed by the code in the content.

    The code runs in a fresh namespace and must leave ``EQUATIONS``, a list of
    ``(left, right)`` pairs of SymPy objects (or strings of LaTeX for the left side);
    each is shown as one display equation ``left = right``.
    """

    has_content = True

    def run(self):
        import sympy as sp

        env = self.state.document.settings.env
        namespace = {}
        exec("\n".join(self.content), namespace)  # noqa: S102 - the page's own code
        out = []
        for left, right in namespace["EQUATIONS"]:
            lhs = left if isinstance(left, str) else sp.latex(left)
            out.append(_math(f"{lhs} = {sp.latex(right)}", env))
        return out

# ---------------------------------------------------------------------- exercises
def parse_solution(text, signals):
    """``(P rows, Q rows)`` from lines ``P: a; b`` and ``Q: c`` (``I(g, n)``: n-fold integral)."""
    import sympy as sp

    from algid.symbolic import TIME, IteratedIntegral

    names = {"t": TIME, "I": lambda g, n: IteratedIntegral(g, n)}
    names.update({s: sp.Function(s) for s in signals})
    p_rows, q_rows = [], []
    for line in text.strip().splitlines():
        kind, _, rest = line.partition(":")
        values = [sp.sympify(v, locals=names) for v in rest.split(";")]
        (p_rows if kind.strip() == "P" else q_rows).append(values)
    return p_rows, q_rows


def _no_zero_fold(expr):
    """``expr`` with every 0-fold integral replaced by its integrand."""
    import sympy as sp

    from algid.symbolic import IteratedIntegral

    return sp.sympify(expr).replace(
        lambda e: isinstance(e, IteratedIntegral) and e.args[1] == 0, lambda e: e.args[0])


def solution_disagreement(equation, parameters, signals, text):
    """``None`` when the solution's rows are those of the engine up to a factor per row."""
    import sympy as sp

    from algid.symbolic import LinearODEModel, derive

    model = LinearODEModel.from_equation(equation, parameters=parameters, input=signals[0],
                                         output=signals[1], name="exercise")
    d = derive(model)
    p_rows, q_rows = parse_solution(text, signals)
    if len(p_rows) != d.P.rows or len(q_rows) != d.Q.rows:
        return f"{len(p_rows)} equations written, the engine gives {d.P.rows}"
    for i in range(d.P.rows):
        mine = list(p_rows[i]) + list(q_rows[i])
        engine = list(d.P.row(i)) + list(d.Q.row(i))
        if len(mine) != len(engine):
            return f"row {i + 1}: {len(mine)} entries, the engine has {len(engine)}"
        mine, engine = [_no_zero_fold(e) for e in mine], [_no_zero_fold(e) for e in engine]
        pivot = next(j for j, e in enumerate(engine) if e != 0)
        factor = sp.simplify(mine[pivot] / engine[pivot])
        if factor == 0 or not factor.is_number:
            return f"row {i + 1}: entry {pivot + 1} is not a constant multiple of the engine's"
        for j, (a, b) in enumerate(zip(mine, engine)):
            if sp.expand(a - factor * b) != 0:
                return (f"row {i + 1}, entry {j + 1}: {a} differs from the engine's "
                        f"{factor}*({b})")
    return None


class ExerciseSolutionDirective(Directive):
    """A solution ``P theta = Q`` of an exercise, checked by the derivation engine."""

    has_content = True
    option_spec = {"equation": directives.unchanged_required,
                   "parameters": directives.unchanged_required,
                   "signals": directives.unchanged}

    def run(self):
        import sympy as sp

        env = self.state.document.settings.env
        signals = self.options.get("signals", "f x").split()
        parameters = self.options["parameters"].split()
        text = "\n".join(self.content)
        problem = solution_disagreement(self.options["equation"], parameters, signals, text)
        if problem is not None:
            raise self.error(f"the solution of {self.options['equation']!r} disagrees with "
                             f"the derivation engine: {problem}")
        p_rows, q_rows = parse_solution(text, signals)
        theta = sp.Matrix([sp.Symbol(p) for p in parameters])
        latex = (sp.latex(sp.Matrix(p_rows)) + sp.latex(theta) + " = "
                 + sp.latex(sp.Matrix(q_rows)))
        note = nodes.paragraph("", "Checked at build time: these rows are those that "
                                   "algid.symbolic.derive gives for this equation "
                                   "(up to a constant factor per row).")
        return [_math(latex, env), note]


# --------------------------------------------------------------------- benchmarks
#: Cells of a benchmark table up to this many characters are not wrapped.
SHORT_CELL = 24


def markdown_to_nodes(text):
    """Nodes for the Markdown of ``benchmarks.report.markdown``: headings, tables, text."""
    out, table_lines = [], []

    def flush():
        if not table_lines:
            return
        rows = [[c.strip() for c in ln.strip().strip("|").split("|")] for ln in table_lines
                if not re.fullmatch(r"\|?(\s*-+\s*\|)+\s*-*\s*", ln.strip())]
        table_lines.clear()
        ncols = len(rows[0])
        table = nodes.table(classes=["algid-benchmark"])
        group = nodes.tgroup(cols=ncols)
        table += group
        for _ in range(ncols):
            group += nodes.colspec(colwidth=1)
        head, body = nodes.thead(), nodes.tbody()
        group += head
        group += body
        for k, cells in enumerate(rows):
            row = nodes.row()
            for cell in (cells + [""] * ncols)[:ncols]:
                entry = nodes.entry()
                if k and len(cell) <= SHORT_CELL:  # a number, a pair of them: one line
                    entry += nodes.paragraph("", "", nodes.inline(cell, cell,
                                                                  classes=["algid-nowrap"]))
                else:
                    entry += nodes.paragraph("", cell)
                row += entry
            (head if k == 0 else body).append(row)
        out.append(table)

    for line in text.splitlines():
        if line.strip().startswith("|"):
            table_lines.append(line)
            continue
        flush()
        if line.startswith("#"):
            out.append(nodes.rubric("", line.lstrip("#").strip()))
        elif line.startswith("- "):
            if not out or not isinstance(out[-1], nodes.bullet_list):
                out.append(nodes.bullet_list())
            out[-1] += nodes.list_item("", nodes.paragraph("", line[2:].replace("`", "")))
        elif line.strip():
            out.append(nodes.paragraph("", line.strip().replace("`", "")))
    flush()
    return out


def adequacy_markdown(rows):
    """The table of ``python -m benchmarks.adequacy --json`` (a list of rows), as Markdown."""
    lines = ["| case | model | warned | misfit / noise, median (range) | "
             "shift in standard errors, median (range) |", "| --- | --- | --- | --- | --- |"]
    for row in rows:
        lines.append(
            f"| {row['case']} | {'wrong' if row['wrong'] else 'right'} | "
            f"{row['warned']} of {row['runs']} | {row['misfit_median']:.3g} "
            f"({row['misfit_min']:.3g}–{row['misfit_max']:.3g}) | {row['shift_median']:.3g} "
            f"({row['shift_min']:.3g}–{row['shift_max']:.3g}) |")
    return "\n".join(lines)


class BenchmarksDirective(Directive):
    """The tables of a results file of ``python -m benchmarks`` (or, for a file named
    ``identify...``, of ``python -m benchmarks.identify_speed --out``; for one named
    ``identify_coverage...``, of ``python -m benchmarks.identify_coverage --out``; for one
    named ``adequacy...``, of ``python -m benchmarks.adequacy --json``)."""

    required_arguments = 1

    def run(self):
        name = Path(self.arguments[0]).name
        if "coverage" in name:  # python -m benchmarks.identify_coverage --out
            from benchmarks.identify_coverage import markdown
        elif "identify" in name:  # python -m benchmarks.identify_speed
            from benchmarks.identify_speed import markdown
        elif "adequacy" in name:  # python -m benchmarks.adequacy: a list of rows
            markdown = adequacy_markdown
        else:
            from benchmarks.report import markdown

        path = ROOT / self.arguments[0]
        env = self.state.document.settings.env
        env.note_dependency(str(path))
        results = json.loads(path.read_text(encoding="utf-8"))
        if isinstance(results, list):  # rows without a header of facts
            return markdown_to_nodes(markdown(results))
        meta = results.get("meta", {})
        facts = ", ".join(f"{k} {meta[k]}" for k in ("mode", "started", "python", "numpy",
                                                      "scipy", "algid") if k in meta)
        out = [nodes.paragraph("", f"From {self.arguments[0]}" + (f" ({facts})." if facts
                                                                    else "."))]
        return out + markdown_to_nodes(markdown(results))


#: A number as the result tables print it (``-3.2e-05``, ``1.66``, ``0.005 s``, ``82 %``,
#: ``86×``): kept on one line, while the text around it may wrap.
NUMBER = re.compile(r"[-+−]?\d[\d,]*(?:\.\d+)?(?:e[-+−]?\d+)?"
                    r"(?:\s?(?:%|s\b|ms\b|µs\b|mV\b|mm\b|MB\b|×|x\b))?")
NUMERIC_TABLES = ("algid-benchmark", "algid-results")


def keep_numbers_whole(app, doctree, docname):
    """In result tables, wrap every number in ``<span class="algid-nowrap">``.

    A browser may break a line at the hyphen of ``4.9e-15`` or between a value and its
    unit; the stylesheet keeps these spans whole.
    """
    for table in doctree.findall(nodes.table):
        if not any(c in table["classes"] for c in NUMERIC_TABLES):
            continue
        for text in list(table.findall(nodes.Text)):
            if isinstance(text.parent, (nodes.literal, nodes.math, nodes.inline)):
                continue
            pieces, last = [], 0
            for match in NUMBER.finditer(text.astext()):
                pieces.append(nodes.Text(text.astext()[last:match.start()]))
                pieces.append(nodes.inline(match.group(), match.group(),
                                           classes=["algid-nowrap"]))
                last = match.end()
            if not pieces:
                continue
            pieces.append(nodes.Text(text.astext()[last:]))
            text.parent.replace(text, [p for p in pieces if p.astext()])


def setup(app):
    app.add_config_value("algid_notebooks_quick", False, "env")
    app.add_config_value("algid_aliases", {}, "")
    app.add_directive("algid-derivation", DerivationDirective)
    app.add_directive("algid-errata", ErrataDirective)
    app.add_directive("algid-sympy", SympyDirective)
    app.add_directive("algid-exercise-solution", ExerciseSolutionDirective)
    app.add_directive("algid-benchmarks", BenchmarksDirective)
    app.connect("config-inited", on_config_inited)
    app.connect("missing-reference", resolve_alias)
    app.connect("doctree-resolved", keep_numbers_whole)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
