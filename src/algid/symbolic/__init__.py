"""The SymPy side of algid: models, the algebraic derivation and code generation.

Importing this package needs SymPy (``pip install 'algid[derive]'``); the estimator
itself never does.
"""

from algid.symbolic.derivation import Derivation, IteratedIntegral, Kernel, derive, evaluate_kernel
from algid.symbolic.model import LAPLACE, TIME, LinearODEModel
from algid.symbolic.report import derivation_report

__all__ = ["Derivation", "IteratedIntegral", "Kernel", "LinearODEModel", "TIME", "LAPLACE",
           "derive", "evaluate_kernel", "derivation_report"]
