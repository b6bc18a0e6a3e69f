"""Start-up and the first call of a fresh installation: import time, compile waits.

``PYTHONPATH=src:. python -m benchmarks.cold_start`` measures, each in a fresh process:

- ``import algid``: CPU time (best of seven), peak memory, and whether numba or SciPy
  was imported;
- the first ``Tracker.update`` and the first ``estimate(engine="numba")`` with empty
  caches: the package copied to a temporary folder without ``__pycache__`` and an empty
  ``NUMBA_CACHE_DIR``, so that numba compiles every kernel; CPU time of the call and
  the compile time of each jitted function (numba's compile events).

Each first call takes tens of seconds (numba compiling); the whole run about two
minutes.  The figures are printed and returned as a dict.
"""

from __future__ import annotations

import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]

_IMPORT = """
import resource, sys, time
t = time.process_time()
import algid
cpu = time.process_time() - t
heavy = [m for m in ("numba", "scipy") if m in sys.modules]
print(cpu, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, " ".join(heavy))
"""

_FIRST_CALL = """
import json, resource, sys, time
from numba.core import event

stack, compiled = [], {}

class Listener(event.Listener):   # exclusive compile time per jitted function
    def on_start(self, ev):
        f = ev.data["dispatcher"].py_func
        stack.append([f"{f.__module__}.{f.__qualname__}", time.process_time(), 0.0])

    def on_end(self, ev):
        name, start, nested = stack.pop()
        spent = time.process_time() - start
        compiled[name] = compiled.get(name, 0.0) + spent - nested
        if stack:
            stack[-1][2] += spent

event.register("numba:compile", Listener())

def cpu():
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime

import numpy as np
import algid

start = cpu()
if sys.argv[1] == "tracker":
    t = np.arange(3000) / 1000.0
    algid.Tracker("y'' + B*y' + K*y = G*u + d", "B K G d", rate=1000, window=0.5).update(
        {"y": np.cos(3 * t), "u": np.sin(7 * t) + np.sin(31 * t)})
else:
    sim = algid.simulate("sine", m=1, c=2, k=3, noise_std=0.01, seed=0)
    algid.estimate(sim.t, sim.f, sim.x, engine="numba")
print(json.dumps({"cpu": cpu() - start, "compiled": compiled}))
"""


def import_cost(src, runs=7):
    """CPU (best of ``runs``), peak memory (MB) and heavy modules of ``import algid``."""
    results = []
    for _ in range(runs):
        out = subprocess.run([sys.executable, "-c", _IMPORT], capture_output=True,
                             text=True, check=True,
                             env=dict(os.environ, PYTHONPATH=str(src))).stdout.split()
        results.append((float(out[0]), float(out[1]), out[2:]))
    best = min(results)
    return {"cpu_s": best[0], "peak_mb": best[1], "heavy_modules": best[2]}


def first_call(what):
    """CPU of the first call with empty caches, and the compile time per function."""
    with tempfile.TemporaryDirectory() as folder:
        src = pathlib.Path(folder) / "src"
        shutil.copytree(ROOT / "src", src, ignore=shutil.ignore_patterns("__pycache__"))
        env = dict(os.environ, PYTHONPATH=str(src), NUMBA_CACHE_DIR=f"{folder}/numba",
                   ALGID_CACHE_DIR=f"{folder}/algid", OPENBLAS_NUM_THREADS="1")
        out = subprocess.run([sys.executable, "-c", _FIRST_CALL, what], capture_output=True,
                             text=True, check=True, env=env).stdout
    result = json.loads(out.strip().splitlines()[-1])
    top = sorted(result["compiled"].items(), key=lambda item: -item[1])
    return {"cpu_s": result["cpu"], "compile_s": sum(result["compiled"].values()),
            "functions": len(top), "largest": top[:8], "all": top}


def main():
    """Print and return the measurements."""
    out = {"import": import_cost(ROOT / "src")}
    print(f"import algid: {out['import']['cpu_s']:.3f} s CPU, "
          f"{out['import']['peak_mb']:.0f} MB, heavy modules: "
          f"{out['import']['heavy_modules'] or 'none'}")
    for what in ("tracker", "estimate"):
        out[what] = result = first_call(what)
        print(f"first {what} call, empty caches: {result['cpu_s']:.1f} s CPU, of which "
              f"{result['compile_s']:.1f} s compiling {result['functions']} functions")
        for name, seconds in result["largest"]:
            print(f"  {seconds:6.2f} s  {name}")
    return out


if __name__ == "__main__":
    main()
