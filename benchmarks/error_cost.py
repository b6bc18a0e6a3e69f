"""What the numerical error costs (``python -m benchmarks.error_cost [--smoke|--quick]``).

On the same record (:func:`benchmarks.measure.sine_record`, as the other speed
sections), in one process, every run times once each of

- the naive NumPy estimator of :mod:`benchmarks.baselines` (the paper's formulas with
  ``cumulative_trapezoid``; the baseline);
- :func:`algid.estimate` with the NumPy and the numba engine, by default (with the
  numerical error) and with ``numerical_error=False``;
- :class:`algid.OnlineEstimator` fed the record in chunks of 1000 samples, NumPy and
  numba (with the numerical error, as a stream computes it);

at two sizes (``n_batch / 5`` and ``n_batch``: 2e6 and 1e7 samples in the full run).
The naive baseline is memory-bound and its rate varies from run to run, so each ratio
to it is computed within a run and the lowest (the most pessimistic) over the runs is
reported, with the baseline's rates; algid's own ratios (the cost of the error, stream
over batch) are those of the best times.  Times are process CPU times
(``time.process_time``).  The section is :func:`error_cost`; :func:`markdown` and
:func:`targets` format it for the suite's report.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from benchmarks.measure import sine_record

__all__ = ["error_cost", "markdown", "targets", "STREAM_CHUNK"]

#: Samples per chunk of the streams.
STREAM_CHUNK = 1000
#: Runs at least (each times every method once).
MIN_RUNS = 3


def _cpu(func):
    start = time.process_time()
    func()
    return time.process_time() - start


def _methods(t, f, x, engines):
    import algid
    from benchmarks.baselines import naive_algebraic

    def stream(engine):
        def run():
            online = algid.OnlineEstimator(rate=1.0 / (t[1] - t[0]), engine=engine)
            for i in range(0, t.size, STREAM_CHUNK):
                online.update(t[i:i + STREAM_CHUNK], f[i:i + STREAM_CHUNK],
                              x[i:i + STREAM_CHUNK])
        return run

    methods = {"naive": lambda: naive_algebraic(t, f, x)}
    for engine in engines:
        methods[f"{engine}"] = lambda e=engine: algid.estimate(t, f, x, engine=e)
        methods[f"{engine}_alone"] = lambda e=engine: algid.estimate(
            t, f, x, engine=e, numerical_error=False)
        methods[f"{engine}_stream"] = stream(engine)
    return methods


def error_cost(config):
    """The cost of the numerical error, and the estimator against the naive one.

    Parameters
    ----------
    config : benchmarks.sections.Config
        ``n_batch`` (the larger size) and ``repeats`` (runs: at least 3, one in the
        smoke run).

    Returns
    -------
    dict
        ``sizes``: per size, ``naive_rates`` (samples/s of each run), ``times`` (method ->
        CPU time of each run), and per engine ``speed`` (lowest ratio over the runs of
        the naive time to the default estimate's), ``speed_alone`` (the same without
        the numerical error), ``error_cost`` (the default's best time over the best time
        without the error) and ``stream_over_batch`` (the stream's best time over the
        default estimate's).
    """
    from algid.estimation._backends import numba_available

    engines = ("numpy", "numba") if numba_available() else ("numpy",)
    runs = 1 if config.mode == "smoke" else max(MIN_RUNS, int(config.repeats))
    out = {"runs": runs, "engines": list(engines), "stream_chunk": STREAM_CHUNK, "sizes": []}
    for n in (int(config.n_batch) // 5, int(config.n_batch)):
        t, f, x = sine_record(n)
        for run in _methods(t[:3000], f[:3000], x[:3000], engines).values():
            run()  # warm-up: numba's compilation or cache, NumPy's first calls
        methods = _methods(t, f, x, engines)
        times = {name: [] for name in methods}
        for _ in range(runs):  # interleaved: the load of the machine varies
            for name, run in methods.items():
                times[name].append(_cpu(run))
        naive = np.array(times["naive"])
        size = {"n_samples": n, "naive_rates": list(n / naive), "times": times}
        for engine in engines:
            own = np.array(times[engine])
            size[engine] = {
                "speed": float(np.min(naive / own)),
                "speed_alone": float(np.min(naive / np.array(times[f"{engine}_alone"]))),
                # algid against itself: the best times (no memory-bound baseline here)
                "error_cost": float(own.min() / min(times[f"{engine}_alone"])),
                "stream_over_batch": float(min(times[f"{engine}_stream"]) / own.min()),
            }
        out["sizes"].append(size)
    return out


def targets(data):
    """The section's targets: name -> ``(measured, detail)``, each ``measured <= limit``.

    ``error_speed``: the default estimate's time over the naive estimator's (limit 1/4),
    ``error_cost``: the default's time over ``numerical_error=False``'s (limit 1.25),
    ``error_stream``: the stream's time over the batch's (limit 1.5); each the worst of
    the engines, sizes and runs.
    """
    def worst(key, pick):
        cases = [(pick(size[e][key]), e, size["n_samples"]) for size in data["sizes"]
                 for e in data["engines"]]
        value, engine, n = max(cases)
        return value, f"worst: {engine} at {n:.0e} samples"

    speed, where = worst("speed", lambda r: 1.0 / r)
    cost, cost_where = worst("error_cost", lambda r: r)
    stream, stream_where = worst("stream_over_batch", lambda r: r)
    return {"error_speed": (speed, f"{1.0 / speed:.2f}× the naive estimator; {where}"),
            "error_cost": (cost, f"{cost:.2f}× numerical_error=False; {cost_where}"),
            "error_stream": (stream, f"chunks of {data['stream_chunk']}: {stream:.2f}× the "
                                     f"batch; {stream_where}")}


def markdown(data):
    """The section as Markdown (heading, table, notes)."""
    lines = [f"### 7. The cost of the numerical error (lowest ratio of {data['runs']} "
             "runs; CPU times)\n",
             "| samples | naive rate [M samples/s] | engine | default × naive | "
             "numerical_error=False × naive | cost of the error | stream / batch |",
             "|---|---|---|---|---|---|---|"]
    for size in data["sizes"]:
        rates = size["naive_rates"]
        rate = f"{min(rates) / 1e6:.2f}–{max(rates) / 1e6:.2f}"
        for engine in data["engines"]:
            r = size[engine]
            lines.append(f"| {size['n_samples']:.0e} | {rate} | {engine} | {r['speed']:.2f} | "
                         f"{r['speed_alone']:.2f} | {r['error_cost']:.2f}× | "
                         f"{r['stream_over_batch']:.2f} |")
    lines += ["", "- default × naive: the naive time over the default estimate's (with the "
              "numerical error), the lowest over the runs; the cost of the error: the default "
              "time over the time with `numerical_error=False`; stream / batch: "
              f"OnlineEstimator in chunks of {data['stream_chunk']} over the batch (best "
              "times)."]
    return "\n".join(lines)


def main(argv=None):
    """Run the section alone and print it (``--json`` for the raw figures)."""
    from benchmarks.run import section_main

    return section_main(argv, "benchmarks.error_cost", error_cost, markdown,
                        ('2e5 and 1e6 samples', '2e3 and 1e4 samples (seconds)'))


if __name__ == "__main__":
    sys.exit(main())
