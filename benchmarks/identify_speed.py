"""``identify`` against an output-error fit (``python -m benchmarks.identify_speed``).

On the same records, in one process:

1. Speed and simulation error.  :func:`algid.identify` (automatic window) against an
   output-error fit: ``scipy.optimize.least_squares`` over the parameters and the
   initial state, started from the algebraic estimate, each residual a simulation of
   the model (:func:`algid.simulation.simulate_model` with ``method="RK4"``, 4
   sub-steps per sample), with a cubic-spline input on Silverbox and a
   band-limited one on the synthetic multisines: a spline of their 15 Hz lines at
   80 Hz sampling adds errors that the output-error fit absorbs into its parameters).
   Records: Silverbox (identified on rows [40650, 105712), validated on the arrow part
   [100, 40575), when the data folder is present) and the synthetic linear and cubic records of
   :mod:`benchmarks.synthetic_records` (validated on a second noise realisation).
   Reported: the time ratio (output-error time / identify time) and the ratio of the
   validation simulation errors (identify / output-error).  Target: at least 20x
   faster at a simulation error within 1.3x.
2. Monte Carlo on the synthetic records (linear with offsets, the same with 5 % of
   its rows missing, cubic spring, friction under a position loop): RMSE of
   ``identify`` (default solver, the bias-compensated least squares) next to that of the
   output-error fit on the first ``--oe-runs`` realisations (every record) and to the
   Cramer-Rao bound (linear record with offsets; also plain least squares and
   instrumental variables); target within 3x of the bound where it is computed, else
   of the output-error fit.  And the ratio of the spread of the estimates to the mean
   reported standard error (every record; target within 1.5x).

Options: ``--runs N`` (Monte Carlo realisations, default 50), ``--oe-runs N``
(realisations with an output-error fit, default 20), ``--no-silverbox``,
``--smoke`` (tiny sizes, seconds), ``--out FILE`` (JSON).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

import algid
from algid.simulation._model import fit_initial_state, simulate_model
from benchmarks.synthetic_records import (
    CUBIC_EQUATION,
    FRICTION_EQUATION,
    LINEAR_EQUATION,
    cubic_spring,
    friction_loop,
    linear_gaps,
    linear_offsets,
)

ROOT = Path(__file__).resolve().parent.parent
DATA_FOLDERS = (ROOT.parent / "shared" / "data", Path("/work/shared/data"))
SILVERBOX = ("V2'' + B*V2' + K*V2 + K3*V2**3 = G*V1 + d", "B K K3 G d")


def output_error_fit(result, record, *, substeps=4, interpolation="cubic"):
    """Output-error least squares over parameters and initial state, from ``result``.

    Returns
    -------
    dict
        Parameter name -> value.
    """
    model = result.model
    names = model.parameters
    seg_t = np.asarray(record["t"], dtype=float)
    inputs = {name: np.asarray(record[name], dtype=float) for name in model.inputs}
    y = np.asarray(record[model.output], dtype=float)
    start = np.array([result.values[p] for p in names])
    options = {"method": "RK4", "substeps": substeps, "interpolation": interpolation}
    x0 = fit_initial_state(model, result.values, seg_t, inputs, y, 50, **options)
    scale = np.abs(np.r_[start, x0]) + 1e-12

    def residual(z):
        values = dict(zip(names, z[:len(names)] * scale[:len(names)]))
        sim = simulate_model(model, values, seg_t, inputs,
                             initial_state=z[len(names):] * scale[len(names):], **options)
        r = sim - y
        return np.where(np.isfinite(r), r, 1e3 * np.std(y))

    fit = least_squares(residual, np.r_[start, x0] / scale, method="lm", xtol=1e-10,
                        ftol=1e-10)
    return dict(zip(names, (fit.x[:len(names)] * scale[:len(names)]).tolist()))


def _with_time(record, rate=None):
    if "t" in record:
        return record
    return dict(record, t=np.arange(len(next(iter(record.values())))) / rate)


def speed_case(name, train, validate, equation, *, rate=None, repeats=3, truth=None,
               interpolation="cubic"):
    """Time and validation error of identify and of the output-error fit (and of the
    true parameters, for a synthetic record: the simulator's own error)."""
    train, validate = _with_time(train, rate), _with_time(validate, rate)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = algid.identify(train, *equation)
        times.append(time.perf_counter() - start)
    start = time.perf_counter()
    oe_values = output_error_fit(result, train, interpolation=interpolation)
    oe_time = time.perf_counter() - start
    error = result.simulate(validate, interpolation=interpolation).rmse
    oe_result = result.with_parameters(oe_values)
    oe_error = oe_result.simulate(validate, interpolation=interpolation).rmse
    truth_error = None
    if truth is not None:
        truth_error = result.with_parameters(truth).simulate(
            validate, interpolation=interpolation).rmse
    return {"record": name, "samples": int(result.n_samples), "window": result.window,
            "truth_rmse": truth_error,
            "identify_s": min(times), "output_error_s": oe_time,
            "speed_ratio": oe_time / min(times), "identify_rmse": error,
            "output_error_rmse": oe_error, "error_ratio": error / oe_error,
            "identify": result.values, "output_error": oe_values}


def monte_carlo(generator, equation, runs, oe_runs, method="bc", interpolation="bandlimited"):
    """RMSE and honesty of the standard errors over noise realisations (the output-error
    fit simulates with ``interpolation`` of the inputs)."""
    estimates, errors, oe = [], [], []
    truth = None
    for seed in range(runs):
        record, truth = generator(seed)
        r = algid.identify(record, *equation, method=method)
        estimates.append([r.values[p] for p in truth])
        errors.append([r.stderr[p] for p in truth])
        if seed < oe_runs:
            values = output_error_fit(r, record, interpolation=interpolation)
            oe.append([values[p] for p in truth])
    true = np.array(list(truth.values()))
    estimates, errors = np.array(estimates), np.array(errors)
    out = {"runs": runs, "method": method, "parameters": list(truth),
           "rmse": np.sqrt(np.mean((estimates - true) ** 2, axis=0)).tolist(),
           "spread_over_stderr": (np.std(estimates, axis=0, ddof=1)
                                  / np.mean(errors, axis=0)).tolist(),
           "bias_over_stderr": ((np.mean(estimates, axis=0) - true)
                                / np.mean(errors, axis=0)).tolist()}
    if oe:
        oe = np.array(oe)
        sub = estimates[:len(oe)]
        out["oe_runs"] = len(oe)
        out["rmse_same_runs"] = np.sqrt(np.mean((sub - true) ** 2, axis=0)).tolist()
        out["oe_rmse"] = np.sqrt(np.mean((oe - true) ** 2, axis=0)).tolist()
        out["rmse_over_oe"] = (np.array(out["rmse_same_runs"]) / np.array(out["oe_rmse"])).tolist()
    return out


def linear_crlb(truth, n, noise):
    """Cramer-Rao bound of (B, K, G, d) for the linear record with offsets.

    The record is in periodic steady state, so the output is an explicit function of
    the parameters (the multisine lines through the frequency response, plus the
    static response to the input offset and ``d``); its sensitivities are taken by
    central differences, and the bound is ``sigma^2 (S^T S)^-1`` for white output
    noise of standard deviation ``noise * rms(y)``.
    """
    from benchmarks import synthetic_records as sr

    freqs, phases, amp = sr.multisine_lines(np.random.default_rng(sr.INPUT_SEED), 0.2,
                                              15.0, 40, 1.0)
    t = np.arange(n) / 80.0
    w = 2 * np.pi * freqs
    u_offset = 0.1

    def output(theta):
        B, K, G, d = theta
        H = G / (K - w ** 2 + 1j * B * w)
        y = np.sum(amp * np.abs(H)[:, None] * np.sin(w[:, None] * t + phases[:, None]
                                                      + np.angle(H)[:, None]), axis=0)
        return y + (G * u_offset + d) / K

    theta = np.array([truth[p] for p in ("B", "K", "G", "d")])
    S = np.empty((n, 4))
    for i in range(4):
        h = 1e-6 * max(abs(theta[i]), 1.0)
        up, down = theta.copy(), theta.copy()
        up[i] += h
        down[i] -= h
        S[:, i] = (output(up) - output(down)) / (2 * h)
    sigma = noise * np.std(output(theta))
    return np.sqrt(np.diag(sigma ** 2 * np.linalg.inv(S.T @ S)))


def _silverbox():
    folder = next((f for f in DATA_FOLDERS if (f / "silverbox").is_dir()), None)
    if folder is None:
        return None
    rows = np.loadtxt(folder / "silverbox" / "SNLS80mV.csv", delimiter=",", skiprows=1,
                      usecols=(0, 1))
    record = {"V1": rows[:, 0], "V2": rows[:, 1]}
    return ({k: v[40650:105712] for k, v in record.items()},
            {k: v[100:40575] for k, v in record.items()})


def run(*, runs=50, oe_runs=20, silverbox=True, smoke=False, speed=True, log=print):
    """Every measurement; returns JSON-ready data."""
    n = 600 if smoke else 4000
    results = {"speed": [], "monte_carlo": {}}
    cases = []
    if silverbox and not smoke:
        data = _silverbox()
        if data is not None:
            cases.append(("silverbox", data[0], data[1], SILVERBOX, 610.35, None))
    for name, generator, equation in (("linear_offsets", linear_offsets, LINEAR_EQUATION),
                                      ("cubic_spring", cubic_spring, CUBIC_EQUATION)):
        train, truth = generator(0, n=n)
        cases.append((name, train, generator(1000, n=n)[0], equation, None, truth))
    for name, train, validate, equation, rate, truth in (cases if speed else []):
        # the synthetic inputs are band-limited multisines: simulate them so
        row = speed_case(name, train, validate, equation, rate=rate,
                         repeats=1 if smoke else 3, truth=truth,
                         interpolation="cubic" if truth is None else "bandlimited")
        results["speed"].append(row)
        log(f"{name:15s} identify {row['identify_s']:.3f} s, output-error "
            f"{row['output_error_s']:.2f} s: {row['speed_ratio']:.0f}x faster; simulation "
            f"error {row['identify_rmse']:.4g} vs {row['output_error_rmse']:.4g} "
            f"({row['error_ratio']:.3f}x)" + (
                f"; true parameters {row['truth_rmse']:.4g}" if truth is not None else ""))
    for name, generator, equation, with_oe in (
            ("linear_offsets", linear_offsets, LINEAR_EQUATION, True),
            ("linear_gaps", linear_gaps, LINEAR_EQUATION, True),
            ("cubic_spring", cubic_spring, CUBIC_EQUATION, True),
            ("friction_loop", friction_loop, FRICTION_EQUATION, True)):
        def gen(seed, generator=generator):
            return generator(seed, n=n) if not smoke or name != "friction_loop" else \
                generator(seed, n=2000)
        mc = monte_carlo(gen, equation, 3 if smoke else runs,
                         0 if not with_oe else oe_runs if not smoke
                         else int(name == "linear_offsets"),
                         interpolation="cubic" if name == "friction_loop" else "bandlimited")
        if name == "linear_offsets":
            bound = linear_crlb(gen(0)[1], n, 0.01)
            mc["crlb"] = bound.tolist()
            mc["rmse_over_crlb"] = (np.array(mc["rmse"]) / bound).tolist()
            log(f"{name:15s} RMSE/CRLB " + ", ".join(
                f"{p} {v:.2f}" for p, v in zip(mc["parameters"], mc["rmse_over_crlb"])))
            for other in ("ls", "iv"):
                alt = monte_carlo(gen, equation, 3 if smoke else runs, 0, method=other)
                alt["rmse_over_crlb"] = (np.array(alt["rmse"]) / bound).tolist()
                results["monte_carlo"][f"{name}_{other}"] = alt
                log(f"{name:15s} method {other}: RMSE/CRLB " + ", ".join(
                    f"{p} {v:.2f}" for p, v in zip(alt["parameters"], alt["rmse_over_crlb"]))
                    + "; spread/stderr " + ", ".join(
                    f"{p} {v:.2f}" for p, v in zip(alt["parameters"],
                                                   alt["spread_over_stderr"])))
        results["monte_carlo"][name] = mc
        log(f"{name:15s} {mc['runs']} runs: spread/stderr "
            + ", ".join(f"{p} {v:.2f}" for p, v in zip(mc["parameters"],
                                                        mc["spread_over_stderr"]))
            + ("; RMSE/OE RMSE " + ", ".join(f"{p} {v:.2f}" for p, v in
                                            zip(mc["parameters"], mc["rmse_over_oe"]))
               if "rmse_over_oe" in mc else ""))
    return results


def _ratios(mc, key):
    values = mc.get(key)
    if values is None:
        return "—"
    return ", ".join(f"{p} {v:.2f}" for p, v in zip(mc["parameters"], values))


def markdown(results):
    """The tables of a run (what ``--out`` writes), as Markdown.

    Parameters
    ----------
    results : dict

    Returns
    -------
    str
    """
    lines = []
    if results.get("speed"):
        lines += ["# identify against an output-error fit", "",
                  "| record | identify | output-error fit | speed | simulation error, "
                  "identify / output-error |", "| --- | --- | --- | --- | --- |"]
        for row in results["speed"]:
            lines.append(f"| {row['record']} | {row['identify_s']:.3g} s | "
                         f"{row['output_error_s']:.3g} s | {row['speed_ratio']:.0f}x | "
                         f"{row['identify_rmse']:.4g} / {row['output_error_rmse']:.4g} = "
                         f"{row['error_ratio']:.3f} |")
        lines.append("")
    if results.get("monte_carlo"):
        lines += ["# Monte Carlo over noise realisations", "",
                  "| record (method) | runs | RMSE / Cramer-Rao bound | RMSE / output-error "
                  "RMSE (runs) | spread / mean reported standard error |",
                  "| --- | --- | --- | --- | --- |"]
        for name, mc in results["monte_carlo"].items():
            oe = _ratios(mc, "rmse_over_oe")
            if "oe_runs" in mc:
                oe += f" ({mc['oe_runs']})"
            lines.append(f"| {name} ({mc['method']}) | {mc['runs']} | "
                         f"{_ratios(mc, 'rmse_over_crlb')} | {oe} | "
                         f"{_ratios(mc, 'spread_over_stderr')} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m benchmarks.identify_speed",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--oe-runs", type=int, default=20)
    parser.add_argument("--no-silverbox", action="store_true")
    parser.add_argument("--smoke", action="store_true")
    parser.add_argument("--no-speed", action="store_true",
                        help="only the Monte Carlo part")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    results = run(runs=args.runs, oe_runs=args.oe_runs, silverbox=not args.no_silverbox,
                  smoke=args.smoke, speed=not args.no_speed)
    if args.out:
        args.out.write_text(json.dumps(results, indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
