"""identify on long records, read in chunks (``python -m benchmarks.long_records``).

``y'' + 0.6 y' + 40 y = 40 u + 0.5`` (a 1 Hz mode), sampled at 1 kHz, a multisine
input of 12 lines from 0.1 to 5 Hz, 30 dB of white output noise; simulated exactly
(first-order hold) chunk by chunk, so that no record is ever built larger than asked.

Every measurement runs in a fresh process that loads the record (saved as ``.npy``
files), so that its peak memory (``VmHWM``) beyond the record is what ``identify``
itself needs; its CPU time is the least of three fits (one for the Parquet file):

1. CPU time and peak memory of ``identify`` on records of ``--sizes`` samples, at a
   given window (0.887 s) and with the automatic window, every record read in chunks
   (``chunk=`` given, so that all sizes take the same path; records over
   :data:`algid.identification.STREAM_SAMPLES` take it by default).  Reported: the
   exponent ``a`` of ``time ~ n^a`` from the smallest to the largest size (target
   <= 1.05), the peak memory beyond the record (target <= 300 MB) and the ratio of the
   automatic window's time to the given window's (target <= 2).
2. The same record of ``--parquet`` samples written to a Parquet file (two columns,
   ``u`` and ``y``, at ``rate=1000``) and identified from the file: peak memory of the
   whole process (target <= 2 GB) and its CPU time.
3. The equality of the chunked and in-memory estimates at the same window on the
   largest in-memory size (target: 1e-9 relative).
4. The CPU time of the given and automatic windows on a record of ``--memory``
   samples identified in memory (the default path of records of up to
   :data:`algid.identification.STREAM_SAMPLES` samples; ``refine=False``, as a record
   read in chunks is not refined), and their ratio.

Options: ``--sizes`` (default ``1e5 1e6 1e7``), ``--parquet`` (default ``1e8``; 0 to
skip), ``--memory`` (default ``1e5``; 0 to skip), ``--out FILE`` (JSON, default
``benchmarks/long_records_results.json``).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

EQUATION = ("y'' + B*y' + K*y = G*u + d", "B K G d")
TRUTH = {"B": 0.6, "K": 40.0, "G": 40.0, "d": 0.5}
RATE = 1000.0
WINDOW = 0.887
SNR_DB = 30.0
PIECE = 2**20

#: Each record of up to :data:`REPEAT_UPTO` samples is identified this many times and
#: the least CPU time kept (a tenth of a second varies with what else the machine runs).
REPEATS, REPEAT_UPTO = 3, 10**7
ROOT = Path(__file__).resolve().parent


def record_pieces(n, seed=0):
    """The record in pieces of :data:`PIECE` rows: ``(first row, u, y)``."""
    from scipy import signal

    rng = np.random.default_rng(seed)
    freqs, phases = np.linspace(0.1, 5.0, 12), rng.uniform(0, 2 * np.pi, 12)
    b, a, _ = signal.cont2discrete(([TRUTH["G"]], [1.0, TRUTH["B"], TRUTH["K"]]),
                                   1 / RATE, method="foh")
    b = b.ravel()
    state = np.zeros(max(len(a), len(b)) - 1)
    noise = None
    for first in range(0, n, PIECE):
        t = np.arange(first, min(n, first + PIECE)) / RATE
        u = np.sqrt(2 / 12) * np.sum(
            [np.sin(2 * np.pi * f * t + p) for f, p in zip(freqs, phases)], axis=0)
        y, state = signal.lfilter(b, a, u, zi=state)
        y = y + TRUTH["d"] / TRUTH["K"]
        if noise is None:   # the level of the first piece (stationary)
            noise = float(np.std(y)) * 10 ** (-SNR_DB / 20)
        yield first, u, y + rng.normal(0.0, noise, len(y))


def make_record(n, seed=0):
    """The whole record in memory: ``{"t", "u", "y"}``."""
    u, y = zip(*[(u, y) for _, u, y in record_pieces(n, seed)])
    return {"t": np.arange(n) / RATE, "u": np.concatenate(u), "y": np.concatenate(y)}


def write_parquet(path, n, seed=0):
    """The record as a Parquet file of ``u`` and ``y`` (row groups of :data:`PIECE`)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    writer = None
    for _, u, y in record_pieces(n, seed):
        table = pa.table({"u": u, "y": y})
        writer = writer or pq.ParquetWriter(path, table.schema)
        writer.write_table(table)
    writer.close()


def _peak_mb():
    """The process's peak resident memory (MB): ``VmHWM`` on Linux (``ru_maxrss`` keeps
    the parent's across ``fork`` and ``exec``: the record the parent made)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def measure(n, window, chunk, source):
    """One identify in this process: CPU time, peak memory before and after (MB).

    ``source``: a Parquet file, or the folder of the record's ``.npy`` files (loaded
    whole, so that the peak before ``identify`` is the record's).  A short record is
    identified first: the modules ``identify`` imports are not counted.  The least CPU
    time of :data:`REPEATS` fits (records of up to :data:`REPEAT_UPTO` samples)."""
    import algid

    small = make_record(20000)   # the modules identify imports, imported first
    for given in (WINDOW, None):
        algid.identify(small, *EQUATION, window=given, chunk=chunk or None)
    del small
    parquet = str(source).endswith(".parquet")
    data = source if parquet else {name: np.load(Path(source) / f"{name}.npy")
                                   for name in ("t", "u", "y")}
    before = _peak_mb()
    # (in memory, without the refinement a record read in chunks does not have)
    options = {"rate": RATE} if parquet else {"chunk": chunk} if chunk else {"refine": False}
    cpu = np.inf
    for _ in range(1 if n > REPEAT_UPTO else REPEATS):   # (the least: the others waited)
        start = time.process_time()
        result = algid.identify(data, *EQUATION, window=window, **options)
        cpu = min(cpu, time.process_time() - start)
    return {"n": int(n), "window_given": window, "cpu_s": cpu, "peak_before_mb": before,
            "peak_mb": _peak_mb(), "window": result.window, "values": result.values,
            "stderr": result.stderr, "warnings": result.warnings,
            "estimate": result.estimate}


def _in_fresh_process(*arguments):
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", PYTHONPATH=os.pathsep.join(
        [str(ROOT.parent / "src"), str(ROOT.parent)]))
    done = subprocess.run([sys.executable, "-m", "benchmarks.long_records", "--one",
                           *map(str, arguments)], capture_output=True, text=True, env=env,
                          check=True)
    return json.loads(done.stdout.splitlines()[-1])


def equality(n):
    """Chunked against in-memory at the same window: the largest relative differences."""
    import algid

    record = make_record(int(n))
    memory = algid.identify(record, *EQUATION, window=WINDOW, refine=False,
                            chunk=None) if n <= 2**18 else None
    if memory is None:   # longer records stream by default: the in-memory path is forced
        from algid.identification import _identify

        saved = _identify.STREAM_SAMPLES
        _identify.STREAM_SAMPLES = 10 * int(n)
        try:
            memory = algid.identify(record, *EQUATION, window=WINDOW, refine=False)
        finally:
            _identify.STREAM_SAMPLES = saved
    streamed = algid.identify(record, *EQUATION, window=WINDOW, refine=False, chunk=2**16)
    return {"n": int(n),
            "values": max(abs(streamed.values[p] / memory.values[p] - 1) for p in TRUTH),
            "stderr": max(abs(streamed.stderr[p] / memory.stderr[p] - 1) for p in TRUTH)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", type=float, default=[1e5, 1e6, 1e7])
    parser.add_argument("--parquet", type=float, default=1e8)
    parser.add_argument("--equality", type=float, default=1e6)
    parser.add_argument("--memory", type=float, default=1e5)
    parser.add_argument("--out", default=str(ROOT / "long_records_results.json"))
    parser.add_argument("--one", nargs=4, default=None, help=argparse.SUPPRESS)
    # (--one N WINDOW CHUNK SOURCE: one measurement in a fresh process)
    args = parser.parse_args(argv)
    if args.one:   # a measurement in this (fresh) process
        n, window, chunk, parquet = args.one
        print(json.dumps(measure(float(n), None if window == "auto" else float(window),
                                 int(chunk), parquet)))
        return
    rows = []
    for n in args.sizes:
        folder = tempfile.TemporaryDirectory()
        for name, values in make_record(int(n)).items():
            np.save(Path(folder.name) / f"{name}.npy", values)
        for window in (WINDOW, "auto"):
            row = _in_fresh_process(int(n), window, 2**16, folder.name)
            row["record_mb"] = 3 * 8 * int(n) / 2**20
            row["beyond_record_mb"] = row["peak_mb"] - row["peak_before_mb"]
            rows.append(row)
            print(f"n={int(n):>10} window={window!s:>6}: {row['cpu_s']:7.2f} s CPU, "
                  f"{row['beyond_record_mb']:6.0f} MB beyond the record, chosen "
                  f"{row['window']:.4g} s", flush=True)
        folder.cleanup()
    summary = {}
    for window in (WINDOW, "auto"):
        mine = [r for r in rows if r["window_given"] == (None if window == "auto" else window)]
        n = np.array([r["n"] for r in mine], dtype=float)
        cpu = np.array([r["cpu_s"] for r in mine])
        summary[str(window)] = {
            "exponent": float(np.log(cpu[-1] / cpu[0]) / np.log(n[-1] / n[0]))
            if len(n) > 1 else None,
            "largest_beyond_record_mb": max(r["beyond_record_mb"] for r in mine)}
    fixed = {r["n"]: r["cpu_s"] for r in rows if r["window_given"] == WINDOW}
    summary["auto_over_given"] = {str(r["n"]): r["cpu_s"] / fixed[r["n"]]
                                  for r in rows if r["window_given"] is None}
    print(json.dumps(summary, indent=1))
    result = {"rows": rows, "summary": summary}
    if args.memory:   # the same in memory (chunk 0: the default path of a short record)
        folder = tempfile.TemporaryDirectory()
        for name, values in make_record(int(args.memory)).items():
            np.save(Path(folder.name) / f"{name}.npy", values)
        memory = [_in_fresh_process(int(args.memory), window, 0, folder.name)
                  for window in (WINDOW, "auto")]
        folder.cleanup()
        result["memory"] = {"rows": memory,
                            "auto_over_given": memory[1]["cpu_s"] / memory[0]["cpu_s"]}
        print(f"in memory, n={int(args.memory)}: {memory[0]['cpu_s']:.2f} s CPU at "
              f"{WINDOW} s, {memory[1]['cpu_s']:.2f} s automatic (chosen "
              f"{memory[1]['window']:.4g} s): ratio {result['memory']['auto_over_given']:.2f}",
              flush=True)
    if args.equality:
        result["equality"] = equality(args.equality)
        print("chunked vs in memory:", result["equality"])
    if args.parquet:
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "long.parquet"
            start = time.time()
            write_parquet(path, int(args.parquet))
            print(f"wrote {int(args.parquet)} rows ({path.stat().st_size / 2**30:.2f} GB) "
                  f"in {time.time() - start:.0f} s", flush=True)
            for window in (WINDOW, "auto"):
                row = _in_fresh_process(int(args.parquet), window, 2**16, path)
                row["file_gb"] = path.stat().st_size / 2**30
                result.setdefault("parquet", []).append(row)
                print(f"Parquet n={int(args.parquet)} window={window}: {row['cpu_s']:.1f} s "
                      f"CPU, peak {row['peak_mb']:.0f} MB, chosen {row['window']:.4g} s, "
                      f"K={row['values']['K']:.6g} ± {row['stderr']['K']:.2g}", flush=True)
    Path(args.out).write_text(json.dumps(result, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
