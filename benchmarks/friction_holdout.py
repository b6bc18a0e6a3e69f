"""The algebraic friction estimate on a record it was not developed on
(``PYTHONPATH=src:. python -m benchmarks.friction_holdout --runs 40``).

The open-loop mass ``M*q'' + Fv*q' + Fc*sign(q') + off = F`` with other values than
:mod:`benchmarks.nonlinear_refinement_study`'s (M = 0.5, Fv = 1.2, Fc = 0.6, off = 0.1),
another input (6 lines from 0.15 to 2.5 Hz of random amplitudes, 1.1 N rms), 20 s at
500 Hz, at rest 9 % of the time; simulated by :func:`algid.simulate_model` (DOP853 at
1e-10, the switches as events), white noise at 25 dB on the position (``--snr``), noise
seeds from 1000.  Per parameter: the estimates' bias over their spread, their spread
over the mean reported standard error, the coverage of ±2 reported standard errors, bias
and RMSE over the Cramér–Rao bound (white noise, the initial state a nuisance), and the
records refused; ``identify(refine=False)``, its steps of ``sign(q')`` placed as
``--crossings`` says (default ``auto``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import algid
from algid.models import parse_equation
from benchmarks.window_rule_study import sensitivities

EQUATION = "M*q'' + Fv*q' + Fc*sign(q') + off = F"
TRUTH = {"M": 0.5, "Fv": 1.2, "Fc": 0.6, "off": 0.1}
RATE, DURATION = 500.0, 20.0


def record():
    """Time, force and noise-free position."""
    t = np.arange(int(DURATION * RATE) + 1) / RATE
    rng = np.random.default_rng(2024)
    lines = zip(np.geomspace(0.15, 2.5, 6), rng.uniform(0.5, 1.5, 6))
    F = sum(a * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi)) for f, a in lines)
    F = 1.1 * F / np.sqrt(np.mean(F ** 2))
    q = algid.simulate_model(parse_equation(EQUATION, " ".join(TRUTH)), TRUTH, t, {"F": F},
                             initial_state=(0.0, -0.05), rtol=1e-10, atol=1e-13)
    return t, F, q


def cramer_rao(t, F, sigma, relative_step=1e-6):
    """Standard deviations of the Cramér–Rao bound (white noise ``sigma``, the initial
    state a nuisance), by central differences of the accurate simulator."""
    model = parse_equation(EQUATION, " ".join(TRUTH))
    x0 = [0.0, -0.05]

    def output(theta, state):
        return algid.simulate_model(model, theta, t, {"F": F}, initial_state=state,
                                    rtol=1e-10, atol=1e-13)

    J = sensitivities(output, TRUTH, x0, relative_step, [relative_step] * 2)
    return np.sqrt(np.diag(np.linalg.inv(J.T @ J)))[:len(TRUTH)] * sigma


def study(runs, snr=25.0, crossings="auto"):
    """The table, as a dict."""
    t, F, q = record()
    sigma = np.sqrt(np.mean(q ** 2)) / 10 ** (snr / 20)
    exact = np.array(list(TRUTH.values()))
    values, errors, cpu, refused = [], [], [], []
    for seed in range(1000, 1000 + runs):
        noisy = q + sigma * np.random.default_rng(seed).standard_normal(len(t))
        start = time.process_time()
        try:
            r = algid.identify({"t": t, "F": F, "q": noisy}, EQUATION, " ".join(TRUTH),
                               refine=False, crossings=crossings)
        except algid.AlgidError as error:
            refused.append(str(error).split(":")[0])
            continue
        cpu.append(time.process_time() - start)
        values.append([r.values[p] for p in TRUTH])
        errors.append([r.stderr[p] for p in TRUTH])
    values, errors = np.array(values), np.array(errors)
    spread = values.std(axis=0)
    bound = cramer_rao(t, F, sigma)
    return {"runs": runs, "identified": len(values), "refused": refused,
            "bias/crlb": dict(zip(TRUTH, ((values.mean(axis=0) - exact) / bound).tolist())),
            "rmse/crlb": dict(zip(TRUTH, (np.sqrt(np.mean((values - exact) ** 2, axis=0))
                                          / bound).tolist())),
            "bias/sd": dict(zip(TRUTH, ((values.mean(axis=0) - exact) / spread).tolist())),
            "sd/se": dict(zip(TRUTH, (spread / errors.mean(axis=0)).tolist())),
            "coverage": dict(zip(TRUTH, (np.abs(values - exact) <= 2 * errors)
                                 .mean(axis=0).tolist())),
            "median_cpu_s": float(np.median(cpu))}


def main(argv=None):
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--snr", type=float, default=25.0)
    parser.add_argument("--crossings", choices=("auto", "velocity", "local"), default="auto")
    args = parser.parse_args(argv)
    out = study(args.runs, args.snr, args.crossings)
    reasons = {r: out["refused"].count(r) for r in out["refused"]}
    print(f"identified {out['identified']} of {out['runs']}; refused: "
          + (", ".join(f"{n} ({r})" for r, n in reasons.items()) or "none"))
    for p in TRUTH:
        print(f"  {p:4} bias/sd {out['bias/sd'][p]:+.2f}  sd/se {out['sd/se'][p]:.2f}  "
              f"coverage {100 * out['coverage'][p]:.0f} %  bias/CRLB "
              f"{out['bias/crlb'][p]:+.2f}  RMSE/CRLB {out['rmse/crlb'][p]:.2f}")
    print(f"  median CPU {out['median_cpu_s']:.2f} s")


if __name__ == "__main__":
    main()
