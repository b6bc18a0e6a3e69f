"""A CUSUM test that the parameters of a tracked model changed (:class:`algid.Tracker`).

The test looks at *innovations*: the residual of a window equation at the estimate made
before the window's first sample.  Only windows that share no sample are tested (one
window in every ``ceil(length / stride)``), so that under white output noise the
innovations are independent; each is divided by its predicted standard deviation (the
residual scatter of the windows so far, inflated by the uncertainty of the estimate),
which makes ``z**2`` a chi-square variable of one degree of freedom while nothing
changes.  A change of the parameters adds to every innovation the change times the
window's regressors, which raises the variance of ``z``.

The statistic is Page's CUSUM of the log-likelihood ratio of a variance ``rho`` times
larger (:data:`VARIANCE_RATIO`) against the predicted one::

    S_n = max(0, S_{n-1} + min(z_n**2, c) - k),   k = ln(rho) / (1 - 1/rho),

each increment capped at ``c`` (:data:`INCREMENT_CAP`, a 3-sigma innovation) so that
one outlier (a misplaced ``sign(q')`` crossing, a spike) cannot raise an alarm alone:
it takes a run of large innovations, which a change of the parameters makes.  An alarm
is raised where ``S_n`` exceeds ``h`` (then ``S`` restarts from 0).  ``h`` is chosen
so that the average run length between false alarms, computed for chi-square increments
by the Markov chain of Brook and Evans (:func:`average_run_length`), is the design one
(:func:`cusum_threshold`).  The design false-alarm rate holds where the misfit of the
equations is white output noise; a misfit that is the model's own error
(quadrature error at few samples per period, unmodelled dynamics) is correlated across
windows and raises the false alarms.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from algid.identification._tracker_state import TrackerSetupError

__all__ = ["VARIANCE_RATIO", "INCREMENT_CAP", "DEFAULT_FALSE_ALARM_RATE", "MAX_RUN_LENGTH",
           "cusum_reference", "average_run_length", "cusum_threshold", "cusum_design"]

#: Design false alarms per second of stream time.
DEFAULT_FALSE_ALARM_RATE = 1e-3

#: Longest average run between false alarms (tests) that the CUSUM threshold is tuned
#: to: beyond about 1e13 its run-length recursion loses the precision to place it.
MAX_RUN_LENGTH = 1e12

#: Variance ratio of the innovations the CUSUM is tuned to detect.
VARIANCE_RATIO = 4.0

#: Largest increment ``z**2`` counted by the CUSUM.
INCREMENT_CAP = 9.0

#: States of the Markov chain approximating the CUSUM on ``[0, h]``.
CHAIN_STATES = 400


def cusum_reference(rho=VARIANCE_RATIO):
    """The drift ``k`` of the CUSUM for a variance ratio ``rho`` (log-likelihood ratio).

    Parameters
    ----------
    rho : float
        Variance ratio to detect (above 1).

    Returns
    -------
    float
    """
    return math.log(rho) / (1.0 - 1.0 / rho)


def _chi2_cdf(x):
    """Distribution function of chi-square with one degree of freedom, capped at
    :data:`INCREMENT_CAP` (all the mass beyond it there)."""
    from scipy.special import erf

    return np.where(x >= INCREMENT_CAP, 1.0, erf(np.sqrt(np.maximum(x, 0.0) / 2.0)))


@lru_cache(maxsize=64)
def average_run_length(h, k):
    """Average number of tests before ``S`` exceeds ``h`` with chi-square(1) increments.

    Brook and Evans' Markov chain: ``[0, h]`` cut into :data:`CHAIN_STATES` cells, the
    transition from a cell's centre by the law of ``z**2 - k``, absorbed above ``h``.

    Parameters
    ----------
    h : float
        Threshold.
    k : float
        Drift of the CUSUM.

    Returns
    -------
    float
    """
    n = CHAIN_STATES
    width = h / n
    # from state i to cell j: z**2 in [edges[j] - c_i + k, edges[j+1] - c_i + k];
    # to state 0 also everything that falls below 0
    # the law depends on j - i only: on the 2 n + 1 differences of cell edges and centres
    offsets = (np.arange(-n, n + 1) - 0.5) * width + k
    cdf = _chi2_cdf(offsets)
    difference = np.arange(n)[None, :] - np.arange(n)[:, None] + n
    upper = cdf[difference + 1]
    lower = cdf[difference]
    transition = upper - lower
    transition[:, 0] = upper[:, 0]
    # start at 0: the first cell's centre stands for it
    runs = np.linalg.solve(np.eye(n) - transition, np.ones(n))
    return float(runs[0])


@lru_cache(maxsize=64)
def cusum_threshold(run_length, k):
    """The threshold ``h`` whose average run length is ``run_length`` tests.

    Parameters
    ----------
    run_length : float
        Average number of tests between false alarms (at least 2).
    k : float
        Drift of the CUSUM.

    Returns
    -------
    float
    """
    low, high = 1e-3, 1.0
    while average_run_length(round(high, 12), k) < run_length:
        low, high = high, 2 * high
    for _ in range(30):
        middle = (low + high) / 2
        if average_run_length(round(middle, 12), k) < run_length:
            low = middle
        else:
            high = middle
    return high


def cusum_design(false_alarm_rate, test_interval, tests=1):
    """The drift and threshold of a CUSUM for a false-alarm rate per second.

    Parameters
    ----------
    false_alarm_rate : float
        Design false alarms per second of stream time, for all ``tests`` together.
    test_interval : float
        Seconds of stream between tests.
    tests : int
        CUSUMs run side by side (one per equation of a system): each is tuned to its
        share of the rate.

    Returns
    -------
    k, h : float
        :func:`cusum_reference` and :func:`cusum_threshold`.

    Raises
    ------
    TrackerSetupError
        A rate of more than one alarm in two tests, or beyond :data:`MAX_RUN_LENGTH`.
    """
    k = cusum_reference()
    rate = false_alarm_rate / tests
    run_length = 1.0 / (rate * test_interval)
    if run_length < 2.0:   # (the CUSUM's threshold is tuned from two tests up)
        raise TrackerSetupError(f"false_alarm_rate {false_alarm_rate:g} per second is more "
                                f"than one alarm in two tests (every {test_interval:.4g} s); "
                                f"use at most {0.5 * tests / test_interval:.3g}")
    if run_length > MAX_RUN_LENGTH:
        raise TrackerSetupError(f"false_alarm_rate {false_alarm_rate:g} per second is one "
                                f"alarm in {run_length:.3g} tests (every {test_interval:.4g} "
                                f"s); the threshold is tuned up to {MAX_RUN_LENGTH:.0e}: use "
                                f"at least {tests / (MAX_RUN_LENGTH * test_interval):.3g}")
    return k, cusum_threshold(run_length, k)
