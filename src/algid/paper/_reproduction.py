"""Reproduction of the paper's Section 3: every experiment, the studies that explain
the differences, the figures and ``summary.json``."""

from __future__ import annotations

import json
import math
import pathlib
import time
from dataclasses import dataclass, field

import numpy as np

from algid.errors import AlgidError
from algid.paper._experiments import (
    AMPLITUDE,
    DURATION,
    EXPERIMENTS,
    FIGURE_FILES,
    FREQUENCY,
    NOISE_STD,
    PAPER_STYLE,
    PAPER_STYLE_NOISY,
    RATE,
    SYSTEM,
    TOLERANCES,
    TOOLKIT,
    TRUE_VALUES,
    accuracy,
    estimate_experiment,
    experiment_named,
    seed_statistics,
    simulate_experiment,
)
from algid.paper._summary import format_summary

__all__ = ["PaperReproduction", "reproduce", "MAX_SEEDS"]


@dataclass
class PaperReproduction:
    """What :func:`reproduce` measured and wrote.

    Attributes
    ----------
    summary : dict
        JSON-ready summary (NaN written as ``None``); see :func:`reproduce`.
    figures : dict
        Figure key (``"fig3"`` ... ``"fig9"``) -> path of the PNG written.
    out : pathlib.Path or None
        Directory written to.
    runs : dict
        Experiment name -> ``(SimulationResult, toolkit EstimationResult,
        paper-style EstimationResult)`` of the shown realisation.

    Examples
    --------
    >>> from algid.paper import reproduce
    >>> reproduction = reproduce(n_seeds=1, rates=(1000.0,), filter_orders=(2,),
    ...                          noisy_rates=(1000.0,))   # a quick run, nothing written
    >>> reproduction.out, reproduction.figures, list(reproduction.runs)
    (None, {}, ['step', 'sine', 'step_noise', 'sine_noise'])
    """

    summary: dict
    figures: dict = field(default_factory=dict)
    out: pathlib.Path | None = None
    runs: dict = field(default_factory=dict, repr=False)

    def table(self) -> str:
        """The summary as a plain-text table (see :func:`format_summary`).

        Returns
        -------
        str
            The report.
        """
        return format_summary(self.summary)

    def to_json(self, **kwargs) -> str:
        """The summary as JSON text.

        Parameters
        ----------
        **kwargs
            Passed to :func:`json.dumps` (e.g. ``indent``).

        Returns
        -------
        str
            The JSON document (no NaN: missing values are ``null``).
        """
        return json.dumps(self.summary, allow_nan=False, **kwargs)


def _prepare_out(out):
    path = pathlib.Path(out)
    if path.exists() and not path.is_dir():
        raise AlgidError(f"{out}: exists and is not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise AlgidError(f"{out}: cannot create directory ({exc.strerror or exc})") from None
    return path


#: Most noise realisations :func:`reproduce` runs (each a few seconds of estimation per
#: study: more would run for days, and the per-seed statistics grow with them).
MAX_SEEDS = 10_000


def reproduce(out=None, *, seed=0, n_seeds=20, figures=True, rates=(1000.0, 10000.0, 100000.0),
              filter_orders=(0, 1, 2, 3, 4), noisy_rates=(1000.0, 10000.0)):
    """Reproduce the experiments of the paper's Section 3 and measure the differences.

    Parameters
    ----------
    out : str or path-like, optional
        Directory for the figures (PNG) and ``summary.json``; created if missing.  With
        ``None`` nothing is written.
    seed : int, optional
        Seed of the noise realisation shown in the figures and the single-seed rows.
    n_seeds : int, optional
        Number of noise realisations (seeds ``0 .. n_seeds - 1``, at most
        ``MAX_SEEDS``) for the medians and RMSEs, and in the filter-order and
        sampling-rate studies with noise.
    figures : bool, optional
        Write the figures (needs matplotlib) when ``out`` is given.
    rates : sequence of float, optional
        Sampling rates [Hz] of the noise-free quadrature study.
    filter_orders : sequence of int, optional
        Filter orders of the study with noise.
    noisy_rates : sequence of float, optional
        Sampling rates [Hz] of the study with noise (same noise per sample).

    Returns
    -------
    PaperReproduction
        ``summary`` has the keys ``"system"``, ``"settings"``, ``"experiments"`` (per
        experiment: ``"paper"`` claim, ``"toolkit"`` and ``"paper_style"`` accuracy
        of the shown realisation, and for noisy ones ``"toolkit_seeds"`` and
        ``"paper_style_seeds"`` statistics), ``"quadrature_vs_rate"``,
        ``"filter_order_noise"``, ``"rate_noise"``, ``"figures"`` and
        ``"runtime_s"``.

    Raises
    ------
    AlgidError
        ``out`` exists and is not a directory, or cannot be created; bad ``seed`` or
        ``n_seeds``.

    Examples
    --------
    >>> from algid.paper import reproduce
    >>> reproduction = reproduce(n_seeds=1, rates=(1000.0,), filter_orders=(2,),
    ...                          noisy_rates=(1000.0,))   # a quick run, nothing written
    >>> toolkit = reproduction.summary["experiments"]["step"]["toolkit"]
    >>> toolkit["quadrature_order"], toolkit["t_1pct"]
    (8, 0.005)
    """
    started = time.perf_counter()
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise AlgidError(f"seed must be an integer >= 0, got {seed!r}")
    if isinstance(n_seeds, bool) or not isinstance(n_seeds, (int, np.integer)) \
            or not 1 <= n_seeds <= MAX_SEEDS:
        raise AlgidError(f"n_seeds must be an integer from 1 to {MAX_SEEDS}, got "
                         f"{n_seeds!r:.40}")
    out_path = _prepare_out(out) if out is not None else None
    seeds = range(int(n_seeds))

    experiments, runs = {}, {}
    for exp in EXPERIMENTS:
        sim = simulate_experiment(exp, seed=seed)
        paper_style = PAPER_STYLE_NOISY if exp.noisy else PAPER_STYLE
        r_tool = estimate_experiment(sim, **TOOLKIT)
        r_paper = estimate_experiment(sim, **paper_style)
        runs[exp.name] = (sim, r_tool, r_paper)
        entry = {
            "input": exp.input,
            "noise_std": exp.noise_std,
            "paper": {"figure": exp.figure, "t_good": exp.claim_time,
                      "estimator_zero_until": exp.claim_zero_until, "claim": exp.claim},
            "toolkit": {**TOOLKIT, **accuracy(r_tool)},
            "paper_style": {**paper_style, **accuracy(r_paper)},
        }
        if exp.noisy:
            entry["seed"] = int(seed)
            entry["toolkit_seeds"] = {**TOOLKIT, **seed_statistics(exp, seeds, **TOOLKIT)}
            entry["paper_style_seeds"] = {**paper_style,
                                          **seed_statistics(exp, seeds, **paper_style)}
        experiments[exp.name] = entry

    quadrature = []
    for name in ("step", "sine"):
        for rate in rates:
            sim = simulate_experiment(name, rate=rate)
            for q in (PAPER_STYLE["quadrature_order"], TOOLKIT["quadrature_order"]):
                acc = accuracy(estimate_experiment(sim, quadrature_order=q, filter_order=0))
                quadrature.append({"input": name, "rate": float(rate), "quadrature_order": q,
                                   "filter_order": 0, **acc})

    filters = []
    for name in ("step_noise", "sine_noise"):
        for p in filter_orders:
            stats = seed_statistics(name, seeds, quadrature_order=TOOLKIT["quadrature_order"],
                                    filter_order=int(p))
            filters.append({"input": experiment_named(name).input, "rate": RATE,
                            "filter_order": int(p),
                            "quadrature_order": TOOLKIT["quadrature_order"], **stats})

    noisy_rate = []
    for name in ("step_noise", "sine_noise"):
        for rate in noisy_rates:
            stats = seed_statistics(name, seeds, rate=rate, **TOOLKIT)
            noisy_rate.append({"input": experiment_named(name).input, "rate": float(rate),
                               **TOOLKIT, **stats})

    summary = {
        "system": {**SYSTEM, **TRUE_VALUES, "duration": DURATION, "rate": RATE,
                   "noise_std": NOISE_STD, "amplitude": AMPLITUDE, "frequency": FREQUENCY},
        "settings": {"seed": int(seed), "n_seeds": int(n_seeds),
                     "tolerances": list(TOLERANCES), "toolkit": dict(TOOLKIT),
                     "paper_style": dict(PAPER_STYLE),
                     "paper_style_noisy": dict(PAPER_STYLE_NOISY)},
        "experiments": experiments,
        "quadrature_vs_rate": quadrature,
        "filter_order_noise": filters,
        "rate_noise": noisy_rate,
        "figures": {},
    }

    written = {}
    try:
        if out_path is not None and figures:
            written = _write_figures(out_path, runs)
            summary["figures"] = {k: p.name for k, p in written.items()}
        summary["runtime_s"] = time.perf_counter() - started
        summary = _jsonable(summary)
        if out_path is not None:
            (out_path / "summary.json").write_text(
                json.dumps(summary, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    except OSError as exc:
        raise AlgidError(f"{out}: cannot write ({exc.strerror or exc})") from None
    return PaperReproduction(summary=summary, figures=written, out=out_path, runs=runs)


def _jsonable(obj):
    """Replace NaN/inf by None and NumPy scalars by Python numbers, recursively."""
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    return obj


def _write_figures(out, runs):
    from algid import plotting

    paths = {}
    view = {"step": 1.0, "sine": 2.0, "step_noise": DURATION, "sine_noise": DURATION}
    for key, name, title in (("fig3", "step", "Step input (1 N) and response"),
                             ("fig5", "sine", "Sinusoidal input (1 N, 1 rad/s) and response")):
        sim = runs[name][0]
        fig = plotting.plot_input_response(sim.t, sim.f, sim.x, title=title)
        paths[key] = plotting.save_figure(fig, out / FIGURE_FILES[key])

    step, sine = runs["step_noise"][0], runs["sine_noise"][0]
    fig = plotting.plot_responses(
        [(step.t, step.x, step.x_true, "(a) step input"),
         (sine.t, sine.x, sine.x_true, "(b) sinusoidal input")],
        title=f"Measured position with noise (std {NOISE_STD:g} m, seed {step.seed})")
    paths["fig7"] = plotting.save_figure(fig, out / FIGURE_FILES["fig7"])

    for key, name in (("fig4", "step"), ("fig6", "sine"), ("fig8", "step_noise"),
                      ("fig9", "sine_noise")):
        exp = experiment_named(name)
        sim, r_tool, r_paper = runs[name]
        style = PAPER_STYLE_NOISY if exp.noisy else PAPER_STYLE
        t1 = accuracy(r_tool)["t_1pct"]
        marks = [(exp.claim_time, f"paper: good at {exp.claim_time:g} s")]
        if math.isfinite(t1):
            marks.append((t1, f"toolkit: within 1 % from {t1:.3g} s"))
        title = (f"Estimates of B and K, {exp.label}"
                 + (f" (seed {sim.seed})" if exp.noisy else ""))
        fig = plotting.plot_estimates(
            r_tool, true_values=TRUE_VALUES, t_max=view[name], ylim=(0.0, 5.0),
            reference=r_paper,
            label=(f"toolkit ({TOOLKIT['quadrature_order']}-point rule, "
                   f"1/s^{TOOLKIT['filter_order']})"),
            reference_label=f"paper-style (trapezoid, 1/s^{style['filter_order']})",
            marks=marks, spans=[(0.0, exp.claim_zero_until, "paper: output held at 0")],
            title=title)
        paths[key] = plotting.save_figure(fig, out / FIGURE_FILES[key])
    return dict(sorted(paths.items()))
