"""The ``algid track`` command: :class:`algid.Tracker` on a file or on standard input.

``algid track FILE ...`` streams the file in chunks of ``--chunk`` rows and prints the
estimates every ``--every`` seconds of stream time and at its end (``--json``: one object
with the lists).  ``algid track - ...`` reads CSV rows from standard input as they arrive (a
header line first) and prints a report line per interval, flushed at once (``--json``:
one object per line); a malformed row is reported on standard error and skipped, the
tracker's state intact.
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np

from algid.errors import AlgidError, InputDataError, ModelError

__all__ = ["add_track_parser", "track_command", "TRACK_JSON_KEYS"]

#: Keys of the ``--json`` output that a parameter may not be named.
TRACK_JSON_KEYS = ("t", "stderr", "alarms", "window", "half_life")


def add_track_parser(commands, positive):
    """Add the ``track`` command to the sub-parsers of the ``algid`` command line.

    Parameters
    ----------
    commands : argparse._SubParsersAction
        The sub-parsers.
    positive : callable
        The argument type of positive numbers.
    """
    track = commands.add_parser(
        "track",
        help="track the parameters of your model equation on a stream (a file or - for "
             "standard input), with change alarms",
        description=(
            "Identify the parameters of a model equation on a stream, window after window "
            "(the windows of identify, accumulated with exponential forgetting), with "
            "standard errors and alarms when the parameters change. FILE - reads CSV rows "
            "from standard input as they arrive (a header line first)."),
    )
    track.add_argument("file", metavar="FILE", help="data file, or - for standard input")
    track.add_argument("--equation", required=True, metavar="EQ", action="append",
                       help="the model equation (one: a system is tracked from Python)")
    track.add_argument("--parameters", required=True, metavar="\"P1 P2 ...\"",
                       help="the unknown parameters, separated by spaces")
    track.add_argument("--time", default=None, metavar="COL",
                       help="time column (default: t or time when present)")
    track.add_argument("--rate", type=positive, default=None, metavar="HZ",
                       help="sampling rate in Hz, for a stream without a time column")
    track.add_argument("--output", default=None, metavar="COL",
                       help="output signal (default: the one of highest derivative order)")
    track.add_argument("--window", type=positive, default=None, metavar="SECONDS",
                       help="window length (default: chosen on the first seconds)")
    track.add_argument("--half-life", type=positive, default=None, metavar="SECONDS",
                       help="half-life of the forgetting (default: keep every window)")
    track.add_argument("--chunk", type=int, default=1000, metavar="N",
                       help="rows per chunk when reading a file (default 1000)")
    track.add_argument("--every", type=positive, default=0.1, metavar="SECONDS",
                       help="reporting interval in seconds of stream time (default 0.1)")
    track.add_argument("--json", action="store_true",
                       help="print JSON: one object (a file) or one per line (standard input)")
    track.set_defaults(handler=track_command)


def read_model_columns(path, names, model, optional):
    """:func:`algid.io.read_columns` of a model's signals (``algid identify`` and
    ``algid track``): a name of the equation that is not a column may be a parameter
    left out of ``--parameters``, and the error says so."""
    from algid.io import read_columns

    try:
        return read_columns(path, names, optional=optional)
    except AlgidError as exc:
        missing = [n for n in model.signals if f"{n!r} not found" in str(exc)]
        if not missing:
            raise
        raise type(exc)(f"{exc}; if {missing[0]!r} is an unknown, add it to "
                        f"--parameters") from None


def _value(x):
    return float(x) if math.isfinite(x) else None


def _tracker(args, model, time, every):
    from algid.identification._tracker import Tracker

    return Tracker(model, rate=args.rate, time=time, window=args.window,
                   half_life=args.half_life, every=every)


class _Reports:
    """The window ends to print: those that cross a multiple of ``--every`` seconds (as
    ``Tracker(every=...)`` reports them), and the stream's last one when it ends.

    Parameters
    ----------
    every : float
        The reporting interval (s of stream time).
    """

    def __init__(self, every):
        self.every = every
        self.previous = -math.inf   # floor(end / every) of the last window end seen
        self.unprinted = None       # (update, row) of the last end when not printed

    def select(self, out):
        """Rows of ``out`` (a TrackUpdate) to print now."""
        crossed = np.floor(out.t / self.every)
        rows = np.flatnonzero(crossed > np.concatenate([[self.previous], crossed[:-1]]))
        if len(out):
            self.previous = float(crossed[-1])
            self.unprinted = None if rows.size and rows[-1] == len(out) - 1 else (
                out, len(out) - 1)
        return rows

    def final(self):
        """``(update, row)`` of the stream's last window end if it was not printed."""
        return self.unprinted


def track_command(args) -> int:
    """Run ``algid track`` (see the module notes).

    Parameters
    ----------
    args : argparse.Namespace

    Returns
    -------
    int
        0.
    """
    from algid.models._grammar import parse_equation

    if len(args.equation) > 1:
        raise ModelError(f"algid track follows one equation; --equation was given "
                         f"{len(args.equation)} times (a system is tracked from Python: "
                         f"algid.Tracker([...]))")
    model = parse_equation(args.equation[0], args.parameters, output=args.output)
    clash = [p for p in model.parameters if p in TRACK_JSON_KEYS]
    if clash:
        raise ModelError(f"parameter name {clash[0]!r} is reserved by the output "
                         f"({', '.join(TRACK_JSON_KEYS)}); rename it")
    if args.chunk < 1:
        raise InputDataError(f"--chunk must be a positive number of rows, got {args.chunk}")
    if args.file == "-":
        return _live(args, model)
    return _file(args, model)


def _file(args, model):
    from algid._record_input import TIME_COLUMNS

    names = list(model.signals) + ([args.time] if args.time else [])
    optional = () if args.time else TIME_COLUMNS  # (with --rate too: they must agree)
    record = read_model_columns(args.file, names, model, optional)
    time = args.time or (None if args.rate else next(
        (c for c in TIME_COLUMNS if c in record), None))
    if time is None and args.rate is None:
        raise InputDataError(f"{args.file}: no time column ({' or '.join(TIME_COLUMNS)}); "
                             f"give --time COL or --rate HZ")
    tracker = _tracker(args, model, time, args.every)
    n = len(record[names[0]])
    printed, alarms, chosen = [], [], _Reports(args.every)
    for start in range(0, n, args.chunk):   # (the last chunk reports its every window end)
        out = tracker.update({k: np.asarray(v)[start:start + args.chunk]
                              for k, v in record.items()}, last=start + args.chunk >= n)
        printed.extend((out, row) for row in chosen.select(out))
        alarms.append(out.alarms)
    if chosen.final() is not None:   # the end of the stream
        printed.append(chosen.final())
    if not printed:
        raise InputDataError(_nothing(args.file, n, tracker))
    t = np.array([out.t[row] for out, row in printed])
    values = np.array([out.values[row] for out, row in printed])
    stderr = np.array([out.stderr[row] for out, row in printed])
    alarms = np.concatenate(alarms)
    if args.json:
        payload = {"t": t.tolist()}
        for i, p in enumerate(model.parameters):
            payload[p] = [_value(v) for v in values[:, i]]
        payload["stderr"] = {p: [_value(v) for v in stderr[:, i]]
                             for i, p in enumerate(model.parameters)}
        payload["alarms"] = alarms.tolist()
        payload["window"] = tracker.window
        payload["half_life"] = args.half_life
        print(json.dumps(payload, allow_nan=False))
        return 0
    print(model.equation)
    print(f"{n} samples, window {tracker.window:.6g} s, half-life "
          f"{'none' if args.half_life is None else f'{args.half_life:g} s'}, "
          f"{len(alarms)} alarm(s)")
    _header(model)
    for i in range(len(t)):
        print(_line(model, t[i], values[i], stderr[i]))
    for when in alarms:
        print(f"alarm at t = {when:.6g} s")
    return 0


def _print_row(args, model, out, i, alarms):
    """One report line of standard input; with ``--json`` it carries the alarms raised
    since the last line (and empties ``alarms``)."""
    if args.json:
        payload = {"t": float(out.t[i])}
        payload.update({p: _value(v) for p, v in zip(model.parameters, out.values[i])})
        payload["stderr"] = {p: _value(v) for p, v in zip(model.parameters, out.stderr[i])}
        payload["alarms"] = list(alarms)
        alarms.clear()
        print(json.dumps(payload, allow_nan=False))
    else:
        print(_line(model, out.t[i], out.values[i], out.stderr[i]))
    sys.stdout.flush()


def _nothing(source, n, tracker):
    """Why a stream that ended gave no report."""
    if not n:
        return f"{source}: no samples"
    if tracker.window is None:
        return (f"{source}: no window could be chosen on its {n} samples; give a longer "
                f"record or --window")
    return (f"{source}: no window completed: {n} samples, the window is "
            f"{tracker.window:.6g} s")


def _header(model):
    print("t (s)".rjust(10) + "".join(f"  {p:>13}  {'± ' + p:>10}" for p in model.parameters))


def _line(model, t, values, stderr):
    return f"{t:10.4f}" + "".join(f"  {v:>13.6g}  {s:>10.2g}" for v, s in zip(values, stderr))


def _number(field, column):
    """A field of a live row as a float, or the refusal that names it as file mode does."""
    try:
        return float(field)
    except ValueError:
        raise InputDataError(f"column {column!r}: {field.strip()!r} is not a number") from None


def _rate_agrees(rate, stamps, name):
    """Refuse --rate beside a time column of standard input that contradicts it."""
    from algid._record_input import check_rate_agrees

    try:
        check_rate_agrees(rate, np.array(stamps), name, "standard input")
    except InputDataError as exc:
        raise _StreamRefused(str(exc)) from None


def _emit(args, model, out, chosen, alarms):
    """Print the reports of ``out`` that ``chosen`` picks, and its alarms (gathered in
    ``alarms`` with --json); whether any report was printed."""
    if args.json:   # (printed at once otherwise)
        alarms.extend(out.alarms.tolist())
    rows = chosen.select(out)
    for i in rows:
        _print_row(args, model, out, i, alarms)
    if not args.json:
        for when in out.alarms:
            print(f"alarm at t = {when:.6g} s")
    if rows.size or len(out.alarms):
        sys.stdout.flush()
    return rows.size > 0


class _StreamRefused(InputDataError):
    """A refusal of the whole stream (not of one row, which is skipped)."""


def _live(args, model):
    """Rows from standard input, one report per interval, flushed at once."""
    from algid._record_input import TIME_COLUMNS

    header = sys.stdin.readline().removeprefix("\ufeff")  # (a UTF-8 byte-order mark)
    if not header.strip():
        raise InputDataError("standard input: no header line (the column names)")
    delimiter = "," if "," in header else (";" if ";" in header else None)
    columns = [c.strip() for c in header.strip().split(delimiter)]
    stamps = args.time or next((c for c in TIME_COLUMNS if c in columns), None)
    time = None if args.rate and not args.time else stamps
    # beside --rate a time column must agree with it, as in a file: its first steps are
    # checked (the tracker sees one row at a time)
    check = stamps if args.rate and stamps in columns else None
    needed = list(model.signals) + ([time] if time else [])
    missing = [c for c in needed if c not in columns]
    if missing:
        raise InputDataError(f"standard input: no column {missing[0]!r} (columns: "
                             f"{', '.join(columns)})")
    if time is None and args.rate is None:
        raise InputDataError("standard input: no time column (t or time); give --time COL "
                             "or --rate HZ")
    where = [columns.index(c) for c in needed]
    # every window end comes out (the stream's end is not known before it comes);
    # _Reports picks those to print
    tracker = _tracker(args, model, time, None)
    from algid.identification._tracker import STEP_SAMPLES
    from algid.identification._tracker_state import TrackerSetupError

    first_stamps = []
    if not args.json:
        _header(model)
        sys.stdout.flush()
    row, reported, samples = 1, False, 0
    chosen, alarms = _Reports(args.every), []   # (alarms not yet printed, with --json)
    while True:
        line = sys.stdin.readline()
        if not line:
            break
        row += 1
        if not line.strip():
            continue
        fields = line.strip().split(delimiter)
        try:
            if len(fields) != len(columns):
                raise InputDataError(f"{len(fields)} fields, the header has {len(columns)}")
            values = [_number(fields[i], columns[i]) for i in where]
            if check is not None and len(first_stamps) <= STEP_SAMPLES:
                first_stamps.append(float(fields[columns.index(check)]))
                if len(first_stamps) > STEP_SAMPLES:
                    _rate_agrees(args.rate, first_stamps, check)
            out = tracker.update({c: [v] for c, v in zip(needed, values)})
            samples += 1
        except (_StreamRefused, TrackerSetupError):
            raise
        except (ValueError, InputDataError) as exc:
            message = " ".join(str(exc).split())
            print(f"algid: warning: standard input row {row} skipped: {message}",
                  file=sys.stderr, flush=True)
            continue
        reported = _emit(args, model, out, chosen, alarms) or reported
    if samples and tracker.window is None:   # the stream ended in the window's warm-up
        out = tracker.update({c: np.empty(0) for c in needed}, last=True)
        reported = _emit(args, model, out, chosen, alarms) or reported
    if chosen.final() is not None:   # the end of the stream
        _print_row(args, model, *chosen.final(), alarms)
        reported = True
    if not reported:
        raise InputDataError(_nothing("standard input", samples, tracker))
    return 0
