"""Hits and false alarms of the residual test of a refined system
(``PYTHONPATH=src:. python -m benchmarks.system_adequacy --runs 30``).

The two coupled masses of :mod:`benchmarks.systems_study` (``m1*x1'' + c1*x1' + k1*x1 +
k2*(x1 - x2) = u``, ``m2*x2'' + c2*x2' + k2*(x2 - x1) = 0``; 20 s at 1 kHz, 40 dB of
white noise on both positions, the study's multisine) fitted with that system to
records of it and of variants: an offset in the first equation (``= u + 0.5``), a cubic
spring on the first mass (``+ 300*x1**3``), ``x2`` 3 samples late, a force growing
with time in the first equation (``+ 0.02*t``), and AR(1) output noise of pole 0.9 on
the right system.  The cubic two masses of :mod:`benchmarks.systems_study`
(``two_mass_cubic``: a hardening spring ``k3*x1**3``, 12 s at 500 Hz; refined by the
compiled simulation) likewise, with an offset in the first equation, ``x2`` 3 samples
late, a ``tanh`` damping of the first mass (``+ 0.3*tanh(3*x1')``) or a quadratic one
of the second (``+ 0.3*x2'*|x2'|``), or a quintic spring on the first (``+
500*x1**5``) that the equations lack (none of the last three is a candidate of the
test: the cause of the first two is "the system misses the records", the third's is
never named).  Per class,
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

#: class -> (the truth's changes, the cause's words in the first warning)
CASES = {
    "right": ({}, None),
    "right, AR(1) noise": ({"colour": True}, None),
    "offset missing in equation 1": ({"offset": 0.5}, "offset"),
    "cubic spring missing in equation 1": ({"cubic": 300.0}, "x1**3"),
    "x2 3 samples late": ({"shift": 3}, "x2 simulated delayed"),
    "slow drift of the force": ({"drift": 0.02}, "drift"),
    "cubic system: right": ({"system": "two_mass_cubic"}, None),
    "cubic system: right, AR(1) noise": ({"system": "two_mass_cubic", "colour": True}, None),
    "cubic system: offset missing in equation 1": (
        {"system": "two_mass_cubic", "offset": 0.5}, "offset"),
    "cubic system: x2 3 samples late": (
        {"system": "two_mass_cubic", "shift": 3}, "x2 simulated delayed"),
    "cubic system: tanh damping missing in equation 1": (
        {"system": "two_mass_cubic", "tanh": 0.3}, "the system misses the records"),
    "cubic system: quadratic damping missing in equation 2": (
        {"system": "two_mass_cubic", "quadratic": 0.3}, "the system misses the records"),
    "cubic system: quintic spring missing in equation 1": (
        {"system": "two_mass_cubic", "quintic": 500.0}, "x1**5"),
}


def clean_record(offset=0.0, cubic=0.0, drift=0.0, system="two_mass", tanh=0.0,
                 quadratic=0.0, quintic=0.0, **_):
    """The noise-free record of the system with the class's changes."""
    spec = SYSTEMS[system]
    truth = dict(spec["truth"])
    t = np.arange(0, spec["duration"], 1 / spec.get("rate", RATE))
    phases = np.random.default_rng(12345).uniform(0, 2 * np.pi, len(spec["lines"]))
    u = spec.get("gain", 1.0) * np.sum(
        np.sin(2 * np.pi * np.array(spec["lines"])[:, None] * t + phases[:, None]), axis=0)
    spline = CubicSpline(t, u)
    cubic += truth.get("k3", 0.0)

    def rhs(time_, x):
        x1, v1, x2, v2 = x
        force = spline(time_) + offset + drift * time_ - truth["c1"] * v1 - truth["k1"] * x1 \
            - cubic * x1 ** 3 - truth["k2"] * (x1 - x2) - tanh * np.tanh(3 * v1) \
            - quintic * x1 ** 5
        return [v1, force / truth["m1"], v2,
                (-truth["c2"] * v2 - truth["k2"] * (x2 - x1) - quadratic * v2 * abs(v2))
                / truth["m2"]]

    x = solve_ivp(rhs, (t[0], t[-1]), spec["x0"], t_eval=t, method="DOP853", rtol=1e-11,
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
        spec = SYSTEMS[changes.get("system", "two_mass")]
        results = (algid.identify(record(clean, seed, **changes), spec["equations"],
                                  list(spec["truth"])) for seed in range(1000, 1000 + runs))
        out[name] = tally(name, results, cause, runs)
    return out


def main(argv=None):
    """Print the table (and write it with ``--json FILE``)."""
    return command_line(study, __doc__, argv)


if __name__ == "__main__":
    main()
