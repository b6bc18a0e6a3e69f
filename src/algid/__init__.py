"""algid: algebraic identification of continuous-time linear systems.

The names a user needs are here: :func:`estimate` and :class:`OnlineEstimator` (the
paper's estimator), :func:`identify` (your own equation, or a system of equations that
share parameters, on measured records),
:func:`identify_many` (the same on every record of a fleet, on a Dask cluster if one is
active) and :class:`Tracker` (the same on a stream, with change alarms),
:func:`compile_equation`, :func:`simulate`, :func:`simulate_model` and
:func:`simulate_system`, the errors.  The
subpackages hold the rest by concept: :mod:`algid.models`, :mod:`algid.estimation`,
:mod:`algid.identification`, :mod:`algid.simulation`, :mod:`algid.signals`,
:mod:`algid.symbolic` (SymPy), :mod:`algid.paper`, with :mod:`algid.io`,
:mod:`algid.datasets` and :mod:`algid.plotting`.

The estimator needs only NumPy and SciPy.  The plant simulator needs python-control
(``algid[simulate]``), the symbolic derivation SymPy (``algid[derive]``), figures
matplotlib (``algid[plot]``), fleets pandas and Dask (``algid[fleet]``).
"""

from algid.errors import AlgidError, DataFileError, InputDataError, ModelError
from algid.estimation import EstimationResult, OnlineEstimator, crlb, estimate, refine
from algid.identification import IdentificationResult, Tracker, identify, identify_many
from algid.models import available_models, compile_equation
from algid.simulation import simulate_model, simulate_system

__version__ = "0.1.0"

__all__ = ["estimate", "OnlineEstimator", "EstimationResult", "identify", "identify_many",
           "IdentificationResult", "Tracker", "compile_equation", "available_models", "simulate",
           "simulate_model", "simulate_system", "refine", "crlb", "AlgidError", "InputDataError",
           "DataFileError", "ModelError", "__version__"]


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
