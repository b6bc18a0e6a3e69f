"""Symbolic: the algebraic derivation with SymPy, and code generation from it.

Public:

- :class:`LinearODEModel` (with the symbols :data:`TIME` and :data:`LAPLACE`) and
  :func:`builtin_model`: the model in the Laplace domain;
- :func:`derive` takes it through ``d^n/ds^n`` and ``s^-N`` to the linear system
  ``P(t) theta = Q(t)`` of a :class:`Derivation` (its :class:`Kernel`\\ s are sums of
  :class:`IteratedIntegral`\\ s, evaluated by :func:`evaluate_kernel`); given a system
  of equations, a :class:`SystemDerivation`;
- :func:`derivation_report` writes the derivation out step by step (text, LaTeX, Markdown);
- :func:`numpy_module_source` and :func:`c_sources` / :func:`write_c_sources` generate the
  NumPy estimator module and a self-contained C99 estimator.

Importing this package needs SymPy (``pip install 'algid[derive]'``); the estimator
itself never does.
"""

from algid.symbolic._builtin_models import builtin_model
from algid.symbolic._codegen import numpy_module_source
from algid.symbolic._codegen_c import c_sources, write_c_sources
from algid.symbolic._derivation import Derivation, IteratedIntegral, Kernel, derive, evaluate_kernel
from algid.symbolic._model import LAPLACE, TIME, LinearODEModel
from algid.symbolic._report import derivation_report
from algid.symbolic._system_derivation import SystemDerivation

__all__ = ["LinearODEModel", "TIME", "LAPLACE", "builtin_model", "derive", "Derivation",
           "SystemDerivation",
           "Kernel", "IteratedIntegral", "evaluate_kernel", "derivation_report",
           "numpy_module_source", "c_sources", "write_c_sources"]
