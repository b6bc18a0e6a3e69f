"""Monte Carlo study of the estimators against the Cramér–Rao bound.

:func:`crlb_study` simulates seeded noisy experiments on ``x'' + B x' + K x = f``,
estimates ``B`` and ``K`` at several horizons with the algebraic estimator and with
its output-error refinement, and compares the root-mean-square errors with the
Cramér–Rao bound (:mod:`algid.estimation._cramer_rao`, initial conditions unknown).  An efficient
estimator has ``RMSE / CRLB`` close to 1; with ``n`` runs the RMSE itself has a
relative standard deviation of about ``1 / sqrt(2 n)`` (5 % for 200 runs).

The estimate at horizon ``T`` is computed from the samples ``0 <= t <= T`` only (a run
of length ``T``: the first samples of the run of the longest horizon).  The noise-free
response comes from :func:`algid.simulate` (which needs the ``control`` package), once
per input; each run adds the noise ``simulate`` would add with the run's seed.
"""

from __future__ import annotations

import numpy as np

__all__ = ["crlb_study", "format_study"]


def crlb_study(n_runs=200, horizons=(1, 2.5, 5), inputs=("step", "sine"), noise_std=0.01,
               seed=0, filter_order=2, *, B=2.0, K=3.0, initial_state=(0.0, 0.0),
               rate=1000.0, refined=True, iterations=10, quadrature_order=None, lowpass=None):
    """RMSE of the algebraic and refined estimates against the Cramér–Rao bound.

    Parameters
    ----------
    n_runs : int, optional
        Monte Carlo runs per input.  Default 200.
    horizons : sequence of float, optional
        Lengths ``T`` [s] of the records.  Default (1, 2.5, 5).
    inputs : sequence of str, optional
        Inputs of :func:`algid.simulate` (``"step"``, ``"sine"``).
    noise_std : float, optional
        Standard deviation of the white Gaussian noise on ``x``.  Default 0.01.
    seed : int, optional
        Seed of the study; run ``r`` of input ``i`` uses
        ``numpy.random.SeedSequence([seed, i, r])``.  Default 0.
    filter_order : int, optional
        ``p`` of the invariant filter ``1/s**p`` of the algebraic estimator.  Default 2.
    B, K : float, optional
        True parameters (mass 1).  Default 2 and 3 (the paper's system).
    initial_state : (float, float), optional
        True ``(x0, v0)``, unknown to both estimators.  Default (0, 0).
    rate : float, optional
        Sampling rate [Hz].  Default 1000.
    refined : bool, optional
        Also run :func:`algid.estimation.refine` from the algebraic estimate.  Default True.
    iterations : int, optional
        Largest number of Gauss–Newton iterations of the refinement.
    quadrature_order : int, optional
        Quadrature rule of both estimators and of the bound's input interpolation.
        Default :data:`algid.estimation._options.DEFAULT_QUADRATURE_POINTS`.
    lowpass : optional
        Extra LTI filter of the algebraic estimator (``lowpass`` of
        :func:`algid.estimate`).

    Returns
    -------
    list of dict
        One row per input, horizon and method (``"algebraic"``, ``"refined"``) with
        keys ``input, horizon, method, filter_order, n_runs, n_valid, bias_B, bias_K,
        rmse_B, rmse_K, crlb_B, crlb_K, ratio_B, ratio_K``.  Runs whose estimate is
        undefined (NaN), or whose refinement cannot start from it, are left out of the
        statistics of that method (``n_valid`` counts the others).
    """
    from algid.errors import InputDataError
    from algid.estimation._batch import estimate
    from algid.estimation._cramer_rao import crlb
    from algid.estimation._options import DEFAULT_QUADRATURE_POINTS
    from algid.estimation._refinement import refine
    from algid.simulation import simulate

    if quadrature_order is None:
        quadrature_order = DEFAULT_QUADRATURE_POINTS
    horizons = tuple(float(T) for T in horizons)
    duration = max(horizons)
    lengths = [int(round(T * rate)) + 1 for T in horizons]
    rows = []
    for i_input, name in enumerate(inputs):
        errors = {(T, method): [] for T in horizons for method in ("algebraic", "refined")}
        sim = simulate(name, m=1.0, c=B, k=K, duration=duration, rate=rate,
                       initial_state=initial_state)
        for run in range(n_runs):
            # the noise algid.simulate would add with this seed, on the same response
            rng = np.random.default_rng(np.random.SeedSequence([seed, i_input, run]))
            x_run = sim.x_true + rng.normal(0.0, noise_std, size=sim.t.size)
            for T, n in zip(horizons, lengths):
                t, f, x = sim.t[:n], sim.f[:n], x_run[:n]
                alg = estimate(t, f, x, filter_order=filter_order, lowpass=lowpass,
                               quadrature_points=quadrature_order).final()
                errors[T, "algebraic"].append([alg["B"] - B, alg["K"] - K])
                if refined:
                    try:
                        ref = refine(t, f, x, start=alg, iterations=iterations,
                                     quadrature_order=quadrature_order)
                        errors[T, "refined"].append([ref.B - B, ref.K - K])
                    except InputDataError:  # undefined or unusable start
                        errors[T, "refined"].append([np.nan, np.nan])
        for T, n in zip(horizons, lengths):
            bound = crlb(sim.t[:n], sim.f[:n], B=B, K=K, x0=initial_state[0],
                         v0=initial_state[1], noise_std=noise_std,
                         quadrature_order=quadrature_order)
            for method in ("algebraic", "refined") if refined else ("algebraic",):
                err = np.array(errors[T, method])
                ok = np.all(np.isfinite(err), axis=1)
                err = err[ok]
                rmse = np.sqrt(np.mean(err**2, axis=0)) if err.size else np.full(2, np.nan)
                bias = np.mean(err, axis=0) if err.size else np.full(2, np.nan)
                rows.append(dict(
                    input=name, horizon=T, method=method, filter_order=filter_order,
                    n_runs=n_runs, n_valid=int(ok.sum()),
                    bias_B=float(bias[0]), bias_K=float(bias[1]),
                    rmse_B=float(rmse[0]), rmse_K=float(rmse[1]),
                    crlb_B=bound["B"], crlb_K=bound["K"],
                    ratio_B=float(rmse[0] / bound["B"]), ratio_K=float(rmse[1] / bound["K"]),
                ))
    return rows


def format_study(rows):
    """The rows of :func:`crlb_study` as a Markdown table.

    Parameters
    ----------
    rows : list of dict

    Returns
    -------
    str
    """
    head = ("| input | T [s] | method | p | valid | RMSE(B) | CRLB(B) | ratio B "
            "| RMSE(K) | CRLB(K) | ratio K |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for r in rows:
        lines.append(
            f"| {r['input']} | {r['horizon']:g} | {r['method']} | {r['filter_order']} "
            f"| {r['n_valid']}/{r['n_runs']} | {r['rmse_B']:.4g} | {r['crlb_B']:.4g} "
            f"| {r['ratio_B']:.3f} | {r['rmse_K']:.4g} | {r['crlb_K']:.4g} "
            f"| {r['ratio_K']:.3f} |")
    return "\n".join(lines)
