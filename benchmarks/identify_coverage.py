"""Coverage of the standard errors of the algebraic estimate of :func:`algid.identify`
(``python -m benchmarks.identify_coverage --runs 300``).

On the synthetic records of :mod:`benchmarks.synthetic_records` (linear with offsets,
the same with 5 % of its rows missing, cubic spring, friction under a position loop),
``--runs`` noise realisations each, automatic window, default solver: per record and
parameter, the fraction of realisations whose estimate lies within two reported
standard errors of the truth (nominal 95.4 %; target at least 93 %), the same with the
numerical error added in quadrature, and the number of standard errors that are exactly
zero or not finite.  Per record also the windows chosen, the refusals (an
``AlgidError``) and the warnings (none is expected on these records, with their right
models).

The cubic spring's noise-free response is integrated once; each realisation adds the
noise of the generator's seed (the same samples as the generator gives for that seed).

Options: ``--runs N`` (default 300), ``--records NAME ...`` (default all), ``--out FILE``
(JSON).
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter

import numpy as np

import algid
from algid.errors import AlgidError
from benchmarks.synthetic_records import (
    CUBIC_EQUATION,
    FRICTION_EQUATION,
    LINEAR_EQUATION,
    cubic_spring,
    friction_loop,
    linear_gaps,
    linear_offsets,
)

#: Nominal coverage of +-2 standard errors of a normal estimate.
NOMINAL = 0.9545

#: Target coverage of +-2 reported standard errors.
TARGET = 0.93


def _linear_noise(base, seed, noise=0.01):
    record = dict(base)
    y = base["y"]
    rng = np.random.default_rng(seed)
    record["y"] = y + noise * np.std(y) * rng.standard_normal(len(y))
    return record


def records():
    """Name -> (truth, equation, the record of a seed)."""
    linear_truth = linear_offsets(0)[1]
    cubic, cubic_truth = cubic_spring(0, noise=0.0)
    return {
        "linear_offsets": (linear_truth, LINEAR_EQUATION, lambda seed: linear_offsets(seed)[0]),
        "linear_gaps": (linear_truth, LINEAR_EQUATION, lambda seed: linear_gaps(seed)[0]),
        "cubic_spring": (cubic_truth, CUBIC_EQUATION, lambda seed: _linear_noise(cubic, seed)),
        "friction_loop": (friction_loop(0)[1], FRICTION_EQUATION,
                          lambda seed: friction_loop(seed)[0]),
    }


def coverage(name, truth, equation, noisy, runs):
    """Coverage figures of one record over ``runs`` realisations."""
    inside = Counter()
    inside_total = Counter()
    zero, refused, windows, z_scores = 0, [], Counter(), {p: [] for p in truth}
    warned = Counter()
    start = time.perf_counter()
    done = 0
    for seed in range(runs):
        try:
            r = algid.identify(noisy(seed), *equation, refine=False)   # the algebraic
        except AlgidError as error:
            refused.append(str(error))
            continue
        done += 1
        windows[round(r.window, 6)] += 1
        for line in r.warnings:
            warned[line.split(":")[0]] += 1
        numerical = getattr(r, "numerical_error", None) or {}
        for p, value in truth.items():
            se = r.stderr[p]
            if not (np.isfinite(se) and se > 0):
                zero += 1
            error = abs(r.values[p] - value)
            inside[p] += error <= 2 * se
            inside_total[p] += error <= 2 * np.hypot(se, numerical.get(p, 0.0))
            z_scores[p].append((r.values[p] - value) / se if se > 0 else np.inf)
    return {
        "record": name,
        "runs": runs,
        "identified": done,
        "coverage": {p: inside[p] / max(done, 1) for p in truth},
        "coverage_with_numerical_error": {p: inside_total[p] / max(done, 1) for p in truth},
        "z_rms": {p: float(np.sqrt(np.mean(np.square(z)))) if z else None
                  for p, z in z_scores.items()},
        "zero_or_nonfinite_stderr": zero,
        "refused": refused[:5],
        "refusals": len(refused),
        "warnings": dict(warned),
        "windows": {str(k): v for k, v in sorted(windows.items())},
        "seconds": time.perf_counter() - start,
    }


def markdown(results):
    """The coverage table of a results file of this benchmark (``--out``), as Markdown."""
    lines = [f"{results['runs']} realisations per record.", "",
             "| record | parameter | ±2σ coverage | with the numerical error | rms of "
             "error / σ | zero σ | refused | warned |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for row in results["results"]:
        for p, cover in row["coverage"].items():
            z = row["z_rms"][p]
            lines.append(
                f"| {row['record']} | {p} | {cover:.1%} | "
                f"{row['coverage_with_numerical_error'][p]:.1%} | "
                f"{'—' if z is None else f'{z:.2f}'} | {row['zero_or_nonfinite_stderr']} | "
                f"{row['refusals']} | {sum(row['warnings'].values())} |")
    return "\n".join(lines)


def main(argv=None):
    """Run the coverage benchmark and print a table (and JSON with ``--out``)."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.identify_coverage")
    parser.add_argument("--runs", type=int, default=300)
    parser.add_argument("--records", nargs="*", default=None)
    parser.add_argument("--out", default=None)
    args = parser.parse_args(argv)
    available = records()
    names = args.records or list(available)
    results = []
    print(f"+-2 standard errors around the truth, {args.runs} realisations per record "
          f"(nominal {NOMINAL:.1%}, target {TARGET:.0%})")
    print(f"{'record':<16} {'param':<6} {'cover':>7} {'+numerr':>8} {'z rms':>7}")
    for name in names:
        truth, equation, noisy = available[name]
        row = coverage(name, truth, equation, noisy, args.runs)
        results.append(row)
        for p in truth:
            z = row["z_rms"][p]
            print(f"{name:<16} {p:<6} {row['coverage'][p]:>7.1%} "
                  f"{row['coverage_with_numerical_error'][p]:>8.1%} "
                  f"{z if z is not None else float('nan'):>7.2f}")
        print(f"{name:<16} zero or non-finite standard errors: "
              f"{row['zero_or_nonfinite_stderr']}, refused: {row['refusals']}, "
              f"warned: {sum(row['warnings'].values())}, {row['seconds']:.0f} s")
    worst = min((min(row["coverage"].values()) for row in results if row["identified"]),
                default=float("nan"))
    zeros = sum(row["zero_or_nonfinite_stderr"] for row in results)
    print(f"worst coverage {worst:.1%} (target {TARGET:.0%}: "
          f"{'met' if worst >= TARGET else 'missed'}); zero standard errors: {zeros}")
    if args.out:
        with open(args.out, "w") as handle:
            json.dump({"runs": args.runs, "results": results, "worst": worst,
                       "zero_stderr": zeros}, handle, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
