"""The documentation site builds without a warning, and its pages hold what they promise.

The site is built once per module, as ``./dev docs --quick`` builds it
(``-W --keep-going``, ``nitpicky``, the notebooks' small workload), into a temporary
directory.  The notebooks are not executed again: the build renders those that the
session's ``executed_notebooks`` fixture executed (``tests/conftest.py``), which
``tests/test_notebooks.py`` checks.  Skipped without the ``docs`` extra.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
import zlib
from html.parser import HTMLParser

import pytest
from conftest import ROOT

for _module in ("sphinx", "pydata_sphinx_theme", "numpydoc", "myst_nb", "sphinxarg",
                "sphinx-mathjax-offline",
                "jupytext", "nbclient", "ipykernel", "sympy", "control", "matplotlib"):
    pytest.importorskip(_module, reason="needs the 'docs' extra: pip install -e '.[docs]'")

DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS / "_ext"))
import algid_docs  # noqa: E402
import algid_notebooks  # noqa: E402


@pytest.fixture(scope="module")
def site(executed_notebooks, tmp_path_factory):
    """The built HTML directory (the build's output is shown when it fails)."""
    failed = {n: e for n, e in executed_notebooks.items() if isinstance(e, Exception)}
    assert not failed, f"notebooks failed to execute: {sorted(failed)}"
    out = tmp_path_factory.mktemp("docs")
    env = dict(os.environ, ALGID_NOTEBOOK_QUICK="1")
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-b", "html", "-W", "--keep-going", "-q",
         "-d", str(out / "doctrees"), str(DOCS), str(out / "html")],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-6000:]
    print(f"documentation built in {time.perf_counter() - start:.1f} s")
    return out / "html"


class _Tags(HTMLParser):
    """The tags of a page: ``[(tag, attrs dict)]``."""

    def __init__(self):
        super().__init__()
        self.tags = []

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))


def tags(path):
    parser = _Tags()
    parser.feed(path.read_text(encoding="utf-8"))
    return parser.tags


def inventory_names(path):
    """Names of the Python objects in a Sphinx ``objects.inv``."""
    raw = path.read_bytes()
    body = raw.split(b"\n", 4)[4]
    names = set()
    for line in zlib.decompress(body).decode().splitlines():
        name, role = line.split(" ", 2)[:2]
        if role.startswith("py:"):
            names.add(name)
    return names


def test_every_notebook_page_shows_its_figures(site):
    for name in algid_notebooks.notebook_names():
        page = site / "examples" / f"{name}.html"
        assert page.exists(), name
        nb = json.loads((DOCS / "examples" / f"{name}.ipynb").read_text(encoding="utf-8"))
        # figures: PNG outputs that are not SymPy displays (those render as MathJax)
        figures = sum("image/png" in out.get("data", {}) and "text/latex" not in out["data"]
                      for cell in nb["cells"] for out in cell.get("outputs", ()))
        assert figures > 0, f"{name}: the executed notebook has no figure"
        images = [a.get("src", "") for tag, a in tags(page) if tag == "img"]
        assert len(images) >= figures, f"{name}: {len(images)} <img> for {figures} figures"
        for src in images:
            assert (page.parent / src).exists(), f"{name}: missing image {src}"
        # the checks live in cells tagged remove-cell: none of them reaches the page
        text = page.read_text(encoding="utf-8")
        assert "RESULTS" not in text and "assert" not in text, f"{name}: test code shown"


def test_every_public_name_has_an_entry(site):
    documented = inventory_names(site / "objects.inv")
    table = algid_docs.public_names()
    assert "algid.estimation.estimate" in documented
    # a class defined in a private module is also listed under its canonical (private)
    # name: only as an alias of its public entry
    private = re.compile(r"\._[a-z]")
    public_tails = {n.rsplit(".", 1)[-1] for n in documented if not private.search(n)}
    assert not [n for n in documented if private.search(n) and n.rsplit(".", 1)[-1]
                not in public_tails], "internals in the reference"
    missing = []
    for modname, names in table.items():
        assert modname in documented, modname  # the module's own page
        for name in names:
            if name.startswith("__"):
                home = modname
            else:
                home = algid_docs.home_of(modname, name, table)
            if f"{home}.{name}" not in documented:
                missing.append(f"{modname}.{name}")
    assert not missing, f"public names without an entry: {missing}"
    # the top-level names link to their entries from the algid page
    page = (site / "api" / "algid.html").read_text(encoding="utf-8")
    for name in table["algid"]:
        if not name.startswith("__"):
            assert f"{algid_docs.home_of('algid', name, table)}.{name}" in page, name


def test_command_line_page_has_every_subcommand_and_option(site):
    import argparse

    from algid.cli import build_parser

    text = (site / "user_guide" / "command_line.html").read_text(encoding="utf-8")
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert len(sub.choices) >= 7
    for command, subparser in sub.choices.items():
        assert re.search(rf"\b{command}\b", text), command
        for action in subparser._actions:
            if isinstance(action, argparse._HelpAction):
                continue  # -h/--help: argparse's own, not listed
            for option in action.option_strings:
                assert option in text, f"{command} {option}"
            if not action.option_strings:
                assert action.dest in text, f"{command} {action.dest}"


def test_method_page_is_computed(site):
    text = (site / "method.html").read_text(encoding="utf-8")
    assert text.count("Checked at build time") == 3  # the three exercise solutions
    assert re.search(r"\d+ of \d+ printed equations are wrong", text)
    assert r"\int^{(2)}" in text  # the derivation's iterated integrals, as LaTeX


def test_benchmark_page_renders_results(site):
    text = (site / "benchmarks.html").read_text(encoding="utf-8")
    results = json.loads((ROOT / "benchmarks" / "results.json").read_text(encoding="utf-8"))
    assert results["meta"]["started"] in text
    assert text.count("<table") >= 5


def test_a_wrong_exercise_solution_is_caught():
    right = "P: -I(t*x(t), 1); I(t*f(t), 1)\nQ: t*x(t) - I(x(t), 1)\n" \
            "P: -I(t*x(t), 2); I(t*f(t), 2)\nQ: I(t*x(t), 1) - I(x(t), 2)"
    assert algid_docs.solution_disagreement("x' + a*x = b*f", ["a", "b"], ["f", "x"],
                                            right) is None
    negated = right.replace("P: -I(t*x(t), 1); I(t*f(t), 1)\nQ: t*x(t) - I(x(t), 1)",
                            "P: I(t*x(t), 1); -I(t*f(t), 1)\nQ: -t*x(t) + I(x(t), 1)")
    assert algid_docs.solution_disagreement("x' + a*x = b*f", ["a", "b"], ["f", "x"],
                                            negated) is None  # a row times -1 is fine
    wrong = right.replace("Q: t*x(t) - I(x(t), 1)", "Q: t*x(t) + I(x(t), 1)")
    problem = algid_docs.solution_disagreement("x' + a*x = b*f", ["a", "b"], ["f", "x"],
                                               wrong)
    assert problem is not None and "row 1" in problem


def test_landing_page_opens_with_the_product(site):
    page = site / "index.html"
    text = page.read_text(encoding="utf-8")
    images = [a.get("src", "") for tag, a in tags(page) if tag == "img"]
    assert any("algid_overview" in src and (page.parent / src).exists() for src in images)
    assert "EstimationResult model=" in text            # the example's printed output
    assert "_static/algid.css" in text
    # the path in order, the API reference last; its ~75 module pages are not listed here
    body = text[text.find('id="where-to-go"'):]
    path = ("getting_started.html", "method.html", "user_guide/index.html",
            "examples/index.html", "benchmarks.html", "developer.html", "api/index.html")
    positions = [body.find(f'href="{target}"') for target in path]
    assert min(positions) >= 0 and positions == sorted(positions), positions
    assert "api/algid.identification._adequacy.html" not in text
