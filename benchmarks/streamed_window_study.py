"""The automatic window of a record read in chunks against the in-memory rule
(``python -m benchmarks.streamed_window_study --runs 20``).

Records nothing was tuned on: ``y'' + 1.2 y' + 90 y = 60 u - 0.3`` at 500 Hz, 300 000
samples (over :data:`algid.identification.STREAM_SAMPLES`: read in chunks, the window
chosen on excerpts), a multisine of 10 lines from 0.2 to 6 Hz, 25 dB of white output
noise.  Each realisation is identified twice: by default (streamed, not refined) and in
memory (the threshold raised; ``refine=False``, the same algebraic estimator).  Printed
per path: the windows chosen, the CPU time per record, and per parameter the bias over
the mean standard error, the RMSE, its ratio to the mean standard error, and the
coverage of the ±2σ intervals.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

TRUTH = {"B": 1.2, "K": 90.0, "G": 60.0, "d": -0.3}
EQUATION = ("y'' + B*y' + K*y = G*u + d", "B K G d")
SAMPLES, RATE, SNR_DB = 300_000, 500.0, 25.0


def record(seed):
    """One realisation (exact for inputs linear between samples)."""
    from scipy import signal

    rng = np.random.default_rng(seed)
    t = np.arange(SAMPLES) / RATE
    lines, phases = np.linspace(0.2, 6.0, 10), rng.uniform(0, 2 * np.pi, 10)
    u = np.sqrt(2 / 10) * np.sum([np.sin(2 * np.pi * f * t + p)
                                  for f, p in zip(lines, phases)], axis=0)
    b, a, _ = signal.cont2discrete(([TRUTH["G"]], [1, TRUTH["B"], TRUTH["K"]]), 1 / RATE,
                                   method="foh")
    y = signal.lfilter(b.ravel(), a, u) + TRUTH["d"] / TRUTH["K"]
    return {"t": t, "u": u, "y": y + rng.normal(0, np.std(y) * 10 ** (-SNR_DB / 20), SAMPLES)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    args = parser.parse_args(argv)

    import algid
    from algid.identification import _identify

    rows, cpu = {"streamed": [], "memory": []}, {"streamed": 0.0, "memory": 0.0}
    for seed in range(args.runs):
        data = record(100 + seed)
        start = time.process_time()
        streamed = algid.identify(data, *EQUATION)
        cpu["streamed"] += time.process_time() - start
        saved, _identify.STREAM_SAMPLES = _identify.STREAM_SAMPLES, 10**12
        try:
            start = time.process_time()
            memory = algid.identify(data, *EQUATION, refine=False)
            cpu["memory"] += time.process_time() - start
        finally:
            _identify.STREAM_SAMPLES = saved
        for key, result in (("streamed", streamed), ("memory", memory)):
            rows[key].append((result.window, [result.values[p] for p in TRUTH],
                              [result.stderr[p] for p in TRUTH]))
    truth = np.array(list(TRUTH.values()))
    for key, found in rows.items():
        values = np.array([r[1] for r in found])
        errors = np.array([r[2] for r in found]).mean(axis=0)
        rmse = np.sqrt(((values - truth) ** 2).mean(axis=0))
        cover = (np.abs(values - truth) <= 2 * np.array([r[2] for r in found])).mean(axis=0)
        print(f"{key}: windows {sorted({round(r[0], 3) for r in found})}, "
              f"{cpu[key] / args.runs:.2f} s CPU per record")
        for i, p in enumerate(TRUTH):
            print(f"  {p}: bias/se {(values[:, i].mean() - truth[i]) / errors[i]:+.2f}  "
                  f"rmse {rmse[i]:.3g}  rmse/se {rmse[i] / errors[i]:.2f}  "
                  f"coverage {100 * cover[i]:.0f} %")


if __name__ == "__main__":
    main()
