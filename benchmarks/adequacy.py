"""Hits and false alarms of the adequacy test of the algebraic estimate of :func:`algid.identify`

Run from the repository root: ``python -m benchmarks.adequacy [--runs N] [--json FILE]``.

For every case, ``--runs`` noise realisations (seeds 0 .. N-1) are identified and the
warnings counted: right models (the synthetic records of
:mod:`benchmarks.synthetic_records` at their default noise, and :func:`second_order`,
``y'' + 2 y' + 3 y = u`` at 100 Hz for 60 s with 1 % output noise) must stay silent,
wrong ones (a linear model on the cubic record, ``G*u'`` for ``G*u``, the output
delayed by 5 samples) must be flagged.  The real records (EMPS with its friction model,
the three parts of Silverbox with its cubic model) are run once.  Each row gives the
warnings out of the runs and the median and extreme values of the test's two numbers
(:mod:`algid.identification._adequacy`: misfit over the output-noise bound, shift in standard
errors).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

import algid
from benchmarks.synthetic_records import (
    CUBIC_EQUATION,
    FRICTION_EQUATION,
    LINEAR_EQUATION,
    cubic_spring,
    friction_loop,
    linear_offsets,
    multisine_lines,
)

SECOND_ORDER = ("y'' + B*y' + K*y = G*u", "B K G")


def second_order(seed=0, *, noise=0.01, rate=100.0, duration=60.0):
    """``y'' + 2 y' + 3 y = u`` driven by a multisine (20 lines, 0.05-3 Hz), in periodic
    steady state (exact: every line through the frequency response), ``noise`` x rms(y)
    white noise on the output.

    Returns
    -------
    dict
        ``t``, ``u``, ``y``.
    """
    freqs, phases, amp = multisine_lines(np.random.default_rng(2024), 0.05, 3.0, 20, 1.0)
    t = np.arange(int(round(duration * rate))) / rate
    w = 2 * np.pi * freqs
    response = 1.0 / (3.0 - w ** 2 + 2j * w)
    u = np.sum(amp * np.sin(w[:, None] * t + phases[:, None]), axis=0)
    y = np.sum(amp * np.abs(response)[:, None]
               * np.sin(w[:, None] * t + phases[:, None] + np.angle(response)[:, None]), axis=0)
    y = y + noise * np.std(y) * np.random.default_rng(seed).standard_normal(len(t))
    return {"t": t, "u": u, "y": y}


def delayed(record, samples, output):
    """The record with its output ``samples`` samples late (the other columns cut to
    the same rows)."""
    return {name: (v[samples:] if name == output else v[:-samples])
            for name, v in record.items()}


def synthetic_cases():
    """``(name, make(seed) -> record, equation, parameters, wrong)``."""
    return [
        ("linear, right model", lambda s: linear_offsets(s)[0], *LINEAR_EQUATION, False),
        ("cubic, right model", lambda s: cubic_spring(s)[0], *CUBIC_EQUATION, False),
        ("friction loop, right model", lambda s: friction_loop(s)[0], *FRICTION_EQUATION,
         False),
        ("second order, right model", second_order, *SECOND_ORDER, False),
        ("cubic, linear model", lambda s: cubic_spring(s)[0], *LINEAR_EQUATION, True),
        ("second order, G*u' for G*u", second_order, "y'' + B*y' + K*y = G*u'", "B K G",
         True),
        ("second order, output 5 samples late", lambda s: delayed(second_order(s), 5, "y"),
         *SECOND_ORDER, True),
        ("linear, G*u' for G*u", lambda s: linear_offsets(s)[0],
         "y'' + B*y' + K*y = G*u' + d", "B K G d", True),
        ("linear, output 5 samples late", lambda s: delayed(linear_offsets(s)[0], 5, "y"),
         *LINEAR_EQUATION, True),
    ]


def real_cases():
    """``(name, record, equation, parameters, options)`` of the shipped real records:
    the three parts of Silverbox with the cubic model, the EMPS runs with the friction
    model (the validation run also with the pulses added to the force once more, as
    ``tests/identification/test_identify_real.py`` does)."""
    from algid import datasets

    silverbox = datasets.silverbox()
    cases = []
    for part in silverbox.segments:
        signals = silverbox.segment(part)
        cases.append((f"Silverbox {part} part, cubic model",
                      {k: signals[k] for k in ("V1", "V2")},
                      "V2'' + B*V2' + K*V2 + K3*V2**3 = G*V1 + d", "B K K3 G d",
                      {"rate": silverbox.rate}))
    for run, pulses in (("estimation", False), ("validation", False), ("validation", True)):
        record = datasets.emps(run)
        force = record.gtau * np.asarray(record["vir"])
        if pulses:
            force = force + np.asarray(record["pulses_N"])
        cases.append((f"EMPS {run} run{' + pulses_N' if pulses else ''}, friction model",
                      {"t": np.asarray(record["t"]), "q": np.asarray(record["qm"]),
                       "F": force}, *FRICTION_EQUATION, {}))
    return cases


def _row(name, results, wrong):
    misfit = np.array([r.adequacy.misfit for r in results])
    shift = np.array([r.adequacy.shift for r in results])
    flagged = sum(bool(r.warnings) for r in results)
    return {"case": name, "wrong": wrong, "runs": len(results), "warned": flagged,
            "misfit_median": float(np.median(misfit)), "misfit_min": float(misfit.min()),
            "misfit_max": float(misfit.max()), "shift_median": float(np.nanmedian(shift)),
            "shift_min": float(np.nanmin(shift)), "shift_max": float(np.nanmax(shift))}


def main(argv=None):
    """Run the cases and print one row per case."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.adequacy")
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--json", default=None, help="also write the rows to this file")
    args = parser.parse_args(argv)
    rows = []
    print(f"{'case':42s} {'wrong':>5s} {'warned':>9s}  misfit (median, min-max)   "
          f"shift (median, min-max)")
    for name, make, equation, parameters, wrong in synthetic_cases():
        results = [algid.identify(make(seed), equation, parameters, refine=False)
                   for seed in range(args.runs)]
        rows.append(_row(name, results, wrong))
    for name, record, equation, parameters, options in real_cases():
        rows.append(_row(name, [algid.identify(record, equation, parameters, refine=False,
                                               **options)],
                         False))
    for row in rows:
        print(f"{row['case']:42s} {str(row['wrong']):>5s} {row['warned']:4d}/{row['runs']:<4d}"
              f"  {row['misfit_median']:8.3g} ({row['misfit_min']:.3g}-{row['misfit_max']:.3g})"
              f"   {row['shift_median']:7.3g} ({row['shift_min']:.3g}-{row['shift_max']:.3g})")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as out:
            json.dump(rows, out, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
