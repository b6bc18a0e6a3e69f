"""One record read in chunks of rows: the sources of a streamed :func:`algid.identify`.

A record too long to hold in memory, or kept on disk, is read a chunk of rows at a
time, front to back, once per pass of the streamed reduction
(:mod:`algid.identification._streamed_problem`).  :func:`record_source` gives the
source of a record:

- a mapping of column name -> array, or a pandas ``DataFrame`` (time as a column or as
  its index): its columns are sliced, so NumPy memory maps (``np.load(path,
  mmap_mode="r")``) are read from disk a chunk at a time;
- a path to a Parquet file (``.parquet``, ``.pq``; read by pyarrow, its row batches
  one at a time) or a CSV file (``.csv``; pyarrow's streaming reader);
- a Dask ``DataFrame``: each pass is a chain of tasks where the partitions are (on the
  active ``dask.distributed`` client when there is one), a task feeding its partition
  to the pass's state that the previous task left (:meth:`DaskSource.reduce`); only
  the window equations and the states travel, never the samples (the automatic
  window's excerpts come from the partitions that hold them).

Each chunk is a mapping of the columns asked for (float arrays) that the record layer
(:func:`algid._record_input.record_columns`) then checks as it checks a whole record.
pyarrow and dask are imported only when a file or a Dask ``DataFrame`` is read
(``algid[fleet]`` installs them).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from algid._record_input import as_record, is_record
from algid.errors import InputDataError

__all__ = ["record_source", "is_streamed_input", "ArraySource", "ParquetSource",
           "CsvSource", "DaskSource", "PARQUET_SUFFIXES", "CSV_SUFFIXES"]

#: File names read as Parquet.
PARQUET_SUFFIXES = (".parquet", ".pq")

#: File names read as CSV (a header line of column names, then numbers).
CSV_SUFFIXES = (".csv",)


def is_streamed_input(data):
    """Whether ``data`` can only be read in chunks: a file path or a Dask ``DataFrame``.

    Parameters
    ----------
    data : object
        What :func:`algid.identify` was given.

    Returns
    -------
    bool
    """
    return isinstance(data, (str, os.PathLike)) or _is_dask_frame(data)


def _is_dask_frame(data):
    return type(data).__module__.split(".")[0] == "dask" and hasattr(data, "to_delayed")


def record_source(data):
    """The chunked reader of one record.

    Parameters
    ----------
    data : mapping, pandas.DataFrame, str, os.PathLike or dask.dataframe.DataFrame
        The record (see the module notes).

    Returns
    -------
    ArraySource, ParquetSource, CsvSource or DaskSource

    Raises
    ------
    InputDataError
        A missing file, a file of another kind, or data of another type.
    """
    if isinstance(data, (str, os.PathLike)):
        path = Path(data)
        if not path.exists():
            raise InputDataError(f"{path}: no such file")
        if not path.is_file():
            raise InputDataError(f"{path}: not a file (a streamed record is one Parquet "
                                 f"or CSV file)")
        suffix = path.suffix.lower()
        if suffix in PARQUET_SUFFIXES:
            return ParquetSource(path)
        if suffix in CSV_SUFFIXES:
            return CsvSource(path)
        raise InputDataError(f"{path}: a streamed record is a Parquet "
                             f"({', '.join(PARQUET_SUFFIXES)}) or CSV (.csv) file")
    if _is_dask_frame(data):
        return DaskSource(data)
    if is_record(data):
        return ArraySource(data)
    raise InputDataError("a streamed record is a mapping of column name -> samples, a "
                         "pandas DataFrame, a Parquet or CSV path, or a Dask DataFrame")


class _Source:
    """Chunks of rows of one record, front to back."""

    #: Rows of the record (None until a pass has counted them).
    n_rows = None

    def chunks(self, names, size):
        """The record in chunks of about ``size`` rows.

        Parameters
        ----------
        names : sequence of str
            Columns to read (those missing are left out: the record layer names them).
        size : int
            Rows per chunk (a file's own batches may be shorter).

        Yields
        ------
        first : int
            Row of the chunk's first sample in the record.
        chunk : dict
            Column name -> samples.
        """
        raise NotImplementedError

    def reduce(self, machine, names, size):
        """Feed the record's chunks in order to ``machine`` (a pass of the streamed
        reduction: ``machine.feed(first, chunk)``).

        Parameters
        ----------
        machine : object
            The pass's state, with ``feed``, ``take`` and ``absorb``.
        names : sequence of str
            Columns to read.
        size : int
            Rows per chunk.

        Returns
        -------
        object
            ``machine``, having seen every chunk.
        """
        for first, chunk in self.chunks(names, size):
            machine.feed(first, chunk)
        return machine

    def read(self, names, ranges, size):
        """Rows ``[start, stop)`` of each range, in one pass.

        Parameters
        ----------
        names : sequence of str
            Columns to read.
        ranges : sequence of tuple of int
            Increasing, disjoint row ranges.
        size : int
            Rows per chunk of the pass.

        Returns
        -------
        list of dict
            Per range, column name -> samples.
        """
        pieces = [{name: [] for name in names} for _ in ranges]
        for first, chunk in self.chunks(names, size):
            last = first + len(next(iter(chunk.values()))) if chunk else first
            for (start, stop), piece in zip(ranges, pieces):
                lo, hi = max(start, first), min(stop, last)
                if lo < hi:
                    for name in chunk:
                        piece[name].append(chunk[name][lo - first:hi - first])
            if ranges and last >= ranges[-1][1]:
                break
        return [{name: _join(parts) for name, parts in piece.items() if parts}
                for piece in pieces]


class ArraySource(_Source):
    """Columns of a mapping or a pandas ``DataFrame``, sliced (memory maps stay on disk).

    Parameters
    ----------
    record : mapping, pandas.DataFrame, xarray.Dataset or control.TimeResponseData
        Column name -> samples (:func:`algid._record_input.as_record`).
    """

    def __init__(self, record):
        self.columns = as_record(record)
        lengths = {len(self.columns[name]) for name in self.columns.keys()
                   if np.ndim(self.columns[name]) == 1}
        self.n_rows = max(lengths) if lengths else 0

    def chunks(self, names, size):
        for first in range(0, max(self.n_rows, 1), size):
            yield first, {name: _rows(self.columns[name], first, size)
                          for name in names if name in self.columns}


class ParquetSource(_Source):
    """A Parquet file read a row batch at a time (pyarrow).

    Parameters
    ----------
    path : pathlib.Path
        The file.
    """

    def __init__(self, path):
        pq = _pyarrow("parquet")
        self.path = path
        try:
            self._file = pq.ParquetFile(path)
        except Exception as error:   # pyarrow's own exception types vary by version
            raise InputDataError(f"{path}: not a readable Parquet file "
                                 f"({str(error).splitlines()[0]})") from None
        self.n_rows = self._file.metadata.num_rows
        self.columns = list(self._file.schema_arrow.names)

    def chunks(self, names, size):
        present = [name for name in names if name in self.columns]
        first = 0
        # a row group at a time (pyarrow's own batch iterator reads ahead: the whole
        # file's memory for a long record)
        for group in range(self._file.num_row_groups):
            try:
                table = self._file.read_row_group(group, columns=present, use_threads=False)
            except Exception as error:   # a damaged page: pyarrow's OSError, ArrowInvalid
                raise InputDataError(f"{self.path}: row group {group} (from row {first}) "
                                     f"cannot be read ({str(error).splitlines()[0]})") from None
            for start in range(0, table.num_rows, size):
                batch = table.slice(start, size)
                yield first, {name: _file_column(batch.column(name), (self.path, name, first))
                              for name in present}
                first += batch.num_rows
            del table


class CsvSource(_Source):
    """A CSV file (a header of column names) read a block at a time (pyarrow).

    Parameters
    ----------
    path : pathlib.Path
        The file.
    """

    def __init__(self, path):
        self.path = path
        self._csv = _pyarrow("csv")
        self.columns = list(self._open(None).schema.names)

    def _open(self, names):
        csv = self._csv
        options = csv.ConvertOptions(include_columns=names) if names else None
        try:
            return csv.open_csv(self.path, convert_options=options,
                                read_options=csv.ReadOptions(block_size=1 << 22))
        except Exception as error:
            raise InputDataError(f"{self.path}: not a readable CSV file "
                                 f"({str(error).splitlines()[0]})") from None

    def chunks(self, names, size):
        present = [name for name in names if name in self.columns]
        first = 0
        reader = self._open(present)
        while True:
            try:
                batch = reader.read_next_batch()
            except StopIteration:
                break
            except Exception as error:
                raise InputDataError(f"{self.path}: unreadable after row {first} "
                                     f"({str(error).splitlines()[0]})") from None
            yield first, {name: _file_column(batch.column(name), (self.path, name, first))
                          for name in present}
            first += batch.num_rows
        self.n_rows = first


class DaskSource(_Source):
    """A Dask ``DataFrame``, its partitions computed one at a time, in order.

    Parameters
    ----------
    frame : dask.dataframe.DataFrame
        The record (time as a column, or as a named index).
    """

    def __init__(self, frame):
        self.frame = frame
        index = getattr(frame.index, "name", None)
        self.columns = [str(c) for c in frame.columns] + ([str(index)] if index else [])

    def reduce(self, machine, names, size):
        """The pass on the partitions where they are (a ``dask.distributed`` cluster,
        or dask's scheduler): a chain of tasks, each feeding its partition to the
        state the previous one left, hands over what it made (``machine.take()``); only
        those and the final state come to this process, never the samples."""
        import dask

        state, made = machine, []
        for part in self.frame.to_delayed():
            step = dask.delayed(_feed_partition, nout=3, pure=False)(state, part, names, size)
            state, rows, output = step[0], step[1], step[2]
            made.append((rows, output))
        final, made = dask.compute(state, made)
        final.absorb([output for _, output in made])
        self.lengths = [rows for rows, _ in made]
        self.n_rows = sum(self.lengths)
        return final

    def read(self, names, ranges, size):
        """Rows ``[start, stop)`` of each range: only the partitions that hold them are
        computed (once a pass has counted the partitions' rows)."""
        if getattr(self, "lengths", None) is None:
            return super().read(names, ranges, size)
        import dask

        ends = np.cumsum(self.lengths)
        starts = ends - np.asarray(self.lengths)
        wanted = [i for i, (lo, hi) in enumerate(zip(starts, ends))
                  if any(start < hi and lo < stop for start, stop in ranges)]
        parts = self.frame.to_delayed()
        frames = dask.compute(*[parts[i] for i in wanted])
        pieces = [{name: [] for name in names} for _ in ranges]
        for i, frame in zip(wanted, frames):
            source = ArraySource(frame)
            chunk = next(source.chunks(names, max(source.n_rows, 1)))[1]
            for (start, stop), piece in zip(ranges, pieces):
                lo, hi = max(start, starts[i]), min(stop, ends[i])
                if lo < hi:
                    for name in chunk:
                        piece[name].append(chunk[name][lo - starts[i]:hi - starts[i]])
        return [{name: _join(parts) for name, parts in piece.items() if parts}
                for piece in pieces]

    def chunks(self, names, size):
        first = 0
        for part in self.frame.to_delayed():
            source = ArraySource(part.compute())   # pandas, as the record layer reads it
            for start, chunk in source.chunks(names, size):
                yield first + start, chunk
            first += source.n_rows
        self.n_rows = first


def _feed_partition(machine, part, names, size):
    """One task of :meth:`DaskSource.reduce`: the partition's chunks fed to ``machine``
    (its rows counted from where the previous partition ended)."""
    source = ArraySource(part)
    first = getattr(machine, "fed_rows", 0)
    for start, chunk in source.chunks(names, size):
        machine.feed(first + start, chunk)
    machine.fed_rows = first + source.n_rows
    return machine, source.n_rows, machine.take()


def _join(parts):
    """Pieces of a column as one (masks kept)."""
    if any(isinstance(p, np.ma.MaskedArray) for p in parts):
        return np.ma.concatenate(parts)
    return np.concatenate([np.asarray(p) for p in parts])


def _rows(values, first, size):
    """Rows ``first .. first + size`` of a column (a scalar as it is: the record layer
    refuses it); its type kept (masks, dates, integers: the record layer reads them)."""
    return values[first:first + size] if np.ndim(values) >= 1 else values


def _file_column(values, where):
    """A file's column as NumPy (nulls as NaN: missing samples; dates as dates).

    ``where``: ``(file, column, first row)``.  A column a reader took as text because
    of one entry that is not a number is refused here, naming that entry's row."""
    kind = str(values.type)
    values = values.to_numpy(zero_copy_only=False)
    if kind in ("string", "large_string"):
        path, name, first = where
        for row, value in enumerate(values):
            try:
                float(value)
            except (TypeError, ValueError):
                raise InputDataError(f"{path}: column {name!r} is not numeric: row "
                                     f"{first + row} holds {str(value)[:40]!r}") from None
        return values.astype(float)
    if values.dtype == object:   # nullable integers and the like: None is missing
        try:
            return np.array([np.nan if v is None else v for v in values], dtype=float)
        except (TypeError, ValueError):
            return values
    return values


def _pyarrow(module):
    try:
        if module == "parquet":
            import pyarrow.parquet as reader
        else:
            import pyarrow.csv as reader
    except ImportError:
        raise InputDataError("reading a Parquet or CSV record in chunks needs pyarrow: "
                             "pip install 'algid[fleet]'") from None
    return reader
