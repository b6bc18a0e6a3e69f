"""Accuracy of the default estimator over a population of random plants
(``python -m benchmarks.population``).

Every plant is ``x'' + B x' + K x = f`` with ``B`` log-uniform in [0.01, 100] and
``K`` log-uniform in [0.01, 1e4], a random initial state, an input of one to three
sines at frequencies log-uniform within a factor 2 of the natural frequency
``sqrt(K)`` plus, one time in two, a step; noise-free.  The step is set by the fastest
mode (the sines, the damped oscillation of an underdamped plant, and for an overdamped
plant the fast real pole, whose "period" is ``2 pi / |pole|``): 20 to 100 samples per
period, log-uniform.  The record lasts five periods of the slowest mode (the same
modes, with the slow real pole), at most 10**6 samples.  With ``--oscillations-only``
the step is set by the oscillations alone, as in an earlier version of this study: the
fast pole of a stiff overdamped plant then decays within a sample or a few, and no
quadrature resolves the start of its record.

The true response is computed in closed form, independently of the project's
simulators: the particular solution of every sine and of the step, plus the
homogeneous solution that meets the initial state, written so that it stays accurate
near critical damping and for stiff overdamped plants (:func:`exact_response`).

Reported: the final relative error of the estimate (largest over ``B`` and ``K``),
its median, 95th percentile, maximum and the share within 1e-6, overall, by damping
ratio and by samples per period; with the estimator's ``numerical_error`` (when the
result carries one), how often it bounds the actual error within a factor 10 (or the
actual error is below 1e-10), how often it is at most 1e-6, and the silent failures
(actual error above 1e-3 with a reported error of at most 1e-4).

Options: ``--n 400`` plants, ``--seed 0``, ``--quick`` (60 plants of at most 2e5
samples), ``--filter-order``, ``--points``, ``--late-origin``, ``--json FILE``,
``--oscillations-only``, ``--worst 10`` (list the worst cases with a diagnosis: the
error with the largest rule (9 points), with ``filter_order=0``, and at the middle of the
record).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time

import numpy as np

import algid

__all__ = ["Plant", "draw_plants", "exact_response", "run_case", "summarise", "main"]

#: Samples per period of the fastest oscillation: log-uniform in this range.
SAMPLES_PER_PERIOD = (20.0, 100.0)
#: At most this many samples per record.
MAX_SAMPLES = 10**6
#: Damping-ratio classes of the summary (upper bounds).
ZETA_BINS = ((0.01, "zeta < 0.01"), (0.05, "0.01 <= zeta < 0.05"), (0.3, "0.05 <= zeta < 0.3"),
             (1.0, "0.3 <= zeta < 1"), (math.inf, "zeta >= 1"))
#: Classes of samples per period (upper bounds).
SPP_BINS = ((30.0, "20-30 samples/period"), (40.0, "30-40 samples/period"),
            (math.inf, "40-100 samples/period"))


@dataclasses.dataclass
class Plant:
    """One random plant, its input and its sampling.

    Attributes
    ----------
    B, K : float
        The parameters.
    x0, v0 : float
        Initial position and velocity.
    sines : tuple of (amplitude, omega, phase)
        ``f`` holds ``amplitude * sin(omega * t + phase)`` for each.
    step : float
        Constant added to ``f`` (0: none).
    dt : float
        Sampling step [s].
    n : int
        Number of samples.
    samples_per_period : float
        Of the fastest oscillation.
    """

    B: float
    K: float
    x0: float
    v0: float
    sines: tuple
    step: float
    dt: float
    n: int
    samples_per_period: float

    @property
    def zeta(self) -> float:
        """Damping ratio ``B / (2 sqrt(K))``."""
        return self.B / (2.0 * math.sqrt(self.K))

    def poles(self):
        """The two poles, the slow one first (accurate for stiff overdamped plants)."""
        half = self.B / 2.0
        disc = half * half - self.K
        if disc > 0:
            mu = math.sqrt(disc)
            fast = -(half + mu)
            return self.K / fast, fast  # product of the poles is K: no cancellation
        mu = math.sqrt(-disc)
        return complex(-half, mu), complex(-half, -mu)


def draw_plants(n, seed=0, *, max_samples=MAX_SAMPLES, oscillations_only=False):
    """``n`` random plants (see the module's docstring).

    Parameters
    ----------
    n : int
        Number of plants.
    seed : int, optional
        Seed of :func:`numpy.random.default_rng`.
    max_samples : int, optional
        Longest record.
    oscillations_only : bool, optional
        Set the step by the fastest oscillation only, ignoring an overdamped plant's
        fast real pole (which may then decay within a sample: a harder population).

    Returns
    -------
    list of Plant
    """
    rng = np.random.default_rng(seed)
    plants = []
    for _ in range(n):
        B = 10.0 ** rng.uniform(-2, 2)
        K = 10.0 ** rng.uniform(-2, 4)
        wn = math.sqrt(K)
        n_sines = int(rng.integers(1, 4))
        sines = tuple((float(rng.uniform(0.5, 2.0)) * K,  # x of order 1
                       float(wn * 2.0 ** rng.uniform(-1, 1)),
                       float(rng.uniform(0, 2 * math.pi))) for _ in range(n_sines))
        step = float(rng.uniform(0.5, 2.0) * K) if rng.random() < 0.5 else 0.0
        x0, v0 = float(rng.normal()), float(rng.normal() * wn)
        plant = Plant(B, K, x0, v0, sines, step, 1.0, 0, 0.0)
        oscillations = [w for _, w, _ in sines]
        slow, fast = plant.poles()
        if isinstance(slow, complex):
            oscillations.append(abs(slow.imag))
            rates = oscillations
            fastest = max(oscillations)
        else:
            rates = oscillations + [abs(slow)]
            fastest = max(oscillations) if oscillations_only else \
                max(max(oscillations), abs(fast))
        spp = float(np.exp(rng.uniform(*np.log(SAMPLES_PER_PERIOD))))
        dt = 2 * math.pi / (fastest * spp)
        duration = 5 * 2 * math.pi / min(rates)
        plant.dt, plant.samples_per_period = dt, spp
        plant.n = int(min(max_samples, math.ceil(duration / dt) + 1))
        plants.append(plant)
    return plants


def _homogeneous(plant, t, a, b):
    """The free response from ``x(0) = a``, ``x'(0) = b``, accurate near critical
    damping (series form of ``sinh(mu t) / mu``) and for stiff plants."""
    half = plant.B / 2.0
    mu = np.sqrt(complex(half * half - plant.K))
    span = abs(mu) * t[-1]
    if span < 1.0:  # near critical damping: e^{-Bt/2} (cosh(mu t), sinh(mu t) / mu)
        z = mu * t
        decay = np.exp(-half * t)
        small = np.abs(z) < 1e-8
        shc = np.where(small, 1.0, np.sinh(z) / np.where(small, 1.0, z))  # sinh(z) / z
        phi1 = decay * t * shc
        phi0 = decay * (np.cosh(z) + half * t * shc)
        return np.real(a * phi0 + b * phi1)
    l1, l2 = plant.poles()
    l1, l2 = complex(l1), complex(l2)
    e1, e2 = np.exp(l1 * t), np.exp(l2 * t)
    d = l1 - l2
    phi1 = (e1 - e2) / d  # impulse response
    phi0 = (-l2 * e1 + l1 * e2) / d
    return np.real(a * phi0 + b * phi1)


def exact_response(plant, t=None):
    """Input and response of ``plant`` at its samples, in closed form.

    Parameters
    ----------
    plant : Plant
    t : ndarray, optional
        Times (default: ``arange(plant.n) * plant.dt``).

    Returns
    -------
    t, f, x : ndarray
    """
    if t is None:
        t = np.arange(plant.n) * plant.dt
    f = np.full(t.shape, plant.step)
    x = np.full(t.shape, plant.step / plant.K)
    x_start, v_start = plant.step / plant.K, 0.0
    for amp, w, phase in plant.sines:
        f += amp * np.sin(w * t + phase)
        gain = amp / complex(plant.K - w * w, plant.B * w)  # x_p = Im(gain e^{i(wt+phase)})
        arg = w * t + phase
        x += gain.real * np.sin(arg) + gain.imag * np.cos(arg)
        x_start += gain.real * math.sin(phase) + gain.imag * math.cos(phase)
        v_start += w * (gain.real * math.cos(phase) - gain.imag * math.sin(phase))
    x += _homogeneous(plant, t, plant.x0 - x_start, plant.v0 - v_start)
    return t, f, x


def _relative_error(result, plant, index=-1):
    values = {"B": result.B[index], "K": result.K[index]}
    errors = [abs(values[k] / getattr(plant, k) - 1.0) for k in ("B", "K")]
    return float(max(errors)) if all(np.isfinite(errors)) else math.inf


def run_case(plant, *, filter_order=None, points=None, diagnose=False, late_origin=False):
    """The final error of the estimate (and its reported numerical error) for a plant.

    Parameters
    ----------
    plant : Plant
    filter_order, points : int, optional
        Options of :func:`algid.estimate` (default: its defaults).
    diagnose : bool, optional
        Also the error with the largest rule (9 points), with ``filter_order=0`` and at
        mid-record.
    late_origin : bool, optional
        Pass ``late_origin=True`` to :func:`algid.estimate`.

    Returns
    -------
    dict
        ``error`` (largest final relative error over B and K), ``reported`` (final
        ``numerical_error``, NaN if the result has none), and the plant's ``zeta``,
        ``spp``, ``n``.
    """
    t, f, x = exact_response(plant)
    options = {}
    if filter_order is not None:
        options["filter_order"] = filter_order
    if points is not None:
        options["quadrature_points"] = points
    if late_origin:
        options["late_origin"] = True
    r = algid.estimate(t, f, x, **options)
    reported = getattr(r, "numerical_error", None)
    row = {"B": plant.B, "K": plant.K, "zeta": plant.zeta, "spp": plant.samples_per_period,
           "n": plant.n, "error": _relative_error(r, plant),
           "reported": float(reported[-1]) if reported is not None else math.nan}
    if diagnose:
        row["error_9_points"] = _relative_error(
            algid.estimate(t, f, x, **{**options, "quadrature_points": 9}), plant)
        row["error_filter_0"] = _relative_error(
            algid.estimate(t, f, x, **{**options, "filter_order": 0}), plant)
        row["error_mid_record"] = _relative_error(r, plant, plant.n // 2)
    return row


def _quantiles(errors):
    e = np.asarray(errors, dtype=float)
    if e.size == 0:
        return {"count": 0}
    return {"count": int(e.size), "median": float(np.median(e)),
            "p95": float(np.quantile(e, 0.95)), "max": float(np.max(e)),
            "within_1e-6": float(np.mean(e <= 1e-6))}


def _honesty(rows):
    err = np.array([r["error"] for r in rows])
    rep = np.array([r["reported"] for r in rows])
    if not np.isfinite(rep).any() and not np.isinf(rep).any():
        return None
    bounded = (err <= 10 * rep) | (err < 1e-10)
    return {"bounded_within_10x": float(np.mean(bounded)),
            "reported_at_most_1e-6": float(np.mean(rep <= 1e-6)),
            "silent_failures": int(np.sum((err > 1e-3) & ~(rep > 1e-4)))}


def summarise(rows):
    """The error distribution overall and by class, and the honesty of the report.

    Parameters
    ----------
    rows : list of dict
        From :func:`run_case`.

    Returns
    -------
    dict
    """
    out = {"overall": _quantiles([r["error"] for r in rows]), "by_zeta": {}, "by_spp": {}}
    lo = 0.0
    for hi, name in ZETA_BINS:
        out["by_zeta"][name] = _quantiles([r["error"] for r in rows if lo <= r["zeta"] < hi])
        lo = hi
    lo = 0.0
    for hi, name in SPP_BINS:
        out["by_spp"][name] = _quantiles([r["error"] for r in rows if lo <= r["spp"] < hi])
        lo = hi
    target = [r["error"] for r in rows if r["zeta"] >= 0.05 and r["spp"] >= 40]
    out["zeta_ge_0.05_spp_ge_40"] = _quantiles(target)
    out["above_1e-3"] = int(sum(r["error"] > 1e-3 for r in rows))
    out["honesty"] = _honesty(rows)
    return out


def _table(summary):
    lines = ["| class | count | median | 95th pct | max | within 1e-6 |",
             "|---|---|---|---|---|---|"]

    def row(name, q):
        if q["count"] == 0:
            lines.append(f"| {name} | 0 | | | | |")
        else:
            lines.append(f"| {name} | {q['count']} | {q['median']:.1e} | {q['p95']:.1e} | "
                         f"{q['max']:.1e} | {100 * q['within_1e-6']:.0f} % |")

    row("all", summary["overall"])
    for name, q in summary["by_zeta"].items():
        row(name, q)
    for name, q in summary["by_spp"].items():
        row(name, q)
    row("zeta >= 0.05 and >= 40 samples/period", summary["zeta_ge_0.05_spp_ge_40"])
    lines.append(f"\nfinal error above 1e-3: {summary['above_1e-3']}")
    honesty = summary["honesty"]
    if honesty:
        lines.append(f"numerical_error bounds the error within 10x (or error < 1e-10): "
                     f"{100 * honesty['bounded_within_10x']:.1f} %; reported <= 1e-6: "
                     f"{100 * honesty['reported_at_most_1e-6']:.1f} %; silent failures "
                     f"(error > 1e-3, reported <= 1e-4): {honesty['silent_failures']}")
    return "\n".join(lines)


def main(argv=None):
    """Command line: see the module's docstring.

    Parameters
    ----------
    argv : list of str, optional

    Returns
    -------
    int
        Exit code.
    """
    parser = argparse.ArgumentParser(prog="python -m benchmarks.population")
    parser.add_argument("--n", type=int, default=400)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--filter-order", type=int, default=None)
    parser.add_argument("--points", type=int, default=None)
    parser.add_argument("--worst", type=int, default=10)
    parser.add_argument("--json", default=None)
    parser.add_argument("--late-origin", action="store_true")
    parser.add_argument("--oscillations-only", action="store_true")
    args = parser.parse_args(argv)
    n, max_samples = (60, 2 * 10**5) if args.quick else (args.n, MAX_SAMPLES)
    start = time.perf_counter()
    rows = [run_case(p, filter_order=args.filter_order, points=args.points,
                     late_origin=args.late_origin)
            for p in draw_plants(n, args.seed, max_samples=max_samples,
                                 oscillations_only=args.oscillations_only)]
    summary = summarise(rows)
    print(f"{n} plants, seed {args.seed}, {time.perf_counter() - start:.0f} s\n")
    print(_table(summary))
    plants = draw_plants(n, args.seed, max_samples=max_samples,
                         oscillations_only=args.oscillations_only)
    worst = sorted(range(n), key=lambda i: -rows[i]["error"])[:args.worst]
    if worst:
        print("\nworst cases (error; with 9 points; filter_order=0; at mid-record):")
    for i in worst:
        d = run_case(plants[i], filter_order=args.filter_order, points=args.points,
                     diagnose=True, late_origin=args.late_origin)
        rows[i] = d
        print(f"  #{i}: B={d['B']:.3g} K={d['K']:.3g} zeta={d['zeta']:.3g} "
              f"spp={d['spp']:.0f} n={d['n']}: {d['error']:.1e}; {d['error_9_points']:.1e}; "
              f"{d['error_filter_0']:.1e}; {d['error_mid_record']:.1e}; "
              f"reported {d['reported']:.1e}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"summary": summary, "rows": rows}, fh, indent=1, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
