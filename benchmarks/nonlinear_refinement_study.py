"""Monte Carlo of identify's algebraic and refined estimates of nonlinear models against
the Cramér–Rao bound (``PYTHONPATH=src:. python -m benchmarks.nonlinear_refinement_study
--runs 100``).

Two models, 30 s at 1 kHz, output noise at 30 dB SNR (``--snr``), white or AR(1) of
pole 0.9 (the same variance):

- ``duffing``: ``y'' + B*y' + K*y + K3*y**3 = G*u + d`` as in
  :mod:`benchmarks.window_rule_study` (a 1 Hz mode, the cubic spring about 25 % of the
  linear one at the peaks, a multisine of 30 lines from 0.1 to 5 Hz), simulated there by
  DOP853 at a relative tolerance of 1e-11;
- ``friction``: the open-loop mass ``M*q'' + Fv*q' + Fc*sign(q') + off = F`` (M = 2,
  Fv = 5, Fc = 1, off = -0.2) driven by a multisine of 8 lines from 0.2 to 3 Hz of 2 N
  rms, the mass at rest 11 % of the time (48 reversals); simulated by
  :func:`algid.simulate_model` (DOP853 at 1e-10, the switches located as events, the
  sticking as sliding).

The data come from those accurate simulators, not from the fast one the refinement
uses.  Per model, noise and parameter: bias and RMSE over the runs in units of the
Cramér–Rao bound (white noise, the initial state as nuisance, sensitivities by central
differences of the accurate simulator), and the coverage of ±2 reported standard
errors, for the algebraic estimate (``result.algebraic``) and the reported one
(``identify()``, refined where it is applied); the median CPU time of
``identify(refine=False)`` and of ``identify()``.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

import algid
from algid.models import parse_equation
from benchmarks import window_rule_study as wr

SNR_DB, AR_POLE = 30.0, 0.9

FRICTION = {"equation": "M*q'' + Fv*q' + Fc*sign(q') + off = F",
            "parameters": "M Fv Fc off",
            "truth": {"M": 2.0, "Fv": 5.0, "Fc": 1.0, "off": -0.2}}

MODELS = ("duffing", "friction")


def _friction_output(theta, x0):
    t = np.arange(int(round(wr.DURATION * wr.RATE)) + 1) / wr.RATE
    rng = np.random.default_rng(99)
    freqs = np.geomspace(0.2, 3.0, 8)
    F = sum(np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi)) for f in freqs)
    F = 2.0 * F / np.sqrt(np.mean(F ** 2))
    model = parse_equation(FRICTION["equation"], FRICTION["parameters"])
    y = algid.simulate_model(model, theta, t, {"F": F}, initial_state=x0, rtol=1e-10,
                             atol=1e-13)
    return t, F, y


def noise_free(name, theta=None, x0=None):
    """Time, input and noise-free output of a model at ``theta`` (its truth)."""
    if name == "duffing":
        x0 = (0.0, 0.0) if x0 is None else x0
        return wr.simulate(wr.DUFFING, theta, x0)
    return _friction_output(dict(FRICTION["truth"] if theta is None else theta),
                            (0.0, 0.1) if x0 is None else x0)


def cramer_rao(name, sigma, relative_step=1e-6):
    """Standard deviations of the Cramér–Rao bound (white noise ``sigma``, the initial
    state a nuisance), by central differences of the accurate simulator."""
    truth = (wr.DUFFING if name == "duffing" else FRICTION)["truth"]
    x0 = [0.0, 0.0] if name == "duffing" else [0.0, 0.1]
    J = wr.sensitivities(lambda theta, state: noise_free(name, theta, state)[2], truth, x0,
                         relative_step, [relative_step * 1.0, relative_step * 6.0])
    return np.sqrt(np.diag(np.linalg.inv(J.T @ J)))[:len(truth)] * sigma


def _noise(rng, n, sigma, colour):
    e = rng.standard_normal(n)
    if colour == "white":
        return sigma * e
    from scipy.signal import lfilter
    return sigma * lfilter([1.0], [1.0, -AR_POLE], e) * np.sqrt(1.0 - AR_POLE ** 2)


def study(name, runs, colours=("white", "ar1"), timed=5, snr=SNR_DB):
    """One model's table, as a dict (output noise at ``snr`` dB)."""
    spec = wr.DUFFING if name == "duffing" else FRICTION
    equation, parameters, truth = spec["equation"], spec["parameters"], spec["truth"]
    names = parameters.split()
    t, u, y = noise_free(name)
    signals = ("u", "y") if name == "duffing" else ("F", "q")
    sigma = np.sqrt(np.mean(y ** 2)) / 10 ** (snr / 20)
    bound = cramer_rao(name, sigma)
    exact = np.array([truth[p] for p in names])
    out = {"equation": equation, "crlb": dict(zip(names, bound.tolist())), "runs": runs}
    for colour in colours:
        rows = {"algebraic": [], "reported": []}
        cpu = {"algebraic": [], "reported": []}
        applied, reasons = 0, {}
        for seed in range(runs):
            rng = np.random.default_rng(seed)
            record = {"t": t, signals[0]: u, signals[1]: y + _noise(rng, len(t), sigma,
                                                                      colour)}
            if seed < timed:
                start = time.process_time()
                algid.identify(record, equation, parameters, refine=False)
                cpu["algebraic"].append(time.process_time() - start)
            start = time.process_time()
            r = algid.identify(record, equation, parameters)
            if seed < timed:
                cpu["reported"].append(time.process_time() - start)
            se = np.sqrt(np.diag(r.algebraic["covariance"]))
            rows["algebraic"].append([[r.algebraic["values"][p], se[i]]
                                      for i, p in enumerate(names)])
            rows["reported"].append([[r.values[p], r.stderr[p]] for p in names])
            applied += r.estimate == "refined"
            if r.estimate != "refined":
                key = r.refinement.reason[:60]
                reasons[key] = reasons.get(key, 0) + 1
        table = {}
        for kind, values in rows.items():
            a = np.array(values)            # runs x params x (value, stderr)
            err = a[:, :, 0] - exact
            table[kind] = {p: {"bias/crlb": float(np.mean(err[:, i]) / bound[i]),
                               "rmse/crlb": float(np.sqrt(np.mean(err[:, i] ** 2))
                                                  / bound[i]),
                               "coverage": float(np.mean(np.abs(err[:, i])
                                                         <= 2 * a[:, i, 1]))}
                           for i, p in enumerate(names)}
            table[kind]["median_cpu_s"] = float(np.median(cpu[kind]))
        table["refined_applied"] = applied
        table["not_refined_because"] = reasons
        out[colour] = table
    return out


def main(argv=None):
    """Print the tables (and write them with ``--json FILE``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--models", nargs="+", choices=MODELS, default=list(MODELS))
    parser.add_argument("--snr", type=float, default=SNR_DB,
                        help="output signal-to-noise ratio, dB (default %(default)s)")
    parser.add_argument("--colours", nargs="+", choices=("white", "ar1"),
                        default=["white", "ar1"])
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    out = {}
    for name in args.models:
        out[name] = result = study(name, args.runs, tuple(args.colours), snr=args.snr)
        print(f"{name}: {result['equation']}")
        print(f"  CRLB: {', '.join(f'{p} {v:.3g}' for p, v in result['crlb'].items())}")
        for colour in args.colours:
            for kind in ("algebraic", "reported"):
                row = result[colour][kind]
                cells = "  ".join(f"{p}: bias {v['bias/crlb']:+.2f} rmse "
                                  f"{v['rmse/crlb']:.2f} cov {100 * v['coverage']:.0f}%"
                                  for p, v in row.items() if p != "median_cpu_s")
                print(f"  {colour:5} {kind:9} ({row['median_cpu_s']:.2f} s)  {cells}")
            print(f"  {colour:5} refined in {result[colour]['refined_applied']} of "
                  f"{args.runs}; otherwise: {result[colour]['not_refined_because']}")
        if args.json:
            with open(args.json, "w") as f:
                json.dump(out, f, indent=1)
    return out


if __name__ == "__main__":
    main()
