"""The window-rule study on records it was not tuned on
(``PYTHONPATH=src:. python -m benchmarks.window_rule_holdout --runs 40``).

:mod:`benchmarks.window_rule_study` with other values (linear ``B, K, G, d = 1.2, 90,
60, -0.3``; Duffing ``0.9, 25, 3, 30, 0.2``), another input (20 lines from 0.2 to 8 Hz,
phase seed 7), 500 Hz, 20 s and 25 dB: bias, RMSE / CRLB, the rms of error / reported
standard error and ±2σ coverage per parameter of the algebraic estimate
(``refine=False``), and the windows chosen.  To compare another checkout, put its
``src`` first on ``PYTHONPATH``.

Options: ``--runs N`` (default 40), ``--method {bc,ls,gls}`` (default ``bc``),
``--window S`` (default: automatic), ``--out FILE`` (JSON).
"""

from __future__ import annotations

import argparse
import functools
import json

import benchmarks.window_rule_study as study

__all__ = ["main"]

TRUTH = {"linear": {"B": 1.2, "K": 90.0, "G": 60.0, "d": -0.3},
         "duffing": {"B": 0.9, "K": 25.0, "K3": 3.0, "G": 30.0, "d": 0.2}}


def main(argv=None):
    """Run the study on the held-out records and print its tables."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.window_rule_holdout")
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--method", default="bc", choices=("bc", "ls", "gls"))
    parser.add_argument("--window", type=float, default=None)
    parser.add_argument("--out", default=None)
    args = parser.parse_args(argv)
    for name, truth in TRUTH.items():
        study.MODELS[name] = dict(study.MODELS[name], truth=truth)
    study.SNR_DB = 25.0
    study.multisine = functools.partial(study.multisine, seed=7, f_low=0.2, f_high=8.0,
                                        count=20)
    simulate = study.simulate
    study.simulate = lambda model, theta=None, x0=(0.0, 0.0), lines=None: simulate(
        model, theta, x0, lines, rate=500.0, duration=20.0)
    print("held-out records: 500 Hz, 20 s, 25 dB, multisine 0.2-8 Hz (seed 7)")
    rows = []
    for name in TRUTH:
        rows.append(study.study(name, args.runs, window=args.window, method=args.method))
        print("\n".join(study.report(rows[-1])), flush=True)
    if args.out:
        with open(args.out, "w") as handle:
            json.dump(rows, handle, indent=1)
    return 0


if __name__ == "__main__":
    main()
