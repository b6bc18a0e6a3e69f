"""How close the automatic window of :func:`algid.identify` comes to the Cramér–Rao bound
(``PYTHONPATH=src:. python -m benchmarks.window_rule_study --runs N``).

Records of 30 s at 1 kHz of a lightly damped 1 Hz mode driven by a multisine
(0.1-5 Hz, 30 lines), with white output noise at 30 dB SNR (noise variance a thousandth
of the output's):

- ``linear``: ``y'' + B*y' + K*y = G*u + d`` (:data:`LINEAR`), simulated exactly (the
  multisine lines through the frequency response, plus the free response from the
  initial state by the matrix exponential of the state matrix);
- ``duffing``: ``y'' + B*y' + K*y + K3*y**3 = G*u + d`` (:data:`DUFFING`), integrated
  by ``scipy.integrate.solve_ivp`` (DOP853, relative tolerance 1e-11) with the analytic
  input.

The Cramér–Rao bound is that of white output noise with the initial state as a nuisance:
``sigma^2 (J^T J)^-1`` restricted to the parameter block, ``J`` the sensitivities of the
noise-free output to the parameters and the initial position and velocity (central
finite differences of the simulation).  Per parameter and realisation the study records
the algebraic estimate of ``identify`` (the default solver ``"bc"`` or ``--method``,
``refine=False``), its
reported standard error and the window chosen; it reports the bias, RMSE / CRLB, the rms
of error / reported standard error and the fraction of realisations within two reported
standard errors of the truth (±2σ coverage).  Targets: RMSE / CRLB at most 2 and
coverage at least 90 % for every parameter.

To compare the rule of another checkout, run this module with that checkout's ``src``
first on ``PYTHONPATH`` (``PYTHONPATH=/other/src:. python -m benchmarks.window_rule_study``).

Options: ``--runs N`` (default 50), ``--models linear duffing`` (default both),
``--window SECONDS`` (a fixed window instead of the automatic rule), ``--method
{bc,ls,gls}`` (``gls``: the windows weighed by their noise; the count of records where
it fell back to ``bc`` is ``reported_methods``), ``--out FILE`` (JSON).
"""

from __future__ import annotations

import argparse
import json
import time
from collections import Counter

import numpy as np
from scipy.linalg import expm

import algid
from algid.errors import AlgidError

__all__ = ["LINEAR", "DUFFING", "simulate", "sensitivities", "crlb", "study", "main"]

#: Sampling rate (Hz) and duration (s) of the records.
RATE, DURATION = 1000.0, 30.0

#: Output signal-to-noise ratio (dB): noise variance over the noise-free output's.
SNR_DB = 30.0

#: Seed of the multisine's phases (the same input in every realisation).
INPUT_SEED = 2024

#: Linear model: a 1 Hz mode (K = 40 rad^2/s^2), damping ratio 4.7 %, static gain 1.
LINEAR = {"equation": "y'' + B*y' + K*y = G*u + d", "parameters": "B K G d",
          "truth": {"B": 0.6, "K": 40.0, "G": 40.0, "d": 0.1}}

#: Duffing oscillator: the linear model with a hardening spring, ``K3 y^2`` about 25 %
#: of ``K`` at the peaks of the response.
DUFFING = {"equation": "y'' + B*y' + K*y + K3*y**3 = G*u + d",
           "parameters": "B K K3 G d",
           "truth": {"B": 0.6, "K": 40.0, "K3": 1.0, "G": 40.0, "d": 0.1}}

MODELS = {"linear": LINEAR, "duffing": DUFFING}

#: Target RMSE / CRLB and ±2σ coverage.
TARGET_RATIO, TARGET_COVERAGE = 2.0, 0.90


def multisine(seed=INPUT_SEED, f_low=0.1, f_high=5.0, count=30, rms=1.0):
    """Frequencies (Hz), phases and amplitude of the input multisine."""
    rng = np.random.default_rng(seed)
    freqs = np.linspace(f_low, f_high, count)
    return freqs, rng.uniform(0, 2 * np.pi, count), rms * np.sqrt(2.0 / count)


def _input(t, lines):
    freqs, phases, amp = lines
    t = np.atleast_1d(np.asarray(t, dtype=float))
    return amp * np.sin(2 * np.pi * np.outer(t, freqs) + phases).sum(axis=1)


def _linear_output(theta, x0, t, lines):
    """Exact response of ``y'' + B y' + K y = G u + d`` from the state ``x0`` at t = 0."""
    B, K, G, d = (theta[p] for p in ("B", "K", "G", "d"))
    freqs, phases, amp = lines
    w = 2 * np.pi * freqs
    H = G / (K - w ** 2 + 1j * B * w)
    # the particular solution: the lines through H and the constant d / K
    forced = amp * H * np.exp(1j * (np.outer(t, w) + phases))
    y_p = forced.imag.sum(axis=1) + d / K
    v_p = (1j * w * forced).imag.sum(axis=1)
    a = np.array([[0.0, 1.0], [-K, -B]])
    # the free response from x0 less the particular solution's state at t = 0
    e0 = np.asarray(x0, dtype=float) - np.array([y_p[0], v_p[0]])
    h = t[1] - t[0]
    step = expm(a * h)
    free = np.empty((len(t), 2))
    free[0] = e0
    for i in range(1, len(t)):   # exact on the uniform grid
        free[i] = step @ free[i - 1]
    return y_p + free[:, 0]


def _duffing_output(theta, x0, t, lines):
    """Response of the Duffing model by DOP853 (relative tolerance 1e-11)."""
    from scipy.integrate import solve_ivp

    B, K, K3, G, d = (theta[p] for p in ("B", "K", "K3", "G", "d"))

    def rhs(s, x):
        u = _input(s, lines)[0]
        return [x[1], G * u + d - B * x[1] - K * x[0] - K3 * x[0] ** 3]

    sol = solve_ivp(rhs, (t[0], t[-1]), x0, method="DOP853", t_eval=t, rtol=1e-11,
                    atol=1e-12, max_step=0.01)
    return sol.y[0]


def simulate(model, theta=None, x0=(0.0, 0.0), lines=None, *, rate=RATE, duration=DURATION):
    """Time, input and noise-free output of ``model`` (a dict of :data:`MODELS`),
    ``duration`` s at ``rate`` Hz."""
    theta = dict(model["truth"] if theta is None else theta)
    lines = multisine() if lines is None else lines
    t = np.arange(int(round(duration * rate)) + 1) / rate
    output = _duffing_output if "K3" in theta else _linear_output
    return t, _input(t, lines), output(theta, x0, t, lines)


def sensitivities(output, truth, x0, relative_step, state_steps):
    """Sensitivities of a simulated output by central differences: one column per
    parameter (step ``relative_step`` times its value, at least 1), then one per initial
    state (steps ``state_steps``).

    Parameters
    ----------
    output : callable
        ``output(theta, x0)`` -> the output samples (``theta`` a dict).
    truth : dict
        Parameter name -> value, where the differences are taken.
    x0 : sequence of float
        Initial state there.
    relative_step : float
    state_steps : sequence of float

    Returns
    -------
    numpy.ndarray, shape (samples, parameters + states)
    """
    columns = []
    for p in truth:
        h = relative_step * max(abs(truth[p]), 1.0)
        up, down = dict(truth), dict(truth)
        up[p] += h
        down[p] -= h
        columns.append((output(up, x0) - output(down, x0)) / (2 * h))
    for i, h in enumerate(state_steps):
        up, down = list(x0), list(x0)
        up[i] += h
        down[i] -= h
        columns.append((output(truth, up) - output(truth, down)) / (2 * h))
    return np.column_stack(columns)


def crlb(model, y, sigma, x0=(0.0, 0.0), relative_step=1e-5):
    """Cramér–Rao bound (standard deviations) of the parameters under white output noise
    of standard deviation ``sigma``, the initial state a nuisance.

    Central finite differences of the simulation for the sensitivities; the bound is
    ``sigma^2 (J^T J)^-1`` restricted to the parameters.
    """
    truth = model["truth"]
    names = list(truth)
    scale = max(float(np.max(np.abs(y))), 1e-12)
    J = sensitivities(lambda theta, state: simulate(model, theta, state)[2], truth, x0,
                      relative_step, [relative_step * scale * (1 if i == 0 else 2 * np.pi)
                                      for i in range(2)])   # position, velocity
    covariance = sigma ** 2 * np.linalg.inv(J.T @ J)
    return dict(zip(names, np.sqrt(np.diag(covariance))[:len(names)]))


def study(name, runs, window=None, method="bc"):
    """Monte Carlo figures of one model over ``runs`` noise realisations (``method`` of
    :func:`algid.identify`)."""
    model = MODELS[name]
    truth = model["truth"]
    t, u, y = simulate(model)
    sigma = float(np.std(y)) * 10 ** (-SNR_DB / 20)
    bound = crlb(model, y, sigma)
    estimates, stderrs, windows, refused, warned = [], [], Counter(), [], Counter()
    methods = Counter()
    start = time.perf_counter()
    for seed in range(runs):
        rng = np.random.default_rng(seed)
        record = {"t": t, "u": u, "y": y + sigma * rng.standard_normal(len(t))}
        try:
            r = algid.identify(record, model["equation"], model["parameters"], window=window,
                               refine=False, method=method)
        except AlgidError as error:
            refused.append(str(error))
            continue
        methods[r.method] += 1
        estimates.append([r.values[p] for p in truth])
        stderrs.append([r.stderr[p] for p in truth])
        windows[round(r.window, 4)] += 1
        for line in r.warnings:
            warned[line.split(":")[0]] += 1
    est, se = np.array(estimates), np.array(stderrs)
    value = np.array(list(truth.values()))
    rows = {}
    for i, p in enumerate(truth):
        if not len(est):
            break
        error = est[:, i] - value[i]
        rmse = float(np.sqrt(np.mean(error ** 2)))
        rows[p] = {"truth": value[i], "crlb": bound[p], "bias": float(np.mean(error)),
                   "rmse": rmse, "rmse_over_crlb": rmse / bound[p],
                   "z_rms": float(np.sqrt(np.mean((error / se[:, i]) ** 2))),
                   "coverage": float(np.mean(np.abs(error) <= 2 * se[:, i]))}
    return {"model": name, "runs": runs, "identified": len(est), "sigma": sigma,
            "window": window, "method": method, "reported_methods": dict(methods),
            "parameters": rows,
            "windows": {str(k): v for k, v in sorted(windows.items())},
            "refusals": len(refused), "refused": refused[:3], "warnings": dict(warned),
            "seconds": time.perf_counter() - start}


def report(row):
    """Lines of the table of one model."""
    lines = [f"{row['model']}: {row['identified']}/{row['runs']} identified, "
             f"{row['refusals']} refused, {sum(row['warnings'].values())} warnings, "
             f"{row['seconds']:.0f} s; windows (s: count) {row['windows']}",
             f"{'param':<6} {'truth':>8} {'CRLB':>9} {'bias':>10} {'bias/CRLB':>9} "
             f"{'RMSE/CRLB':>9} {'z rms':>6} {'cover':>6}"]
    for p, v in row["parameters"].items():
        ok = v["rmse_over_crlb"] <= TARGET_RATIO and v["coverage"] >= TARGET_COVERAGE
        lines.append(f"{p:<6} {v['truth']:>8.4g} {v['crlb']:>9.3g} {v['bias']:>10.3g} "
                     f"{v['bias'] / v['crlb']:>9.2f} {v['rmse_over_crlb']:>9.2f} "
                     f"{v['z_rms']:>6.2f} {v['coverage']:>6.1%}{'' if ok else '  *'}")
    return lines


def main(argv=None):
    """Run the study and print its table (and JSON with ``--out``)."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.window_rule_study")
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--models", nargs="*", default=list(MODELS), choices=list(MODELS))
    parser.add_argument("--window", type=float, default=None)
    parser.add_argument("--method", default="bc", choices=("bc", "ls", "gls"))
    parser.add_argument("--out", default=None)
    args = parser.parse_args(argv)
    print(f"algid from {algid.__file__}; {RATE:g} Hz, {DURATION:g} s, {SNR_DB:g} dB SNR; "
          f"targets RMSE/CRLB <= {TARGET_RATIO:g}, coverage >= {TARGET_COVERAGE:.0%} "
          f"(* missed)")
    results = []
    for name in args.models:
        row = study(name, args.runs, args.window, args.method)
        results.append(row)
        print("\n".join(report(row)), flush=True)
    if args.out:
        with open(args.out, "w") as handle:
            json.dump({"algid": algid.__file__, "results": results}, handle, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
