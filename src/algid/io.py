"""Reading measured experiments from CSV/text and MATLAB files.

A CSV/text file may be gzip-compressed (``.csv.gz``, ``.txt.gz``, as the Silverbox
record ships in the package): it is decompressed while read.

Only file-specific problems are reported here (missing file, unreadable format,
missing or non-numeric column).  Checks on the signals themselves (NaN, lengths,
time axis, excitation) are made by :func:`algid._signal_checks.check_experiment`.
Every :class:`~algid.errors.DataFileError` message starts with the file name.
"""

from __future__ import annotations

import csv
import gzip
import math
import os
import sys
import zlib
from pathlib import Path

import numpy as np

import algid._memory as memory
from algid._memory import check_fits
from algid._record_input import check_rate, check_rate_agrees
from algid.errors import DataFileError, InputDataError

__all__ = ["read_experiment", "read_columns", "CSV_SUFFIXES", "MAT_SUFFIXES",
           "GZIP_SUFFIXES"]

CSV_SUFFIXES = (".csv", ".txt")
MAT_SUFFIXES = (".mat",)
#: gzip-compressed CSV/text files, decompressed while read.
GZIP_SUFFIXES = (".csv.gz", ".txt.gz")


def read_experiment(path, *, time="t", input="f", output="x", rate=None):
    """Read the time, input and output signals of one experiment from a file.

    Parameters
    ----------
    path : str or os.PathLike
        A ``.csv``/``.txt`` file with a header line of column names (or the same
        gzip-compressed, ``.csv.gz``/``.txt.gz``), or a MATLAB ``.mat`` file (up to
        version 7.2) whose variables are named like the columns.
    time : str, optional
        Name of the time column.  When ``rate`` is given, the column is optional; if
        the file has it, it must agree with the rate.
    input : str, optional
        Name of the input (force) column.
    output : str, optional
        Name of the output (displacement) column.
    rate : float, optional
        Sampling rate in Hz.  When given, the file has no time column and the time is
        ``arange(n) / rate`` with ``n`` the number of samples of the input.

    Returns
    -------
    t, f, x : numpy.ndarray
        The time, input and output signals as 1-D ``float64`` arrays.  They are not
        checked for NaN, equal lengths or a valid time axis; use
        :func:`algid._signal_checks.check_experiment` for that.

    Raises
    ------
    DataFileError
        If the file is missing or unreadable, has an unknown extension, is empty or has
        no data rows, lacks a requested column (the message lists the available ones),
        or holds a non-numeric value (the message gives the column and the 1-based line
        number for CSV files).
    InputDataError
        If ``rate`` is not a positive finite number whose step lies in
        :data:`algid._record_input.STEP_RANGE`, or contradicts the file's time column.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from algid.io import read_experiment
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = pathlib.Path(folder, "step.csv")
    ...     _ = path.write_text("f,x\\n1.0,0.0\\n1.0,0.5\\n1.0,1.5\\n")   # no time column
    ...     t, f, x = read_experiment(path, rate=10.0)
    >>> t, x
    (array([0. , 0.1, 0.2]), array([0. , 0.5, 1.5]))
    """
    if rate is not None:
        rate = _check_rate(rate)
    p, label, suffix = _checked_path(path)
    # with a rate, a time column present in the file is read too: the two must agree
    timed = rate is None or time in _available(p, label, suffix)
    wanted = [time, input, output] if timed else [input, output]
    if suffix in MAT_SUFFIXES:
        columns = _read_mat(p, label, wanted, time if rate is None else None)
    else:
        columns = _read_csv(p, label, wanted, time if rate is None else None)

    f = columns[input]
    x = columns[output]
    if rate is None:
        return columns[time], f, x
    if timed and np.all(np.diff(columns[time]) > 0):
        check_rate_agrees(rate, columns[time], time, label)
    return np.arange(f.size, dtype=np.float64) / rate, f, x


def _checked_path(path):
    label = os.fspath(path)
    if isinstance(label, bytes):
        label = os.fsdecode(label)
    p = Path(label)
    suffix = p.suffix.lower()
    if suffix == ".gz":
        suffix = "".join(p.suffixes[-2:]).lower()
    if suffix not in CSV_SUFFIXES + GZIP_SUFFIXES + MAT_SUFFIXES:
        supported = ", ".join(CSV_SUFFIXES + GZIP_SUFFIXES + MAT_SUFFIXES)
        shown = f"extension {p.suffix!r}" if p.suffix else "no extension"
        raise DataFileError(f"{label}: unknown file type ({shown}); supported: {supported}")
    if not p.exists():
        raise DataFileError(f"{label}: file not found")
    if p.is_dir():
        raise DataFileError(f"{label}: is a directory, not a data file")
    return p, label, suffix


def _available(p, label, suffix):
    """Column names of a CSV/text file, or variable names of a .mat file."""
    if suffix in MAT_SUFFIXES:
        from scipy.io import whosmat
        try:
            return [name for name, _, _ in whosmat(p)]
        except Exception:  # unreadable: _read_mat reports it
            return []
    opener = gzip.open if suffix in GZIP_SUFFIXES else open
    try:  # the header only: the first line that is neither blank nor a comment
        with opener(p, "rt", encoding="utf-8-sig") as lines:
            for line in lines:
                if line.strip() and not line.strip().startswith("#"):
                    return _fields(line.rstrip("\r\n"), _delimiter(line))
    except (UnicodeDecodeError, OSError, EOFError, csv.Error):
        return []  # _read_csv reports it
    return []


def read_columns(path, names, *, optional=()):
    """Read named columns (CSV/text) or variables (.mat) of a data file.

    Parameters
    ----------
    path : str, path-like or text stream
        A ``.csv``/``.txt`` file with a header line (or the same gzip-compressed,
        ``.csv.gz``/``.txt.gz``), or a MATLAB ``.mat`` file; or an open text stream
        of CSV/text (``sys.stdin``: ``algid identify -``), read to its end.
    names : sequence of str
        Columns or variables that must be present.
    optional : sequence of str
        Columns read only when present (e.g. a time column ``t``).

    Returns
    -------
    dict
        Name -> float64 vector, for ``names`` and the optional names found.

    Raises
    ------
    DataFileError
        Missing file, unknown type, missing or non-numeric column (the message starts
        with the file name and lists the available columns).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> from algid.io import read_columns
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = pathlib.Path(folder, "record.csv")
    ...     _ = path.write_text("t,u,y\\n0.0,1.0,0.0\\n0.1,1.0,0.5\\n")
    ...     columns = read_columns(path, ["u", "y"], optional=["t", "z"])
    >>> sorted(columns), columns["y"]
    (['t', 'u', 'y'], array([0. , 0.5]))
    """
    if hasattr(path, "read"):   # a text stream: CSV/text to its end
        stdin = path is sys.stdin or getattr(path, "name", None) == "<stdin>"
        label = "standard input" if stdin else str(getattr(path, "name", "stream"))
        text = _stream_text(path, label)
        header = next(_split_lines(text), (0, ""))[1]
        found = _fields(header, _delimiter(header)) if header else []
        wanted = list(dict.fromkeys(list(names) + [n for n in optional if n in found]))
        if not wanted:
            raise DataFileError(f"{label}: no column requested")
        return _parse_csv(text, label, wanted, None)
    p, label, suffix = _checked_path(path)
    found = _available(p, label, suffix)
    wanted = list(dict.fromkeys(list(names) + [n for n in optional if n in found]))
    if not wanted:
        raise DataFileError(f"{label}: no column requested")
    reader = _read_mat if suffix in MAT_SUFFIXES else _read_csv
    return reader(p, label, wanted, None)


def _stream_text(stream, label):
    """The text of a stream, to its end (bytes read as UTF-8)."""
    try:
        text = stream.read()
        if isinstance(text, bytes):
            text = text.decode("utf-8")
    except UnicodeDecodeError:
        raise DataFileError(f"{label}: not UTF-8 text") from None
    except OSError as exc:
        raise DataFileError(f"{label}: cannot read ({exc.strerror or exc})") from None
    return text.removeprefix("\ufeff")   # (a UTF-8 byte-order mark)


def _check_rate(rate) -> float:
    if isinstance(rate, (bool, np.bool_)):
        raise InputDataError(f"rate must be a number of Hz, got {rate!r}")
    try:
        value = float(rate)
    except (TypeError, ValueError):
        raise InputDataError(f"rate must be a number of Hz, got {rate!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise InputDataError(f"rate must be a positive finite number of Hz, got {rate!r}")
    return check_rate(value)


def _missing(label, kind, name, available, time_name):
    """Build the error for a requested column/variable that is not in the file."""
    listing = ", ".join(available) if available else "none"
    plural = "columns" if kind == "column" else "variables"
    if time_name is not None and name == time_name:
        return DataFileError(
            f"{label}: time {kind} {name!r} not found ({plural}: {listing}); "
            f"name it with --time, or give the sampling rate with --rate HZ "
            f"if the file has no time {kind}"
        )
    return DataFileError(f"{label}: {kind} {name!r} not found ({plural}: {listing})")


# --------------------------------------------------------------------------- CSV


def _split_lines(text):
    """Yield (line_number, line) for lines that are neither blank nor comments."""
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        yield number, line


def _delimiter(header_line):
    for candidate in (",", ";", "\t"):
        if candidate in header_line:
            return candidate
    return None  # whitespace separated


def _fields(line, delimiter):
    if delimiter is None:
        return line.split()
    if '"' in line:
        row = next(csv.reader([line], delimiter=delimiter, skipinitialspace=True))
    else:
        row = line.split(delimiter)
    row = [cell.strip() for cell in row]
    while row and row[-1] == "":
        row.pop()  # trailing delimiter ("1,2,")
    return row


def _number(text):
    """``float(text)`` for a number as data files write it.

    Python's ``float`` also reads ``1_0`` as 10 and non-ASCII digits; neither is a
    number in a data file, so both are refused.
    """
    if "_" in text or not text.isascii():
        raise ValueError(f"not a number: {text!r}")
    return float(text)


def _is_number(text):
    try:
        _number(text)
    except ValueError:
        return False
    return True


#: Peak memory of reading a CSV/text file per byte of the file (measured: 5.2).
CSV_BYTES_PER_FILE_BYTE = 6
#: Peak memory of reading a .mat file per byte of the file (the whole file is loaded).
MAT_BYTES_PER_FILE_BYTE = 2


def _check_size(p, label, bytes_per_file_byte):
    """Refuse a file whose reading would not fit in the memory available."""
    try:
        size = p.stat().st_size
    except OSError as exc:
        raise DataFileError(f"{label}: cannot read file ({exc.strerror or exc})") from None
    try:
        check_fits(size, bytes_per_file_byte, what=f"{label}: too large to read",
                   unit="bytes of file")
    except InputDataError as exc:
        raise DataFileError(str(exc)) from None


def _read_gzip(p, label):
    """The decompressed bytes of a gzip file, refused beyond what memory can parse.

    The reading's peak memory is :data:`CSV_BYTES_PER_FILE_BYTE` per byte of text, the
    decompressed text (not the file) is what counts, and its size is known only once
    decompressed: at most the budget plus one byte is decompressed.
    """
    available = memory.available_memory()
    budget = available // CSV_BYTES_PER_FILE_BYTE
    try:
        with gzip.open(p, "rb") as stream:
            data = stream.read(budget + 1)
    except (OSError, EOFError, zlib.error) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise DataFileError(f"{label}: not a readable gzip file ({reason})") from None
    if len(data) > budget:
        raise DataFileError(
            f"{label}: too large to read: its decompressed text exceeds "
            f"{memory._size(budget)}, the most that the {memory._size(available)} "
            f"of memory available can parse ({CSV_BYTES_PER_FILE_BYTE} bytes per byte of text)")
    return data


def _read_text(p, label):
    """The text of a CSV/text file (decompressed when gzip), refused when too large."""
    try:
        if p.name.lower().endswith(".gz"):
            return _read_gzip(p, label).decode("utf-8-sig")
        _check_size(p, label, CSV_BYTES_PER_FILE_BYTE)
        return p.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise DataFileError(f"{label}: not a UTF-8 text file") from None
    except OSError as exc:
        raise DataFileError(f"{label}: cannot read file ({exc.strerror or exc})") from None


def _read_csv(p, label, wanted, time_name):
    return _parse_csv(_read_text(p, label), label, wanted, time_name)


def _parse_csv(text, label, wanted, time_name):
    lines = _split_lines(text)
    try:
        header_number, header_line = next(lines)
    except StopIteration:
        raise DataFileError(f"{label}: {'file' if label != 'standard input' else 'input'} "
                            f"is empty") from None

    delimiter = _delimiter(header_line)
    try:
        header = _fields(header_line, delimiter)
    except csv.Error as exc:
        raise DataFileError(f"{label}: line {header_number}: cannot parse header ({exc})") from None
    if header and all(_is_number(cell) for cell in header):
        raise DataFileError(
            f"{label}: line {header_number} holds numbers, expected a header line "
            f"with column names"
        )
    for position, name in enumerate(header, start=1):
        if name == "":
            raise DataFileError(
                f"{label}: line {header_number}: column {position} has an empty name"
            )
    for name in dict.fromkeys(wanted):
        if name not in header:
            raise _missing(label, "column", name, header, time_name)
        if header.count(name) > 1:
            raise DataFileError(f"{label}: column {name!r} appears more than once in the header")

    index = {name: header.index(name) for name in dict.fromkeys(wanted)}
    values = {name: [] for name in index}
    ncols = len(header)
    for number, line in lines:
        try:
            row = _fields(line, delimiter)
        except csv.Error as exc:
            raise DataFileError(f"{label}: line {number}: cannot parse ({exc})") from None
        if len(row) < ncols and "".join(row) and line.rstrip().endswith(delimiter or " "):
            row += [""] * (ncols - len(row))  # trailing empty cells ("0.2,1.0,"): named below
        if len(row) != ncols:
            raise DataFileError(
                f"{label}: line {number} has {len(row)} fields but the header has {ncols} columns"
            )
        for name, col in index.items():
            cell = row[col]
            try:
                values[name].append(_number(cell))
            except ValueError:
                shown = "an empty cell" if cell == "" else repr(cell)
                raise DataFileError(
                    f"{label}: column {name!r}, line {number}: {shown} is not a number"
                ) from None

    if not values[wanted[0]]:
        raise DataFileError(f"{label}: no data rows after the header (line {header_number})")
    return {name: np.asarray(column, dtype=np.float64) for name, column in values.items()}


# --------------------------------------------------------------------------- MAT


def _read_mat(p, label, wanted, time_name):
    from scipy.io import loadmat

    _check_size(p, label, MAT_BYTES_PER_FILE_BYTE)
    try:
        contents = loadmat(p, squeeze_me=False)
    except NotImplementedError:
        raise DataFileError(
            f"{label}: MATLAB v7.3 (HDF5) files are not supported; save with '-v7'"
        ) from None
    except OSError as exc:
        raise DataFileError(f"{label}: cannot read file ({exc.strerror or exc})") from None
    except Exception as exc:  # scipy raises several types on corrupt files
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise DataFileError(f"{label}: not a readable MATLAB file ({reason})") from None

    available = [key for key in contents if not key.startswith("__")]
    columns = {}
    for name in dict.fromkeys(wanted):
        if name not in contents or name.startswith("__"):
            raise _missing(label, "variable", name, available, time_name)
        columns[name] = _mat_vector(label, name, contents[name])
    return columns


def _mat_vector(label, name, value):
    if hasattr(value, "toarray") and hasattr(value, "nnz"):  # a sparse matrix: its values
        value = value.toarray()
    arr = np.asarray(value)
    kind = arr.dtype.kind
    if kind == "c":
        raise DataFileError(f"{label}: variable {name!r} is complex, expected real numbers")
    if kind not in "biuf":
        kinds = {"U": "text", "S": "text", "O": "a cell array", "V": "a struct"}
        what = kinds.get(kind, "not numeric")
        raise DataFileError(f"{label}: variable {name!r} is {what}, expected a numeric vector")
    if arr.size == 0:
        raise DataFileError(f"{label}: variable {name!r} is empty")
    squeezed = arr.squeeze()
    if squeezed.ndim > 1:
        shape = "x".join(str(n) for n in arr.shape)
        raise DataFileError(f"{label}: variable {name!r} is a {shape} matrix, expected a vector")
    return np.atleast_1d(squeezed).astype(np.float64)
