"""``algid identify TABLE --by COL``: :func:`algid.identify_many` on a long table.

The table (Parquet: a file or a folder of files; CSV/text, possibly gzip-compressed; or
``-``, CSV on standard input) holds the rows of every record and a column ``--by``
naming each row's record.  Only the columns of the equation, the id and the time are
read.  The records are identified in this process, on a local cluster of ``--workers``
processes, or on the Dask scheduler at ``--scheduler``; the results table (one row per
record, an ``error`` column for a record refused) is written to ``--out`` (``.csv`` or
``.parquet``), printed as CSV, or printed as JSON (``--json``: a list of rows).  A record
refused does not stop the fleet nor change the exit code; a table that cannot be read
does (one line on standard error, exit code 2).
"""

from __future__ import annotations

import contextlib
import gzip
import importlib
import io
import json
import math
import sys
from pathlib import Path

from algid.errors import AlgidError, DataFileError, InputDataError

__all__ = ["fleet_command", "check_out", "read_fleet_table", "write_table", "TABLE_SUFFIXES",
           "PARQUET_SUFFIXES", "CSV_TABLE_SUFFIXES"]

#: Results tables ``--out`` writes, by extension.
TABLE_SUFFIXES = (".csv", ".parquet", ".pq")
#: Parquet files (a folder is read as a Parquet dataset).
PARQUET_SUFFIXES = (".parquet", ".pq")
#: CSV/text tables, possibly gzip-compressed.
CSV_TABLE_SUFFIXES = (".csv", ".txt", ".csv.gz", ".txt.gz")

FLEET_HINT = "pip install 'algid[fleet]'"


def _need(module, what):
    """Import an optional dependency of the fleet command, or refuse in one line."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.split(".")[0] == module.split(".")[0]:
            raise AlgidError(f"{what} needs {module.split('.')[0]}: {FLEET_HINT}") from None
        raise


def _suffix(path):
    p = Path(path)
    suffix = p.suffix.lower()
    return "".join(p.suffixes[-2:]).lower() if suffix == ".gz" else suffix


def check_out(out):
    """Refuse an ``--out`` that is neither ``.csv`` nor ``.parquet`` (before any work).

    Parameters
    ----------
    out : str or None
        The ``--out`` argument.
    """
    if out is None:
        return
    if _suffix(out) not in TABLE_SUFFIXES:
        raise AlgidError(f"--out {out}: the results table is written as .csv or .parquet; "
                         f"name the file so")
    _need("pandas", "--out")
    if _suffix(out) in PARQUET_SUFFIXES:
        _need("pyarrow", "--out .parquet")


def _columns_wanted(label, available, by, names, optional):
    if by not in available:
        raise DataFileError(f"{label}: no column {by!r} for --by (columns: "
                            f"{_listing(available)})")
    for name in names:
        if name not in available:
            raise DataFileError(f"{label}: column {name!r} not found (columns: "
                                f"{_listing(available)}); if {name!r} is an unknown, add "
                                f"it to --parameters")
    return list(dict.fromkeys([by] + list(names) + [n for n in optional if n in available]))


def _listing(columns, most=12):
    shown = ", ".join(str(c) for c in list(columns)[:most])
    return shown + (", ..." if len(columns) > most else "") if columns else "none"


def _read_parquet(path, label, by, names, optional):
    _need("pandas", "algid identify --by")
    pyarrow = _need("pyarrow", "algid identify --by of a Parquet table")
    import pyarrow.dataset as ds

    try:
        dataset = ds.dataset(str(path), format="parquet")
        wanted = _columns_wanted(label, dataset.schema.names, by, names, optional)
        return dataset.to_table(columns=wanted).to_pandas()
    except (pyarrow.ArrowException, OSError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise DataFileError(f"{label}: not a readable Parquet table ({reason:.160})") from None


def _read_csv_table(source, label, by, names, optional):
    pd = _need("pandas", "algid identify --by")
    try:
        if isinstance(source, Path):
            opener = gzip.open if source.name.lower().endswith(".gz") else open
            with opener(source, "rt", encoding="utf-8-sig") as stream:
                text = stream.read()
        else:
            text = source.read().removeprefix("\ufeff")
    except UnicodeDecodeError:
        raise DataFileError(f"{label}: not a UTF-8 text file") from None
    except (OSError, EOFError) as exc:
        raise DataFileError(f"{label}: cannot read ({getattr(exc, 'strerror', None) or exc})"
                            ) from None
    header = next((line for line in text.splitlines()
                   if line.strip() and not line.strip().startswith("#")), None)
    if header is None:
        raise DataFileError(f"{label}: no header line (the column names)")
    separator = next((c for c in (",", ";", "\t") if c in header), r"\s+")
    try:
        available = list(pd.read_csv(io.StringIO(text), sep=separator, comment="#",
                                     nrows=0).columns)
        wanted = _columns_wanted(label, available, by, names, optional)
        return pd.read_csv(io.StringIO(text), sep=separator, comment="#", usecols=wanted)
    except (ValueError, pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        if isinstance(exc, AlgidError):
            raise
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise DataFileError(f"{label}: cannot read the table ({reason:.160})") from None


def read_fleet_table(path, by, names, optional):
    """The long table of ``algid identify --by``: the id, the signals and the time.

    Parameters
    ----------
    path : str
        A Parquet file or folder, a CSV/text file, or ``-`` (CSV on standard input).
    by : str
        The id column.
    names : sequence of str
        Columns that must be present.
    optional : sequence of str
        Columns read when present (the time column).

    Returns
    -------
    pandas.DataFrame
    """
    if path == "-":
        return _read_csv_table(sys.stdin, "standard input", by, names, optional)
    p = Path(path)
    suffix = _suffix(path)
    if not p.exists():
        raise DataFileError(f"{path}: file not found")
    if suffix in PARQUET_SUFFIXES or p.is_dir():
        return _read_parquet(p, path, by, names, optional)
    if suffix in CSV_TABLE_SUFFIXES:
        return _read_csv_table(p, path, by, names, optional)
    shown = f"extension {p.suffix!r}" if p.suffix else "no extension"
    raise DataFileError(f"{path}: unknown table type ({shown}); --by reads "
                        f"{', '.join(PARQUET_SUFFIXES + CSV_TABLE_SUFFIXES)} or a folder of "
                        f"Parquet files")


@contextlib.contextmanager
def _cluster(args):
    """The Dask client of ``--workers`` or ``--scheduler`` (none without either)."""
    if args.workers is None and args.scheduler is None:
        yield None
        return
    _need("distributed", "--workers and --scheduler")
    from distributed import Client, LocalCluster

    with contextlib.ExitStack() as stack:
        if args.scheduler is not None:
            try:
                client = stack.enter_context(Client(args.scheduler, timeout="10s"))
            except (OSError, TimeoutError, ValueError, TypeError) as exc:
                reason = " ".join(str(exc).split()) or type(exc).__name__
                raise AlgidError(f"--scheduler {args.scheduler}: cannot connect "
                                 f"({reason:.160})") from None
        else:
            cluster = stack.enter_context(LocalCluster(
                n_workers=args.workers, threads_per_worker=1, processes=True,
                dashboard_address=None))
            client = stack.enter_context(Client(cluster))
        yield client


def write_table(table, out):
    """Write the results table: CSV or Parquet by the extension of ``out``."""
    try:
        if _suffix(out) in PARQUET_SUFFIXES:
            table.to_parquet(out)
        else:
            table.to_csv(out)
    except OSError as exc:
        raise AlgidError(f"{out}: cannot write file ({exc.strerror or exc})") from None


def _json_value(value):
    """A cell of the table as JSON: NaN and missing as null, NumPy scalars as numbers."""
    if value is None:
        return None
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        value = value.item()
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, (bool, int, str)):
        return value
    try:
        import pandas as pd

        if pd.isna(value):
            return None
    except (TypeError, ValueError):
        pass
    return str(value)


def fleet_command(args, model):
    """Run ``algid identify TABLE --by COL`` (see the module notes).

    Parameters
    ----------
    args : argparse.Namespace
    model : Model
        The parsed equation.

    Returns
    -------
    int
        0 (refused records are rows of the table).
    """
    from algid._record_input import TIME_COLUMNS
    from algid.identification._fleet import identify_many

    if len(args.files) != 1:
        raise InputDataError(f"--by reads one table (a Parquet file or folder, a CSV file "
                             f"or -), got {len(args.files)} files")
    check_out(args.out)
    source = args.files[0]
    label = "standard input" if source == "-" else source
    names = list(model.signals) + ([args.time] if args.time else [])
    if args.by in names:
        raise InputDataError(f"--by {args.by}: the id column is also a signal of the "
                             f"equation or the time column")
    optional = () if args.time else TIME_COLUMNS
    table = read_fleet_table(source, args.by, names, optional)
    if table.empty:
        raise DataFileError(f"{label}: no rows")
    options = {"time": args.time, "rate": args.rate, "window": args.window,
               "method": args.method, "refine": "auto" if args.refine is None else args.refine}
    with _cluster(args):
        results = identify_many(table, args.equation[0], args.parameters, by=args.by,
                                progress=args.progress,
                                output=args.output[0] if args.output else None, **options)
    refused = int(results["error"].notna().sum())
    warned = int((results["warnings"].fillna("") != "").sum())
    if refused:
        print(f"warning: {label}: {refused} of {len(results)} records refused (the error "
              f"column says why)", file=sys.stderr)
    if warned:
        print(f"warning: {label}: {warned} of {len(results)} records with warnings (the "
              f"warnings column)", file=sys.stderr)
    if args.out is not None:
        write_table(results, args.out)
    if args.json:
        rows = [{args.by: _json_value(key), **{c: _json_value(v) for c, v in row.items()}}
                for key, row in zip(results.index, results.to_dict(orient="records"))]
        print(json.dumps(rows, allow_nan=False))
    elif args.out is None:
        results.to_csv(sys.stdout)
    else:
        print(f"{len(results)} records ({refused} refused): wrote {args.out}")
    return 0
