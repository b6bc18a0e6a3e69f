"""The record layer: the record types every entry point takes, one column, the time axis.

A *record* is a mapping of column name -> samples.  :func:`algid.estimate`,
:class:`algid.OnlineEstimator`, :func:`algid.identify` and :class:`algid.Tracker` all
take, through :func:`as_record`:

- a mapping (``dict``, or anything with ``keys()`` and ``[]``);
- a pandas ``DataFrame``: its columns, and its index as a time column when the index
  holds times (floats, dates or durations, or integers in an index named ``t`` or
  ``time``); a plain row-number index (a ``RangeIndex``, named or not) is not time;
- an xarray ``Dataset``: its data variables and coordinates (a dimension coordinate
  ``time`` is the time column);
- a python-control ``TimeResponseData``: ``t`` and the inputs and outputs by their
  labels (the default labels ``u[0]``, ``y[0]`` of a single input and output are also
  readable as ``u`` and ``y``).

None of these libraries is imported: the types are recognised by their attributes.
:func:`read_column` turns one column into float samples with the same refusals and
messages wherever it is read (masked samples become NaN, that is missing), and
:func:`record_columns` reads a record's signals and its sample times: from a time
column (``t`` or ``time`` by default), or from a sampling rate; a rate given with a
time column must agree with it (:data:`RATE_TOLERANCE`).  Times of type ``datetime64``
or ``timedelta64`` become seconds from the first sample.  Cutting a record at its gaps
is :func:`algid.identify`'s (``algid.identification._records``).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from algid.errors import InputDataError

__all__ = ["TIME_COLUMNS", "RATE_TOLERANCE", "STEP_RANGE", "is_record", "is_timeresponse",
           "timeresponse_pair",
           "as_record", "read_column", "refuse_unusable", "record_columns", "check_rate",
           "check_rate_agrees", "refuse_nonfinite", "refuse_infinite", "refuse_missing",
           "refuse_unequal_lengths", "refuse_too_few", "refuse_not_increasing", "read_chunk",
           "refuse_stream_dates", "GAP_FACTOR",
           "refuse_nonfinite_sample",
           "column_list",
           "first_non_number"]

#: Column names taken as the time axis when neither ``time`` nor ``rate`` is given.
TIME_COLUMNS = ("t", "time")

#: A rate and a time column agree when the rate's step is within this fraction of the
#: column's median step.
RATE_TOLERANCE = 1e-3

#: A step longer than this many median steps is a gap (missing rows).
GAP_FACTOR = 1.5

#: Sampling steps (s) accepted: the window integrals divide by powers of the window's
#: span up to the 2(k+1)-th (noise weights of a k-th derivative), which leave the
#: floating-point range beyond about 1e-60 and 1e40 s (measured on a second-order
#: model); this range keeps a wide margin and holds every physical record.
STEP_RANGE = (1e-30, 1e30)


def is_timeresponse(data) -> bool:
    """Whether ``data`` is a python-control ``TimeResponseData`` (by its attributes; a
    DataFrame's columns ``time``, ``inputs``, ``outputs`` are attributes too)."""
    return (not _is_dataframe(data) and not _is_dataset(data)
            and all(hasattr(data, name) for name in ("time", "outputs", "inputs",
                                                     "output_labels", "input_labels")))


def _is_dataframe(data):
    return hasattr(data, "columns") and hasattr(data, "index") and hasattr(data, "iloc")


def _is_series(data):
    return hasattr(data, "index") and hasattr(data, "iloc") and not hasattr(data, "columns")


def _is_dataset(data):
    return hasattr(data, "data_vars") and hasattr(data, "coords") and hasattr(data, "dims")


def is_record(data) -> bool:
    """Whether ``data`` is a record of named columns (any of the types in the module's
    description).

    Parameters
    ----------
    data : object

    Returns
    -------
    bool
    """
    return (isinstance(data, dict) or is_timeresponse(data) or _is_dataframe(data)
            or _is_dataset(data) or (hasattr(data, "keys") and hasattr(data, "__getitem__")))


def as_record(data, what="record"):
    """The record as a mapping of column name -> samples.

    Parameters
    ----------
    data : mapping, pandas.DataFrame, xarray.Dataset or control.TimeResponseData
        See the module's description.
    what : str, optional
        Names the record in messages (``"record 0"``).

    Returns
    -------
    mapping
        ``data`` itself when it is a plain mapping; else a ``dict`` of its columns.

    Raises
    ------
    InputDataError
        A DataFrame whose time index contradicts its time column, a TimeResponseData
        of several traces.
    """
    if is_timeresponse(data):
        return _timeresponse_columns(data, what)
    if _is_series(data):
        raise InputDataError(f"{what} is a pandas Series, one signal: give a DataFrame (e.g. "
                             f"series.to_frame()) or a mapping of column name -> samples")
    if _is_dataframe(data):
        return _dataframe_columns(data, what)
    if _is_dataset(data):
        return {str(name): np.asarray(variable) for name, variable in data.variables.items()}
    return data


def _series_values(values):
    """A pandas column or index as an array: a nullable numeric one's missing values as
    NaN, dates with a time zone as UTC dates."""
    dtype = values.dtype
    if getattr(dtype, "tz", None) is not None:   # (a Series' own tz_convert is its index's)
        values = values.dt.tz_convert(None) if hasattr(values, "dt") else \
            values.tz_convert(None)
    elif not isinstance(dtype, np.dtype) and getattr(dtype, "kind", "O") in "iuf":
        return values.to_numpy(dtype=float, na_value=np.nan)
    return values.to_numpy()


def _dataframe_columns(frame, what):
    names = list(frame.columns)
    repeated = next((name for i, name in enumerate(names) if name in names[:i]), None)
    if repeated is not None:
        raise InputDataError(f"{what}: the DataFrame has several columns named {repeated!r}")
    columns = {name: _series_values(frame[name]) for name in names}
    index = frame.index
    if getattr(index, "nlevels", 1) != 1 or type(index).__name__ == "RangeIndex":
        return columns
    kind = getattr(index.dtype, "kind", "O")
    if not (kind in "fmM" or index.name in TIME_COLUMNS):
        return columns     # row numbers (a filtered frame keeps its old ones): not time
    name = "t" if index.name is None else index.name
    stamps = _series_values(index)
    if name in columns:
        same = np.asarray(columns[name])
        if same.shape != stamps.shape or not np.array_equal(same, stamps):
            raise InputDataError(f"{what}: the DataFrame's index and its column {name!r} "
                                 f"both hold times, and they differ; drop one")
    columns[name] = stamps
    return columns


def timeresponse_pair(response):
    """``t, u, y`` of a python-control ``TimeResponseData`` of one input and one output
    (the paper's form ``estimate(t, f, x)``).

    Parameters
    ----------
    response : control.TimeResponseData

    Returns
    -------
    t, u, y : numpy.ndarray

    Raises
    ------
    InputDataError
        Not one input and one output.
    """
    t = np.asarray(response.time, dtype=float)
    u = np.asarray(response.inputs, dtype=float)
    y = np.asarray(response.outputs, dtype=float)
    if u.ndim != 1 or y.ndim != 1:
        raise InputDataError(
            f"TimeResponseData must have one input and one output (got input shape {u.shape}, "
            f"output shape {y.shape}); squeeze it or pick the signals")
    return t, u, y


def _timeresponse_columns(response, what):
    inputs, outputs = np.asarray(response.inputs), np.asarray(response.outputs)
    t = np.asarray(response.time)
    if inputs.ndim > 2 or outputs.ndim > 2:
        raise InputDataError(f"{what}: the TimeResponseData holds several traces "
                             f"(inputs {inputs.shape}, outputs {outputs.shape}); give one "
                             f"trace at a time")
    columns = {}
    for labels, values, default in ((response.input_labels, inputs, "u"),
                                    (response.output_labels, outputs, "y")):
        count = values.shape[0] if values.ndim == 2 else int(values.size > 0)
        labels = list(labels or (f"{default}[{i}]" for i in range(count)))
        values = values.reshape(len(labels), -1) if values.size else values
        for label, row in zip(labels, values):
            columns[label] = row
        if len(labels) == 1 and labels[0] == f"{default}[0]":
            columns.setdefault(default, values[0])
    columns.setdefault("t", t)
    return columns


def column_list(record, most=12):
    """The record's column names for a message (the first ``most``, and their count).

    Parameters
    ----------
    record : mapping
    most : int, optional

    Returns
    -------
    str
    """
    names = list(map(str, record.keys()))
    return ", ".join(names[:most]) + (f", ... ({len(names)} columns)"
                                      if len(names) > most else "")


def first_non_number(arr):
    """The first item of an array that is no number (numbers stored as text are text).

    Parameters
    ----------
    arr : numpy.ndarray
        Of text or of objects.

    Returns
    -------
    tuple or None
        ``(row, item)``, or None if every item is a number.
    """
    if arr.dtype.kind in "US":
        items = [item.decode("latin-1") if isinstance(item, bytes) else str(item)
                 for item in arr.tolist()]
        for row, item in enumerate(items):
            try:
                float(item)
            except ValueError:
                return row, item
        return (0, items[0]) if items else None  # numbers stored as text are still text
    for row, item in enumerate(arr.tolist()):
        if not isinstance(item, numbers.Real):
            return row, item
    return None


def refuse_unusable(values, what, *, dates=False):
    """Refuse an array that is not one signal of real measurements.

    Parameters
    ----------
    values : ndarray
        The column as given.
    what : str
        Names it at the head of the message (``"record 0: column 'u'"``).
    dates : bool, optional
        Whether dates and durations are accepted (a time column).

    Raises
    ------
    InputDataError
        For a 2-D array (a column vector is one signal), complex numbers, booleans, or
        dates and durations where they are not accepted.
    """
    if sum(size > 1 for size in values.shape) > 1:
        raise InputDataError(f"{what} has shape {values.shape}: give one 1-D array per "
                             f"signal")
    kind = values.dtype.kind
    if kind == "c":
        raise InputDataError(f"{what} is complex; give real measurements (e.g. its real "
                             f"part or its modulus)")
    if kind == "b":
        raise InputDataError(f"{what} holds booleans, not measurements (convert with "
                             f".astype(float) if 0 and 1 are meant)")
    if kind in "mM" and not dates:
        raise InputDataError(f"{what} holds dates or durations, not measurements")


def _describe_scalar(values):
    """What a 0-d value is, for a message that expected samples."""
    if values is None:
        return "None"
    if isinstance(values, (str, bytes)):
        return f"a {type(values).__name__} ({values!r:.40})"
    if isinstance(values, numbers.Number) or getattr(values, "ndim", None) == 0:
        return f"one number ({values!r:.40})"
    return f"a {type(values).__name__}"


def read_column(values, what, *, time=False, every_sample=False, one_number=False):
    """One column as 1-D float samples, or a one-line refusal.

    The one reading of a signal: the paper's form (:func:`algid._signal_checks.as_signal`,
    ``what`` is ``"signal 'f'"``), a record's column (``"record 0: column 'u'"``) and a
    chunk's (``"column 'u'"``) are refused in the same words.

    Parameters
    ----------
    values : array_like
        The column as given (a masked array's masked samples become NaN: missing).
    what : str
        Names the column at the head of messages (``"record 0: column 'u'"``).
    time : bool, optional
        A time column: dates and durations are accepted and become seconds from the
        first sample (the difference taken first, in the column's own integer unit, so
        that no precision is lost to the size of the epoch).
    every_sample : bool, optional
        The estimator needs every sample (:func:`algid.estimate`): a masked sample is
        refused rather than taken as missing.
    one_number : bool, optional
        A single number is one sample (a chunk of a stream); otherwise it is refused.

    Returns
    -------
    numpy.ndarray

    Raises
    ------
    InputDataError
        Not numeric, not one array of samples (2-D, a single number, None, text),
        complex, boolean, dates (for a signal), numbers beyond floating point, or (with
        ``every_sample``) masked samples.
    """
    if isinstance(values, np.ma.MaskedArray):  # masked samples are missing, as NaN are
        masked = np.flatnonzero(np.ma.getmaskarray(values))
        if every_sample and masked.size:
            raise InputDataError(
                f"{what} has a masked sample at row {int(masked[0])} ({masked.size} "
                f"masked): every sample is needed here (fill or cut them)")
        try:
            values = np.ma.filled(values.astype(float), np.nan)
        except (TypeError, ValueError):
            raise InputDataError(f"{what} is not numeric") from None
    given = values
    try:
        values = np.asarray(values)
    except (TypeError, ValueError):
        raise InputDataError(f"{what} is not a 1-D array of numbers (ragged or "
                             f"unconvertible)") from None
    if values.ndim == 0 and values.dtype.kind in "bcmM":
        refuse_unusable(values, what, dates=time)   # (a boolean, complex, date is that)
    if values.ndim == 0 and not (one_number and (values.dtype.kind in "iuf" or isinstance(
            given, numbers.Real) and not isinstance(given, (bool, np.bool_)))):
        raise InputDataError(f"{what} is {_describe_scalar(given)}: give one 1-D array "
                             f"of samples per signal")
    refuse_unusable(values, what, dates=time)
    if values.dtype.kind in "USO":   # numbers stored as text are text
        if values.dtype.kind == "O" and any(isinstance(v, (bool, np.bool_))
                                            for v in values.reshape(-1).tolist()):
            raise InputDataError(f"{what} holds booleans, not measurements (convert with "
                                 f".astype(float) if 0 and 1 are meant)")
        bad = first_non_number(values.reshape(-1))
        if bad is not None:
            try:
                float(bad[1])
            except (TypeError, ValueError):
                raise InputDataError(f"{what} is not numeric: row {bad[0]} holds "
                                     f"{bad[1]!r}") from None
            raise InputDataError(f"{what} holds numbers stored as text (row {bad[0]}: "
                                 f"{bad[1]!r}): convert them (.astype(float))")
    if values.dtype.kind in "mM":
        values = values.reshape(-1)
        return (values - values[0]) / np.timedelta64(1, "s") if len(values) else \
            values.astype(float)
    try:
        return values.astype(float).reshape(-1)
    except (TypeError, ValueError):
        raise InputDataError(f"{what} is not numeric") from None
    except OverflowError:   # Python integers beyond floating point
        raise InputDataError(f"{what} holds numbers too large for floating point "
                             f"(beyond 1.8e308)") from None


def refuse_stream_dates(values, what):
    """Refuse dates or durations as a stream's times: each chunk would become seconds from
    its own first sample.

    Parameters
    ----------
    values : object
        The time column as given.
    what : str
        Names it (``"time column 't' of the chunk starting at stream sample 0"``).

    Raises
    ------
    InputDataError
    """
    if getattr(np.asarray(values), "dtype", np.dtype(float)).kind in "mM":
        raise InputDataError(f"{what} holds dates or durations: a stream's times are "
                             f"numbers of seconds (e.g. (index - start) / "
                             f"pd.Timedelta('1s'), the same start for every chunk)")


def _column(record, name, where, label, every_sample=False, one_number=False):
    if name not in record:
        available = column_list(record)
        hint = (f"; if {name!r} is an unknown, add it to the parameters"
                if label == "signal" else "")
        raise InputDataError(f"{where}: no column {name!r} for the {label} "
                             f"(columns: {available}){hint}")
    return read_column(record[name], f"{where}: column {name!r}",
                       time=label == "time", every_sample=every_sample,
                       one_number=one_number)


def check_rate(rate, what="rate"):
    """The sampling rate as a float, or a one-line error.

    Parameters
    ----------
    rate : float
        Sampling rate (Hz): a real number (not a boolean or a string), positive and
        finite, whose step lies in :data:`STEP_RANGE`.
    what : str
        Name of the argument, for the message.

    Returns
    -------
    float

    Raises
    ------
    InputDataError
    """
    if isinstance(rate, (bool, np.bool_)) or not isinstance(rate, numbers.Real):
        raise InputDataError(f"{what} must be a number of Hz, got {rate!r}")
    value = float(rate)
    if not (math.isfinite(value) and value > 0):
        raise InputDataError(f"{what} must be a positive finite number of Hz, got {rate!r}")
    low, high = STEP_RANGE
    if not low <= 1.0 / value <= high:
        raise InputDataError(
            f"{what} {value:g} Hz gives a sampling step of {1.0 / value:.3g} s, outside "
            f"{low:g} .. {high:g} s: the estimators' integrals would overflow or "
            f"underflow; express the time in other units")
    return value


def check_rate_agrees(rate, t, name, where):
    """Refuse a sampling rate that contradicts a time column.

    Parameters
    ----------
    rate : float
        The rate given (Hz).
    t : numpy.ndarray
        The time column (s), strictly increasing.
    name : str
        The time column's name.
    where : str
        Prefix of the message (a record or a file).

    Raises
    ------
    InputDataError
        If ``1 / rate`` differs from the column's median step by more than
        :data:`RATE_TOLERANCE` of it.
    """
    if len(t) < 2:
        return
    step = float(np.median(np.diff(t)))
    if not abs(step * rate - 1.0) <= RATE_TOLERANCE:
        raise InputDataError(
            f"{where}: rate {rate:g} Hz contradicts time column {name!r} (sampled at "
            f"{1.0 / step:.6g} Hz); give the time column or a rate that agrees with it")


def _time_axis(record, where, n, time, rate, one_number=False, stream=False):
    if rate is not None:
        rate = check_rate(rate)
    if time is None:
        time = next((c for c in TIME_COLUMNS if c in record), None)
        if time is None and rate is None:
            raise InputDataError(f"{where}: no time column ({' or '.join(TIME_COLUMNS)}); "
                                 f"give time= (a column name) or rate= (Hz)")
    if time is None:
        return np.arange(n) / rate, None
    if stream and time in record:
        refuse_stream_dates(record[time], f"{where}: time column {time!r}")
    t = _column(record, time, where, "time", one_number=one_number)
    if len(t) != n:
        raise InputDataError(f"{where}: time column {time!r} has {len(t)} samples, "
                             f"the signals {n}")
    refuse_nonfinite_sample(t, f"{where}: time column {time!r}")
    refuse_not_increasing(t, f"{where}: time column {time!r}")
    steps = np.diff(t)
    if rate is not None:
        check_rate_agrees(rate, t, time, where)
    if len(steps):
        median, low, high = float(np.median(steps)), *STEP_RANGE
        if not low <= median <= high:
            raise InputDataError(
                f"{where}: time column {time!r} has a step of {median:.3g}, outside "
                f"{low:g} .. {high:g} s: the window integrals would overflow or "
                f"underflow; express the time in other units")
    return t, time


def record_columns(record, signals, *, time=None, rate=None, first_sample=0, index=0,
                   min_samples=0, every_sample=False, what=None, one_number=False,
                   stream=False):
    """The time axis and the named signals of one record, checked as :func:`algid.identify`
    checks them (no gaps are cut: the estimator needs the record whole).

    Parameters
    ----------
    record : mapping, pandas.DataFrame, xarray.Dataset or control.TimeResponseData
        Column name -> samples (:mod:`algid._record_input`).
    signals : sequence of str
        Signals to read.
    time : str, optional
        Name of the time column; by default ``t`` or ``time`` if present.
    rate : float, optional
        Sampling rate (Hz) when there is no time column.
    first_sample : int, optional
        Index of the first sample when the times come from ``rate``: sample ``i`` is at
        ``(first_sample + i) / rate`` (a stream's later chunk goes on where the previous
        one ended, at the same times as the whole record).
    index : int, optional
        The record's place among several (named in the messages).
    min_samples : int, optional
        Fewer samples are refused (before the time axis is read).
    every_sample : bool, optional
        Masked samples are refused rather than missing (:func:`read_column`).
    what : str, optional
        Names the record in messages (default ``"record {index}"``; a stream's chunk).
    one_number : bool, optional
        A single number is one sample (a chunk of a stream).
    stream : bool, optional
        The record is a stream's chunk: dates or durations as times are refused
        (:func:`refuse_stream_dates`).

    Returns
    -------
    t : numpy.ndarray
    columns : dict
        Signal name -> samples (float arrays of the same length as ``t``).

    Raises
    ------
    InputDataError
        A missing or non-numeric column, signals of different lengths, a bad time axis.
    """
    where = what or f"record {index}"
    record = as_record(record, where)
    columns = {name: _column(record, name, where, "signal", every_sample, one_number)
               for name in signals}
    refuse_unequal_lengths(columns, where)
    n = len(next(iter(columns.values()))) if columns else 0
    refuse_too_few(n, min_samples, where)
    t, _ = _time_axis(record, where, n, time, rate, one_number, stream)
    if first_sample and time is None and not any(c in record for c in TIME_COLUMNS):
        t = (first_sample + np.arange(n)) / check_rate(rate)
    return t, columns


def refuse_nonfinite_sample(values, what, why=None):
    """Refuse the first NaN or infinite sample.

    Parameters
    ----------
    values : numpy.ndarray
        Float samples.
    what : str
        Names them (``"time 't'"``, ``"input 'u'"``).
    why : str, optional
        Follows the value and its row in the message.

    Raises
    ------
    InputDataError
        ``"{what} has NaN at row 17; {why}"`` (``inf``, ``-inf``).
    """
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        row = int(bad[0])
        value = values[row]
        text = "NaN" if np.isnan(value) else "inf" if value > 0 else "-inf"
        raise InputDataError(f"{what} has {text} at row {row}" + (f"; {why}" if why else ""))


def refuse_infinite(values, what):
    """Refuse an infinite sample (no measurement: an overflow?) where NaN marks a missing
    one (:func:`algid.identify`, the tracker).

    Parameters
    ----------
    values : numpy.ndarray
        A column's float samples.
    what : str
        Names the column (``"record 0: column 'u'"``).

    Raises
    ------
    InputDataError
        Naming the value and its row.
    """
    refuse_nonfinite_sample(np.where(np.isnan(values), 0.0, values), what,
                            "a missing sample is NaN")


def refuse_missing(values, what):
    """:func:`refuse_infinite` where NaN is refused too: the estimator of
    :func:`algid.estimate` and :class:`algid.OnlineEstimator` needs every sample.

    Parameters
    ----------
    values : numpy.ndarray
    what : str

    Raises
    ------
    InputDataError
    """
    refuse_nonfinite_sample(values, what, "the estimator needs every sample (identify takes "
                                          "NaN as a gap)")


def refuse_nonfinite(columns, what):
    """:func:`refuse_missing` for every column of a record or chunk.

    Parameters
    ----------
    columns : dict
        Column name -> float samples.
    what : str
        Names the record or chunk at the head of the message (``"record 0"``).

    Raises
    ------
    InputDataError
        Naming the column, the value and its row.
    """
    for name, values in columns.items():
        refuse_missing(values, f"{what}: column {name!r}")


def refuse_unequal_lengths(columns, what=""):
    """Refuse signals of different lengths.

    Parameters
    ----------
    columns : dict
        Name -> samples.
    what : str, optional
        Names the record or chunk at the head of the message (``"record 0"``).

    Raises
    ------
    InputDataError
        Naming every signal's length.
    """
    if len({len(v) for v in columns.values()}) > 1:
        head = f"{what}: signals" if what else "signals"
        raise InputDataError(f"{head} have different lengths ("
                             + ", ".join(f"{k}: {len(v)}" for k, v in columns.items()) + ")")


def refuse_too_few(n, needed, what=""):
    """Refuse fewer than ``needed`` samples.

    Parameters
    ----------
    n, needed : int
        Samples given, samples needed.
    what : str, optional
        Names the record at the head of the message (``"record 0"``).

    Raises
    ------
    InputDataError
    """
    if n < needed:
        count = "no samples" if n == 0 else "only 1 sample" if n == 1 else f"only {n} samples"
        head = f"{what}: {count}" if what else count
        raise InputDataError(f"{head}: at least {needed} are needed")


def refuse_not_increasing(t, what, *, previous=None, first=0, unit="row"):
    """Refuse times that do not strictly increase.

    Parameters
    ----------
    t : numpy.ndarray
        The times (finite).
    what : str
        Names the time axis (``"time 't'"``, ``"record 0: time column 't'"``).
    previous : float, optional
        The time before ``t[0]`` (a stream's last sample).
    first : int, optional
        The number of ``t[0]`` in the message (a stream's count of samples before it).
    unit : str, optional
        What the number counts (``"row"``, ``"stream sample"``).

    Raises
    ------
    InputDataError
        Naming the first sample that does not follow its predecessor, and both times.
    """
    full = t if previous is None else np.concatenate(([previous], t))
    bad = np.flatnonzero(~(np.diff(full) > 0))
    if bad.size:
        i = int(bad[0])
        number = first + i + (1 if previous is None else 0)
        raise InputDataError(f"{what} does not increase at {unit} {number}: "
                             f"{full[i + 1]:.10g} after {full[i]:.10g}")


def read_chunk(chunk, signals, *, time, rate, seen, last_time, last_stamp=math.nan):
    """The times and signals of a tracker's next chunk (:class:`algid.Tracker`).

    Parameters
    ----------
    chunk : record
        Any record type of this module.
    signals : sequence of str
        The signals to read.
    time : str or None
        The time column; None with a ``rate`` (times from the count of samples), or to
        find ``t`` or ``time`` in the chunk.
    rate : float or None
        The sampling rate (Hz), if given.
    seen : int
        Samples of the stream before this chunk.
    last_time : float
        Time of the stream's last sample (``-inf`` at the start).
    last_stamp : float
        With ``rate`` and no ``time``: the last value of the stream's time column, which
        the times from the count of samples must agree with (NaN: none yet).

    Returns
    -------
    t : numpy.ndarray
        The chunk's times.
    columns : dict
        Signal name -> samples (NaN: missing).
    time : str or None
        The time column read (found in the chunk when ``time`` and ``rate`` were None).
    last_stamp : float
        ``last_stamp`` after this chunk.

    Raises
    ------
    InputDataError
        Not a record, a missing column, a column refused by :func:`read_column`, an
        infinite sample, columns of different lengths, times that are not finite or do
        not increase from the stream's last, a time column that contradicts ``rate``.
    """
    if not is_record(chunk):
        raise InputDataError("a chunk must be a record: a mapping of column name -> samples, "
                             "a pandas DataFrame, an xarray Dataset or a TimeResponseData")
    chunk = as_record(chunk, "the chunk")
    if time is None and rate is None:
        time = next((c for c in TIME_COLUMNS if c in chunk), None)
        if time is None:
            raise InputDataError(f"no time column ({' or '.join(TIME_COLUMNS)}) in the "
                                 f"stream; give time= (a column name) or rate= (Hz)")
    where = f"the chunk starting at stream sample {seen}"
    columns = {}
    for name in list(signals) + ([time] if time is not None else []):
        if name not in chunk:
            raise InputDataError(f"no column {name!r} in the chunk (columns: "
                                 f"{column_list(chunk)})")
        if name == time:
            refuse_stream_dates(chunk[name], f"time column {name!r} of {where}")
        values = read_column(chunk[name], f"column {name!r} of {where}", one_number=True)
        if name == time:
            refuse_nonfinite_sample(values, f"time column {time!r} of {where}")
        else:
            refuse_infinite(values, f"column {name!r} of {where}")
        columns[name] = values
    refuse_unequal_lengths(columns, where)
    n = len(next(iter(columns.values()))) if columns else 0
    if time is None:
        t = (seen + np.arange(n)) / rate
        given = next((c for c in TIME_COLUMNS if c in chunk), None)
        stamps = np.asarray(chunk[given]) if given is not None and n else None
        if stamps is not None and stamps.dtype.kind in "iuf":
            # a time column beside rate= must agree (as identify's), if it holds
            # numbers: within the chunk, and from the stream's last stamp on (a stream
            # of one-row chunks has no step of its own)
            stamps = stamps.astype(float).reshape(-1)
            check_rate_agrees(rate, stamps, given, "the chunk")
            _check_stamp_continues(rate, last_stamp, stamps[0], given, seen)
            last_stamp = float(stamps[-1])
        return t, columns, time, last_stamp
    t = columns.pop(time)
    if not (n == 1 and t[0] > last_time):   # (one sample of a live stream: checked)
        refuse_not_increasing(t, f"time column {time!r}", previous=last_time, first=seen,
                              unit="stream sample")
        if rate is not None and n > 1:   # (as identify's)
            check_rate_agrees(rate, t, time, "the chunk")
    if rate is not None and n:   # no closer than the rate allows (a gap may be longer)
        _check_stamp_continues(rate, last_time, t[0], time, seen, gaps=True)
    return t, columns, time, last_stamp


def _check_stamp_continues(rate, previous, stamp, name, seen, gaps=False):
    """Refuse a stream sample ``seen`` stamped ``stamp`` where the one before it was
    stamped ``previous`` (not finite: none), unless one ``1 / rate`` earlier within
    :data:`RATE_TOLERANCE` (or, where a gap may fall, ``gaps``, a gap's
    :data:`GAP_FACTOR` steps or more)."""
    if not (math.isfinite(previous) and math.isfinite(stamp)):
        return
    steps = (stamp - previous) * rate
    if abs(steps - 1.0) <= RATE_TOLERANCE or (gaps and steps > GAP_FACTOR):
        return
    raise InputDataError(
        f"rate {rate:g} Hz contradicts time column {name!r}: stream sample {seen} is "
        f"stamped {stamp - previous:.6g} s after the one before, where the rate's step is "
        f"{1.0 / rate:.6g} s; give the time column or a rate that agrees with it")
