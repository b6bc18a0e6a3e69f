"""Estimation: the paper's algebraic estimator, batch and on-line, and its companions.

Public:

- :func:`estimate` runs the estimator of a built-in or compiled model over a record and
  returns an :class:`EstimationResult` (estimates over time, their numerical error, the
  time from which they are valid);
- :class:`OnlineEstimator` runs the same estimator on a stream, chunk by chunk, with the
  same results bit for bit;
- :func:`refine` polishes an estimate by output-error least squares
  (:class:`RefinementResult`); :func:`crlb` is the Cramér–Rao bound of the paper's model;
- :func:`convergence_time` measures when estimates settle within a tolerance.

The estimator needs only NumPy and SciPy; numba, when installed, runs its loop compiled.
"""

from algid.estimation._batch import (
           DEFAULT_FILTER_ORDER,
           DEFAULT_QUADRATURE_POINTS,
           ENGINES,
           estimate,
)
from algid.estimation._cramer_rao import crlb
from algid.estimation._online import OnlineEstimator
from algid.estimation._refinement import RefinementResult, refine
from algid.estimation._result import EstimationResult, convergence_time

__all__ = ["estimate", "OnlineEstimator", "EstimationResult", "refine", "RefinementResult",
           "crlb", "convergence_time", "DEFAULT_FILTER_ORDER", "DEFAULT_QUADRATURE_POINTS",
           "ENGINES"]
