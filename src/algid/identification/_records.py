"""Measured records for :func:`algid.identify`: gaps, segments, derivatives.

Records are read by the record layer (:mod:`algid._record_input`: the record types,
the columns, the time axis, the rate), as for every entry point.  A record is cut
into *segments* of contiguous samples at every gap (a time step larger than 1.5 times
the median step, i.e. missing rows) and at every row holding a NaN: windows never
straddle a segment boundary.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from algid._record_input import (
    GAP_FACTOR,
    as_record,
    is_record,
    record_columns,
    refuse_infinite,
)
from algid.errors import InputDataError

__all__ = ["Segment", "prepare_records", "estimate_derivative", "check_factors",
           "white_noise_floor", "GAP_FACTOR", "NOISE_ORDERS"]

#: A segment counts as uniformly sampled when no sample time is further than this
#: fraction of a step from the uniform grid (times stored in single precision, as in
#: the EMPS files, are off by about 3e-5 of a step).
UNIFORM_TOLERANCE = 1e-4

@dataclass
class Segment:
    """Contiguous samples of one record.

    Attributes
    ----------
    record : int
        Index of the record it comes from.
    rows : numpy.ndarray
        Row indices in the record.
    t : numpy.ndarray
        Sample times (s).
    values : dict
        Signal name (or ``(name, k)`` for an estimated derivative) -> samples.
    step : float or None
        The sampling step when the segment is uniform, else ``None``.
    """

    record: int
    rows: np.ndarray
    t: np.ndarray
    values: dict = field(default_factory=dict)
    step: float | None = None

    def __len__(self):
        return len(self.t)


def _as_records(data):
    if is_record(data):
        return [as_record(data, "record 0")]
    if isinstance(data, (list, tuple)) and data and all(is_record(r) for r in data):
        return [as_record(r, f"record {i}") for i, r in enumerate(data)]
    raise InputDataError("data must be a record (a mapping of column name -> samples, a "
                         "pandas DataFrame, an xarray Dataset or a TimeResponseData), or "
                         "a list of records")


def _split(t, valid, min_length):
    """Row ranges ``[start, stop)`` of contiguous valid samples without gaps."""
    n = len(t)
    steps = np.diff(t)
    median = float(np.median(steps))
    # a run breaks before an invalid row, after it, and across a gap
    breaks = np.zeros(n + 1, dtype=bool)
    breaks[0] = breaks[n] = True
    breaks[1:n] |= steps > GAP_FACTOR * median
    breaks[:n] |= ~valid
    breaks[1:] |= ~valid
    edges = np.flatnonzero(breaks)
    ranges = []
    for start, stop in zip(edges[:-1], edges[1:]):
        if valid[start] and stop - start >= min_length:
            ranges.append((int(start), int(stop)))
    return ranges, median


def prepare_records(data, signals, *, time=None, rate=None, min_length=8):
    """Check the records and cut them into segments of contiguous samples.

    Parameters
    ----------
    data : record or list of records
        Column name -> samples, one mapping per record (or any record type of
        :mod:`algid._record_input`).
    signals : sequence of str
        Signals the model reads.
    time : str, optional
        Name of the time column.
    rate : float, optional
        Sampling rate (Hz) when there is no time column.
    min_length : int
        Segments shorter than this are dropped.

    Returns
    -------
    segments : list of Segment
    step : float
        The median sampling step over all records (s).
    n_samples : int
        Usable samples (in the segments kept).

    Raises
    ------
    InputDataError
        Missing or non-numeric columns, bad time axis, or nothing usable left.
    """
    records = _as_records(data)
    segments, steps = [], []
    for index, record in enumerate(records):
        t, columns = record_columns(record, signals, time=time, rate=rate, index=index,
                                    min_samples=2)
        for name, values in columns.items():
            refuse_infinite(values, f"record {index}: column {name!r}")
        valid = np.all([~np.isnan(v) for v in columns.values()], axis=0)
        ranges, median = _split(t, valid, min_length)
        steps.append(median)
        for start, stop in ranges:
            seg_t = t[start:stop]
            step = (seg_t[-1] - seg_t[0]) / (len(seg_t) - 1)
            grid = seg_t[0] + step * np.arange(len(seg_t))
            uniform = np.max(np.abs(seg_t - grid)) <= UNIFORM_TOLERANCE * step
            segments.append(Segment(index, np.arange(start, stop), seg_t,
                                    {k: v[start:stop] for k, v in columns.items()},
                                    float(step) if uniform else None))
    if not segments:
        raise InputDataError(f"no run of {min_length} contiguous samples without gaps or "
                             f"NaN in any record: nothing to identify on")
    n_samples = sum(len(s) for s in segments)
    return segments, float(np.median(steps)), n_samples


def estimate_derivative(y, t, order, step=None, span=None):
    """Numerical estimate of the ``order``-th derivative of ``y`` (a fallback).

    A Savitzky-Golay derivative (local cubic least squares) on a uniform grid, finite
    differences on the actual times otherwise.  Used for the derivatives inside
    nonlinear factors (``sign(q')``).

    Parameters
    ----------
    y, t : numpy.ndarray
        Samples and times.
    order : int
        Derivative order.
    step : float or None
        Sampling step when uniform.
    span : int, optional
        Samples in the local fit (odd; default 2 * order + 7).

    Returns
    -------
    numpy.ndarray
    """
    n = len(y)
    if step is not None:
        span = span or 2 * order + 7
        span = min(span + (span % 2 == 0), n - (n % 2 == 0))
        polyorder = min(max(3, order + 1), span - 1)
        if span > polyorder >= order:
            from scipy.signal import savgol_filter

            return savgol_filter(y, span, polyorder, deriv=order, delta=step)
    out = np.asarray(y, dtype=float)
    for _ in range(order):
        out = np.gradient(out, t)
    return out


def check_factors(model, segments):
    """Refuse a model whose terms are not finite on the records.

    A term's factor may leave its domain on measured samples (``log(y)`` with
    ``y <= 0``, ``C/y`` or ``1/t`` at zero, ``sqrt(y)`` with ``y < 0``); the window
    integrals would then be NaN.

    Parameters
    ----------
    model : algid.models._model.Model
        The model (its ``terms``).
    segments : list of Segment
        The records' segments, with the derivatives the model's factors read.

    Raises
    ------
    InputDataError
        Naming the first such term, the time and the record's row.
    """
    for term in model.terms:
        for seg in segments:
            with np.errstate(all="ignore"):
                z = np.asarray(term.factor.evaluate(seg.values, seg.t), dtype=float)
            bad = ~np.isfinite(z)
            if np.any(bad):
                i = int(np.flatnonzero(np.broadcast_to(bad, seg.t.shape))[0])
                value = float(np.broadcast_to(z, seg.t.shape)[i])
                with np.errstate(all="ignore"):   # finite on signals of unit size: overflow
                    small = np.asarray(term.factor.evaluate(
                        {k: np.asarray(v, dtype=float) / np.max(np.abs(v), initial=1e-300)
                         for k, v in seg.values.items()}, seg.t), dtype=float)
                if np.isinf(value) and np.isfinite(np.broadcast_to(small, seg.t.shape)[i]):
                    raise InputDataError(
                        f"record {seg.record}: the term {term.factor} overflows at t = "
                        f"{seg.t[i]:.6g} s (row {int(seg.rows[i])}): the signals are too "
                        f"large for it in these units; express them in other units")
                raise InputDataError(
                    f"record {seg.record}: the term {term.factor} is {value} at t = "
                    f"{seg.t[i]:.6g} s (row {int(seg.rows[i])}): the data leave its "
                    f"domain (a division by zero, the log or square root of a "
                    f"non-positive value)")


#: Difference orders of :func:`white_noise_floor`.
NOISE_ORDERS = (4, 8)


def white_noise_floor(samples):
    """Whether white noise shows in a signal's differences, and its variance.

    The ``k``-th difference of white noise of variance ``sigma^2`` has the variance
    ``C(2k, k) sigma^2`` for every ``k``; that of a sampled band-limited signal,
    divided by ``C(2k, k)``, falls geometrically with ``k``.  When the normalised
    variances of the 4th and 8th differences agree within a factor 2, the differences
    have reached a noise floor; otherwise the signal itself dominates them (few
    samples per period, or no visible noise).

    Parameters
    ----------
    samples : array_like
        The signal (uniformly sampled).

    Returns
    -------
    visible : bool
        True when the differences have reached a white-noise floor.
    variance : float
        The normalised variance of the 8th differences (an upper bound on the noise
        variance).
    """
    x = np.asarray(samples, dtype=float)
    low, high = NOISE_ORDERS
    if len(x) <= 2 * high:
        return False, float("nan")
    normalised = [float(np.mean(np.diff(x, k) ** 2)) / math.comb(2 * k, k)
                  for k in NOISE_ORDERS]
    return bool(normalised[1] >= 0.5 * normalised[0]), normalised[1]
