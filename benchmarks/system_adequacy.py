"""Hits and false alarms of the residual test of a refined system
(``PYTHONPATH=src:. python -m benchmarks.system_adequacy --runs 30``).

The two coupled masses of :mod:`benchmarks.systems_study` (``m1*x1'' + c1*x1' + k1*x1 +
k2*(x1 - x2) = u``, ``m2*x2'' + c2*x2' + k2*(x2 - x1) = 0``; 20 s at 1 kHz, 40 dB of
white noise on both positions, the study's multisine) fitted with that system to
records of it and of variants: an offset in the first equation (``= u + 0.5``), a cubic
spring on the first mass (``+ 300*x1**3``), ``x2`` 3 samples late, a force growing
with time in the first equation (``+ 0.02*t``), and AR(1) output noise of pole 0.9 on
the right system.  Per class,
``--runs`` noise realisations (seeds 1000 ..) identified with the default
``refine="auto"``; a row counts the records whose result warns and those whose first
warning names the class's cause (right systems must stay silent).  The records come from
DOP853 at 1e-11 on a cubic spline of the input.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline
from scipy.signal import lfilter

import algid
from benchmarks.residual_adequacy import command_line, tally
from benchmarks.systems_study import RATE, SNR_DB, SYSTEMS

SPEC = SYSTEMS["two_mass"]

#: class -> (the truth's changes, the cause's words in the first warning)
CASES = {
    "right": ({}, None),
    "right, AR(1) noise": ({"colour": True}, None),
    "offset missing in equation 1": ({"offset": 0.5}, "offset"),
    "cubic spring missing in equation 1": ({"cubic": 300.0}, "x1**3"),
    "x2 3 samples late": ({"shift": 3}, "x2 simulated delayed"),
    "slow drift of the force": ({"drift": 0.02}, "drift"),
}


def clean_record(offset=0.0, cubic=0.0, drift=0.0, **_):
    """The noise-free record of the two masses with the class's changes."""
    truth = SPEC["truth"]
    t = np.arange(0, SPEC["duration"], 1 / RATE)
    phases = np.random.default_rng(12345).uniform(0, 2 * np.pi, len(SPEC["lines"]))
    u = np.sum(np.sin(2 * np.pi * np.array(SPEC["lines"])[:, None] * t + phases[:, None]),
               axis=0)
    spline = CubicSpline(t, u)

    def rhs(time_, x):
        x1, v1, x2, v2 = x
        force = spline(time_) + offset + drift * time_ - truth["c1"] * v1 - truth["k1"] * x1 \
            - cubic * x1 ** 3 - truth["k2"] * (x1 - x2)
        return [v1, force / truth["m1"], v2,
                (-truth["c2"] * v2 - truth["k2"] * (x2 - x1)) / truth["m2"]]

    x = solve_ivp(rhs, (t[0], t[-1]), SPEC["x0"], t_eval=t, method="DOP853", rtol=1e-11,
                  atol=1e-14).y
    return {"t": t, "u": u, "x1": x[0], "x2": x[2]}


def record(clean, seed, colour=False, shift=0, **_):
    """One realisation: 40 dB of white (or AR(1)) noise on each position."""
    rng = np.random.default_rng(seed)
    out = dict(clean)
    for name in ("x1", "x2"):
        e = rng.standard_normal(len(clean[name]))
        if colour:
            e = lfilter([1.0], [1.0, -0.9], e) * np.sqrt(1 - 0.81)
        out[name] = clean[name] + 10 ** (-SNR_DB / 20) * float(np.std(clean[name])) * e
    if shift:
        out["x2"] = np.concatenate([np.full(shift, out["x2"][0]), out["x2"][:-shift]])
    return out


def study(runs, names=None):
    """Per class: warned, named (the first warning names the cause), refined."""
    out = {}
    for name in names or CASES:
        changes, cause = CASES[name]
        clean = clean_record(**changes)
        results = (algid.identify(record(clean, seed, **changes), SPEC["equations"],
                                  list(SPEC["truth"])) for seed in range(1000, 1000 + runs))
        out[name] = tally(name, results, cause, runs)
    return out


def main(argv=None):
    """Print the table (and write it with ``--json FILE``)."""
    return command_line(study, __doc__, argv)


if __name__ == "__main__":
    main()
