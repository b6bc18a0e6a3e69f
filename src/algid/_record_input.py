"""The record types every entry point takes, and the reading of one column.

A *record* is a mapping of column name -> samples.  :func:`algid.estimate`,
:class:`algid.OnlineEstimator`, :func:`algid.identify` and :class:`algid.Tracker` all
take, through :func:`as_record`:

- a mapping (``dict``, or anything with ``keys()`` and ``[]``);
- a pandas ``DataFrame``: its columns, and its index as a time column when the index
  holds times (floats, dates or durations, or any index named ``t`` or ``time``); a
  plain row-number index is not time;
- an xarray ``Dataset``: its data variables and coordinates (a dimension coordinate
  ``time`` is the time column);
- a python-control ``TimeResponseData``: ``t`` and the inputs and outputs by their
  labels (the default labels ``u[0]``, ``y[0]`` of a single input and output are also
  readable as ``u`` and ``y``).

None of these libraries is imported: the types are recognised by their attributes.
:func:`read_column` turns one column into float samples with the same refusals and
messages wherever it is read (masked samples become NaN, that is missing).
"""

from __future__ import annotations

import numpy as np

from algid.errors import InputDataError

__all__ = ["TIME_COLUMNS", "is_record", "is_timeresponse", "as_record", "read_column",
           "refuse_unusable"]

#: Column names taken as the time axis when neither ``time`` nor ``rate`` is given.
TIME_COLUMNS = ("t", "time")


def is_timeresponse(data) -> bool:
    """Whether ``data`` is a python-control ``TimeResponseData`` (by its attributes)."""
    return hasattr(data, "time") and hasattr(data, "outputs") and hasattr(data, "inputs")


def _is_dataframe(data):
    return hasattr(data, "columns") and hasattr(data, "index") and hasattr(data, "iloc")


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
    if _is_dataframe(data):
        return _dataframe_columns(data, what)
    if _is_dataset(data):
        return {str(name): np.asarray(variable) for name, variable in data.variables.items()}
    return data


def _series_values(series):
    """A pandas column as an array; a nullable numeric column's missing values as NaN."""
    dtype = series.dtype
    if not isinstance(dtype, np.dtype) and getattr(dtype, "kind", "O") in "iuf":
        return series.to_numpy(dtype=float, na_value=np.nan)
    return series.to_numpy()


def _dataframe_columns(frame, what):
    columns = {name: _series_values(frame[name]) for name in frame.columns}
    index = frame.index
    if getattr(index, "nlevels", 1) != 1 or type(index).__name__ == "RangeIndex":
        return columns
    kind = getattr(index.dtype, "kind", "O")
    if not (kind in "fmM" or index.name in TIME_COLUMNS):
        return columns     # row numbers (a filtered frame keeps its old ones): not time
    name = "t" if index.name is None else index.name
    stamps = index.to_numpy()
    if name in columns:
        same = np.asarray(columns[name])
        if same.shape != stamps.shape or not np.array_equal(same, stamps):
            raise InputDataError(f"{what}: the DataFrame's index and its column {name!r} "
                                 f"both hold times, and they differ; drop one")
    columns[name] = stamps
    return columns


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
                             f".astype(float))")
    if kind in "mM" and not dates:
        raise InputDataError(f"{what} holds dates or durations, not measurements")


def read_column(values, what, *, time=False):
    """One column as 1-D float samples, or a one-line refusal.

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

    Returns
    -------
    numpy.ndarray

    Raises
    ------
    InputDataError
        Not numeric, 2-D, complex, boolean, dates (for a signal), or numbers beyond
        floating point.
    """
    if isinstance(values, np.ma.MaskedArray):  # masked samples are missing, as NaN are
        try:
            values = np.ma.filled(values.astype(float), np.nan)
        except (TypeError, ValueError):
            raise InputDataError(f"{what} is not numeric") from None
    try:
        values = np.asarray(values)
    except (TypeError, ValueError):
        raise InputDataError(f"{what} is not numeric") from None
    refuse_unusable(values, what, dates=time)
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
