"""Reproduction of the simulation experiments of Becedas et al. (WCECS 2007), Section 3.

The paper identifies ``B = c/m`` and ``K = k/m`` of the mass-spring-damper
``x'' + B x' + K x = f`` of its Table 1 (``m = 1`` kg, ``c = 2`` N s/m, ``k = 3`` N/m)
from a step and from a sinusoidal force (1 N, 1 rad/s), first without noise, then with
white noise of standard deviation 0.01 m on the measured position (Figures 3-9).  It
reports *when* the estimates become good: at 0.04 s (step) and 0.06 s (sine) without
noise, at 2.5 s with noise.

:func:`reproduce` runs the four experiments, measures for each the time from which both
estimates stay within 1 % and within 0.1 % of the true values and the relative error
at the end of the record, and sets them beside the paper's claims.  It measures the
same quantities for a *paper-style* computation (cumulative trapezoid), and the
effect of the sampling rate, of the quadrature rule and of the invariant filter order,
so that the differences between the paper and the toolkit are explained by numbers
measured in the same run.  For the noisy experiments one seed gives one realisation:
the realisation of ``seed`` is shown, and the median convergence time and the RMSE of
the final estimates over seeds ``0 .. n_seeds - 1`` are reported.

The paper does not state its sampling rate, its integration method or the order of its
filter ``1/s**p`` (only ``p >= 1``, Remark 2.1).  The paper-style computation here uses
the cumulative trapezoid at the rate of the figures (1 kHz, 5 s) and no filter without
noise (equations (24)-(25) are unfiltered) and the smallest admissible filter ``p = 1``
with noise (equations (32)-(33)).
"""

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
                                     Experiment,
                                     accuracy,
                                     estimate_experiment,
                                     seed_statistics,
                                     simulate_experiment,
)
from algid.paper._reproduction import PaperReproduction, reproduce
from algid.paper._summary import format_summary

__all__ = ["SYSTEM", "TRUE_VALUES", "DURATION", "RATE", "NOISE_STD", "TOLERANCES",
           "EXPERIMENTS", "Experiment", "PaperReproduction", "simulate_experiment",
           "estimate_experiment", "accuracy", "seed_statistics", "reproduce",
           "format_summary", "FIGURE_FILES", "TOOLKIT", "PAPER_STYLE", "PAPER_STYLE_NOISY",
           "AMPLITUDE", "FREQUENCY"]
