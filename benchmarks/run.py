"""Command line of the benchmark: ``python -m benchmarks [--quick | --smoke]``.

Runs every section (:mod:`benchmarks.sections`) in one process, on the same data,
prints the Markdown tables and writes the results as JSON (NaN as ``null``).

Usage, from the repository root::

    .venv/bin/python -m benchmarks                      # full (tens of minutes)
    .venv/bin/python -m benchmarks --quick              # a few minutes
    .venv/bin/python -m benchmarks --smoke --out r.json # seconds (the test suite)
    .venv/bin/python -m benchmarks --only accuracy,tracking
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import pathlib
import platform
import sys
import time

if __package__ in (None, ""):  # run as a script: python benchmarks/run.py
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))

__all__ = ["run", "main", "section_main", "SECTIONS", "to_json"]

#: Section names, in the order they run.
SECTIONS = ("accuracy", "efficiency", "performance", "long_stream", "tracking", "c_speed",
            "error_cost")

DEFAULT_OUT = pathlib.Path(__file__).resolve().parent / "results.json"


def to_json(value):
    """``value`` with NaN and infinities replaced by None and tuples by lists."""
    if isinstance(value, dict):
        return {str(k): to_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_json(v) for v in value]
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):  # NumPy scalar
        return to_json(value.item())
    return value


def section_main(argv, module, section, markdown, sizes):
    """Command line of one section run alone: ``--quick``, ``--smoke``, ``--json``.

    Parameters
    ----------
    argv : list of str or None
    module : str
        ``benchmarks.<name>`` (the program's name); its docstring's first line is the
        description.
    section, markdown : callable
        ``section(config) -> data`` and ``markdown(data) -> str``.
    sizes : tuple of str
        Help of ``--quick`` and of ``--smoke``.

    Returns
    -------
    int
        Exit code.
    """
    import importlib

    from benchmarks.sections import CONFIGS

    description = (importlib.import_module(module).__doc__ or "").splitlines()[0]
    parser = argparse.ArgumentParser(prog=f"python -m {module}", description=description)
    size = parser.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true", help=sizes[0])
    size.add_argument("--smoke", action="store_true", help=sizes[1])
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parser.parse_args(argv)
    data = section(CONFIGS["smoke" if args.smoke else "quick" if args.quick else "full"])
    print(json.dumps(to_json(data), indent=1) if args.json else markdown(data))
    return 0


def run(mode="full", *, only=None, log=None):
    """Run the benchmark.

    Parameters
    ----------
    mode : {"full", "quick", "smoke"}
        Sizes (:data:`benchmarks.sections.CONFIGS`).
    only : sequence of str, optional
        Run only these sections (default: all of :data:`SECTIONS`).
    log : callable, optional
        Called with a progress message before each section.

    Returns
    -------
    dict
        ``meta``, one entry per section that ran, and ``targets``.
    """
    import numpy
    import scipy

    import algid
    from benchmarks import report, sections

    config = sections.CONFIGS[mode]
    chosen = tuple(SECTIONS if not only else only)
    unknown = [s for s in chosen if s not in SECTIONS]
    if unknown:
        raise ValueError(f"unknown section(s) {unknown}; choose from {SECTIONS}")
    results = {"meta": {
        "mode": mode, "config": {k: v for k, v in vars(config).items() if k != "extra"},
        "started": datetime.datetime.now().isoformat(timespec="seconds"),
        "python": platform.python_version(), "numpy": numpy.__version__,
        "scipy": scipy.__version__, "algid": algid.__version__,
        "machine": platform.machine(), "optional": sections.optional_features(),
        "sections": list(chosen), "elapsed": {},
    }}
    for name in SECTIONS:
        if name not in chosen:
            continue
        if log:
            log(f"[{mode}] {name} ...")
        start = time.perf_counter()
        results[name] = getattr(sections, name)(config)
        results["meta"]["elapsed"][name] = time.perf_counter() - start
    results["targets"] = report.targets(results)
    return results


def main(argv=None):
    """Entry point; returns the exit code."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.split(
        "\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    size = parser.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true", help="smaller sizes (a few minutes)")
    size.add_argument("--smoke", action="store_true", help="smallest sizes (seconds)")
    parser.add_argument("--out", type=pathlib.Path, default=None,
                        help=f"JSON output (default {DEFAULT_OUT.name} next to this file "
                             f"for a full run, none otherwise; '-' for none)")
    parser.add_argument("--only", default=None,
                        help=f"comma-separated sections among {', '.join(SECTIONS)}")
    args = parser.parse_args(argv)
    mode = "smoke" if args.smoke else "quick" if args.quick else "full"
    only = None if not args.only else [s.strip() for s in args.only.split(",") if s.strip()]
    try:
        results = run(mode, only=only, log=lambda msg: print(msg, file=sys.stderr, flush=True))
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    from benchmarks import report

    print(report.markdown(results))
    out = args.out if args.out is not None else (DEFAULT_OUT if mode == "full" else None)
    if out is not None and str(out) != "-":
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(to_json(results), indent=1, allow_nan=False) + "\n")
        print(f"results written to {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
