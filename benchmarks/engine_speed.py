"""Throughput and memory of the two backends of the estimator core
(``python -m benchmarks.engine_speed``).

Measures, in one process (the machine is shared: ratios are what to compare):

- samples per second of the naive NumPy trapezoid estimator
  (:func:`benchmarks.baselines.naive_algebraic`), of :func:`algid.estimate` with
  ``engine="numpy"`` and ``engine="numba"`` (validation and result included; with the
  numerical error, the default, and alone, ``numerical_error=False``), and of
  the compiled loop alone (:func:`algid.estimation._core.advance` on one chunk), with the ratios
  to the naive estimator;
- streaming in chunks of 1000 samples through :func:`algid.estimation._core.advance`, as a
  ratio to one chunk; the cost per call of chunks of one sample;
- the peak of traced memory (:mod:`tracemalloc`) of each engine, and the growth of
  the peak resident set size of a fresh process, as ratios to the bytes of the input
  arrays ``t``, ``f``, ``x``;
- the time to import numba, to compile the loop (in a fresh process with an empty
  cache) and to load it from the cache.

Times are the minimum over repeats of the process CPU time (``time.process_time``),
which other users of the machine disturb less than the wall time; the wall time is
given as well.  Options: ``--sizes 1e6 1e7``, ``--model msd``, ``--repeats 3``,
``--skip-numpy-above 2e7``, ``--no-compile``.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

import algid
from algid.estimation import _core as core
from algid.estimation._options import DEFAULT_QUADRATURE_POINTS
from algid.models._registry import load_model
from benchmarks.baselines import naive_algebraic
from benchmarks.measure import peak_memory, sine_record


def _best(func, repeats):
    cpu = wall = float("inf")
    for _ in range(repeats):
        c0, w0 = time.process_time(), time.perf_counter()
        func()
        cpu = min(cpu, time.process_time() - c0)
        wall = min(wall, time.perf_counter() - w0)
    return cpu, wall


def _stream(state, f, x, chunk, out):
    for start in range(0, f.size, chunk):
        stop = min(start + chunk, f.size)
        core.advance(state, (f[start:stop], x[start:stop]), backend="numba",
                     out=out[:, start:stop])


def _compile_times(model, q):
    """(import of numba, compile with an empty cache, load from the cache) [s, wall],
    each in a fresh process."""
    code = ("import time; t0 = time.perf_counter(); import numba; t1 = time.perf_counter(); "
            "from algid import core; from algid.models._registry import load_model; "
            f"gen = load_model({model!r}); t2 = time.perf_counter(); "
            f"s = core.new_state(gen, points={q}, filter_order=0, dt=1.0); "
            f"core.advance(s, [[0.0] * {q + 1}] * 2, backend='numba'); "
            "print(t1 - t0, time.perf_counter() - t2)")
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, NUMBA_CACHE_DIR=tmp)
        runs = [subprocess.run([sys.executable, "-c", code], env=env, check=True,
                               capture_output=True, text=True).stdout.split()
                for _ in range(2)]
    return float(runs[1][0]), float(runs[0][1]), float(runs[1][1])


def _rss_growth(n, engine_name, opts):
    """Peak resident set size of a fresh process during one estimate minus its resident
    size just before, once the input arrays exist (and, for numba, after a warm-up)
    [bytes; Linux: reads /proc/self/status]."""
    code = (
        "import numpy as np, algid\n"
        "from benchmarks.measure import sine_record\n"
        f"t, f, x = sine_record({n})\n"
        f"if {engine_name!r} == 'numba':\n"
        f"    algid.estimate(t[:1000], f[:1000], x[:1000], engine='numba', **{opts!r})\n"
        "status = open('/proc/self/status').read().split()\n"
        "before = int(status[status.index('VmRSS:') + 1])\n"
        "status = open('/proc/self/status').read().split()\n"
        "open('/proc/self/clear_refs', 'w').write('5')  # reset the peak (VmHWM)\n"
        f"r = algid.estimate(t, f, x, engine={engine_name!r}, **{opts!r})\n"
        "status = open('/proc/self/status').read().split()\n"
        "peak = int(status[status.index('VmHWM:') + 1])\n"
        "print((peak - before) * 1024)\n")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True).stdout
    return float(out)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=[1e6, 1e7])
    parser.add_argument("--model", default="msd")
    parser.add_argument("--filter-order", type=int, default=2)
    parser.add_argument("--quadrature-points", type=int, default=DEFAULT_QUADRATURE_POINTS)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--skip-numpy-above", type=float, default=2e7)
    parser.add_argument("--no-compile", action="store_true", help="skip the compile timing")
    args = parser.parse_args(argv)
    model, p, q = args.model, args.filter_order, args.quadrature_points
    gen = load_model(model)
    opts = dict(model=model, filter_order=p, quadrature_points=q)

    if not args.no_compile:
        imp, cold, warm = _compile_times(model, q)
        print(f"import numba: {imp:.2f} s; compile the loop (empty cache): {cold:.2f} s; "
              f"load it from the cache: {warm:.2f} s (wall, fresh processes)")
    core.advance(core.new_state(gen, points=q, filter_order=p, dt=1e-3),
                 [np.ones(2 * q)] * 2, backend="numba")  # compile or load the loop

    for n in (int(v) for v in args.sizes):
        t, f, x = sine_record(n)
        h = float((t[-1] - t[0]) / (n - 1))
        in_bytes = t.nbytes + f.nbytes + x.nbytes
        print(f"\n== {model}, q={q}, p={p}, n={n:.0e} samples (input {in_bytes / 1e6:.0f} MB)")
        rows = []
        if model == "msd":  # the naive estimator is that of this model
            cpu, wall = _best(lambda: naive_algebraic(t, f, x), args.repeats)
            rows.append(("naive NumPy trapezoid (baseline)", cpu, wall))
        # the default (with the numerical error: companion and twin), then the estimator
        # alone (numerical_error=False)
        for engine in ("numpy", "numba"):
            if engine == "numpy" and n > args.skip_numpy_above:
                continue
            for checked in (True, False):
                cpu, wall = _best(lambda: algid.estimate(t, f, x, engine=engine,
                                                         numerical_error=checked, **opts),
                                  args.repeats)
                label = "" if checked else ", alone"
                rows.append((f"estimate, engine={engine!r}{label}", cpu, wall))
        out = np.empty((len(gen.PARAMETERS), n))

        def one_chunk():
            state = core.new_state(gen, points=q, filter_order=p, dt=h)
            core.advance(state, (f, x), backend="numba", out=out)

        def chunked():
            state = core.new_state(gen, points=q, filter_order=p, dt=h)
            _stream(state, f, x, 1000, out)

        cpu_core, wall_core = _best(one_chunk, args.repeats)
        rows.append(("engine loop, one chunk", cpu_core, wall_core))
        cpu_ch, wall_ch = _best(chunked, args.repeats)
        rows.append(("engine loop, chunks of 1000", cpu_ch, wall_ch))
        naive = rows[0][1] if rows[0][0].startswith("naive") else None
        for name, cpu, wall in rows:
            ratio = "" if naive is None else f"  ratio to naive {naive / cpu:5.2f}"
            print(f"  {name:34s} {n / cpu / 1e6:8.2f} M samples/s CPU "
                  f"({n / wall / 1e6:6.2f} wall){ratio}")
        print(f"  chunk-1000 / one-chunk time (CPU): {cpu_ch / cpu_core:.2f}")

        m = min(n, 20_000)
        state = core.new_state(gen, points=q, filter_order=p, dt=h)
        f1, x1 = f[:m], x[:m]

        def single():
            state.restart()
            for i in range(m):
                core.advance(state, (f1[i:i + 1], x1[i:i + 1]), backend="numba")

        cpu1, wall1 = _best(single, 2)
        print(f"  chunks of 1 sample: {cpu1 / m * 1e6:.2f} us per call CPU "
              f"({wall1 / m * 1e6:.2f} wall)")

        if n <= args.skip_numpy_above:
            peak_np = peak_memory(lambda: algid.estimate(t, f, x, engine="numpy", **opts))
            print(f"  peak traced memory, numpy: {peak_np / 1e6:8.0f} MB = "
                  f"{peak_np / in_bytes:5.1f} x input")
        peak_nb = peak_memory(lambda: algid.estimate(t, f, x, engine="numba", **opts))
        print(f"  peak traced memory, numba: {peak_nb / 1e6:8.0f} MB = "
              f"{peak_nb / in_bytes:5.1f} x input "
              f"(result {len(gen.PARAMETERS) * 8 * n / 1e6:.0f} MB)")
        for name in ("numpy", "numba") if n <= args.skip_numpy_above else ("numba",):
            growth = _rss_growth(n, name, opts)
            print(f"  peak RSS growth, {name}: {growth / 1e6:8.0f} MB = "
                  f"{growth / in_bytes:5.1f} x input")
    return 0


if __name__ == "__main__":
    sys.exit(main())
