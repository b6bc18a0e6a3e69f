"""Monte Carlo of identify's algebraic and refined estimates against the Cramér–Rao bound
(``PYTHONPATH=src:. python -m benchmarks.refinement_study --runs 100``).

The linear model ``y'' + B*y' + K*y = G*u + d`` (B = 0.6, K = 40, G = 40, d = 0.5: a
mode at 1 Hz, damping ratio 0.05) driven by a multisine of 12 lines from 0.1 to 5 Hz,
30 s at 1 kHz from a nonzero initial state, simulated by :func:`algid.simulate_model`
(DOP853, relative tolerance 1e-10); output noise at 30 dB SNR, white or AR(1) of pole
0.9 (the same variance).  Per noise and parameter: bias and RMSE over the runs in units
of the Cramér–Rao bound (white output noise, the initial state as nuisance:
``sigma^2 (J'J)^-1`` with ``J`` the output's sensitivities at the truth, the initial
state projected out), and the coverage of +-2 reported standard errors, for
``identify(refine=False)`` and ``identify()`` (refined); the median CPU time of each.
Under AR(1) noise the bound is still the white-noise one: it shows the loss of an
output-error fit that ignores the noise's colour (its coverage is what must hold).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

import algid
from algid.identification._output_error import prepare, projected_jacobian
from algid.identification._records import Segment
from algid.models import parse_equation

EQUATION = ("y'' + B*y' + K*y = G*u + d", "B K G d")
TRUTH = {"B": 0.6, "K": 40.0, "G": 40.0, "d": 0.5}
RATE, DURATION, SNR_DB, AR_POLE = 1000.0, 30.0, 30.0, 0.9
BAND, LINES, SEED = (0.1, 5.0), 12, 2024

#: ``--holdout``: a plant, input, rate and noise level nothing was tuned on (a 2.3 Hz
#: mode of damping 0.11, 8 lines from 0.3 to 9 Hz, 20 s at 400 Hz, 20 dB)
HOLDOUT = {"TRUTH": {"B": 3.2, "K": 210.0, "G": 150.0, "d": -0.8}, "RATE": 400.0,
           "DURATION": 20.0, "SNR_DB": 20.0, "AR_POLE": 0.7, "BAND": (0.3, 9.0),
           "LINES": 8, "SEED": 7}


def noise_free():
    """The record's time, input and noise-free output."""
    rng = np.random.default_rng(SEED)
    t = np.arange(int(DURATION * RATE)) / RATE
    freqs = np.geomspace(*BAND, LINES)
    u = sum(np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi)) for f in freqs)
    model = parse_equation(*EQUATION)
    y = algid.simulate_model(model, TRUTH, t, {"u": u}, initial_state=[0.05, -0.2],
                             rtol=1e-10, atol=1e-14)
    return t, u, y


def cramer_rao(t, u, y, sigma):
    """Standard deviations of the Cramér–Rao bound at the truth, white noise ``sigma``:
    ``sigma^2 (J'J)^-1`` with the initial state projected out of the sensitivities."""
    model = parse_equation(*EQUATION)
    seg = Segment(0, np.arange(len(t)), t, {"u": u, "y": y}, 1.0 / RATE)
    theta = np.array([TRUTH[p] for p in model.parameters])
    data = prepare(model, [seg], 1.0 / RATE)
    J, _ = projected_jacobian(data, theta, np.abs(theta) * 1e-3)
    J = J * data.output_scale     # (the records are scaled to unit size inside)
    return np.sqrt(np.diag(np.linalg.inv(J.T @ J))) * sigma


def noise(rng, n, sigma, colour):
    """White or AR(1) noise of standard deviation ``sigma``."""
    e = rng.standard_normal(n)
    if colour == "white":
        return sigma * e
    from scipy.signal import lfilter
    x = lfilter([1.0], [1.0, -AR_POLE], e)
    return sigma * x / np.sqrt(1.0 / (1.0 - AR_POLE ** 2))


def study(runs, colours=("white", "ar1")):
    """The table, as a dict."""
    t, u, y = noise_free()
    sigma = np.sqrt(np.mean(y ** 2)) / 10 ** (SNR_DB / 20)
    bound = cramer_rao(t, u, y, sigma)
    names = EQUATION[1].split()
    truth = np.array([TRUTH[p] for p in names])
    out = {"crlb": dict(zip(names, bound.tolist())), "runs": runs}
    for colour in colours:
        rows = {"algebraic": [], "refined": []}
        cpu = {"algebraic": [], "refined": []}
        applied = 0
        for seed in range(runs):
            rng = np.random.default_rng(seed)
            record = {"t": t, "u": u, "y": y + noise(rng, len(t), sigma, colour)}
            for kind, refine in (("algebraic", False), ("refined", "auto")):
                start = time.process_time()
                r = algid.identify(record, *EQUATION, refine=refine)
                cpu[kind].append(time.process_time() - start)
                rows[kind].append([[r.values[p], r.stderr[p]] for p in names])
                applied += kind == "refined" and r.estimate == "refined"
        table = {}
        for kind, values in rows.items():
            a = np.array(values)            # runs x params x (value, stderr)
            err = a[:, :, 0] - truth
            table[kind] = {p: {"bias/crlb": float(np.mean(err[:, i]) / bound[i]),
                               "rmse/crlb": float(np.sqrt(np.mean(err[:, i] ** 2)) / bound[i]),
                               "coverage": float(np.mean(np.abs(err[:, i])
                                                         <= 2 * a[:, i, 1]))}
                           for i, p in enumerate(names)}
            table[kind]["median_cpu_s"] = float(np.median(cpu[kind]))
        table["refined_applied"] = applied
        out[colour] = table
    return out


def main(argv=None):
    """Print the table (and write it with ``--json FILE``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--json", default=None)
    parser.add_argument("--holdout", action="store_true",
                        help="the plant, input and noise of HOLDOUT instead")
    args = parser.parse_args(argv)
    if args.holdout:
        globals().update(HOLDOUT)
    out = study(args.runs)
    print(f"CRLB: {', '.join(f'{p} {v:.3g}' for p, v in out['crlb'].items())}")
    for colour in ("white", "ar1"):
        for kind in ("algebraic", "refined"):
            row = out[colour][kind]
            cells = "  ".join(f"{p}: bias {v['bias/crlb']:+.2f} rmse {v['rmse/crlb']:.2f} "
                              f"cov {100 * v['coverage']:.0f}%"
                              for p, v in row.items() if p != "median_cpu_s")
            print(f"{colour:5} {kind:9} ({row['median_cpu_s']:.2f} s)  {cells}")
        print(f"{colour:5} refined applied in {out[colour]['refined_applied']} of {args.runs}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    return out


if __name__ == "__main__":
    main()
