"""Where the error of :func:`algid.identify` on the synthetic cubic spring comes from.

Run from the repository root: ``python -m benchmarks.cubic_study [--runs N]``.

Three measurements on :func:`benchmarks.synthetic_records.cubic_spring`:

With ``--input-scale 1`` the record is the earlier, strongly driven one (``K3 y^2`` up
to 1.7 ``K``), whose third harmonics are aliased at 80 Hz; the default is the record of
the benchmark (about 20 %).  Ratios are to the output-error RMSE stored for the
benchmark's record.

1. ``aliasing``: the error of ``identify`` on the *noise-free* record, at the default
   80 Hz and at 160 and 320 Hz (the same continuous response, sampled finer), on the
   window the rule picks at 80 Hz.  An error that vanishes with a finer sampling is a
   quadrature error of the sampled window sums, not noise.
2. ``terms``: the rms error of every term's window sum at 80 Hz against the same
   window integral on the 320 Hz samples, times the term's coefficient (force units),
   next to the term's own rms.
3. ``monte_carlo``: RMSE over noise realisations split into the noise-free error
   (deterministic, the same in every realisation) and the spread, each relative to the
   output-error RMSE stored in ``benchmarks/identify_results.json``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

import algid
from algid.identification._window_kernels import uniform_window_integrals
from benchmarks.synthetic_records import CUBIC_EQUATION, CUBIC_INPUT_SCALE, cubic_spring

RESULTS = Path(__file__).with_name("identify_results.json")


def _values(result, names):
    return np.array([result.values[p] for p in names])


def stored_oe_rmse():
    """Output-error RMSE per parameter of the cubic record from the stored benchmark."""
    stored = json.loads(RESULTS.read_text())["monte_carlo"]["cubic_spring"]
    return dict(zip(stored["parameters"], stored["oe_rmse"]))


def aliasing(rates=(80.0, 160.0, 320.0), duration=50.0, input_scale=CUBIC_INPUT_SCALE):
    """Noise-free error of ``identify`` per sampling rate, on the 80 Hz rule's window.

    Returns
    -------
    dict
        Rate -> {"window": s, "error": {parameter: estimate - truth}}.
    """
    out, window = {}, None
    for rate in rates:
        record, truth = cubic_spring(0, n=int(round(duration * rate)), noise=0.0, rate=rate,
                                     input_scale=input_scale)
        result = algid.identify(record, *CUBIC_EQUATION, window=window)
        window = window or result.window
        error = _values(result, truth) - np.array(list(truth.values()))
        out[rate] = {"window": result.window, "error": dict(zip(truth, error.tolist()))}
    return out


def terms(window_samples=16, multiplicity=12, stride=2, fine=4,
          input_scale=CUBIC_INPUT_SCALE):
    """Per term: rms error of the window sums at 80 Hz against the window integrals on
    samples ``fine`` times denser (force units), and the term's rms.

    Returns
    -------
    dict
        Term -> (rms quadrature error, rms of the term).
    """
    coarse_rate = 80.0
    record, truth = cubic_spring(0, n=4000 * fine, noise=0.0, rate=coarse_rate * fine,
                                 input_scale=input_scale)
    y_fine, u_fine = record["y"], record["u"]
    y, u = y_fine[::fine], u_fine[::fine]
    step = 1.0 / coarse_rate
    columns = {"y''": (y, y_fine, 2, 1.0), "B*y'": (y, y_fine, 1, truth["B"]),
               "K*y": (y, y_fine, 0, truth["K"]),
               "K3*y**3": (y ** 3, y_fine ** 3, 0, truth["K3"]),
               "G*u": (u, u_fine, 0, truth["G"])}
    out = {}
    for name, (z, z_fine, derivative, coefficient) in columns.items():
        coarse = uniform_window_integrals(z, step, window_samples, multiplicity,
                                          derivative, stride)
        exact = uniform_window_integrals(z_fine, step / fine,
                                         fine * (window_samples - 1) + 1, multiplicity,
                                         derivative, fine * stride)
        n = min(len(coarse), len(exact))
        error = coefficient * (coarse[:n] - exact[:n])
        out[name] = (float(np.sqrt(np.mean(error ** 2))),
                     float(np.sqrt(np.mean((coefficient * exact[:n]) ** 2))))
    return out


def monte_carlo(runs=20, input_scale=CUBIC_INPUT_SCALE, **options):
    """RMSE, noise-free error and spread of ``identify`` over seeds ``0 .. runs - 1``.

    Parameters
    ----------
    runs : int
        Noise realisations.
    input_scale : float
        Amplitude of the record's input (:func:`cubic_spring`).
    **options
        Passed to :func:`algid.identify`.

    Returns
    -------
    dict
        Per parameter: ``rmse``, ``noise_free`` (the error without noise), ``spread``
        (standard deviation over the realisations), ``spread_over_stderr`` and each
        of the first three over the stored output-error RMSE.
    """
    record, truth = cubic_spring(0, noise=0.0, input_scale=input_scale)
    names = list(truth)
    true = np.array(list(truth.values()))
    noise_free = _values(algid.identify(record, *CUBIC_EQUATION, **options), names) - true
    estimates, errors = [], []
    for seed in range(runs):
        result = algid.identify(cubic_spring(seed, input_scale=input_scale)[0],
                                *CUBIC_EQUATION, **options)
        estimates.append(_values(result, names))
        errors.append([result.stderr[p] for p in names])
    estimates, errors = np.array(estimates), np.array(errors)
    oe = np.array([stored_oe_rmse()[p] for p in names])
    rmse = np.sqrt(np.mean((estimates - true) ** 2, axis=0))
    spread = np.std(estimates, axis=0, ddof=1)
    return {p: {"rmse": rmse[i], "noise_free": noise_free[i], "spread": spread[i],
                "spread_over_stderr": spread[i] / np.mean(errors[:, i]),
                "rmse_over_oe": rmse[i] / oe[i],
                "noise_free_over_oe": abs(noise_free[i]) / oe[i],
                "spread_over_oe": spread[i] / oe[i]}
            for i, p in enumerate(names)}


def main(argv=None):
    """Print the three measurements."""
    parser = argparse.ArgumentParser(prog="python -m benchmarks.cubic_study")
    parser.add_argument("--runs", type=int, default=20, help="noise realisations")
    parser.add_argument("--input-scale", type=float, default=CUBIC_INPUT_SCALE,
                        help="amplitude of the input (1: the earlier, aliased record)")
    args = parser.parse_args(argv)
    scale = args.input_scale
    print("noise-free error of identify (window of the 80 Hz rule):")
    for rate, row in aliasing(input_scale=scale).items():
        errors = ", ".join(f"{p} {v:+.3g}" for p, v in row["error"].items())
        print(f"  {rate:5.0f} Hz, window {row['window']:.4g} s: {errors}")
    print("window sums at 80 Hz against the integrals on 320 Hz samples (16 samples, a=12):")
    for name, (error, size) in terms(input_scale=scale).items():
        print(f"  {name:8s} rms error {error:9.3g}   term rms {size:9.4g}")
    print(f"{args.runs} realisations, default identify (ratios to the stored output-error RMSE):")
    for p, row in monte_carlo(args.runs, input_scale=scale).items():
        print(f"  {p:3s} rmse {row['rmse']:.3g} ({row['rmse_over_oe']:.2f}x)  noise-free "
              f"{row['noise_free']:+.3g} ({row['noise_free_over_oe']:.2f}x)  spread "
              f"{row['spread']:.3g} ({row['spread_over_oe']:.2f}x)  spread/stderr "
              f"{row['spread_over_stderr']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
