"""A fingerprint of algid's numbers on the benchmark records, to compare bit for bit.

``PYTHONPATH=src:. python -m benchmarks.fingerprint OUT.json`` writes, for the paper's
estimator (both engines, batch and a stream of odd chunks), identify (EMPS by ls, bc and
iv, the Silverbox's cubic model, the three synthetic records) and the tracker (its loops
compiled by numba, and run as Python in a process with ``ALGID_TRACKER_PYTHON=1``; with
and without forgetting, saved and loaded mid-stream, a chosen window: its
estimates, errors, times and alarms), the exact ``repr`` of the scalar
results and a SHA-256 of each array's bytes.  Two checkouts that give the same file give
the same numbers: ``diff`` the files before and after a change that must not move any (a
refactoring).  Bits may differ across NumPy or numba versions: compare runs of one
environment.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

import algid
import algid.identification._tracker_jit as tracker_jit
from benchmarks.synthetic_records import (
    CUBIC_EQUATION,
    FRICTION_EQUATION,
    LINEAR_EQUATION,
    cubic_spring,
    friction_loop,
    linear_offsets,
)

EMPS = ("M*q'' + Fv*q' + Fc*sign(q') + off = F", "M Fv Fc off")


def digest(x):
    """SHA-256 (its first 20 digits) of an array's float64 bytes, and its shape."""
    a = np.ascontiguousarray(np.asarray(x, dtype=float))
    return hashlib.sha256(a.tobytes()).hexdigest()[:20] + f" {a.shape}"


def fit_entry(fit):
    """An identify result's values, standard errors, numerical errors and window."""
    return {"values": {k: repr(v) for k, v in fit.values.items()},
            "stderr": {k: repr(v) for k, v in fit.stderr.items()},
            "numerical": {k: repr(v) for k, v in fit.numerical_error.items()},
            "window": repr(fit.window)}


def estimator_entries():
    sim = algid.simulate("sine", m=1, c=2, k=3, noise_std=0.01, seed=0)
    out = {}
    for engine in ("numpy", "numba"):
        r = algid.estimate(sim.t, sim.f, sim.x, engine=engine)
        out[f"estimate/{engine}"] = [digest(r.B), digest(r.K),
                                     repr(r.final_numerical_error())]
        online = algid.OnlineEstimator(rate=1000.0, engine=engine)
        chunks = [online.update(*(x[s:s + 777] for x in (sim.t, sim.f, sim.x))).B
                  for s in range(0, len(sim.t), 777)]
        out[f"online/{engine}"] = digest(np.concatenate(chunks))
    return out


def identify_entries(emps):
    out = {"emps/bc": fit_entry(algid.identify(emps, *EMPS)),
           "emps/ls": fit_entry(algid.identify(emps, *EMPS, method="ls", window=0.03)),
           "emps/iv": fit_entry(algid.identify(emps, *EMPS, method="iv", window=0.03))}
    box = algid.datasets.silverbox()
    rows = slice(40650, 60000)
    record = {"t": np.arange(rows.start, rows.stop) / box.rate,
              "y": np.asarray(box["V2"])[rows], "u": np.asarray(box["V1"])[rows]}
    out["silverbox/cubic"] = fit_entry(algid.identify(
        record, "y'' + B*y' + K*y + K3*y**3 = G*u + d", "B K K3 G d"))
    for name, make, equation in (("linear", linear_offsets, LINEAR_EQUATION),
                                 ("cubic", cubic_spring, CUBIC_EQUATION),
                                 ("friction", friction_loop, FRICTION_EQUATION)):
        out[f"synthetic/{name}"] = fit_entry(algid.identify(make(0)[0], *equation))
    return out


def _tracked(reports):
    return [digest(np.concatenate([getattr(r, name) for r in reports]))
            for name in ("values", "stderr", "t", "numerical_error", "alarms")]


def tracker_entries(emps, directory):
    """The tracker's entries, on the loops of this process (compiled or Python)."""
    out = {}
    compiled = tracker_jit.USE_NUMBA
    for half_life in (None, 2.0):
        tracker = algid.Tracker(*EMPS, window=0.03, half_life=half_life)
        reports = [tracker.update({n: x[s:s + 1000] for n, x in emps.items()})
                   for s in range(0, 8000, 1000)]
        out[f"tracker/numba={compiled}/hl={half_life}"] = _tracked(reports)
    # saved and loaded mid-stream: the rest as the whole stream gives it
    tracker = algid.Tracker(*EMPS, window=0.03, half_life=2.0)
    reports = [tracker.update({n: x[:4500] for n, x in emps.items()})]
    path = f"{directory}/tracker.npz"
    tracker.save(path)
    loaded = algid.Tracker.load(path)
    reports.append(loaded.update({n: x[4500:8000] for n, x in emps.items()}))
    out[f"tracker/numba={compiled}/saved"] = _tracked(reports)
    tracker = algid.Tracker(*LINEAR_EQUATION)
    report = tracker.update(linear_offsets(0)[0])
    out[f"tracker/numba={compiled}/linear-auto"] = [digest(report.values),
                                                    digest(report.stderr),
                                                    repr(tracker.window)]
    return out


def _python_tracker_entries(directory):
    """The tracker's entries with its loops run as Python (a process of its own: the
    choice is made at import)."""
    path = f"{directory}/python.json"
    env = {**os.environ, "ALGID_TRACKER_PYTHON": "1"}
    subprocess.run([sys.executable, "-m", "benchmarks.fingerprint", "--tracker", path],
                   env=env, check=True)
    with open(path) as f:
        return json.load(f)


def main(argv=None):
    """Write the fingerprint to the file named by the first argument."""
    argv = sys.argv[1:] if argv is None else argv
    tracker_only = argv[:1] == ["--tracker"]
    argv = argv[1:] if tracker_only else argv
    if len(argv) != 1:
        print("usage: python -m benchmarks.fingerprint OUT.json", file=sys.stderr)
        return 2
    rec = algid.datasets.emps()
    emps = {"t": rec.t, "q": rec.qm, "F": rec.F}
    with tempfile.TemporaryDirectory() as directory:
        if tracker_only:
            out = tracker_entries(emps, directory)
        else:
            out = {**estimator_entries(), **identify_entries(emps),
                   **tracker_entries(emps, directory)}
            if tracker_jit.USE_NUMBA:
                out.update(_python_tracker_entries(directory))
    with open(argv[0], "w") as f:
        json.dump(out, f, indent=1, sort_keys=True)
    print(f"wrote {argv[0]}: {len(out)} entries")
    return 0


if __name__ == "__main__":
    sys.exit(main())
