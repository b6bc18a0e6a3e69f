"""Hits and false alarms of the residual test of a refined fit
(``PYTHONPATH=src:. python -m benchmarks.residual_adequacy --runs 30``).

Per class, ``--runs`` noise realisations (seeds 0 .. N-1) identified with the default
``refine="auto"``; a row counts the records whose refined result warns (right models
must stay silent, wrong ones warn) and those whose first warning names the class's
cause.  Records: the linear plant ``y'' + 0.6 y' + 40 y = 40 u + 0.5`` driven by a
multisine (12 lines, 0.1-5 Hz), 30 s at 1 kHz, 30 dB output SNR (white, or AR(1) of
pole 0.9 for ``right_ar1``), from a nonzero state; the wrong models fitted to it (or to
a variant of it: a cubic spring, a derivative input, the output 3 samples late, a slow
drift); and the friction loop of :mod:`benchmarks.synthetic_records` fitted without its
Coulomb term.  Nonlinear models fitted: a Duffing oscillator (the linear plant with
``+ 0.5 y**3``) right, without its offset and 3 samples late, and the friction loop
right and without its offset (their residual test simulates the model with each
candidate term, :func:`algid.identification._residual_tests.nonlinear_residual_test`);
where a nonlinear model is not refined (``refine="auto"``), its algebraic adequacy test
speaks.
"""

from __future__ import annotations

import argparse
import json

import numpy as np

import algid
from algid.models import parse_equation
from benchmarks.synthetic_records import FRICTION_EQUATION, friction_loop

LINEAR = ("y'' + B*y' + K*y = G*u + d", "B K G d")
TRUTH = {"B": 0.6, "K": 40.0, "G": 40.0, "d": 0.5}
DUFFING = ("y'' + B*y' + K*y + K3*y**3 = G*u + d", "B K K3 G d")
DUFFING_TRUTH = dict(TRUTH, K3=0.5)
RATE, DURATION = 1000.0, 30.0

#: class -> (truth equation, its values, the model fitted, options, the cause's words)
CASES = {
    "right": (LINEAR, TRUTH, LINEAR, {}, None),
    "right_ar1": (LINEAR, TRUTH, LINEAR, {"colour": True}, None),
    "missing offset": (LINEAR, TRUTH, ("y'' + B*y' + K*y = G*u", "B K G"), {}, "offset"),
    "missing cubic": (("y'' + B*y' + K*y + K3*y**3 = G*u + d", "B K K3 G d"),
                      dict(TRUTH, K3=0.5), LINEAR, {}, "cubic"),
    "G*u' for G*u": (("y'' + B*y' + K*y = G*u' + d", "B K G d"), TRUTH, LINEAR, {},
                     "u'"),
    "output 3 samples late": (LINEAR, TRUTH, LINEAR, {"shift": 3}, "delay"),
    "slow drift": (LINEAR, TRUTH, LINEAR, {"drift": 0.002}, "drift"),
    "wrong input gain": (LINEAR, TRUTH, ("y'' + B*y' + K*y = 30*u + d", "B K d"), {},
                         "gain"),
    "missing Coulomb": (None, None, ("M*q'' + Fv*q' + off = F", "M Fv off"), {},
                        "Coulomb"),
    "right Duffing": (DUFFING, DUFFING_TRUTH, DUFFING, {}, None),
    "Duffing, missing offset": (DUFFING, DUFFING_TRUTH,
                                ("y'' + B*y' + K*y + K3*y**3 = G*u", "B K K3 G"), {},
                                "offset"),
    "Duffing, output 3 samples late": (DUFFING, DUFFING_TRUTH, DUFFING, {"shift": 3},
                                       "delay"),
    "right friction": (None, None, FRICTION_EQUATION, {}, None),
    "friction, missing offset": (None, None, ("M*q'' + Fv*q' + Fc*sign(q') = F",
                                              "M Fv Fc"), {}, "offset"),
}


def _input():
    rng = np.random.default_rng(2024)
    t = np.arange(int(DURATION * RATE)) / RATE
    u = sum(np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
            for f in np.geomspace(0.1, 5.0, 12))
    return t, u


def clean_output(equation, values, options):
    """The noise-free output of ``equation`` (cached by the caller)."""
    t, u = _input()
    y = algid.simulate_model(parse_equation(*equation), values, t, {"u": u},
                             initial_state=[0.05, -0.2], rtol=1e-10, atol=1e-14)
    shift = options.get("shift", 0)
    if shift:
        y = np.concatenate([np.full(shift, y[0]), y[:-shift]])
    return y + options.get("drift", 0.0) * t


def record(clean, seed, colour=False):
    """The record of one realisation: 30 dB of white or AR(1) output noise."""
    from scipy.signal import lfilter

    t, u = _input()
    e = np.random.default_rng(seed).standard_normal(len(t))
    if colour:
        e = lfilter([1.0], [1.0, -0.9], e) * np.sqrt(1 - 0.81)
    return {"t": t, "u": u, "y": clean + np.sqrt(np.mean(clean ** 2)) / 31.6 * e}


def tally(name, results, cause, runs):
    """One class's row: of ``results`` (identify's, one per record), those that warn,
    those whose first warning holds ``cause`` (None: a right model), those refined."""
    warned = named = refined = 0
    for r in results:
        refined += r.estimate == "refined"
        warned += bool(r.warnings)
        named += bool(cause and r.warnings and cause in r.warnings[0])
    print(f"{name:36} warned {warned:3d}/{runs}  cause named first {named:3d}  "
          f"refined {refined:3d}", flush=True)
    return {"runs": runs, "warned": warned, "named": named, "refined": refined,
            "right": cause is None}


def study(runs, names=None):
    """Per class: warned, named (the first warning names the cause), refined."""
    out = {}
    for name in names or CASES:
        truth_eq, values, model, options, cause = CASES[name]
        clean = None if truth_eq is None else clean_output(truth_eq, values, options)

        def records(clean=clean, truth_eq=truth_eq, options=options):
            for seed in range(runs):
                if truth_eq is None:
                    yield friction_loop(seed, n=30000, noise=1e-6)[0]
                else:
                    yield record(clean, seed, options.get("colour", False))

        out[name] = tally(name, (algid.identify(rec, *model) for rec in records()), cause,
                          runs)
    return out


def command_line(study, doc, argv=None):
    """The command line of an adequacy study: ``--runs``, ``--cases``, ``--json``."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--runs", type=int, default=30)
    parser.add_argument("--cases", nargs="*", default=None)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    out = study(args.runs, args.cases)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    return out


def main(argv=None):
    """Print the table (and write it with ``--json FILE``)."""
    return command_line(study, __doc__, argv)


if __name__ == "__main__":
    main()
