"""Speed of the embedded C estimator (``python -m benchmarks.c_speed [--smoke|--quick]``).

The C pair of model ``msd`` checked in under ``src/algid/_generated/c`` (default options:
filter ``1/s**2``, 8-point rule) is compiled with the system C compiler, ``-O2
-std=c99`` (portable: SSE2 on x86-64) and ``-O2 -std=c99 -march=native`` (the host's
vector instructions, as numba compiles for the host), into shared libraries loaded with
:mod:`ctypes`, together with a small C driver that feeds a record to
``algid_msd_update`` in chunks of a given size (so that the cost of a chunk of one
sample is that of the C call, not of a Python call).  In the same process, on the same
samples, it times

- the naive NumPy trapezoid estimator of :mod:`benchmarks.baselines` (the reference,
  throughput ratio 1.0);
- the numba engine (the estimator core, ``backend="numba"``): its compiled loop on one
  chunk, without and with the numerical error (the companion estimator), and
  ``algid.estimate(engine="numba")`` (which checks the data first);
- the C estimator (which always computes the numerical error) on one chunk, and in
  chunks of 1000 and of 1 sample;
- one ``numpy.cumsum`` pass over the same samples: the memory-bandwidth ceiling.

Times are the best of ``repeats`` process CPU times (``time.process_time``; every
method runs in this one thread), which other users of a shared machine disturb less
than the wall time; compare the ratios.  The section is :func:`c_speed`;
:func:`markdown` and :func:`target` format it for the suite's report.
"""

from __future__ import annotations

import ctypes
import math
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

if __package__ in (None, ""):  # run as a script
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent))

from benchmarks import baselines as bl  # noqa: E402
from benchmarks.measure import sine_record  # noqa: E402

__all__ = ["c_speed", "markdown", "target", "GENERATED", "FLAGS"]

ROOT = pathlib.Path(__file__).resolve().parent.parent
#: The checked-in C pairs (written by ``python -m derivation``).
GENERATED = ROOT / "src" / "algid" / "_generated" / "c"
#: Compiler flags of each build: label -> flags.
FLAGS = {"O2": ["-O2", "-std=c99"], "O2_native": ["-O2", "-std=c99", "-march=native"]}
STEP = 1e-3

_DRIVER = r"""
#include <stddef.h>
#include "algid_msd.h"

/* Feed n samples in chunks of `chunk`, as a caller of the library would: the estimates
   to theta, the numerical error to error. */
void bench_stream(void *state, const double *u, const double *y, size_t n, size_t chunk,
                  double *theta, double *error)
{
    size_t i;
    for (i = 0; i < n; i += chunk) {
        const size_t m = n - i < chunk ? n - i : chunk;
        algid_msd_update(state, u + i, y + i, m, theta + i * ALGID_MSD_N_PARAMETERS,
                         error + i);
    }
}
"""


def _cpu_time(func):
    """Process CPU time of one call of ``func()`` [s]."""
    start = time.process_time()
    func()
    return time.process_time() - start


def _compiler():
    return shutil.which("gcc") or shutil.which("cc")


def _build(cc, flags, where):
    """Compile the msd pair and the driver into a shared library; its ctypes handle."""
    driver = where / "driver.c"
    driver.write_text(_DRIVER)
    lib = where / f"libbench_{abs(hash(tuple(flags)))}.so"
    proc = subprocess.run([cc, *flags, "-Wall", "-Wextra", "-pedantic", "-fPIC", "-shared",
                           f"-I{GENERATED}", "-o", str(lib), str(GENERATED / "algid_msd.c"),
                           str(driver), "-lm"], capture_output=True, text=True)
    if proc.returncode != 0:
        return None, proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else "failed"
    handle = ctypes.CDLL(str(lib))
    dptr = ctypes.POINTER(ctypes.c_double)
    handle.algid_msd_state_size.restype = ctypes.c_size_t
    handle.algid_msd_init.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double]
    handle.algid_msd_init.restype = ctypes.c_int
    handle.bench_stream.argtypes = [ctypes.c_void_p, dptr, dptr, ctypes.c_size_t,
                                    ctypes.c_size_t, dptr, dptr]
    handle.bench_stream.restype = None
    return handle, proc.stderr.strip()


def _c_runner(handle, f, x, out, error, chunk):
    dptr = ctypes.POINTER(ctypes.c_double)
    state = (ctypes.c_double * (handle.algid_msd_state_size() // 8))()
    args = (f.ctypes.data_as(dptr), x.ctypes.data_as(dptr), f.size)
    out_ptr, error_ptr = out.ctypes.data_as(dptr), error.ctypes.data_as(dptr)

    def run():
        handle.algid_msd_init(state, STEP, 0.0)
        handle.bench_stream(state, *args, chunk, out_ptr, error_ptr)

    return run


def _numba_runners(f, x):
    """label -> callable for the numba backend (empty if it cannot run here).

    The loop runs the C pair's own options (the defaults: filter ``1/s**2``, the
    default rule), so that the two do the same arithmetic.
    """
    import algid
    from algid.estimation import _core as core
    from algid.estimation import _numerical_error as numerical_error
    from algid.estimation._backends import numba_available
    from algid.estimation._options import DEFAULT_QUADRATURE_POINTS
    from algid.models._registry import load_model

    if not numba_available():
        return {}, "numba not installed"
    t = np.arange(f.size) * STEP
    gen = load_model("msd")
    out = np.empty((2, f.size))

    error = np.empty(f.size)

    def loop():
        state = core.new_state(gen, points=DEFAULT_QUADRATURE_POINTS, filter_order=2,
                               dt=STEP)
        core.advance(state, (f, x), backend="numba", out=out)

    def loop_with_error():  # the C computes the numerical error: so does this loop
        state = numerical_error.with_companion(core.new_state(
            gen, points=DEFAULT_QUADRATURE_POINTS, filter_order=2, dt=STEP))
        numerical_error.advance_with_error(state, (f, x), backend="numba", out=out,
                                           error_out=error)

    return {"numba_estimate": lambda: algid.estimate(t, f, x, engine="numba"),
            "numba_loop": loop, "numba_loop_error": loop_with_error}, "available"


def c_speed(config):
    """The C estimator against the naive NumPy estimator and numba, in one run.

    Parameters
    ----------
    config : benchmarks.sections.Config
        ``n_batch`` samples (10**7 in the full run) and ``repeats``.

    Returns
    -------
    dict
        ``rows`` (method, label, time, throughput, ratio to the naive estimator),
        ``c_ns_per_sample`` (build -> chunk -> ns), ``fraction_of_cumsum`` (build ->
        throughput of one chunk as a fraction of that of ``numpy.cumsum``),
        ``c_over_numba`` (build -> numba loop time / C time: above 1, C is faster),
        ``max_rel_diff_c_numpy``, or ``not_available`` with the reason.
    """
    cc = _compiler()
    if cc is None:
        return {"not_available": "no C compiler (gcc or cc) on PATH"}
    n = int(config.n_batch)
    repeats = max(1, int(config.repeats))
    t, f, x = sine_record(n, STEP)
    rows = {}
    c_ns, fraction, over_numba, warnings = {}, {}, {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        handles = {}
        for label, flags in FLAGS.items():
            handle, stderr = _build(cc, flags, pathlib.Path(tmp))
            if handle is not None:
                handles[label] = handle
                warnings[label] = stderr
            else:
                rows[f"c_{label}"] = {"method": f"c_{label}", "not_available": stderr}
        numba_runners, numba_why = _numba_runners(f[:2000], x[:2000])
        for run in numba_runners.values():  # warm-up: compilation or cache, untimed
            run()
        numba_runners, _ = _numba_runners(f, x)
        bl.naive_algebraic(t[:2000], f[:2000], x[:2000])
        outs = {label: np.empty((n, 2)) for label in handles}
        errors = {label: np.empty(n) for label in handles}
        timed = {"naive_numpy": lambda: bl.naive_algebraic(t, f, x),
                 "cumsum": lambda: np.cumsum(f)}
        timed.update(numba_runners)
        chunks = {"all": n, "1000": 1000, "1": 1}
        for label, handle in handles.items():
            for name, chunk in chunks.items():
                timed[f"c_{label}_chunk_{name}"] = _c_runner(handle, f, x, outs[label],
                                                             errors[label], chunk)
        times = {key: math.inf for key in timed}
        for _ in range(repeats):  # interleaved: the load of the machine varies
            for key, run in timed.items():
                times[key] = min(times[key], _cpu_time(run))
        ref = times["naive_numpy"]
        labels = {"naive_numpy": "naive NumPy (paper's formulas, cumulative_trapezoid) "
                                 "[baseline]",
                  "numba_estimate": "algid.estimate, numba engine (checks included)",
                  "numba_loop": "numba engine loop, one chunk, without the numerical error",
                  "numba_loop_error": "numba engine loop with the numerical error, one chunk",
                  "cumsum": "one numpy.cumsum pass (memory-bandwidth ceiling)"}
        for key, elapsed in times.items():
            label = labels.get(key)
            if label is None:
                build, _, chunk = key[2:].partition("_chunk_")
                label = (f"C (-{build.replace('_', ' -march=')}), "
                         f"{'one chunk' if chunk == 'all' else 'chunks of ' + chunk}")
            rows[key] = {"method": key, "label": label, "time": elapsed,
                         "throughput": n / elapsed, "throughput_ratio": ref / elapsed}
        numba_key = "numba_loop_error" if "numba_loop_error" in times else (
            "numba_estimate" if "numba_estimate" in times else None)
        for label in handles:
            c_ns[label] = {name: times[f"c_{label}_chunk_{name}"] / n * 1e9 for name in chunks}
            fraction[label] = times["cumsum"] / times[f"c_{label}_chunk_all"]
            if numba_key:
                over_numba[label] = times[numba_key] / times[f"c_{label}_chunk_all"]
        diff = error_diff = None
        if handles:  # agreement with the NumPy engine on the first samples
            first = next(iter(handles))
            diff, error_diff = _max_rel_diff(t, f, x, outs[first], errors[first])
    if not numba_runners:
        rows["numba"] = {"method": "numba", "not_available": numba_why}
    return {"n_samples": n, "repeats": repeats, "compiler": cc, "flags": FLAGS,
            "compiler_warnings": warnings, "rows": list(rows.values()),
            "c_ns_per_sample": c_ns, "fraction_of_cumsum": fraction,
            "numba_reference": numba_key, "c_over_numba": over_numba,
            "max_rel_diff_c_numpy": diff, "max_error_diff_c_numpy": error_diff}


def _max_rel_diff(t, f, x, c_rows, c_error):
    """Largest relative difference between the C estimates and those of
    ``algid.estimate(engine="numpy")`` over the first ``min(n, 10**5)`` samples, from
    0.05 s on; and the largest relative difference of the numerical errors there."""
    import algid

    m = min(t.size, 10**5)
    r = algid.estimate(t[:m], f[:m], x[:m], engine="numpy")
    ref = np.column_stack([r.B, r.K])
    late = t[:m] >= 0.05
    error = r.numerical_error[late]
    return (float(np.max(np.abs(c_rows[:m][late] / ref[late] - 1.0))),
            float(np.max(np.abs(c_error[:m][late] - error) / error)))


def target(data):
    """``(measured, detail)`` of the target "C at least as fast as numba": numba loop
    time over C time with the portable build (``-O2``), both with the numerical error;
    None when it did not run."""
    over = data.get("c_over_numba") or {}
    if "O2" not in over:
        return None, data.get("not_available", "numba or the compiler is missing")
    native = over.get("O2_native")
    detail = (f"{data['n_samples']} samples, one chunk, against {data['numba_reference']}; "
              f"speed-up over numba {over['O2']:.2f}"
              + (f" (-march=native: {native:.2f})" if native is not None else ""))
    return over["O2"], detail


def markdown(data):
    """The section as Markdown (heading, table, figures)."""
    from algid.symbolic._codegen_c import DEFAULT_FILTER_ORDER, DEFAULT_QUADRATURE_ORDER

    head = (f"### 6. Embedded C estimator (msd, p = {DEFAULT_FILTER_ORDER}, "
            f"q = {DEFAULT_QUADRATURE_ORDER})")
    if "not_available" in data:
        return f"{head}\n\nnot available: {data['not_available']}"
    lines = [f"{head}, {data['n_samples']} samples, best of {data['repeats']}, "
             f"compiler {data['compiler']}\n",
             "| method | time [s] | M samples/s | × naive NumPy |", "|---|---|---|---|"]
    for r in data["rows"]:
        if "not_available" in r:
            lines.append(f"| {r['method']} | not available: {r['not_available']} | | |")
            continue
        lines.append(f"| {r['label']} | {r['time']:.4f} | {r['throughput'] / 1e6:.2f} | "
                     f"{r['throughput_ratio']:.2f} |")
    lines.append("")
    for build, ns in data["c_ns_per_sample"].items():
        over = data["c_over_numba"].get(build)
        lines.append(f"- C -{build.replace('_', ' -march=')}: "
                     f"{ns['1']:.1f} ns per sample in chunks of 1, {ns['1000']:.1f} in chunks "
                     f"of 1000, {ns['all']:.1f} in one chunk (numerical error included); "
                     "throughput "
                     f"{data['fraction_of_cumsum'][build]:.2f} of one numpy.cumsum pass"
                     + (f"; {over:.2f} × the numba loop with the numerical error"
                        if over is not None else ""))
    if data.get("max_rel_diff_c_numpy") is not None:
        lines.append(f"- largest relative difference between C and the NumPy engine "
                     f"(first 10^5 samples, from 0.05 s on): {data['max_rel_diff_c_numpy']:.1e}; "
                     "of their numerical errors: "
                     f"{data.get('max_error_diff_c_numpy', float('nan')):.1e}")
    return "\n".join(lines)


def main(argv=None):
    """Run the section alone and print it (``--json`` for the raw figures)."""
    from benchmarks.run import section_main

    return section_main(argv, "benchmarks.c_speed", c_speed, markdown,
                        ('10**6 samples', '10**4 samples (seconds)'))


if __name__ == "__main__":
    sys.exit(main())
