"""algid: algebraic identification of continuous-time linear systems.

The estimator (:func:`estimate`) needs only NumPy and SciPy.  Simulation needs
python-control (``algid[simulate]``), the symbolic derivation SymPy (``algid[derive]``),
figures matplotlib (``algid[plot]``).
"""

from algid.cramer_rao import crlb
from algid.errors import AlgidError, DataFileError, InputDataError, ModelError
from algid.estimator import available_models, estimate
from algid.identification import identify
from algid.identification_result import IdentificationResult
from algid.online import OnlineEstimator
from algid.refinement import refine
from algid.result import EstimationResult

__version__ = "0.1.0"

__all__ = ["estimate", "simulate", "available_models", "EstimationResult", "OnlineEstimator",
           "AlgidError", "InputDataError", "DataFileError", "ModelError", "__version__",
           "refine", "crlb", "identify", "IdentificationResult"]


def __getattr__(name):
    # simulate needs python-control, an optional extra: import it on first use
    if name == "simulate":
        from algid.simulation import simulate
        return simulate
    # the benchmark records are read from package data on first use
    if name == "datasets":
        import importlib
        return importlib.import_module("algid.datasets")
    raise AttributeError(f"module 'algid' has no attribute {name!r}")
