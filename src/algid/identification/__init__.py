"""Identification: the parameters of your own equation from whole measured records.

Public:

- :func:`identify` solves the window equations of the algebraic method (modulating
  kernels on windows of one length, chosen by a rule on the record) by least squares or
  instrumental variables, and returns an :class:`IdentificationResult`: the parameters,
  their standard errors and numerical error, warnings on identifiability and on model
  adequacy (:class:`Adequacy`), and a simulation-based :class:`Validation`;
- :class:`Tracker` is the streaming form of ``identify``: the same window equations,
  accumulated as the samples arrive (with exponential forgetting if asked), estimates
  with standard errors at every window end, and alarms when the parameters change;
- :func:`identify_many` identifies every record of a fleet on its own (a long pandas
  ``DataFrame``, a mapping id -> record or a Dask ``DataFrame``), on a
  ``dask.distributed`` cluster when one is active, and returns a table: one row of
  results per record, or the one-line refusal of a record it could not identify
  (:func:`fleet_outliers` flags the records that stand out);
- given a list of equations that share parameters (one measured output each),
  :func:`identify` stacks the window equations of all of them into one joint estimate,
  refines it by output error on every output, and returns a :class:`SystemResult`
  (joint covariance, the coupled system's :class:`SystemValidation`, a MIMO
  python-control model); ``hidden=[...]`` names outputs that are not measured
  (eliminated), and :class:`Tracker` takes a list of equations too;
- :data:`METHODS` are the solvers ``identify`` offers;
- a Parquet or CSV path, a Dask ``DataFrame`` or a record of more than
  :data:`STREAM_SAMPLES` samples is read in chunks (:data:`CHUNK_SAMPLES` rows), never
  whole: ``identify`` keeps the window equations, not the samples, and chooses its
  window on excerpts (:data:`EXCERPT_SAMPLES`, :data:`EXCERPTS`).

Records are mappings of named columns (``{"t": ..., "u": ..., "y": ...}``), with a time
column or a sampling rate; several records are identified together.
"""

from algid.identification._adequacy import Adequacy
from algid.identification._fleet import fleet_outliers, identify_many
from algid.identification._identify import (
    CHUNK_SAMPLES,
    EXCERPT_SAMPLES,
    EXCERPTS,
    METHODS,
    STREAM_SAMPLES,
    identify,
)
from algid.identification._result import IdentificationResult, Validation
from algid.identification._system_result import SystemResult, SystemValidation
from algid.identification._tracker import Tracker
from algid.identification._tracker_state import TrackUpdate

__all__ = ["identify", "identify_many", "fleet_outliers", "IdentificationResult", "Validation",
           "Adequacy",
           "SystemResult", "SystemValidation", "Tracker", "TrackUpdate", "METHODS",
           "STREAM_SAMPLES", "CHUNK_SAMPLES", "EXCERPT_SAMPLES", "EXCERPTS"]
