"""Fleets of records: :func:`identify_many`, one :func:`algid.identify` per record.

A fleet is many records of the same kind of system (machines, runs, units), each
identified on its own with one equation.  The records come as a long pandas
``DataFrame`` (an id column names each row's record, its rows in order), as a mapping
id -> record, or as a Dask ``DataFrame`` (its groups are put together and identified on
the workers, never on the caller).  The result is a pandas ``DataFrame`` indexed by id:
one row per record (:meth:`IdentificationResult.to_dict`), and an ``error`` column
holding the one-line refusal of a record that :func:`algid.identify` refused; the
others go on.

Where the work runs: on the active ``dask.distributed`` client when there is one (a
task per record; ``distributed`` is only looked for when it has been imported, so a
fleet without a cluster never imports it), else in this process, record after record
(a Dask ``DataFrame`` without a client: by dask's configured scheduler).  Each task
calls ``identify`` on its record with the same arguments, so every row is bit for bit
the one ``identify`` gives.  What travels to the workers is the equation (a string or
a parsed ``Model``; a compiled model is sent as its ``Model``), the options and the
records; the rows come back.

pandas is imported when a fleet is identified, dask when a Dask ``DataFrame`` is given:
``import algid`` imports neither (``algid[fleet]`` installs them).
"""

from __future__ import annotations

import inspect
import pickle
import sys
import time
import types
import uuid

import numpy as np

from algid.errors import AlgidError, InputDataError, ModelError

__all__ = ["identify_many", "fleet_outliers", "fleet_row", "fleet_groups", "FLEET_KEYS",
           "OUTLIER_THRESHOLD"]

#: Columns of the table of :func:`identify_many` besides those of a result's row.
FLEET_KEYS = ("error",)

#: Seconds between two updates of the progress count on a terminal (and elsewhere).
PROGRESS_INTERVAL = (0.5, 10.0)


def fleet_row(record, equation, parameters, options):
    """One row of the table of :func:`identify_many`: ``identify`` on one record.

    Parameters
    ----------
    record : record or list of records
        What :func:`algid.identify` takes.
    equation : str or Model
        The model.
    parameters : str, sequence of str or None
        Its unknowns.
    options : dict
        Keyword arguments of :func:`algid.identify`.

    Returns
    -------
    dict
        :meth:`IdentificationResult.to_dict` and ``error`` None; or only ``error``: the
        one-line message of the :class:`~algid.errors.AlgidError` that refused the
        record.
    """
    from algid.identification._identify import identify

    try:
        row = identify(record, equation, parameters, **options).to_dict()
    except AlgidError as exc:
        return {"error": " ".join(str(exc).split()) or type(exc).__name__}
    row["error"] = None
    return row


def fleet_groups(frame, by):
    """The records of a long table: id -> its rows (in order), without the id column.

    Parameters
    ----------
    frame : pandas.DataFrame
        Rows of every record, an id column ``by``.
    by : str
        The id column.

    Returns
    -------
    dict
        Id -> ``DataFrame``, in the order of each id's first row (the index kept: a
        time index stays the time axis).
    """
    groups = frame.groupby(by, sort=False, observed=True, dropna=False)
    return {key: group.drop(columns=by) for key, group in groups}


def _fleet_row_of_parts(parts, equation, parameters, options):
    """:func:`fleet_row` of a record spread over partitions (a Dask ``DataFrame``)."""
    import pandas as pd

    record = parts[0] if len(parts) == 1 else pd.concat(parts)
    return fleet_row(record, equation, parameters, options)


def _ids_in(frame, by):
    """The ids of a partition, in order of first appearance, and whether one is missing."""
    column = frame[by]
    return column.drop_duplicates().tolist(), bool(column.isna().any())


# ------------------------------------------------------------------------- checks


def _is_pandas_frame(data):
    pandas = sys.modules.get("pandas")
    return pandas is not None and isinstance(data, pandas.DataFrame)


def _is_dask_collection(data):
    return (type(data).__module__.split(".")[0] == "dask"
            and hasattr(data, "to_delayed") and hasattr(data, "npartitions"))


def _is_record(value):
    """Whether a value of a mapping is a record (or a list of records), not samples."""
    from algid._record_input import is_record

    if isinstance(value, (list, tuple)):
        return bool(value) and all(_is_record(v) for v in value)
    series = hasattr(value, "index") and hasattr(value, "iloc") and not hasattr(
        value, "columns")
    return is_record(value) and not series and not isinstance(value, np.ndarray)


def _check_by(by, columns, what):
    if by is None:
        raise InputDataError(f"identify_many: {what} needs by= naming its id column (the "
                             f"column that says which record a row belongs to)")
    if isinstance(by, (list, tuple)):
        raise InputDataError(f"identify_many: by must name one column, got {by!r:.60}")
    try:
        known = by in columns
    except TypeError:   # an unhashable label
        known = False
    if not known:
        shown = ", ".join(str(c) for c in list(columns)[:12])
        more = ", ..." if len(columns) > 12 else ""
        raise InputDataError(f"identify_many: by={by!r:.40} is not a column of the "
                             f"{what} (columns: {shown}{more})")


def _check_progress(progress):
    if progress is not None and not isinstance(progress, (bool, np.bool_)):
        raise InputDataError(f"identify_many: progress must be True, False or None, got "
                             f"{progress!r:.40}")
    if progress is None:
        return bool(getattr(sys.stderr, "isatty", lambda: False)())
    return bool(progress)


def _model_arguments(equation, parameters, options, index_name):
    """Check the equation and options once for the whole fleet; the equation and
    parameters to send to every task (a compiled model as its ``Model``)."""
    from algid.identification._arguments import check_arguments, check_model_columns
    from algid.identification._identify import identify
    from algid.identification._methods import METHODS
    from algid.identification._output_error import check_refine
    from algid.identification._result import check_row_names
    from algid.identification._window_rule import check_multiplicities
    from algid.models._argument import estimator_module
    from algid.models._compiled import model_of
    from algid.models._grammar import parse_equation
    from algid.models._model import Model

    known = {name: p.default for name, p in inspect.signature(identify).parameters.items()
             if p.kind is p.KEYWORD_ONLY}
    unknown = [name for name in options if name not in known]
    if unknown:
        raise TypeError(f"identify_many() got an unexpected keyword argument "
                        f"{unknown[0]!r} (identify's options: {', '.join(known)})")
    given = {**known, **options}
    check_refine(given["refine"])
    if isinstance(equation, (list, tuple)) or given["hidden"] is not None or \
            hasattr(equation, "EQUATIONS"):  # (a compiled system)
        raise ModelError("identify_many takes one equation; identify a system of equations "
                         "record by record with algid.identify")
    if isinstance(equation, types.ModuleType):  # a compiled model: its own equation
        equation = model_of(estimator_module(equation, parameters))
    multiplicities = check_arguments(
        equation, parameters, time=given["time"], rate=given["rate"], output=given["output"],
        window=given["window"], method=given["method"], methods=METHODS,
        multiplicities=given["multiplicities"], name=given["name"],
        iterations=given["iterations"])
    model = equation if isinstance(equation, Model) else parse_equation(
        equation, parameters, output=given["output"], name=given["name"])
    check_model_columns(model, given["time"])
    check_multiplicities(model, multiplicities)
    check_row_names(model.parameters, FLEET_KEYS + (str(index_name),))
    return model, equation


def _sendable(value, what):
    """Refuse what cannot travel to a worker (pickle) with a one-line message."""
    try:
        pickle.dumps(value)
    except Exception as exc:   # any failure of pickling: not sendable
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise InputDataError(f"identify_many: {what} cannot be sent to the workers "
                             f"({reason:.120})") from None


# ----------------------------------------------------------------------- progress


class _Progress:
    """The count of records identified, on standard error: in place on a terminal
    (every half second), a line every ten seconds elsewhere, and a last line."""

    def __init__(self, total, shown):
        self.total, self.shown = total, shown
        self.done = self.refused = 0
        self.terminal = bool(getattr(sys.stderr, "isatty", lambda: False)())
        self.interval = PROGRESS_INTERVAL[0 if self.terminal else 1]
        self.last = time.monotonic()

    def add(self, row):
        self.done += 1
        self.refused += row is not None and row.get("error") is not None
        if self.shown and time.monotonic() - self.last >= self.interval:
            self._write(end="" if self.terminal else "\n")

    def _write(self, end):
        start = "\r" if self.terminal else ""
        refused = f", {self.refused} refused" if self.refused else ""
        sys.stderr.write(f"{start}identify_many: {self.done}/{self.total} records"
                         f"{refused}{end}")
        sys.stderr.flush()
        self.last = time.monotonic()

    def close(self):
        if self.shown:
            self._write(end="\n")


# -------------------------------------------------------------------------- runs


def _active_client():
    """The active ``dask.distributed`` client, or None (``distributed`` not imported
    means none was started)."""
    if "distributed" not in sys.modules:
        return None
    try:
        from distributed import default_client

        return default_client()
    except (ImportError, ValueError):   # ValueError: no client
        return None


def _run_serial(records, call, progress):
    rows = []
    for record in records:
        rows.append(fleet_row(record, *call))
        progress.add(rows[-1])
    return rows


def _collect(client, futures, progress):
    """The rows of ``futures`` in their order, counted as they finish."""
    from distributed import as_completed

    try:
        if not progress.shown:
            return client.gather(futures)
        done = {}
        for future, row in as_completed(futures, with_results=True):
            done[future.key] = row
            progress.add(row)
        return [done[future.key] for future in futures]
    finally:
        client.cancel(futures)


def _run_on_client(client, records, call, progress):
    _sendable(call, "the equation and options")
    scattered = client.scatter(list(records), hash=False)
    futures = client.map(fleet_row, scattered, *[[value] * len(scattered) for value in call],
                         pure=False)
    return _collect(client, futures, progress)


def _dask_tasks(frame, by, call):
    """One delayed row per record of a Dask ``DataFrame``, and the ids (first a pass
    over the id column alone, then each record put together from its partitions)."""
    import dask

    found = dask.compute(*[dask.delayed(_ids_in)(part, by)
                           for part in frame[[by]].to_delayed()])
    if any(missing for _, missing in found):
        raise InputDataError(f"identify_many: the id column {by!r:.40} has missing values")
    holding = {}
    for number, (ids, _) in enumerate(found):
        for key in ids:
            holding.setdefault(key, []).append(number)
    if not holding:
        raise InputDataError("identify_many: no records (the Dask DataFrame has no rows)")
    splits = [dask.delayed(fleet_groups, pure=True)(part, by) for part in frame.to_delayed()]
    prefix = f"algid-identify-{uuid.uuid4().hex}-"
    tasks = [dask.delayed(_fleet_row_of_parts, pure=True)(
        [splits[number][key] for number in numbers], *call, dask_key_name=f"{prefix}{i}")
        for i, (key, numbers) in enumerate(holding.items())]
    return list(holding), tasks, prefix


def _run_dask(frame, by, call, client, progress_shown):
    ids, tasks, prefix = _dask_tasks(frame, by, call)
    progress = _Progress(len(ids), progress_shown)
    if client is not None:
        _sendable(call, "the equation and options")
        rows = _collect(client, client.compute(tasks), progress)
    else:
        import dask
        from dask.callbacks import Callback

        class _Count(Callback):
            def _posttask(self, key, result, dsk, state, worker_id):
                if isinstance(key, str) and key.startswith(prefix):
                    progress.add(result)

        with _Count():
            rows = dask.compute(*tasks)
    progress.close()
    return ids, list(rows)


def _table(ids, rows, parameters, index_name):
    import pandas as pd

    columns = (list(parameters) + [f"stderr_{p}" for p in parameters]
               + [f"numerical_error_{p}" for p in parameters]
               + ["window", "n_samples", "estimate", "warnings", "error"])
    index = pd.Index(ids, name=index_name, tupleize_cols=False)
    table = pd.DataFrame.from_records(rows, index=index, columns=columns)
    for column in columns[:3 * len(parameters) + 1]:
        table[column] = table[column].astype(float)
    table["n_samples"] = table["n_samples"].astype("Int64")
    for column in ("estimate", "warnings", "error"):
        values = table[column].astype(object)
        table[column] = values.where(values.notna(), None)
    return table


#: A record's parameter is an outlier of its fleet when it is further than this many
#: spreads from the fleet's median (:func:`fleet_outliers`).
OUTLIER_THRESHOLD = 3.5


def fleet_outliers(table, parameters=None, *, threshold=OUTLIER_THRESHOLD):
    """The records whose parameters stand out from their fleet.

    A record's value ``x`` of a parameter is an outlier when
    ``|x - median| > threshold * sqrt(s**2 + e**2)``, where the median and ``s`` (the
    median absolute deviation times 1.4826, the standard deviation of a normal
    spread) are the fleet's, over the records identified, and ``e`` is the record's
    standard error: a machine off by more than its fleet's spread and its own
    uncertainty together.  Robust to the outliers themselves (up to half the fleet).

    Parameters
    ----------
    table : pandas.DataFrame
        The table of :func:`identify_many`.
    parameters : sequence of str, optional
        The parameters to look at (default: every column with a ``stderr_`` column).
    threshold : float
        Spreads from the median (default 3.5).

    Returns
    -------
    pandas.DataFrame
        Booleans, a column per parameter, indexed as ``table`` (False for a refused
        record).

    Raises
    ------
    InputDataError
        A parameter the table has no column (or standard error) for, or a threshold
        that is not a positive number.

    Examples
    --------
    >>> import pandas as pd
    >>> from algid.identification import fleet_outliers
    >>> table = pd.DataFrame({"K": [3.0, 3.1, 2.9, 3.05, 6.0],
    ...                       "stderr_K": [0.01] * 5}, index=list("abcde"))
    >>> fleet_outliers(table)["K"].tolist()
    [False, False, False, False, True]
    """
    import pandas as pd

    if parameters is None:
        parameters = [c[len("stderr_"):] for c in table.columns
                      if str(c).startswith("stderr_") and c[len("stderr_"):] in table]
    elif isinstance(parameters, str):
        parameters = parameters.split()
    if isinstance(threshold, bool) or not isinstance(threshold, (int, float)) \
            or not threshold > 0 or not np.isfinite(threshold):
        raise InputDataError(f"threshold must be a positive number of spreads, got "
                             f"{threshold!r}")
    flags = {}
    for p in parameters:
        if p not in table or f"stderr_{p}" not in table:
            raise InputDataError(f"the table has no column {p!r} with its standard error "
                                 f"stderr_{p} (columns: {', '.join(map(str, table.columns))})")
        x = table[p].astype(float).to_numpy()
        e = table[f"stderr_{p}"].astype(float).to_numpy()
        known = np.isfinite(x)
        median = float(np.median(x[known])) if known.any() else np.nan
        spread = 1.4826 * float(np.median(np.abs(x[known] - median))) if known.any() else 0.0
        with np.errstate(invalid="ignore"):
            flags[p] = known & (np.abs(x - median)
                                > threshold * np.sqrt(spread ** 2 + np.nan_to_num(e) ** 2))
    return pd.DataFrame(flags, index=table.index)


def identify_many(data, equation, parameters=None, *, by=None, progress=None,
                  **identify_kwargs):
    """Identify every record of a fleet on its own: a table of results, one row each.

    :func:`algid.identify` on each record with the same equation and options; a record
    it refuses gets a row with the refusal in its ``error`` column and the fleet goes
    on.  On the active ``dask.distributed`` client when there is one (a task per
    record, run by its workers), else in this process, one record after the other.

    Parameters
    ----------
    data : pandas.DataFrame, mapping or dask.dataframe.DataFrame
        The records: a long ``DataFrame`` whose column ``by`` holds each row's record id
        (a record is the rows of one id, in their order, without that column; the
        index is kept, so a time index stays the time axis); a mapping id -> record
        (anything :func:`algid.identify` takes: a mapping of columns, a ``DataFrame``,
        a list of records identified together...); or a Dask ``DataFrame`` with a
        column ``by``, whose records are put together from its partitions and
        identified on the workers (or by dask's configured scheduler without a
        client).
    equation : str, Model or module
        The model, as for :func:`algid.identify`.
    parameters : sequence of str or str, optional
        The unknown parameters, as for :func:`algid.identify`.
    by : str, optional
        The id column of a ``DataFrame`` (not for a mapping: its keys are the ids).
    progress : bool, optional
        Count the records done on standard error (``identify_many: 40/100 records, 2
        refused``): in place on a terminal, a line every ten seconds elsewhere.
        Default: on when standard error is a terminal.
    **identify_kwargs
        The options of :func:`algid.identify` (``time``, ``rate``, ``window``,
        ``method``, ``refine``...), the same for every record.

    Returns
    -------
    pandas.DataFrame
        Indexed by record id (named ``by``, or ``id`` for a mapping), one row per
        record in the order they come (a mapping's order, the first row of each id in
        a ``DataFrame``): the columns of :meth:`IdentificationResult.to_dict` (each
        parameter, ``stderr_<p>``, ``numerical_error_<p>``, ``window``, ``n_samples``,
        ``estimate``, ``warnings``) and ``error``: None, or the one-line message of
        the :class:`~algid.errors.AlgidError` that refused the record (its other
        columns NaN or None).

    Raises
    ------
    InputDataError
        Data that is not a fleet (one record, a list, an empty table), a ``by`` that
        is not one of its columns, missing ids, a bad option.
    ModelError
        A bad equation, or a parameter named like a column of the table.
    TypeError
        A keyword argument that :func:`algid.identify` does not take.

    Examples
    --------
    >>> import algid
    >>> from algid.simulation import simulate
    >>> fleet = {}
    >>> for unit, damping in enumerate([1.5, 2.0, 2.5]):
    ...     sim = simulate("sine", c=damping, frequency=3.0, duration=4.0, rate=100.0,
    ...                    noise_std=1e-4, seed=unit)
    ...     fleet[f"unit{unit}"] = {"t": sim.t, "f": sim.f, "x": sim.x}
    >>> fleet["broken"] = {"t": sim.t[:5], "f": sim.f[:5], "x": sim.x[:5]}
    >>> table = algid.identify_many(fleet, "x'' + B*x' + K*x = f", "B K", refine=False)
    >>> table["B"].round(2).tolist()[:3], table["error"].notna().tolist()
    ([1.5, 2.0, 2.5], [False, False, False, True])
    """
    shown = _check_progress(progress)
    _require_pandas()
    if _is_dask_collection(data):
        if not hasattr(data, "columns"):
            raise InputDataError("identify_many: a Dask Series is one signal; give a Dask "
                                 "DataFrame with an id column (by=)")
        _check_by(by, list(data.columns), "Dask DataFrame")
        model, send = _model_arguments(equation, parameters, identify_kwargs, by)
        ids, rows = _run_dask(data, by, (send, parameters, identify_kwargs), _active_client(),
                              shown)
        return _table(ids, rows, model.parameters, by)
    if _is_pandas_frame(data):
        _check_by(by, list(data.columns), "DataFrame")
        model, send = _model_arguments(equation, parameters, identify_kwargs, by)
        if data.empty:
            raise InputDataError("identify_many: no records (the DataFrame has no rows)")
        if data[by].isna().any():
            raise InputDataError(f"identify_many: the id column {by!r:.40} has missing "
                                 f"values (rows {_first_missing(data[by])})")
        groups = fleet_groups(data, by)
        index_name = by
    elif isinstance(data, (list, tuple)):
        raise InputDataError("identify_many: data is a list; give a mapping id -> record "
                             "(e.g. dict(enumerate(records))) or a long DataFrame with an "
                             "id column")
    elif hasattr(data, "keys") and hasattr(data, "__getitem__") and not hasattr(
            data, "data_vars"):
        if by is not None:
            raise InputDataError("identify_many: by= names the id column of a DataFrame; "
                                 "the keys of a mapping are its ids")
        model, send = _model_arguments(equation, parameters, identify_kwargs, "id")
        groups = {key: data[key] for key in data.keys()}
        if not groups:
            raise InputDataError("identify_many: no records (the mapping is empty)")
        if not any(_is_record(value) for value in groups.values()):
            raise InputDataError("identify_many: data is one record (its values are "
                                 "samples, not records): use identify, or give a mapping "
                                 "id -> record")
        index_name = "id"
    else:
        raise InputDataError(f"identify_many: data must be a long DataFrame with an id "
                             f"column, a mapping id -> record or a Dask DataFrame, got "
                             f"{type(data).__name__}")
    call = (send, parameters, identify_kwargs)
    progress_count = _Progress(len(groups), shown)
    client = _active_client()
    if client is None:
        rows = _run_serial(groups.values(), call, progress_count)
    else:
        rows = _run_on_client(client, groups.values(), call, progress_count)
    progress_count.close()
    return _table(list(groups), rows, model.parameters, index_name)


def _require_pandas():
    """The table is a pandas DataFrame: refuse at once, not after the fleet, without it."""
    try:
        import pandas  # noqa: F401
    except ModuleNotFoundError:
        raise ModuleNotFoundError("identify_many returns a pandas DataFrame: pip install "
                                  "'algid[fleet]'", name="pandas") from None


def _first_missing(column):
    rows = np.flatnonzero(column.isna().to_numpy())
    shown = ", ".join(str(r) for r in rows[:5])
    return shown + (", ..." if rows.size > 5 else "")

