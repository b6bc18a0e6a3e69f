"""Command line interface: ``algid simulate``, ``algid estimate``, ``algid identify``,
``algid datasets``, ``algid derive``, ``algid codegen``, ``algid paper`` and
``algid errata``.

Errors caused by the user (bad data, bad file, unknown model) are printed as one line
``algid: error: <message>`` on standard error with exit code 2; usage errors are
reported by :mod:`argparse`, also with exit code 2.  Optional dependencies
(python-control for ``simulate``, SymPy for ``derive``) are imported only by the
command that needs them.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import re
import sys
from pathlib import Path

from algid.errors import AlgidError, InputDataError, ModelError
from algid.estimation._options import DEFAULT_QUADRATURE_POINTS, MAX_FILTER_ORDER

__all__ = ["main", "build_parser"]

PROG = "algid"


class _MissingDependency(Exception):
    """An optional dependency needed by a subcommand is not installed."""


def _version() -> str:
    try:
        from importlib.metadata import PackageNotFoundError, version
    except ImportError:  # pragma: no cover
        return "unknown"
    try:
        return version("algid")
    except PackageNotFoundError:
        import algid

        return getattr(algid, "__version__", "unknown")


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line on standard error.

    :mod:`argparse` prints the whole usage before the message; the command line of
    algid answers every bad input with one line ``algid: error: <command>: ...`` and
    exit code 2, and points at ``--help`` for the usage.  Sub-parsers are of the same
    class.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        # negative numbers with an exponent (--v0 -1e-3) are values, not options
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")

    def error(self, message):
        """Print ``message`` on one line with a pointer to ``--help``; exit with code 2."""
        line = " ".join(str(message).split())
        command = self.prog[len(PROG):].strip()
        where = f"{command}: " if command else ""
        self.exit(2, f"{PROG}: error: {where}{line} (see {self.prog} --help)\n")


# --------------------------------------------------------------------- arg types


def _number(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"not a finite number: {text!r}")
    return value


def _positive(text):
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be positive, got {text!r}")
    return value


def _nonnegative(text):
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must not be negative, got {text!r}")
    return value


def _nonnegative_int(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must not be negative, got {text!r}")
    return value


def _positive_int(text):
    value = _nonnegative_int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text!r}")
    return value


def _filter_order(text):
    value = _nonnegative_int(text)
    if value > MAX_FILTER_ORDER:
        raise argparse.ArgumentTypeError(f"must be at most {MAX_FILTER_ORDER}, got {text!r}")
    return value


# ------------------------------------------------------------------------ parser


def build_parser() -> argparse.ArgumentParser:
    """Build the argument parser of the ``algid`` command.

    Returns
    -------
    argparse.ArgumentParser
        The parser, with one sub-parser per command; each sets ``handler``.
    """
    parser = _Parser(
        prog=PROG,
        description=(
            "Algebraic identification of continuous-time systems: the parameters of an "
            "ODE linear in them from measured signals (estimate: the paper's B and K of "
            "x'' + B x' + K x = f; identify and track: your equation; derive and codegen: "
            "the estimator's equations and C)."
        ),
    )
    parser.add_argument("--version", action="version", version=f"{PROG} {_version()}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)

    sim = commands.add_parser(
        "simulate",
        help="simulate a mass-spring-damper and write t, f, x to a CSV file",
        description="Simulate m x'' + c x' + k x = f and write columns t, f, x to CSV.",
    )
    sim.add_argument("--input", choices=("step", "sine"), default="step",
                     help="input force shape (default: step)")
    sim.add_argument("--amplitude", type=_number, default=1.0, metavar="A",
                     help="input amplitude (default: 1)")
    sim.add_argument("--frequency", type=_positive, default=1.0, metavar="W",
                     help="sine frequency in rad/s (default: 1)")
    sim.add_argument("--mass", type=_positive, default=1.0, metavar="M",
                     help="mass m (default: 1)")
    sim.add_argument("--damping", type=_number, default=2.0, metavar="C",
                     help="damping c (default: 2)")
    sim.add_argument("--stiffness", type=_number, default=3.0, metavar="K",
                     help="stiffness k (default: 3)")
    sim.add_argument("--duration", type=_positive, default=5.0, metavar="S",
                     help="duration in seconds (default: 5)")
    sim.add_argument("--rate", type=_positive, default=1000.0, metavar="HZ",
                     help="sampling rate in Hz (default: 1000)")
    sim.add_argument("--x0", type=_number, default=0.0, metavar="X",
                     help="initial displacement (default: 0)")
    sim.add_argument("--v0", type=_number, default=0.0, metavar="V",
                     help="initial velocity (default: 0)")
    sim.add_argument("--noise-std", type=_nonnegative, default=0.0, metavar="S",
                     help="standard deviation of noise added to x (default: 0, no noise)")
    sim.add_argument("--seed", type=_nonnegative_int, default=None, metavar="N",
                     help="seed of the noise generator")
    sim.add_argument("--out", required=True, metavar="FILE.csv", help="output CSV file")
    sim.set_defaults(handler=_cmd_simulate)

    est = commands.add_parser(
        "estimate",
        help="estimate the parameters from a measured experiment",
        description=(
            "Read t, f, x from a CSV/text or MATLAB .mat file and estimate the "
            "parameters algebraically. The sampling must be uniform."
        ),
    )
    est.add_argument("file", metavar="FILE", help="data file (.csv, .txt or .mat)")
    timing = est.add_mutually_exclusive_group()
    timing.add_argument("--time", default=None, metavar="COL",
                        help="time column (default: t)")
    timing.add_argument("--rate", type=_positive, default=None, metavar="HZ",
                        help="sampling rate in Hz, for files without a time column")
    est.add_argument("--input", default="f", metavar="COL", help="input column (default: f)")
    est.add_argument("--output", default="x", metavar="COL", help="output column (default: x)")
    est.add_argument("--mass", type=_positive, default=None, metavar="M",
                     help="known mass: the input column is the force F, and c, k are "
                          "reported too")
    est.add_argument("--filter-order", type=_filter_order, default=None, metavar="P",
                     help="order p of the invariant filter 1/s**p, 0 for none "
                          "(default: the estimator's)")
    est.add_argument("--model", default="msd", metavar="NAME", help="model (default: msd)")
    est.add_argument("--json", action="store_true", help="print one JSON object")
    est.set_defaults(handler=_cmd_estimate)

    ide = commands.add_parser(
        "identify",
        help="identify the parameters of your model equation on measured records",
        description=(
            "Identify the unknown parameters of a model equation, linear in them, on one "
            "or more records (CSV columns or .mat variables named as in the equation), "
            "by the algebraic method on sliding windows. Example: --equation "
            "\"V2'' + B*V2' + K*V2 + K3*V2**3 = G*V1 + d\" --parameters \"B K K3 G d\"."
        ),
    )
    ide.add_argument("files", nargs="+", metavar="FILE",
                     help="data files (.csv, .txt, .csv.gz, .txt.gz, .mat), identified "
                          "together, or - for CSV on standard input, or one .parquet "
                          "record (read in chunks); with --by, one table "
                          "of many records (.parquet, a folder of Parquet files, .csv or -)")
    ide.add_argument("--equation", required=True, metavar="EQ", action="append",
                     help="the model equation; several times for a system of equations "
                          "that share parameters (one measured output each)")
    ide.add_argument("--parameters", required=True, metavar="\"P1 P2 ...\"",
                     help="the unknown parameters, separated by spaces")
    ide.add_argument("--hidden", default=None, metavar="SIGNAL", action="append",
                     help="with several --equation: an output of the equations that is not "
                          "measured (eliminated; once per hidden signal)")
    ide.add_argument("--time", default=None, metavar="COL",
                     help="time column (default: t or time when present)")
    ide.add_argument("--rate", type=_positive, default=None, metavar="HZ",
                     help="sampling rate in Hz, for files without a time column (with "
                          "one, it must agree with it)")
    ide.add_argument("--output", default=None, metavar="COL", action="append",
                     help="output signal (default: the one of highest derivative order); "
                          "for a system, once per --equation, in their order")
    ide.add_argument("--window", type=_positive, default=None, metavar="SECONDS",
                     help="window length (default: chosen from the data)")
    ide.add_argument("--method", choices=("bc", "ls", "iv", "gls"), default="bc",
                     help="bias-compensated least squares (default), least squares, "
                          "instrumental variables, or bias-compensated least squares "
                          "with the windows weighed by their noise (nearer the "
                          "Cramér–Rao bound where output noise is the misfit)")
    ide.add_argument("--refine", action=argparse.BooleanOptionalAction, default=None,
                     help="refine the algebraic estimate by output error (efficient under "
                          "white output noise); default: where it is safe (the model "
                          "simulates stably, the simulation error drops and the fit is "
                          "not less precise than the algebraic estimate)")
    ide.add_argument("--crossings", choices=("auto", "velocity", "local"), default="auto",
                     help="how the steps of a sign(q') are placed: by the model's own "
                          "velocity (a noisy position), by local fits of the position "
                          "(a precise one), or (default) by the misfit each leaves")
    ide.add_argument("--chunk", type=_positive_int, default=None, metavar="ROWS",
                     help="read the one record FILE (.csv or .parquet) in chunks of ROWS "
                          "rows, never whole (a .parquet record always is; see the user "
                          "guide, Fleets and long records)")
    ide.add_argument("--json", action="store_true",
                     help="print one JSON object: a key per parameter, stderr, window, "
                          "n_samples, warnings, estimate (refined or algebraic) and the "
                          "algebraic estimate; with --by, a list of the table's rows; a "
                          "refusal prints {\"error\": message}")
    ide.add_argument("--by", default=None, metavar="COL",
                     help="identify every record of a fleet on its own: FILE is one long "
                          "table whose column COL names each row's record (see the user "
                          "guide, Fleets)")
    ide.add_argument("--out", default=None, metavar="FILE",
                     help="write the results as a table (one row per record, the columns "
                          "of IdentificationResult.to_dict and error): .csv or .parquet")
    ide.add_argument("--workers", type=_positive_int, default=None, metavar="N",
                     help="with --by: identify on a local Dask cluster of N processes "
                          "(default: in this process, one record after another)")
    ide.add_argument("--scheduler", default=None, metavar="ADDRESS",
                     help="with --by: identify on the Dask cluster of this scheduler "
                          "(e.g. tcp://10.0.0.1:8786)")
    ide.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                     help="with --by: count the records done on standard error (default: "
                          "when it is a terminal)")
    ide.set_defaults(handler=_cmd_identify)

    from algid._cli_track import add_track_parser

    add_track_parser(commands, _positive)

    dat = commands.add_parser(
        "datasets",
        help="list or export the measured records shipped with algid (Silverbox, EMPS)",
        description=("The measured benchmark records shipped with algid, written as plain "
                     "CSV files with a time column t that `algid identify` reads as they "
                     "are. Example: algid datasets export emps records; algid identify "
                     "records/emps_estimation.csv --equation \"M*qm'' + Fv*qm' + "
                     "Fc*sign(qm') + off = F\" --parameters \"M Fv Fc off\"."),
    )
    actions = dat.add_subparsers(dest="action", metavar="ACTION", required=True)
    actions.add_parser("list", help="the records, the files each exports, their citations",
                       description="List the shipped records, the files `export` writes "
                                   "for each and the papers to cite."
                       ).set_defaults(handler=_cmd_datasets_list)
    export = actions.add_parser(
        "export", help="write a record as CSV files into a folder",
        description=("Write a shipped record as plain CSV files (header line, time column "
                     "t, exact values) into DIR, with the records' provenance note. "
                     "A file of the same name already in DIR is an error unless --force "
                     "is given; a symbolic link there is never written through (--force "
                     "replaces it by the file)."))
    export.add_argument("name", choices=("silverbox", "emps"), metavar="NAME",
                        help="silverbox or emps (see `algid datasets list`)")
    export.add_argument("folder", metavar="DIR", help="folder to write into (created if missing)")
    export.add_argument("--force", action="store_true",
                        help="replace files (or links) of the same names in DIR")
    export.set_defaults(handler=_cmd_datasets_export)

    der = commands.add_parser(
        "derive",
        help="print the symbolic derivation of an estimator (needs SymPy)",
        description="Print the symbolic derivation of the algebraic estimator of a model.",
    )
    der.add_argument("--model", default="msd", metavar="NAME", help="model (default: msd)")
    der.add_argument("--format", choices=("text", "latex", "markdown"), default="text",
                     help="output format (default: text)")
    der.add_argument("--equation", action="append", default=None, metavar="TEXT",
                     help="your own model instead of --model, e.g. \"y'' + a*y' + b*y = u\" "
                          "(derivatives with primes); several times for a system of "
                          "equations that share parameters")
    der.add_argument("--parameters", default=None, metavar="NAMES",
                     help="unknowns of --equation, e.g. \"a b\"")
    der.add_argument("--signals", nargs=2, default=None, metavar=("INPUT", "OUTPUT"),
                     help="names of the input and output of one --equation linear in them "
                          "(default: f x, else every signal of the equation is measured)")
    der.add_argument("--output", action="append", default=None, metavar="SIGNAL",
                     help="the output of each --equation, in order (default: the signal "
                          "of highest derivative order)")
    der.set_defaults(handler=_cmd_derive)

    gen = commands.add_parser(
        "codegen",
        help="write the estimator of a model as C99 source (needs SymPy)",
        description=("Write the algebraic estimator of a model as a self-contained C99 pair "
                     "DIR/algid_<model>.h, DIR/algid_<model>.c (libm only, no allocation)."),
    )
    gen.add_argument("model", nargs="?", default=None, metavar="MODEL",
                     help="built-in model (msd, msd_mass); or give --equation")
    gen.add_argument("--lang", choices=("c",), required=True, help="target language: c")
    gen.add_argument("--out", required=True, metavar="DIR", help="folder to write into")
    gen.add_argument("--filter-order", type=_nonnegative_int, default=2, metavar="P",
                     help="order p of the invariant filter 1/s**p (default: 2)")
    gen.add_argument("--quadrature-order", type=_nonnegative_int,
                     default=DEFAULT_QUADRATURE_POINTS, metavar="Q",
                     help="points of the quadrature rule, 2-9 (default: "
                          f"{DEFAULT_QUADRATURE_POINTS})")
    gen.add_argument("--equation", action="append", default=None, metavar="TEXT",
                     help="your own model instead of MODEL, as for `algid derive` (one "
                          "equation)")
    gen.add_argument("--parameters", default=None, metavar="NAMES",
                     help="unknowns of --equation, e.g. \"a b\"")
    gen.add_argument("--signals", nargs=2, default=("f", "x"), metavar=("INPUT", "OUTPUT"),
                     help="names of the input and output in --equation (default: f x)")
    gen.add_argument("--name", default=None, metavar="NAME",
                     help="<model> in the file and function names (default: the model's "
                          "name; 'custom' for --equation)")
    gen.set_defaults(handler=_cmd_codegen)

    pap = commands.add_parser(
        "paper",
        help="reproduce the experiments of Becedas et al. (2007), Section 3",
        description=(
            "Run the step and sine experiments of the paper with and without noise, write "
            "Figures 3-9 (PNG) and summary.json into DIR and print the paper's claims "
            "beside the measured convergence times and final errors."
        ),
    )
    pap.add_argument("--out", default="paper-figures", metavar="DIR",
                     help="output directory (default: paper-figures)")
    pap.add_argument("--seed", type=_nonnegative_int, default=0, metavar="N",
                     help="seed of the noise realisation shown (default: 0)")
    pap.add_argument("--n-seeds", type=_nonnegative_int, default=20, metavar="N",
                     help="noise realisations for medians and RMSEs (default: 20)")
    pap.add_argument("--json", action="store_true", help="print the summary as JSON")
    pap.set_defaults(handler=_cmd_paper)

    err = commands.add_parser(
        "errata",
        help="check the printed equations of Becedas et al. (2007), Section 2 (needs SymPy)",
        description=(
            "Check each printed equation (1)-(33) of Section 2 and the footnote on iterated "
            "integrals against a symbolic computation; print OK / WRONG, the reason and "
            "the corrected forms."
        ),
    )
    err.add_argument("--json", action="store_true",
                     help="print a JSON list of {number, correct, printed, corrected, "
                          "explanation}")
    err.set_defaults(handler=_cmd_errata)
    return parser


# ---------------------------------------------------------------------- commands


def _require(module, message):
    """Import an optional dependency, raising _MissingDependency when it is absent."""
    try:
        importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.split(".")[0] == module:
            raise _MissingDependency(message) from None
        raise


def _cmd_simulate(args) -> int:
    from algid.io import CSV_SUFFIXES

    if Path(args.out).suffix.lower() not in CSV_SUFFIXES:  # estimate reads by extension
        raise AlgidError(f"--out {args.out}: simulate writes comma-separated text; name the "
                         f"file .csv or .txt")
    _require("control", "algid simulate needs python-control: pip install 'algid[simulate]'")
    simulation = importlib.import_module("algid.simulation")
    result = simulation.simulate(
        args.input,
        m=args.mass,
        c=args.damping,
        k=args.stiffness,
        duration=args.duration,
        rate=args.rate,
        amplitude=args.amplitude,
        frequency=args.frequency,
        initial_state=(args.x0, args.v0),
        noise_std=args.noise_std,
        seed=args.seed,
    )
    try:
        result.to_csv(args.out)
    except OSError as exc:
        raise AlgidError(f"{args.out}: cannot write file ({exc.strerror or exc})") from None
    print(
        f"wrote {len(result.t)} samples to {args.out} ({args.input} input, "
        f"m={args.mass:g} c={args.damping:g} k={args.stiffness:g}, "
        f"{args.duration:g} s at {args.rate:g} Hz)"
    )
    return 0


def _finite_or_none(value):
    value = float(value)
    return value if math.isfinite(value) else None


def _cmd_estimate(args) -> int:
    from algid._signal_checks import check_experiment
    from algid.estimation._error_diagnosis import numerical_error_warning
    from algid.io import read_experiment

    time = "t" if args.time is None else args.time
    named = {"--input": args.input, "--output": args.output}
    if args.rate is None:
        named["--time"] = time
    seen = {}
    for option, column in named.items():
        if column in seen:
            raise InputDataError(f"{seen[column]} and {option} name the same column "
                                 f"{column!r}")
        seen[column] = option
    import numpy as np

    with np.errstate(over="ignore"):  # the times at a tiny --rate: refused below
        t, f, x = read_experiment(
            args.file, time=time, input=args.input, output=args.output, rate=args.rate
        )
    if args.rate is not None and t.size and not np.isfinite(t[-1]):
        raise InputDataError(f"{args.file}: --rate {args.rate:g} Hz puts the times of its "
                             f"{t.size} samples beyond the floating-point range: give the "
                             f"rate in other units")
    from algid.estimation._core import shortest_record

    estimator = importlib.import_module("algid.estimation._batch")
    options = {"model": args.model, "mass": args.mass}
    if args.filter_order is not None:
        options["filter_order"] = args.filter_order
    try:  # (the API's shortest record)
        t, f, x, _ = check_experiment(t, f, x, names=(time, args.input, args.output),
                                      min_samples=shortest_record(DEFAULT_QUADRATURE_POINTS))
        result = estimator.estimate(t, f, x, **options)
    except InputDataError as exc:  # the file named, as the reader's errors name it
        raise InputDataError(f"{args.file}: {exc}") from None

    final = result.final()
    names = tuple(result.parameters)
    t_valid = float(result.t_valid)
    error = getattr(result, "final_numerical_error", lambda: math.nan)()

    def half_rate_error():
        try:
            return estimator.estimate(t[::2], f[::2], x[::2],
                                      **options).final_numerical_error()
        except AlgidError:  # too short at half the rate
            return math.nan

    warning = numerical_error_warning(args.file, error, half_rate_error, args.output, x)
    if warning:
        print(warning, file=sys.stderr)
    if args.json:
        payload = {name: _finite_or_none(final[name]) for name in names}
        payload["t_valid"] = _finite_or_none(t_valid)
        payload["n_samples"] = int(result.n_samples)
        payload["numerical_error"] = "inf" if math.isinf(error) else _finite_or_none(error)
        print(json.dumps(payload, allow_nan=False))
        return 0

    model = getattr(result, "model", args.model)
    order = getattr(result, "filter_order", None)
    details = [f"model {model}"]
    if order is not None:
        details.append(f"filter order {order}")
    details.append(f"{int(result.n_samples)} samples")
    print(f"{args.file}: {', '.join(details)}")
    width = max([len("parameter"), len("numerical error")] + [len(name) for name in names])
    print(f"{'parameter':<{width}}  estimate")
    for name in names:
        print(f"{name:<{width}}  {float(final[name]):.6g}")
    print(f"{'numerical error':<{width}}  {error:.1e} (relative, estimated)")
    if math.isfinite(t_valid):
        print(f"estimates valid from t = {t_valid:.6g} s")
    else:
        print("no valid estimate: the record gave no usable sample")
    return 0


#: Keys of ``algid identify --json`` besides the parameters (``outputs`` and
#: ``correlation`` for a system of equations).
IDENTIFY_JSON_KEYS = ("stderr", "numerical_error", "window", "n_samples", "warnings",
                      "estimate", "algebraic", "outputs", "correlation")


def _cmd_identify(args) -> int:
    from algid._cli_track import read_model_columns
    from algid._record_input import TIME_COLUMNS
    from algid.identification._identify import identify
    from algid.models._grammar import parse_equation
    from algid.models._system import parse_system

    if len(args.equation) > 1:
        model = parse_system(args.equation, args.parameters, outputs=args.output)
    else:
        if args.output is not None and len(args.output) > 1:
            raise InputDataError("--output is given once per --equation")
        model = parse_equation(args.equation[0], args.parameters,
                               output=None if args.output is None else args.output[0])
    clash = [p for p in model.parameters if p in IDENTIFY_JSON_KEYS]
    if clash:
        raise ModelError(f"parameter name {clash[0]!r} is reserved by the output "
                         f"({', '.join(IDENTIFY_JSON_KEYS)}); rename it")
    if args.hidden is not None and len(args.equation) == 1:
        raise InputDataError("--hidden goes with several --equation (a system)")
    if args.by is not None and len(args.equation) > 1:
        raise InputDataError("--by identifies one equation per record; a system of "
                             "equations is identified on one record (or several together)")
    if args.by is not None and args.chunk is not None:
        raise InputDataError("--chunk reads one long record; with --by, each record of the "
                             "table is identified in memory")
    if args.by is not None:
        from algid._cli_fleet import fleet_command

        return fleet_command(args, model)
    fleet_only = [option for option, value in (("--workers", args.workers),
                                               ("--scheduler", args.scheduler),
                                               ("--progress", args.progress))
                  if value is not None]
    if fleet_only:
        raise InputDataError(f"{fleet_only[0]} goes with --by (a table of many records)")
    if "-" in args.files and len(args.files) > 1:
        raise InputDataError("- (standard input) is one record: give it alone")
    if args.out is not None:
        from algid._cli_fleet import check_out

        check_out(args.out)
    hidden = set(args.hidden or ())
    names = [s for s in model.signals if s not in hidden] + ([args.time] if args.time else [])
    # a time column is read with --rate too: the two must agree
    optional = () if args.time else TIME_COLUMNS
    options = {"hidden": args.hidden} if args.hidden else {}
    from algid.identification._record_source import PARQUET_SUFFIXES

    streamed = args.chunk is not None or any(
        str(path).lower().endswith(PARQUET_SUFFIXES) for path in args.files)
    if streamed:   # one record read in chunks, never whole
        if args.files[0] == "-" or "-" in args.files:
            raise InputDataError("--chunk reads a file: standard input is read whole "
                                 "(drop --chunk, or save it to a file)")
        if len(args.files) > 1:
            raise InputDataError("a record read in chunks (a Parquet file, or --chunk) is "
                                 "one file: give it alone")
        records = args.files[0]
        options["chunk"] = args.chunk
    else:
        records = [read_model_columns(sys.stdin if path == "-" else path, names, model,
                                      optional) for path in args.files]
    result = identify(records, model, time=args.time, rate=args.rate, window=args.window,
                      method=args.method, refine="auto" if args.refine is None else args.refine,
                      crossings=args.crossings, **options)
    stderr = result.stderr
    source = args.files[0] if len(args.files) == 1 else f"{len(args.files)} records"
    source = "standard input" if source == "-" else source
    for warning in result.warnings:
        print(f"warning: {source}: {warning}", file=sys.stderr)
    if args.out is not None:
        from algid._cli_fleet import write_table

        table = result.to_pandas()
        table.index = [source]
        write_table(table.rename_axis("source"), args.out)
    if args.json:
        payload = {p: _finite_or_none(v) for p, v in result.values.items()}
        payload["stderr"] = {p: _finite_or_none(v) for p, v in stderr.items()}
        payload["numerical_error"] = {p: _finite_or_none(v)
                                      for p, v in result.numerical_error.items()}
        payload["window"] = float(result.window)
        payload["n_samples"] = int(result.n_samples)
        payload["warnings"] = list(result.warnings)
        payload["estimate"] = result.estimate
        if len(args.equation) > 1:
            payload["outputs"] = list(model.outputs)
            payload["correlation"] = [[_finite_or_none(v) for v in row]
                                      for row in result.correlation.tolist()]
        algebraic = result.algebraic or {"values": result.values,
                                         "covariance": result.covariance}
        cov = algebraic["covariance"]
        payload["algebraic"] = {
            "values": {p: _finite_or_none(v) for p, v in algebraic["values"].items()},
            "stderr": {p: _finite_or_none(math.sqrt(max(float(cov[i, i]), 0.0)))
                       for i, p in enumerate(model.parameters)},
            "numerical_error": {p: _finite_or_none(v) for p, v in
                                algebraic.get("numerical_error",
                                              result.numerical_error).items()}}
        print(json.dumps(payload, allow_nan=False))
        return 0
    print("\n".join(args.equation) if len(args.equation) > 1 else model.equation)
    refined = ", refined by output error" if result.estimate == "refined" else ""
    print(f"{len(args.files)} record(s), {result.n_samples} samples, window "
          f"{result.window:.6g} s ({result.n_windows} windows), method {result.method}"
          f"{refined}")
    width = max([len("parameter")] + [len(p) for p in model.parameters])
    print(f"{'parameter':<{width}}  {'estimate':>13}  {'std. error':>10}  {'numerical':>10}")
    for p, v in result.values.items():
        print(f"{p:<{width}}  {v:>13.6g}  {stderr[p]:>10.2g}  "
              f"{result.numerical_error.get(p, math.nan):>10.2g}")
    return 0


def _cmd_datasets_list(args) -> int:
    from algid import datasets

    citations = {"silverbox": datasets.SILVERBOX_CITATION, "emps": datasets.EMPS_CITATION}
    for name, files in datasets.EXPORTS.items():
        print(f"{name}: {files}")
        print(f"  cite: {citations[name]}")
    return 0


def _cmd_datasets_export(args) -> int:
    from algid.datasets import export

    for path in export(args.name, args.folder, overwrite=args.force):
        print(f"wrote {path}")
    return 0


def _cmd_derive(args) -> int:
    _require("sympy", "algid derive needs SymPy: pip install 'algid[derive]'")
    symbolic = importlib.import_module("algid.symbolic")
    model = args.model
    if args.equation is not None or args.parameters is not None:
        if args.equation is None or args.parameters is None:
            raise ModelError("--equation and --parameters go together")
        if len(args.equation) > 1:
            if args.signals is not None:
                raise ModelError("--signals names the input and output of one equation; "
                                 "a system's outputs come from its equations (--output)")
            from algid.models import parse_system

            model = parse_system(args.equation, args.parameters, outputs=args.output)
        elif args.output is not None:   # one equation, its output named
            if len(args.output) > 1 or args.signals is not None:
                raise ModelError("one equation takes one --output (or --signals INPUT "
                                 "OUTPUT for an equation linear in them), not both")
            from algid.models import parse_equation

            model = parse_equation(args.equation[0], args.parameters, output=args.output[0])
        else:
            model = _derived_equation(symbolic, args.equation[0], args.parameters,
                                      args.signals)
    text = symbolic.derivation_report(model, args.format)
    print(str(text).rstrip("\n"))
    return 0


def _derived_equation(symbolic, equation, parameters, signals):
    """One equation for ``algid derive``: linear in ``signals`` (default f, x) as the
    paper's model, else in every signal it reads (a parsed equation)."""
    try:
        input_, output = signals or ("f", "x")
        return symbolic.LinearODEModel.from_equation(equation, parameters=parameters,
                                                     input=input_, output=output,
                                                     name="custom")
    except ModelError:
        if signals is not None:
            raise
    from algid.models import parse_equation

    return parse_equation(equation, parameters)


def _cmd_codegen(args) -> int:
    _require("sympy", "algid codegen needs SymPy: pip install 'algid[derive]'")
    symbolic = importlib.import_module("algid.symbolic")
    codegen_c = importlib.import_module("algid.symbolic._codegen_c")
    if args.equation is not None or args.parameters is not None:
        if args.equation is None or args.parameters is None:
            raise ModelError("--equation and --parameters go together")
        if args.model is not None:
            raise ModelError(f"give either MODEL ({args.model!r}) or --equation, not both")
        if len(args.equation) > 1:
            raise ModelError(f"codegen writes the estimator of one equation; --equation was "
                             f"given {len(args.equation)} times")
        model = symbolic.LinearODEModel.from_equation(
            args.equation[0], parameters=args.parameters, input=args.signals[0],
            output=args.signals[1], name=args.name or "custom")
    elif args.model is None:
        raise ModelError("give a MODEL (msd, msd_mass) or --equation and --parameters")
    else:
        model = importlib.import_module("algid.symbolic._builtin_models").builtin_model(args.model)
    try:
        paths = codegen_c.write_c_sources(symbolic.derive(model), args.out, name=args.name,
                                          filter_order=args.filter_order,
                                          quadrature_order=args.quadrature_order)
    except OSError as exc:
        raise AlgidError(f"{args.out}: cannot write ({exc.strerror or exc})") from None
    for path in paths:
        print(f"wrote {path}")
    return 0


def _cmd_paper(args) -> int:
    _require("matplotlib", "algid paper needs matplotlib: pip install 'algid[plot]'")
    _require("control", "algid paper needs python-control: pip install 'algid[simulate]'")
    if args.n_seeds < 1:
        raise InputDataError(f"--n-seeds must be at least 1, got {args.n_seeds}")
    paper = importlib.import_module("algid.paper")
    result = paper.reproduce(args.out, seed=args.seed, n_seeds=args.n_seeds)
    if args.json:
        print(result.to_json())
        return 0
    print(result.table())
    print(f"wrote {len(result.figures)} figures and summary.json to {result.out}")
    return 0


def _cmd_errata(args) -> int:
    _require("sympy", "algid errata needs SymPy: pip install 'algid[derive]'")
    errata = importlib.import_module("algid.symbolic._errata")
    verdicts = errata.errata_report()
    print(errata.format_errata(verdicts, "json" if args.json else "text"))
    return 0


# -------------------------------------------------------------------------- main


def _error(message) -> None:
    line = " ".join(str(message).splitlines()).strip()
    print(f"{PROG}: error: {line}", file=sys.stderr)


def main(argv=None) -> int:
    """Run the ``algid`` command line.

    Parameters
    ----------
    argv : list of str, optional
        Arguments without the program name; ``sys.argv[1:]`` when omitted.

    Returns
    -------
    int
        Exit status: 0 on success, 2 on a usage error or bad input (the message is
        printed as one line ``algid: error: ...`` on standard error), 130 when
        interrupted.
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version and usage errors
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    try:
        return int(args.handler(args) or 0)
    except (AlgidError, _MissingDependency) as exc:
        message = str(exc) or type(exc).__name__
        _error(message)
        if args.command == "identify" and args.json:   # a reader of JSON reads why too
            print(json.dumps({"error": " ".join(message.splitlines()).strip()}))
        return 2
    except KeyboardInterrupt:
        _error("interrupted")
        return 130
    except BrokenPipeError:
        # the reader (e.g. `| head`) went away: stop quietly, as Unix tools do
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
