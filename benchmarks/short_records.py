"""The algebraic estimate on short records (``PYTHONPATH=src:. python -m
benchmarks.short_records --runs 100``).

``y'' + B y' + K y = G u + d``, 1 kHz, white output noise, exact (the window-rule
study's simulator), three records:

- ``2 s`` and ``4 s``: a 0.85 Hz mode (``B, K, G, d = 0.5, 28.5, 28.5, 0.1``), a
  multisine of 20 lines from 0.2 to 5 Hz, 1 % noise (2 s: 1.7 periods of the mode);
- ``4 s, 3 lines``: a 0.71 Hz mode (``B, K, G = 1, 20, 15``, no offset, identified
  without one) started at ``y = 0.1``, three lines (0.7, 2.3 and 5.1 Hz), 2 % noise.

Per record, over ``--runs`` noise realisations: the refusals, the warnings, the windows
chosen, and per parameter the root-mean-square error, the rms of error / reported
standard error and the ±2σ coverage of ``identify(..., refine=False)`` with the
automatic window (or ``--window``).  To compare another checkout, put its ``src``
first on ``PYTHONPATH``.

Options: ``--runs N`` (default 100), ``--window S`` (default: automatic), ``--out FILE``
(JSON).
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter

import numpy as np

import algid
from algid.errors import AlgidError
from benchmarks.window_rule_study import _input, _linear_output, multisine

__all__ = ["RECORDS", "record", "study", "report", "main"]

_MULTISINE = {"equation": ("y'' + B*y' + K*y = G*u + d", "B K G d"),
              "truth": {"B": 0.5, "K": (2 * np.pi * 0.85) ** 2,
                        "G": (2 * np.pi * 0.85) ** 2, "d": 0.1},
              "lines": multisine(f_low=0.2, f_high=5.0, count=20), "x0": (0.0, 0.0),
              "noise": 0.01}

#: Name -> the model (equation, parameters), the plant (``truth``: the simulated one's
#: values), its input lines, initial state, relative output noise and duration.
RECORDS = {
    "2 s": dict(_MULTISINE, duration=2.0),
    "4 s": dict(_MULTISINE, duration=4.0),
    "4 s, 3 lines": {"equation": ("y'' + B*y' + K*y = G*u", "B K G"),
                     "truth": {"B": 1.0, "K": 20.0, "G": 15.0, "d": 0.0},
                     "lines": (np.array([0.7, 2.3, 5.1]), np.array([0.0, 1.0, 2.0]), 1.0),
                     "x0": (0.1, 0.0), "noise": 0.02, "duration": 4.0},
}


def record(name, seed):
    """One noisy record of :data:`RECORDS` (``{"t", "u", "y"}``)."""
    spec = RECORDS[name]
    t = np.arange(int(round(spec["duration"] * 1000.0)) + 1) / 1000.0
    y = _linear_output(spec["truth"], spec["x0"], t, spec["lines"])
    rng = np.random.default_rng(seed)
    y = y + spec["noise"] * np.std(y) * rng.standard_normal(len(t))
    return {"t": t, "u": _input(t, spec["lines"]), "y": y}


def study(name, runs, window=None):
    """The figures of one record over ``runs`` realisations (seeds 0 to ``runs - 1``)."""
    spec = RECORDS[name]
    truth = {p: spec["truth"][p] for p in spec["equation"][1].split()}
    errors, stderrs, windows, warned, refused = [], [], Counter(), 0, []
    start = time.perf_counter()
    for seed in range(runs):
        try:
            r = algid.identify(record(name, seed), *spec["equation"], window=window,
                               refine=False)
        except AlgidError as error:
            refused.append(str(error))
            continue
        errors.append([r.values[p] - v for p, v in truth.items()])
        stderrs.append([r.stderr[p] for p in truth])
        windows[f"{r.window:.3g}"] += 1
        warned += bool(r.warnings)
    error, se = np.array(errors).reshape(-1, len(truth)), np.array(stderrs)
    rows = {}
    for i, p in enumerate(truth):
        if not len(error):
            break
        rows[p] = {"rmse": float(np.sqrt(np.mean(error[:, i] ** 2))),
                   "z_rms": float(np.sqrt(np.mean((error[:, i] / se[:, i]) ** 2))),
                   "coverage": float(np.mean(np.abs(error[:, i]) <= 2 * se[:, i]))}
    return {"record": name, "runs": runs, "window": window, "identified": len(error),
            "refusals": len(refused), "refused": refused[:3], "warned": warned,
            "windows": dict(sorted(windows.items())), "parameters": rows,
            "seconds": time.perf_counter() - start}


def report(row):
    """Text lines of one :func:`study` row."""
    lines = [f"{row['record']}: {row['identified']}/{row['runs']} identified, "
             f"{row['refusals']} refused, {row['warned']} warned; windows (s: count) "
             f"{row['windows']}",
             f"{'param':6}{'RMSE':>11}{'z rms':>8}{'cover':>8}"]
    for p, v in row["parameters"].items():
        lines.append(f"{p:6}{v['rmse']:11.3g}{v['z_rms']:8.2f}{v['coverage']:8.1%}")
    return lines


def main(argv=None):
    """Run the study and print its tables."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.short_records")
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--window", type=float, default=None)
    parser.add_argument("--out", default=None)
    args = parser.parse_args(argv)
    print(f"algid from {algid.__file__}")
    rows = []
    for name in RECORDS:
        rows.append(study(name, args.runs, args.window))
        print("\n".join(report(rows[-1])), flush=True)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as handle:
            json.dump({"command": "PYTHONPATH=src:. python -m benchmarks.short_records "
                                  f"--runs {args.runs}", "rows": rows}, handle, indent=1)
    return 0


if __name__ == "__main__":
    main()
