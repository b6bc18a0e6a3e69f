"""Monte Carlo of identify on systems of equations against the Cramér–Rao bound
(``PYTHONPATH=src:. python -m benchmarks.systems_study --runs 50 --json
benchmarks/systems_results.json``).

Two systems, 1 kHz, white noise on every measured output at 40 dB SNR (each output's
own level), the same input in every run (a multisine), the noise drawn anew:

- ``two_mass``: ``m1*x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u`` and
  ``m2*x2'' + c2*x2' + k2*(x2 - x1) = 0`` (m1 1, c1 0.5, k1 20, k2 15, m2 0.8, c2 0.3:
  modes at 0.5 and 1.1 Hz), both positions measured, 20 s; a multisine of 8 lines from
  0.2 to 3 Hz;
- ``two_mass_hidden``: the same records with ``x1`` hidden (not given to identify) and
  ``m1 = 1`` known (written in the equation): ``hidden=["x1"]``, five parameters;
- ``dc_motor``: ``L*i' + R*i + K*w = u`` and ``J*w' + b*w = K*i`` (L 0.5, R 2, K 0.8,
  J 0.2, b 0.1), current and speed measured, 10 s; 7 lines from 0.1 to 5 Hz;
- ``three_mass_hidden`` (only with ``--systems``): a chain of three masses, the first
  position hidden and ``m1 = 1`` known, eight parameters (modes at 0.69, 1.61 and
  2.31 Hz), 20 s at 500 Hz, 8 lines from 0.2 to 3.5 Hz;
- ``two_mass_cubic`` (only with ``--systems``): the two masses with a hardening spring
  ``k3*x1**3`` on the first (k3 200, about three times k1's force at the record's
  spread), both positions measured, 12 s at 500 Hz, the multisine three times larger.

``--ar-pole 0.9`` makes the output noise AR(1) of that pole (the same variance).

``--holdout`` runs the same three with other values, inputs and noise (30 dB): two
masses m1 2, c1 0.2, k1 50, k2 10, m2 0.5, c2 0.6 on 15 s of 10 lines from 0.1 to
4.2 Hz (with ``x1`` hidden, ``m1 = 2`` known), a motor L 0.05, R 1.2, K 0.3, J 0.01,
b 0.02 on 8 s of 7 lines from 0.5 to 21 Hz; the cubic two masses with the hardening
spring ``k3*x2**3`` on the second (k3 300) and the holdout masses' values, 15 s at
500 Hz of the holdout's lines, four times larger.

The records come from DOP853 at a relative tolerance of 1e-11 on a cubic spline of the
input, not from algid's simulator.  Per system and parameter: bias and RMSE over the
runs (relative, and in units of the Cramér–Rao bound: white noise of the true levels,
the initial state as nuisance, the Jacobian of algid's exact simulation of the
noise-free record by central differences; of its compiled fixed-step one for a
nonlinear system), the ratio of the spread to the mean
reported standard error, the coverage of ±2 reported standard errors, for the algebraic
estimate (``result.algebraic``) and the reported one (refined where applied); the
largest difference between the Monte Carlo correlation matrix of the reported estimate
and the mean reported one, beside the sampling error of a correlation over that many
runs (``(1 - rho^2) / sqrt(runs)``), and the rms over the pairs of the difference of
their Fisher transforms in units of its sampling error (``1/sqrt(runs - 3)``): about 1
where the reported correlations are those of the estimates; the median CPU time.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline
from scipy.signal import lfilter

import algid
from algid.identification._records import prepare_records
from algid.identification._system_refinement import SimulationResiduals, central_jacobian
from algid.models import parse_system
from algid.simulation._fast_simulation import FastSystemSimulation
from algid.simulation._system_equations import SystemEquations

SNR_DB = 40.0
RATE = 1000.0

SYSTEMS = {
    "two_mass": {
        "equations": ["m1*x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u",
                      "m2*x2'' + c2*x2' + k2*(x2 - x1) = 0"],
        "truth": {"m1": 1.0, "c1": 0.5, "k1": 20.0, "k2": 15.0, "m2": 0.8, "c2": 0.3},
        "duration": 20.0, "lines": [0.2, 0.45, 0.7, 0.95, 1.3, 1.7, 2.2, 3.0],
        "x0": [0.01, 0.0, -0.02, 0.0]},
    "two_mass_hidden": {
        "equations": ["x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u",
                      "m2*x2'' + c2*x2' + k2*(x2 - x1) = 0"],
        "truth": {"c1": 0.5, "k1": 20.0, "k2": 15.0, "m2": 0.8, "c2": 0.3},
        "duration": 20.0, "lines": [0.2, 0.45, 0.7, 0.95, 1.3, 1.7, 2.2, 3.0],
        "x0": [0.01, 0.0, -0.02, 0.0], "hidden": ["x1"]},
    "dc_motor": {
        "equations": ["L*i' + R*i + K*w = u", "J*w' + b*w = K*i"],
        "truth": {"L": 0.5, "R": 2.0, "K": 0.8, "J": 0.2, "b": 0.1},
        "duration": 10.0, "lines": [0.1, 0.3, 0.6, 1.1, 1.9, 3.1, 5.0],
        "x0": [0.0, 0.0]},
    "three_mass_hidden": {   # (not in the default run: about 20 s a fit)
        "equations": ["x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u",
                      "m2*x2'' + c2*x2' + k2*(x2 - x1) + k3*(x2 - x3) = 0",
                      "m3*x3'' + c3*x3' + k3*(x3 - x2) = 0"],
        "truth": {"c1": 1.0, "k1": 80.0, "k2": 60.0, "m2": 0.8, "c2": 0.6, "k3": 40.0,
                  "m3": 0.6, "c3": 0.4},
        "duration": 20.0, "rate": 500.0, "lines": [0.2, 0.45, 0.75, 1.1, 1.5, 2.0, 2.6, 3.5],
        "x0": [0.005, 0.0, -0.005, 0.0, 0.005, 0.0], "hidden": ["x1"]},
    "two_mass_cubic": {   # (not in the default run: about 4 s a fit, nonlinear)
        "equations": ["m1*x1'' + c1*x1' + k1*x1 + k3*x1**3 + k2*(x1 - x2) = u",
                      "m2*x2'' + c2*x2' + k2*(x2 - x1) = 0"],
        "truth": {"m1": 1.0, "c1": 0.5, "k1": 20.0, "k3": 200.0, "k2": 15.0, "m2": 0.8,
                  "c2": 0.3},
        "duration": 12.0, "rate": 500.0, "gain": 3.0,
        "lines": [0.2, 0.45, 0.7, 0.95, 1.3, 1.7, 2.2, 3.0], "x0": [0.01, 0.0, -0.02, 0.0]},
}

#: The systems of the default run.
DEFAULT_SYSTEMS = ("two_mass", "two_mass_hidden", "dc_motor")


HOLDOUT_SNR_DB = 30.0

HOLDOUT = {
    "two_mass": {
        "equations": SYSTEMS["two_mass"]["equations"],
        "truth": {"m1": 2.0, "c1": 0.2, "k1": 50.0, "k2": 10.0, "m2": 0.5, "c2": 0.6},
        "duration": 15.0, "lines": [0.1, 0.3, 0.5, 0.8, 1.2, 1.6, 2.1, 2.7, 3.4, 4.2],
        "x0": [0.0, 0.05, 0.01, 0.0]},
    "two_mass_hidden": {
        "equations": ["2*x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u",
                      "m2*x2'' + c2*x2' + k2*(x2 - x1) = 0"],
        "truth": {"c1": 0.2, "k1": 50.0, "k2": 10.0, "m2": 0.5, "c2": 0.6},
        "duration": 15.0, "lines": [0.1, 0.3, 0.5, 0.8, 1.2, 1.6, 2.1, 2.7, 3.4, 4.2],
        "x0": [0.0, 0.05, 0.01, 0.0], "hidden": ["x1"]},
    "dc_motor": {
        "equations": SYSTEMS["dc_motor"]["equations"],
        "truth": {"L": 0.05, "R": 1.2, "K": 0.3, "J": 0.01, "b": 0.02},
        "duration": 8.0, "lines": [0.5, 1.3, 2.9, 5.1, 8.7, 13.0, 21.0], "x0": [0.0, 0.0]},
    "two_mass_cubic": {
        "equations": ["m1*x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u",
                      "m2*x2'' + c2*x2' + k2*(x2 - x1) + k3*x2**3 = 0"],
        "truth": {"m1": 2.0, "c1": 0.2, "k1": 50.0, "k2": 10.0, "m2": 0.5, "c2": 0.6,
                  "k3": 300.0},
        "duration": 15.0, "rate": 500.0, "gain": 4.0,
        "lines": [0.1, 0.3, 0.5, 0.8, 1.2, 1.6, 2.1, 2.7, 3.4, 4.2], "x0": [0.0, 0.05, 0.01, 0.0]},
}


def noise_free(spec):
    """The noise-free record of a system (DOP853 at 1e-11)."""
    t = np.arange(0, spec["duration"], 1 / spec.get("rate", RATE))
    phases = np.random.default_rng(12345).uniform(0, 2 * np.pi, len(spec["lines"]))
    u = spec.get("gain", 1.0) * np.sum(
        np.sin(2 * np.pi * np.array(spec["lines"])[:, None] * t + phases[:, None]), axis=0)
    system = parse_system(spec["equations"], list(spec["truth"]))
    spline = CubicSpline(t, u)
    if not system.is_linear:
        equations = SystemEquations(system, spec["truth"])
        x = solve_ivp(lambda time_, x: equations.derivative(time_, x, [spline(time_)]),
                      (t[0], t[-1]), spec["x0"], t_eval=t, method="DOP853", rtol=1e-11,
                      atol=1e-14).y
        record = {"t": t, "u": u}
        for y in system.outputs:
            record[y] = x[equations.states.index((y, 0))]
        return record, system.outputs
    space = algid.simulation._system.state_space(system, spec["truth"])
    col = space.channels.index("u")

    def rhs(time_, x):
        return space.A @ x + space.B[:, col] * spline(time_)

    x = solve_ivp(rhs, (t[0], t[-1]), spec["x0"], t_eval=t, method="DOP853", rtol=1e-11,
                  atol=1e-14).y
    record = {"t": t, "u": u}
    for j, y in enumerate(space.outputs):
        record[y] = space.C[j] @ x
    return record, space.outputs


def cramer_rao(spec, record, outputs, sigma):
    """The Cramér–Rao bound (standard deviations) at the truth, initial state nuisance."""
    system = parse_system(spec["equations"], list(spec["truth"]))
    segments, _, _ = prepare_records(record, system.signals, time="t")
    observed = [y for y in outputs if y not in spec.get("hidden", ())]
    theta = np.array(list(spec["truth"].values()))
    if not system.is_linear:
        return _nonlinear_cramer_rao(system, record, theta, spec["x0"], sigma)
    residuals = SimulationResiduals(system, segments, {y: sigma[y] for y in observed},
                                    observed)
    J = central_jacobian(residuals, theta, 1e-4 * np.abs(theta))
    return np.sqrt(np.diag(np.linalg.inv(J.T @ J)))


def _nonlinear_cramer_rao(system, record, theta, x0, sigma):
    """The bound of a nonlinear system: the Jacobian of the compiled simulation (every
    output over its noise level) in the parameters and the initial state, by central
    differences; the initial state's block as nuisance."""
    simulation = FastSystemSimulation(system, record["t"], record)
    weights = np.array([1.0 / sigma[y] for y in system.outputs])[:, None]
    point = np.concatenate([theta, x0])
    steps = 1e-4 * np.maximum(np.abs(point), 1e-3)
    columns = []
    for k, h in enumerate(steps):
        up, down = point.copy(), point.copy()
        up[k] += h
        down[k] -= h
        columns.append(((simulation.run(up[:len(theta)], up[len(theta):])
                         - simulation.run(down[:len(theta)], down[len(theta):]))
                        * weights).ravel() / (2 * h))
    J = np.column_stack(columns)
    return np.sqrt(np.diag(np.linalg.inv(J.T @ J))[:len(theta)])


def study(spec, runs, snr_db=SNR_DB, pole=0.0):
    """The Monte Carlo of one system (a value of :data:`SYSTEMS`); ``pole``: the output
    noise AR(1) of that pole, of the same variance (0: white)."""
    clean, outputs = noise_free(spec)
    sigma = {y: 10 ** (-snr_db / 20) * float(np.std(clean[y])) for y in outputs}
    bound = cramer_rao(spec, clean, outputs, sigma)
    truth = np.array(list(spec["truth"].values()))
    reported, reported_se, algebraic, algebraic_se, corr, kinds, cpu = [], [], [], [], [], [], []
    for run in range(runs):
        rng = np.random.default_rng(1000 + run)
        record = dict(clean)
        for y in outputs:
            e = rng.standard_normal(len(clean[y]))
            if pole:
                e = lfilter([np.sqrt(1 - pole ** 2)], [1.0, -pole], e)
            record[y] = clean[y] + sigma[y] * e
        for y in spec.get("hidden", ()):
            del record[y]
        start = time.process_time()
        result = algid.identify(record, spec["equations"], list(spec["truth"]),
                                hidden=spec.get("hidden"))
        cpu.append(time.process_time() - start)
        reported.append([result.values[p] for p in spec["truth"]])
        reported_se.append([result.stderr[p] for p in spec["truth"]])
        algebraic.append([result.algebraic["values"][p] for p in spec["truth"]])
        algebraic_se.append(np.sqrt(np.diag(result.algebraic["covariance"])))
        corr.append(result.correlation)
        kinds.append(result.estimate)

    def table(est, se):
        est, se = np.array(est), np.array(se)
        error = est - truth
        return {"bias_percent": (100 * error.mean(0) / truth).tolist(),
                "bias_over_crlb": (error.mean(0) / bound).tolist(),
                "rmse_over_crlb": (np.sqrt(np.mean(error ** 2, 0)) / bound).tolist(),
                "spread_over_stderr": (est.std(0) / se.mean(0)).tolist(),
                "coverage_2se": np.mean(np.abs(error) <= 2 * se, axis=0).tolist()}

    rho = np.corrcoef(np.array(reported).T)
    mean_corr = np.mean(corr, axis=0)
    upper = np.triu_indices(len(truth), 1)
    return {"parameters": list(spec["truth"]), "runs": runs,
            "crlb": bound.tolist(),
            "refined_runs": kinds.count("refined"),
            "reported": table(reported, reported_se),
            "algebraic": table(algebraic, algebraic_se),
            "correlation_max_difference": float(np.max(np.abs(rho - mean_corr)[upper])),
            "correlation_sampling_error": float(np.max(
                (1 - mean_corr[upper] ** 2) / np.sqrt(runs))),
            "correlation_fisher_z_rms": float(np.sqrt(np.mean(
                ((np.arctanh(rho[upper]) - np.arctanh(mean_corr[upper]))
                 * np.sqrt(runs - 3)) ** 2))),
            "median_cpu_s": float(np.median(cpu))}


def main(argv=None):
    """Print the tables (and write them with ``--json FILE``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--systems", nargs="+", choices=list(SYSTEMS),
                        default=list(DEFAULT_SYSTEMS))
    parser.add_argument("--json", default=None)
    parser.add_argument("--ar-pole", type=float, default=0.0,
                        help="AR(1) output noise of this pole, same variance (0: white)")
    parser.add_argument("--holdout", action="store_true",
                        help="other values, inputs and noise (30 dB)")
    args = parser.parse_args(argv)
    specs, snr_db = (HOLDOUT, HOLDOUT_SNR_DB) if args.holdout else (SYSTEMS, SNR_DB)
    if any(name not in specs for name in args.systems):
        parser.error(f"--holdout has {', '.join(HOLDOUT)} only")
    out = {}
    for name in args.systems:
        out[name] = result = study(specs[name], args.runs, snr_db, args.ar_pole)
        print(f"{name}: {args.runs} runs, refined in {result['refined_runs']}, median CPU "
              f"{result['median_cpu_s']:.2f} s")
        for kind in ("algebraic", "reported"):
            print(f"  {kind}")
            for key, values in result[kind].items():
                print(f"    {key:20s}" + " ".join(f"{v:8.3g}" for v in values))
        print(f"  correlation: max |MC - reported| {result['correlation_max_difference']:.3f}"
              f" (sampling error up to {result['correlation_sampling_error']:.3f}; Fisher z "
              f"rms {result['correlation_fisher_z_rms']:.2f} sampling errors)")
        if args.json:
            with open(args.json, "w") as f:
                json.dump(out, f, indent=1)
    return out


if __name__ == "__main__":
    main()
