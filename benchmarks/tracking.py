"""Benchmark of :class:`algid.Tracker`: speed against identify, the EMPS record streamed,
the change records, and recursive least squares on state-variable-filtered regressors.

Run from the repository root (under a minute on one core)::

    PYTHONPATH=src:. python -m benchmarks.tracking   # writes benchmarks/tracking_results.json

Sections (all in one run, so that the speed ratios share the machine's state):

- ``speed``: the EMPS record in chunks of 1000 (every window end reported, and every
  0.1 s) against batch :func:`algid.identify` at the same fixed window; one sample at a
  time on its first 3000 samples (microseconds per sample); the real-time factor.  Each
  timing is the smallest of three runs (a shared machine slows some); the first use of
  the compiled kernels (numba's compilation or cache load) is timed apart, first, and
  is in none of the ratios.
- ``emps``: final estimates against the published ones, the time from which ``M`` stays
  within 5 %, the same outputs bit for bit in chunks of 1, 7 and 1000 (first 3000
  samples), the difference with identify at the same window.
- ``python_loops``: the tracker's loops run as Python (``ALGID_TRACKER_PYTHON=1``, in a
  process of its own: the choice is made at import) against compiled, on the first 3000
  EMPS samples in chunks of 1000, every window end reported (processor time, smallest of
  ``RUNS``; the first use of the kernels not counted).
- ``changes``: the friction loop whose mass rises 25 % and the cubic spring whose ``K``
  drops 10 % (half-life 1 s): estimates before and 4 s after, alarms, detection delay, and
  the tracking error (RMS relative error from 3 s on, excluding the 2 s after the change)
  of the tracker and of recursive least squares with the same forgetting on the same
  equation's regressors filtered by ``lambda**n / (s + lambda)**n`` (:func:`rls_svf`).
"""

from __future__ import annotations

import json
import os
import pathlib
import subprocess
import sys
import time

import numpy as np
from scipy.signal import cont2discrete, lfilter

import algid
from algid.datasets import EMPS_EQUATION, EMPS_PUBLISHED, emps
from algid.identification._tracker import Tracker
from benchmarks.change_records import cubic_change, friction_change
from benchmarks.synthetic_records import CUBIC_EQUATION, FRICTION_EQUATION

OUT = pathlib.Path(__file__).resolve().parent / "tracking_results.json"
EMPS_WINDOW = 0.03   # identify's choice on the whole record
RUNS = 3             # each speed figure: the smallest of this many runs


def _stream(tracker, record, size):
    n = len(next(iter(record.values())))
    outs = [tracker.update({k: v[i:i + size] for k, v in record.items()})
            for i in range(0, n, size)]
    return {key: np.concatenate([getattr(o, key) for o in outs])
            for key in ("t", "values", "stderr", "numerical_error", "alarms")}


def _emps_record():
    rec = emps()
    return {k: np.asarray(rec[k], dtype=float) for k in ("t", "qm", "F")}


CPU_SECONDS = {}   # label -> the smallest processor time of the runs (a shared machine)


def _best_of(runs, measure, label=None):
    """The smallest of ``runs`` wall-clock timings of ``measure()`` (seconds), and its
    last result; the smallest processor time goes to ``CPU_SECONDS[label]``."""
    best, cpu, result = np.inf, np.inf, None
    for _ in range(runs):
        start, start_cpu = time.perf_counter(), time.process_time()
        result = measure()
        best = min(best, time.perf_counter() - start)
        cpu = min(cpu, time.process_time() - start_cpu)
    if label:
        CPU_SECONDS[label] = cpu
    return best, result


def first_compile():
    """Seconds of the first use of the tracker's kernels in this process: numba's
    compilation (or loading from its cache) and the CUSUM threshold; not in the ratios."""
    from algid.identification import _tracker_jit

    record = {k: v[:200] for k, v in _emps_record().items()}
    start = time.perf_counter()
    _stream(Tracker(EMPS_EQUATION, list(EMPS_PUBLISHED), window=EMPS_WINDOW), record, 200)
    return {"seconds": time.perf_counter() - start, "numba": _tracker_jit.USE_NUMBA}


def speed_and_emps(runs=RUNS):
    """Sections ``speed`` and ``emps`` (each timing the smallest of ``runs``)."""
    record = _emps_record()
    names = list(EMPS_PUBLISHED)
    duration = float(record["t"][-1] - record["t"][0])
    batch, reference = _best_of(runs, lambda: algid.identify(record, EMPS_EQUATION, names,
                                                             window=EMPS_WINDOW), "identify")
    every_window, out = _best_of(runs, lambda: _stream(
        Tracker(EMPS_EQUATION, names, window=EMPS_WINDOW), record, 1000), "every_window")
    every_tenth, _ = _best_of(runs, lambda: _stream(
        Tracker(EMPS_EQUATION, names, window=EMPS_WINDOW, every=0.1), record, 1000))
    head = {k: v[:3000] for k, v in record.items()}
    per_sample, ones = _best_of(runs, lambda: _stream(
        Tracker(EMPS_EQUATION, names, window=EMPS_WINDOW), head, 1), "one_sample")
    per_sample /= 3000
    sevens = _stream(Tracker(EMPS_EQUATION, names, window=EMPS_WINDOW), head, 7)
    thousands = _stream(Tracker(EMPS_EQUATION, names, window=EMPS_WINDOW), head, 1000)
    identical = all(np.array_equal(ones[k], other[k], equal_nan=True)
                    for other in (sevens, thousands) for k in ones)
    final = out["values"][-1]
    M = out["values"][:, 0]
    outside = ~(np.abs(M / EMPS_PUBLISHED["M"] - 1) <= 0.05)
    within_from = float(out["t"][np.flatnonzero(outside)[-1] + 1]) if outside.any() \
        else float(out["t"][0])
    speed = {
        "identify_s": batch, "stream_every_window_s": every_window,
        "stream_every_0.1s_s": every_tenth,
        "ratio_every_window_to_identify": every_window / batch,
        "ratio_every_0.1s_to_identify": every_tenth / batch,
        "one_sample_at_a_time_us_per_sample": per_sample * 1e6,
        "real_time_factor_every_window": duration / every_window,
        "real_time_factor_every_0.1s": duration / every_tenth,
        "processor_time": {   # the same figures from processor time (a loaded machine)
            "ratio_every_window_to_identify": CPU_SECONDS["every_window"]
            / CPU_SECONDS["identify"],
            "one_sample_at_a_time_us_per_sample": CPU_SECONDS["one_sample"] / 3000 * 1e6,
            "real_time_factor_every_window": duration / CPU_SECONDS["every_window"]},
    }
    result = {
        "final": dict(zip(names, final.tolist())),
        "final_stderr": dict(zip(names, out["stderr"][-1].tolist())),
        "relative_to_published": {p: float(final[i] / EMPS_PUBLISHED[p] - 1)
                                  for i, p in enumerate(names)},
        "relative_to_identify": {p: float(final[i] / reference.values[p] - 1)
                                 for i, p in enumerate(names)},
        "M_within_5pc_from_s": within_from,
        "all_determined_from_s": float(out["t"][np.isfinite(out["values"]).all(axis=1)][0]),
        "alarms": out["alarms"].tolist(),
        "chunks_1_7_1000_bit_identical": bool(identical),
    }
    return speed, result


def _svf(signal, lam, order, derivative, dt):
    """``s**derivative lambda**order / (s + lambda)**order`` applied to ``signal``."""
    num = np.zeros(order + 1)
    num[order - derivative] = lam ** order
    den = np.poly(-lam * np.ones(order))
    b, a, _ = cont2discrete((num, den), dt, method="bilinear")
    return lfilter(np.ravel(b), a, signal)


def rls_svf(record, regressors, known, half_life, dt, lam, order=3):
    """Recursive least squares with forgetting on filtered regressors.

    ``regressors``: ``(signal, derivative, nonlinearity)`` per parameter (``None`` for a
    constant); a nonlinearity applies to the filtered derivative (``sign``) before a
    second filtering.  ``known``: ``(signal, derivative, coefficient)``, the known side.
    Returns the estimates at every sample.
    """
    forget = 2.0 ** (-dt / half_life)

    def column(name, k, nonlinear):
        if nonlinear is None:
            return _svf(record[name], lam, order, k, dt)
        return _svf(nonlinear(_svf(record[name], lam, order, k, dt)), lam, order, 0, dt)

    phi = np.column_stack([np.ones(len(record["t"])) * _svf(np.ones(len(record["t"])),
                                                             lam, order, 0, dt)
                           if name is None else column(name, k, f)
                           for name, k, f in regressors])
    y = sum(c * column(name, k, None) for name, k, c in known)
    p = phi.shape[1]
    theta, P = np.zeros(p), 1e6 * np.eye(p)
    out = np.empty((len(y), p))
    for i in range(len(y)):
        x = phi[i]
        gain = P @ x / (forget + x @ P @ x)
        theta = theta + gain * (y[i] - x @ theta)
        P = (P - np.outer(gain, x @ P)) / forget
        out[i] = theta
    return out


def _tracking_error(t, values, names, before, after, t_change, skip=3.0):
    use = (t >= skip) & ~((t >= t_change) & (t < t_change + 2.0)) & np.isfinite(values[:, 0])
    truth = np.array([[after[p] if x >= t_change else before[p] for p in names] for x in t[use]])
    scale = np.where(truth == 0, 1.0, np.abs(truth))
    return dict(zip(names, np.sqrt(np.mean(((values[use] - truth) / scale) ** 2,
                                           axis=0)).tolist()))


def changes():
    """Section ``changes``."""
    results = {}
    cases = {
        "friction_mass_+25pc": (friction_change(), FRICTION_EQUATION, 10.0, "M",
                                [("q", 2, None), ("q", 1, None), ("q", 1, np.sign),
                                 (None, 0, None)], [("F", 0, 1.0)], 1e-3, 2 * np.pi * 20,
                                [1, 1, 1, 1]),
        "cubic_K_-10pc": (cubic_change(), CUBIC_EQUATION, 25.0, "K",
                          [("y", 1, None), ("y", 0, None), ("y", 0, lambda x: x ** 3),
                           ("u", 0, None), (None, 0, None)],
                          [("y", 2, -1.0)], 1 / 80.0, 2 * np.pi * 12, [1, 1, 1, -1, -1]),
    }
    for label, (made, (equation, names), t_change, watched, regressors, known, dt,
                lam, signs) in cases.items():
        record, before, after = made
        names = names.split()
        start = time.perf_counter()
        out = Tracker(equation, names, time="t", half_life=1.0, every=0.05).update(record)
        elapsed = time.perf_counter() - start
        i = names.index(watched)
        at = {x: float(out.values[np.searchsorted(out.t, x, side="right") - 1, i])
              for x in (t_change, t_change + 4.0)}
        rls = rls_svf(record, regressors, known, 1.0, dt, lam) * np.array(signs)
        t = record["t"]
        alarms = out.alarms
        after_change = alarms[alarms >= t_change]
        results[label] = {
            "seconds": elapsed,
            f"{watched}_before_relative": at[t_change] / before[watched] - 1,
            f"{watched}_4s_after_relative": at[t_change + 4.0] / after[watched] - 1,
            "alarms": alarms.tolist(),
            "false_alarms_before_change": int(np.sum(alarms < t_change)),
            "detection_delay_s": float(after_change[0] - t_change) if after_change.size
            else None,
            "tracker_rms_relative_error": _tracking_error(out.t, out.values, names,
                                                          before, after, t_change),
            "rls_svf_rms_relative_error": _tracking_error(t, rls, names, before, after,
                                                          t_change),
            "rls_svf_lambda_rad_s": lam,
        }
    return results


def _head_seconds(samples=3000):
    """Processor seconds of the tracker on the first EMPS samples in chunks of 1000 (the
    smallest of ``RUNS``), after a first use of its kernels."""
    record = {k: v[:samples] for k, v in _emps_record().items()}
    names = list(EMPS_PUBLISHED)
    _stream(Tracker(EMPS_EQUATION, names, window=EMPS_WINDOW), record, 1000)
    _best_of(RUNS, lambda: _stream(Tracker(EMPS_EQUATION, names, window=EMPS_WINDOW),
                                   record, 1000), "head")
    return CPU_SECONDS["head"]


def python_loops(samples=3000):
    """Section ``python_loops``: compiled here, as Python in a child process."""
    from algid.identification import _tracker_jit

    compiled = _head_seconds(samples) if _tracker_jit.USE_NUMBA else None
    env = {**os.environ, "ALGID_TRACKER_PYTHON": "1"}
    child = subprocess.run([sys.executable, "-m", "benchmarks.tracking", "--head-seconds",
                            str(samples)], env=env, check=True, capture_output=True, text=True)
    python = float(child.stdout.split()[-1])
    return {"samples": samples, "compiled_s": compiled, "python_s": python,
            "python_us_per_sample": python / samples * 1e6,
            "ratio_python_to_compiled": None if compiled is None else python / compiled}


def main():
    if sys.argv[1:2] == ["--head-seconds"]:
        print(_head_seconds(int(sys.argv[2])))
        return
    compile_once = first_compile()
    speed, emps_result = speed_and_emps()
    speed["first_compile"] = compile_once
    results = {"speed": speed, "emps": emps_result, "python_loops": python_loops(),
               "changes": changes()}
    OUT.write_text(json.dumps(results, indent=1, allow_nan=False) + "\n")
    print(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
