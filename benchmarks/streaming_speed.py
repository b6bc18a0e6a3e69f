"""Speed of the streaming estimator (``python -m benchmarks.streaming_speed``).

Measures, in one process, the cost per sample of :class:`algid.OnlineEstimator` fed a
record in chunks of 1000 samples and one sample at a time (as floats and as
one-element arrays), with the compiled engine (``engine="numba"``) and the NumPy one,
without and with re-anchoring (``reset_period``), and compares it with the batch
estimator :func:`algid.estimate` on the same record (``engine="numba"`` and
``engine="numpy"``).

Times are the minimum over repeats of the process CPU time (``time.process_time``),
which other users of the machine disturb less than the wall time.  Options:
``--samples 1e6`` (record for the batch runs and the chunks of 1000),
``--single-samples 1e5`` (samples fed one at a time with the compiled engine; a
tenth of it with NumPy), ``--reset-period 0.05`` [s] (at 1 kHz: the tracking
setting ``algid.estimation._online.TRACKING_RESET_PERIOD``, a restart every 25 samples),
``--repeats 3``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import algid
from algid.estimation._backends import numba_available

RATE = 1000.0


def _signals(n):
    t = np.arange(n) / RATE
    f = np.sin(1.3 * t) + 0.5 * np.sin(0.37 * t)
    x = 0.4 * np.sin(1.3 * t - 0.8) + 0.2 * np.sin(0.37 * t - 0.1)
    return t, f, x


def _best(func, repeats):
    """Smallest CPU time [s] of ``repeats`` calls of ``func``."""
    best = float("inf")
    for _ in range(repeats):
        start = time.process_time()
        func()
        best = min(best, time.process_time() - start)
    return best


def _stream_chunks(t, f, x, size, **options):
    def run():
        est = algid.OnlineEstimator(rate=RATE, **options)
        for i in range(0, t.size, size):
            est.update(t[i:i + size], f[i:i + size], x[i:i + size])
    return run


def _stream_floats(t, f, x, **options):
    rows = list(zip(t.tolist(), f.tolist(), x.tolist()))

    def run():
        update = algid.OnlineEstimator(rate=RATE, **options).update
        for ti, fi, xi in rows:
            update(ti, fi, xi)
    return run


def _stream_arrays(t, f, x, **options):
    def run():
        update = algid.OnlineEstimator(rate=RATE, **options).update
        for i in range(t.size):
            update(t[i:i + 1], f[i:i + 1], x[i:i + 1])
    return run


def measure(n=1_000_000, n_single=100_000, reset_period=0.05, repeats=3):
    """Cost per sample [µs] of every case, as a list of ``(label, µs per sample)``
    (batch first), and the two batch costs."""
    t, f, x = _signals(n)
    have_numba = numba_available()
    rows = []
    if have_numba:
        algid.estimate(t[:1000], f[:1000], x[:1000], engine="numba")  # compile or load
        batch_numba = _best(lambda: algid.estimate(t, f, x, engine="numba"), repeats) / n
        rows.append(("batch estimate, engine='numba'", batch_numba))
    else:
        batch_numba = None
    batch_numpy = _best(lambda: algid.estimate(t, f, x, engine="numpy"), repeats) / n
    rows.append(("batch estimate, engine='numpy'", batch_numpy))
    engines = (["numba"] if have_numba else []) + ["numpy"]
    for name in engines:
        singles = n_single if name == "numba" else max(n_single // 10, 1000)
        ts, fs, xs = t[:singles], f[:singles], x[:singles]
        for period in (None, reset_period):
            opts = {"engine": name, "reset_period": period}
            algid.OnlineEstimator(rate=RATE, **opts).update(t[:10], f[:10], x[:10])  # warm up
            tag = f"engine='{name}'" + ("" if period is None else f", reset_period={period:g}")
            rows.append((f"stream, chunks of 1000, {tag}",
                         _best(_stream_chunks(t, f, x, 1000, **opts), repeats) / n))
            rows.append((f"stream, single floats, {tag}",
                         _best(_stream_floats(ts, fs, xs, **opts), repeats) / singles))
            rows.append((f"stream, 1-element arrays, {tag}",
                         _best(_stream_arrays(ts, fs, xs, **opts), repeats) / singles))
    return [(label, seconds * 1e6) for label, seconds in rows], batch_numba, batch_numpy


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m benchmarks.streaming_speed",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=float, default=1e6)
    parser.add_argument("--single-samples", type=float, default=1e5)
    parser.add_argument("--reset-period", type=float, default=0.05)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    rows, batch_numba, batch_numpy = measure(int(args.samples), int(args.single_samples),
                                             args.reset_period, args.repeats)
    print(f"{int(args.samples)} samples at {RATE:g} Hz, CPU time, best of {args.repeats}")
    header = f"{'case':<58} {'us/sample':>10} {'x batch numba':>14} {'x batch numpy':>14}"
    print(header)
    print("-" * len(header))
    for label, us in rows:
        vs_numba = "" if batch_numba is None else f"{us / (batch_numba * 1e6):.2f}"
        print(f"{label:<58} {us:>10.4f} {vs_numba:>14} {us / (batch_numpy * 1e6):>14.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
