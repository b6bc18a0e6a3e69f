"""The algebraic estimate on short records (``PYTHONPATH=src:. python -m
benchmarks.short_records --runs 100``).

``y'' + B y' + K y = G u + d`` with a 0.85 Hz mode (``B, K, G, d = 0.5, 28.5, 28.5,
0.1``), a multisine of 20 lines from 0.2 to 5 Hz, 1 kHz, 1 % white output noise,
records of 2 s (1.7 periods of the mode) and 4 s, exact (the window-rule study's
simulator): per record length, over ``--runs`` noise realisations, the refusals, the
warnings, the windows chosen, and per parameter the root-mean-square error, the rms of
error / reported standard error and the ±2σ coverage of ``identify(..., refine=False)``
with the automatic window (or ``--window``).  To compare another checkout, put its
``src`` first on ``PYTHONPATH``.

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

__all__ = ["TRUTH", "DURATIONS", "record", "study", "main"]

EQUATION = ("y'' + B*y' + K*y = G*u + d", "B K G d")
TRUTH = {"B": 0.5, "K": (2 * np.pi * 0.85) ** 2, "G": (2 * np.pi * 0.85) ** 2, "d": 0.1}

#: Record lengths (s).
DURATIONS = (2.0, 4.0)

#: Relative output noise (standard deviation over the output's).
NOISE = 0.01


def record(duration, seed, noise=NOISE):
    """One noisy record of ``duration`` seconds (``{"t", "u", "y"}``)."""
    lines = multisine(f_low=0.2, f_high=5.0, count=20)
    t = np.arange(int(round(duration * 1000.0)) + 1) / 1000.0
    y = _linear_output(TRUTH, (0.0, 0.0), t, lines)
    y = y + noise * np.std(y) * np.random.default_rng(seed).standard_normal(len(t))
    return {"t": t, "u": _input(t, lines), "y": y}


def study(duration, runs, window=None):
    """The figures of one record length over ``runs`` realisations (seeds 0 to
    ``runs - 1``)."""
    errors, stderrs, windows, warned, refused = [], [], Counter(), 0, []
    start = time.perf_counter()
    for seed in range(runs):
        try:
            r = algid.identify(record(duration, seed), *EQUATION, window=window,
                               refine=False)
        except AlgidError as error:
            refused.append(str(error))
            continue
        errors.append([r.values[p] - v for p, v in TRUTH.items()])
        stderrs.append([r.stderr[p] for p in TRUTH])
        windows[f"{r.window:.3g}"] += 1
        warned += bool(r.warnings)
    error, se = np.array(errors).reshape(-1, len(TRUTH)), np.array(stderrs)
    rows = {}
    for i, p in enumerate(TRUTH):
        if not len(error):
            break
        rows[p] = {"rmse": float(np.sqrt(np.mean(error[:, i] ** 2))),
                   "z_rms": float(np.sqrt(np.mean((error[:, i] / se[:, i]) ** 2))),
                   "coverage": float(np.mean(np.abs(error[:, i]) <= 2 * se[:, i]))}
    return {"duration": duration, "runs": runs, "window": window,
            "identified": len(error), "refusals": len(refused), "refused": refused[:3],
            "warned": warned, "windows": dict(sorted(windows.items())),
            "parameters": rows, "seconds": time.perf_counter() - start}


def report(row):
    """Text lines of one :func:`study` row."""
    lines = [f"{row['duration']:g} s: {row['identified']}/{row['runs']} identified, "
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
    print(f"algid from {algid.__file__}; 1 kHz, {NOISE:.0%} output noise")
    rows = []
    for duration in DURATIONS:
        rows.append(study(duration, args.runs, args.window))
        print("\n".join(report(rows[-1])), flush=True)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as handle:
            json.dump({"command": "PYTHONPATH=src:. python -m benchmarks.short_records "
                                  f"--runs {args.runs}", "rows": rows}, handle, indent=1)
    return 0


if __name__ == "__main__":
    main()
