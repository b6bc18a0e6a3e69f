"""A derivative inside a nonlinear factor: quadratic damping (``PYTHONPATH=src:. python -m
benchmarks.quadratic_damping --runs 30``).

``y'' + B abs(y') y' + K y = G u`` (``B, K, G = 0.5, 40, 40``), a multisine of 12 lines
from 0.2 to 5 Hz, 20 s at 1 kHz (DOP853, relative tolerance 1e-11), white output noise
at ``--snr`` dB (default 20, 30 and 45); ``identify(..., window=0.4, refine=False)``.
Per SNR and parameter, over ``--runs`` realisations: the bias and the spread over the
mean reported standard error, the mean numerical error over it, and the ±2σ coverage
without and with the numerical error added.  To compare another checkout, put its
``src`` first on ``PYTHONPATH``.

Options: ``--runs N`` (default 30), ``--snr DB ...``, ``--out FILE`` (JSON).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

import algid

__all__ = ["EQUATION", "TRUTH", "record", "study", "main"]

EQUATION = ("y'' + B*abs(y')*y' + K*y = G*u", "B K G")
TRUTH = {"B": 0.5, "K": 40.0, "G": 40.0}
FREQS, PHASES = np.linspace(0.2, 5.0, 12), np.linspace(0.0, 5.0, 12)


def _input(t):
    return np.sum(np.sin(2 * np.pi * FREQS * np.atleast_1d(t)[:, None] + PHASES), axis=1)


def record():
    """Time, input and noise-free output."""
    from scipy.integrate import solve_ivp

    B, K, G = (TRUTH[p] for p in ("B", "K", "G"))
    t = np.arange(20001) / 1000.0
    y = solve_ivp(lambda s, x: [x[1], G * _input(s)[0] - B * abs(x[1]) * x[1] - K * x[0]],
                  (0, t[-1]), [0, 0], method="DOP853", t_eval=t, rtol=1e-11, atol=1e-12,
                  max_step=0.01).y[0]
    return t, _input(t), y


def study(snr, runs, clean=None):
    """The figures at one SNR (seeds 0 to ``runs - 1``)."""
    t, u, y = record() if clean is None else clean
    sigma = np.std(y) * 10 ** (-snr / 20)
    errors, stderrs, numerical = [], [], []
    for seed in range(runs):
        noisy = y + sigma * np.random.default_rng(seed).standard_normal(len(t))
        r = algid.identify({"t": t, "u": u, "y": noisy}, *EQUATION, window=0.4,
                           refine=False)
        errors.append([r.values[p] - v for p, v in TRUTH.items()])
        stderrs.append([r.stderr[p] for p in TRUTH])
        numerical.append([r.numerical_error[p] for p in TRUTH])
    e, s, n = (np.array(a) for a in (errors, stderrs, numerical))
    scale = s.mean(axis=0)
    return {"snr_db": snr, "runs": runs, "parameters": {p: {
        "bias_over_se": float(e[:, i].mean() / scale[i]),
        "spread_over_se": float(e[:, i].std() / scale[i]),
        "numerical_over_se": float(n[:, i].mean() / scale[i]),
        "coverage": float(np.mean(np.abs(e[:, i]) <= 2 * s[:, i])),
        "coverage_with_numerical": float(np.mean(np.abs(e[:, i]) <= 2 * s[:, i] + n[:, i]))}
        for i, p in enumerate(TRUTH)}}


def main(argv=None):
    """Run the study and print its table."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.quadratic_damping")
    parser.add_argument("--runs", type=int, default=30)
    parser.add_argument("--snr", type=float, nargs="+", default=[20.0, 30.0, 45.0])
    parser.add_argument("--out", default=None)
    args = parser.parse_args(argv)
    print(f"algid from {algid.__file__}")
    print(f"{'SNR':>5} {'param':6}{'bias/se':>9}{'spread/se':>10}{'num/se':>8}{'cover':>8}"
          f"{'+num':>8}")
    clean = record()
    rows = []
    for snr in args.snr:
        rows.append(study(snr, args.runs, clean))
        for p, v in rows[-1]["parameters"].items():
            print(f"{snr:5g} {p:6}{v['bias_over_se']:9.2f}{v['spread_over_se']:10.2f}"
                  f"{v['numerical_over_se']:8.2f}{v['coverage']:8.1%}"
                  f"{v['coverage_with_numerical']:8.1%}", flush=True)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as handle:
            json.dump(rows, handle, indent=1)
    return 0


if __name__ == "__main__":
    main()
