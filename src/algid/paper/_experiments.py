"""The experiments of the paper's Section 3 and what is measured on each.

:data:`EXPERIMENTS` lists the four experiments (step and sine, without and with noise)
on the system of Table 1; :func:`simulate_experiment`, :func:`estimate_experiment`,
:func:`accuracy` and :func:`seed_statistics` measure convergence times and final
errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from algid.errors import AlgidError
from algid.estimation._batch import DEFAULT_FILTER_ORDER, DEFAULT_QUADRATURE_POINTS, estimate
from algid.estimation._result import convergence_time

__all__ = ["SYSTEM", "TRUE_VALUES", "DURATION", "RATE", "NOISE_STD", "TOLERANCES",
           "EXPERIMENTS", "Experiment", "simulate_experiment", "estimate_experiment",
           "accuracy", "seed_statistics", "experiment_named", "tolerance_key", "FIGURE_FILES",
           "TOOLKIT", "PAPER_STYLE", "PAPER_STYLE_NOISY", "AMPLITUDE", "FREQUENCY"]

#: Table 1 of the paper: mass [kg], damping [N s/m], stiffness [N/m].
SYSTEM = {"m": 1.0, "c": 2.0, "k": 3.0}
#: The values the estimator must find, ``B = c/m`` and ``K = k/m``.
TRUE_VALUES = {"B": SYSTEM["c"] / SYSTEM["m"], "K": SYSTEM["k"] / SYSTEM["m"]}
#: Length of the records of Figures 3-9 [s].
DURATION = 5.0
#: Sampling rate [Hz] (1 ms, the resolution of the paper's reported times).
RATE = 1000.0
#: Standard deviation of the noise on the measured position in Section 3.2 [m].
NOISE_STD = 0.01
#: Amplitude [N] of both inputs and frequency [rad/s] of the sine.
AMPLITUDE = 1.0
FREQUENCY = 1.0
#: Relative tolerances at which convergence times are measured.
TOLERANCES = (1e-2, 1e-3)

#: Estimator settings of the toolkit (the defaults of :func:`algid.estimate`).
TOOLKIT = {"quadrature_order": DEFAULT_QUADRATURE_POINTS, "filter_order": DEFAULT_FILTER_ORDER}
#: Paper-style settings: cumulative trapezoid; unfiltered without noise, ``1/s`` with.
PAPER_STYLE = {"quadrature_order": 2, "filter_order": 0}
PAPER_STYLE_NOISY = {"quadrature_order": 2, "filter_order": 1}

#: File names of the figures written by :func:`reproduce`.
FIGURE_FILES = {
    "fig3": "fig3_step_input_response.png",
    "fig4": "fig4_estimates_step.png",
    "fig5": "fig5_sine_input_response.png",
    "fig6": "fig6_estimates_sine.png",
    "fig7": "fig7_noisy_responses.png",
    "fig8": "fig8_estimates_step_noise.png",
    "fig9": "fig9_estimates_sine_noise.png",
}


@dataclass(frozen=True)
class Experiment:
    """One experiment of the paper's Section 3.

    Attributes
    ----------
    name : str
        Key in the summary (``"step"``, ``"sine"``, ``"step_noise"``, ``"sine_noise"``).
    input : str
        ``"step"`` or ``"sine"``.
    noise_std : float
        Standard deviation of the noise on the measured position [m].
    claim_time : float
        Time at which the paper reports good estimates [s].
    claim_zero_until : float
        Time until which the paper holds its estimator output at zero [s].
    figure : str
        The paper's figure with the estimates.
    claim : str
        The paper's words, abridged.

    Examples
    --------
    >>> from algid.paper import EXPERIMENTS
    >>> [experiment.name for experiment in EXPERIMENTS]
    ['step', 'sine', 'step_noise', 'sine_noise']
    >>> EXPERIMENTS[2].noise_std, EXPERIMENTS[2].claim_time
    (0.01, 2.5)
    """

    name: str
    input: str
    noise_std: float
    claim_time: float
    claim_zero_until: float
    figure: str
    claim: str

    @property
    def noisy(self) -> bool:
        """Whether the measured position carries noise."""
        return self.noise_std > 0

    @property
    def label(self) -> str:
        """Short description, e.g. ``"step, noise 0.01 m"``."""
        return f"{self.input}, " + (f"noise {self.noise_std:g} m" if self.noisy else "no noise")


#: The four experiments, in the order of the paper.
EXPERIMENTS = (
    Experiment("step", "step", 0.0, 0.04, 0.01, "Fig. 4",
               "at t = 0.04 s good estimates with null error (estimator held at 0 "
               "until 0.01 s)"),
    Experiment("sine", "sine", 0.0, 0.06, 0.03, "Fig. 6",
               "estimates obtained at t = 0.06 s and maintained (held at 0 within 0.03 s)"),
    Experiment("step_noise", "step", NOISE_STD, 2.5, 1.1, "Fig. 8",
               "held at 0 until 1.1 s; at t = 2.5 s B = 2 and K = 3 are obtained"),
    Experiment("sine_noise", "sine", NOISE_STD, 2.5, 1.1, "Fig. 9",
               "same results as with the step (2.5 s)"),
)
_BY_NAME = {e.name: e for e in EXPERIMENTS}


# ------------------------------------------------------------------ measurements


def simulate_experiment(experiment, *, seed=None, rate=RATE, duration=DURATION):
    """Simulate one experiment of the paper on the system of Table 1.

    Parameters
    ----------
    experiment : Experiment or str
        The experiment or its name (see :data:`EXPERIMENTS`).
    seed : int, optional
        Seed of the measurement noise (noisy experiments only).
    rate : float, optional
        Sampling rate [Hz].
    duration : float, optional
        Record length [s].

    Returns
    -------
    algid.simulation.SimulationResult

    Examples
    --------
    >>> from algid.paper import simulate_experiment
    >>> simulate_experiment("step_noise", seed=0)
    SimulationResult(n=5001, m=1.0, c=2.0, k=3.0, noise_std=0.01, seed=0)
    """
    from algid.simulation import simulate

    exp = experiment_named(experiment)
    return simulate(exp.input, **SYSTEM, duration=duration, rate=rate, amplitude=AMPLITUDE,
                    frequency=FREQUENCY, noise_std=exp.noise_std,
                    seed=seed if exp.noisy else None)


def estimate_experiment(sim, *, quadrature_order=DEFAULT_QUADRATURE_POINTS,
                        filter_order=DEFAULT_FILTER_ORDER):
    """Estimate ``B`` and ``K`` from a simulated experiment (force per unit mass).

    Parameters
    ----------
    sim : algid.simulation.SimulationResult
    quadrature_order, filter_order : int, optional
        Passed to :func:`algid.estimate` (``quadrature_order`` as its
        ``quadrature_points``: the number of points of the rule).

    Returns
    -------
    algid.estimation._result.EstimationResult

    Examples
    --------
    >>> from algid.paper import estimate_experiment, simulate_experiment
    >>> result = estimate_experiment(simulate_experiment("sine"))
    >>> {name: round(value, 6) for name, value in result.final().items()}
    {'B': 2.0, 'K': 3.0}
    """
    return estimate(sim.t, sim.f / sim.m, sim.x, quadrature_points=quadrature_order,
                    filter_order=filter_order)


def accuracy(result, true_values=None, tolerances=TOLERANCES):
    """Convergence times and final relative errors of an estimation.

    Parameters
    ----------
    result : algid.estimation._result.EstimationResult
    true_values : dict, optional
        Default :data:`TRUE_VALUES`.
    tolerances : sequence of float, optional
        Relative tolerances.

    Returns
    -------
    dict
        ``"t_<tol>"``: time from which *all* estimates stay within ``tol`` to the end
        (NaN if not reached by the end of the record), ``"t_<tol>_<name>"`` per
        parameter, ``"final"``: final estimates, ``"final_rel_error"``: signed final
        relative errors, ``"t_valid"``: first defined estimate.

    Examples
    --------
    >>> from algid.paper import accuracy, estimate_experiment, simulate_experiment
    >>> numbers = accuracy(estimate_experiment(simulate_experiment("step")))
    >>> numbers["t_valid"], numbers["t_1pct"], numbers["t_0.1pct"]
    (0.005, 0.005, 0.005)
    """
    true_values = TRUE_VALUES if true_values is None else true_values
    out = {}
    for tol in tolerances:
        per = {k: convergence_time(result.t, result.estimates[k], v, tol)
               for k, v in true_values.items()}
        reached = all(map(math.isfinite, per.values()))
        out[f"t_{tolerance_key(tol)}"] = max(per.values()) if reached else math.nan
        for k, v in per.items():
            out[f"t_{tolerance_key(tol)}_{k}"] = v
    final = result.final()
    out["final"] = {k: final[k] for k in true_values}
    out["final_rel_error"] = {k: final[k] / v - 1.0 for k, v in true_values.items()}
    out["t_valid"] = result.t_valid
    return out


def seed_statistics(experiment, seeds, *, rate=RATE, true_values=None,
                    tolerances=TOLERANCES, **options):
    """Convergence times and final errors of a noisy experiment over many seeds.

    Parameters
    ----------
    experiment : Experiment or str
    seeds : sequence of int
        Seeds of the noise realisations.
    rate : float, optional
        Sampling rate [Hz].
    true_values : dict, optional
        Default :data:`TRUE_VALUES`.
    tolerances : sequence of float, optional
    **options
        ``quadrature_order``, ``filter_order`` for :func:`estimate_experiment`.

    Returns
    -------
    dict
        ``"n"``, ``"seeds"`` (first, last), for each tolerance ``"median_t_<tol>"``
        (a seed that never converges counts as later than any time; NaN if more than
        half never converge) and ``"reached_<tol>"`` (how many seeds converged), and
        ``"rmse"`` / ``"mean"`` of the final relative errors per parameter.

    Examples
    --------
    >>> from algid.paper import seed_statistics
    >>> stats = seed_statistics("step_noise", range(3))
    >>> stats["n"], stats["seeds"], stats["reached_1pct"]
    (3, [0, 2], 3)
    >>> stats["median_t_1pct"] < 2.5        # the paper's claim: 2.5 s
    True
    """
    true_values = TRUE_VALUES if true_values is None else true_values
    seeds = list(seeds)
    times = {tol: [] for tol in tolerances}
    errors = []
    for seed in seeds:
        sim = simulate_experiment(experiment, seed=seed, rate=rate)
        acc = accuracy(estimate_experiment(sim, **options), true_values, tolerances)
        for tol in tolerances:
            times[tol].append(acc[f"t_{tolerance_key(tol)}"])
        errors.append([acc["final_rel_error"][k] for k in true_values])
    errors = np.array(errors)
    out = {"n": len(seeds), "seeds": [seeds[0], seeds[-1]] if seeds else []}
    for tol in tolerances:
        arr = np.array(times[tol], dtype=float)
        arr = np.where(np.isfinite(arr), arr, np.inf)
        med = float(np.median(arr)) if arr.size else math.nan
        out[f"median_t_{tolerance_key(tol)}"] = med if math.isfinite(med) else math.nan
        out[f"reached_{tolerance_key(tol)}"] = int(np.isfinite(arr).sum())
    out["rmse"] = {k: float(np.sqrt(np.mean(errors[:, i] ** 2)))
                   for i, k in enumerate(true_values)}
    out["mean"] = {k: float(np.mean(errors[:, i])) for i, k in enumerate(true_values)}
    return out


def tolerance_key(tol):
    """The key of a relative tolerance in the summaries.

    Parameters
    ----------
    tol : float
        Relative tolerance.

    Returns
    -------
    str
        The tolerance in percent, e.g. ``"1pct"``.

    Examples
    --------
    >>> tolerance_key(0.01), tolerance_key(0.001)
    ('1pct', '0.1pct')
    """
    return f"{100 * tol:g}pct"


def experiment_named(experiment):
    """The experiment of a given name.

    Parameters
    ----------
    experiment : Experiment or str
        An experiment (returned as is) or the name of one of :data:`EXPERIMENTS`.

    Returns
    -------
    Experiment
        The experiment.

    Raises
    ------
    AlgidError
        If no experiment has that name.
    """
    if isinstance(experiment, Experiment):
        return experiment
    try:
        return _BY_NAME[experiment]
    except (KeyError, TypeError):
        raise AlgidError(f"unknown experiment {experiment!r} "
                         f"(known: {', '.join(_BY_NAME)})") from None
