"""Sphinx configuration of the algid documentation (``./dev docs`` builds it).

Everything shown is computed at build time: the API pages from ``__all__`` and the
docstrings, the derivation and the errata from the derivation engine, the command line
from its argument parser, the benchmark tables from ``benchmarks/results.json``, and
the examples by executing ``notebooks/*.py`` (``ALGID_NOTEBOOK_QUICK=1`` selects their
small workload).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(DOCS / "_ext"))
sys.path.insert(0, str(ROOT))  # benchmarks.report

import algid  # noqa: E402

project = "algid"
author = "The algid developers"
copyright = "the algid developers"  # noqa: A001 - Sphinx's name
release = version = algid.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.intersphinx",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",  # MathJax served from _static: the site reads offline too
    "numpydoc",
    "myst_nb",
    "sphinxarg.ext",
    "algid_docs",
]

root_doc = "index"
exclude_patterns = ["_build", "README.md", "**/.ipynb_checkpoints", "_ext", "_templates"]
templates_path = ["_templates"]
# no typographic quotes or dashes: the command-line reference (from the parser's help,
# rendered as prose) must stay copy-pasteable ("--equation", not an en dash)
smartquotes = False
source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}

# Every cross-reference must resolve (-W turns a miss into an error).
nitpicky = True
nitpick_ignore_regex = [
    # generated code is not API (tests/test_docstrings.py skips it too): a docstring may
    # name a generated module without a page to link to
    ("py:mod", r"algid\._generated\..*"),
    # internals are private (a leading underscore) and out of the reference: a docstring
    # may name one without a page to link to
    ("py:.*", r"(.*\.)?_[a-z]\w*(\..*)?"),
]

# The API: autosummary writes one page per public name (see algid_docs.write_api_pages).
autosummary_generate = True
autosummary_ignore_module_all = False
autodoc_typehints = "none"           # the numpydoc sections carry the types
autodoc_member_order = "bysource"
autodoc_default_options = {"exclude-members": "__init__"}
numpydoc_show_class_members = False  # the class template documents the members
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks = set()   # tests/test_docstrings.py validates

# Notebooks: executed once by algid_docs (algid_notebooks), rendered with their outputs.
nb_execution_mode = "off"
nb_merge_streams = True
nb_render_markdown_format = "myst"  # the notebooks' Markdown outputs hold tables and $math$
myst_enable_extensions = ["dollarmath", "amsmath"]
# SymPy's displays as MathJax (text/latex) rather than as its PNG renderings
nb_mime_priority_overrides = [("html", "text/latex", 45)]

# Offline inventories kept in docs/_intersphinx (docs/README.md says where each is from).
INVENTORIES = DOCS / "_intersphinx"
intersphinx_mapping = {
    "python": ("https://docs.python.org/3.11/", str(INVENTORIES / "python.inv")),
    "numpy": ("https://numpy.org/doc/stable/", str(INVENTORIES / "numpy.inv")),
    "scipy": ("https://docs.scipy.org/doc/scipy-1.10.1/", str(INVENTORIES / "scipy.inv")),
    "sympy": ("https://docs.sympy.org/1.11/", str(INVENTORIES / "sympy.inv")),
    "control": ("https://python-control.readthedocs.io/en/0.10.2/",
                str(INVENTORIES / "control.inv")),
    "matplotlib": ("https://matplotlib.org/stable/", str(INVENTORIES / "matplotlib.inv")),
}

html_theme = "pydata_sphinx_theme"
html_title = f"algid {release}"
html_theme_options = {
    "navigation_with_keys": False,
    # the sidebar of every page lists only its own section: with ~260 API pages a
    # fully expanded navigation tree dominates the build time
    "collapse_navigation": True,
    "navigation_depth": 2,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
}
# pages without sub-pages: no empty section navigation beside them, a wider column
html_sidebars = {page: [] for page in ("index", "getting_started", "method", "benchmarks",
                                       "developer")}
html_static_path = ["_static"]    # the overview figure and the stylesheet
html_css_files = ["algid.css"]    # readable tables and long equations
html_last_updated_fmt = None

# ALGID_NOTEBOOK_QUICK=1: the small workload of the notebooks (what the tests build)
algid_notebooks_quick = os.environ.get("ALGID_NOTEBOOK_QUICK", "") not in ("", "0")
