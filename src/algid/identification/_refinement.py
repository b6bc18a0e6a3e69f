"""What an output-error refinement reports, and its covariance under coloured residuals.

Shared by the refinement of models linear in their signals
(:mod:`algid.identification._output_error`) and of nonlinear ones
(:mod:`algid.identification._output_error_nonlinear`).

Covariance (:func:`sandwich_covariance`): the Jacobian with the initial states
projected out, and the residuals' own correlation from an autoregressive model of
them (order by BIC): ``(J'J)^-1 J' S J (J'J)^-1`` with ``S`` the residuals'
covariance.  With white residuals it is ``sigma^2 (J'J)^-1``, the Cramér–Rao bound at
the estimate; with coloured ones (AR output noise, a slowly varying misfit) it stays
honest where ``sigma^2 (J'J)^-1`` would not.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Refinement", "sandwich_covariance", "ar_fit", "ar_order_limit", "MAX_AR_ORDER"]

#: Largest order of the autoregressive model of the residuals (the covariance's).
MAX_AR_ORDER = 40


def ar_fit(residuals, max_order):
    """Autoregressive model of residual runs by Yule–Walker (pooled autocovariances),
    its order by BIC.

    Parameters
    ----------
    residuals : list of numpy.ndarray
        The runs (each a segment of one output).
    max_order : int
        Largest order (:func:`ar_order_limit`).

    Returns
    -------
    a : numpy.ndarray
        The coefficients (``a[0] = 1``; ``[1.0]``: white).
    innovation : float
        The innovation variance.
    """
    from scipy.linalg import solve_toeplitz

    n_total = sum(len(r) for r in residuals)
    gamma = np.zeros(max_order + 1)
    for r in residuals:
        for lag in range(min(max_order, len(r) - 1) + 1):
            gamma[lag] += r[lag:] @ r[:len(r) - lag]
    gamma /= n_total
    best = (np.log(gamma[0]) if gamma[0] > 0 else -np.inf, np.ones(1), gamma[0])
    if not gamma[0] > 0:
        return best[1], gamma[0]
    for order in range(1, max_order + 1):
        try:
            phi = solve_toeplitz(gamma[:order], gamma[1:order + 1])
        except np.linalg.LinAlgError:
            break
        variance = gamma[0] - phi @ gamma[1:order + 1]
        if not variance > 0:
            break
        bic = np.log(variance) + order * np.log(n_total) / n_total
        if bic < best[0]:
            best = (bic, np.concatenate([[1.0], -phi]), variance)
    return best[1], best[2]


def ar_order_limit(bounds, max_order=MAX_AR_ORDER):
    """The largest autoregressive order fitted to runs of these ``bounds`` (rows
    ``(start, stop)``): a twentieth of the shortest, at most ``max_order``.

    Parameters
    ----------
    bounds : list of (int, int)
    max_order : int

    Returns
    -------
    int
    """
    return int(min(max_order, max(0, min(b - a for a, b in bounds) // 20)))


def sandwich_covariance(J, residuals, bounds, dof, max_order=MAX_AR_ORDER):
    """Covariance of an output-error estimate, honest under coloured residuals.

    Parameters
    ----------
    J : numpy.ndarray, shape (N, p)
        Jacobian of the residuals (initial states projected out).
    residuals : numpy.ndarray, shape (N,)
    bounds : list of (int, int)
        The segments' rows in ``J`` and ``residuals``.
    dof : int
        Residual degrees of freedom (samples less the parameters and initial states).
    max_order : int
        Largest autoregressive order.

    Returns
    -------
    covariance : numpy.ndarray, shape (p, p)
    ar : numpy.ndarray
        The autoregressive polynomial of the residuals (``[1.0]``: white).
    """
    from scipy.signal import lfilter

    runs = [residuals[a:b] for a, b in bounds]
    ar, innovation = ar_fit(runs, ar_order_limit(bounds, max_order))
    total = float(residuals @ residuals)
    n = len(residuals)
    bread = np.linalg.pinv(J.T @ J)
    if len(ar) == 1:   # white: the Cramér–Rao form, on the degrees of freedom
        return bread * total / max(dof, 1), ar
    # Cov(r) = s2 H H' with H the AR synthesis filter: J' Cov J = s2 (H'J)'(H'J), H'
    # being the same filter run backwards in time, segment by segment
    whitened = np.concatenate([lfilter([1.0], ar, J[a:b][::-1], axis=0)[::-1]
                               for a, b in bounds])
    innovation *= n / max(dof, 1)
    meat = innovation * (whitened.T @ whitened)
    covariance = bread @ meat @ bread
    # never below the white-noise form: residuals an AR model predicts almost exactly
    # (a noise-free record's interpolation error) would otherwise claim no error at all
    white = np.diag(bread) * total / max(dof, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        raise_by = np.sqrt(np.maximum(1.0, white / np.diag(covariance)))
    raise_by = np.where(np.isfinite(raise_by), raise_by, 1.0)
    return covariance * np.outer(raise_by, raise_by), ar


@dataclass
class Refinement:
    """What the output-error refinement did (:attr:`IdentificationResult.refinement`).

    Attributes
    ----------
    applied : bool
        The result reports the refined estimate (else the algebraic one).
    reason : str
        Why it was applied or not, in one line.
    converged : bool
        The Levenberg–Marquardt iteration met its tolerance.
    evaluations : int
        Simulations of the model on every segment, the Jacobian's included.
    rms_before, rms_after : float
        Root mean square of the simulation residuals at the algebraic and at the
        refined estimate (initial states fitted); NaN where not simulated.
    noise_ar : tuple of float
        The autoregressive polynomial of the residuals that the covariance uses
        (``(1.0,)``: white).
    initial_states : list of numpy.ndarray
        Per segment, the fitted initial state (observable canonical coordinates).
    residual_test : algid.identification._residual_tests.ResidualTest or None
        The tests of the simulation residuals for model errors.
    numerical_error : numpy.ndarray or None
        Per parameter, the change of the estimate when the inputs are interpolated by
        a cubic spline instead (the simulation's own error, which the standard errors
        do not hold; it matters on noise-free records at few samples per period).
    """

    applied: bool
    reason: str
    converged: bool = False
    evaluations: int = 0
    rms_before: float = float("nan")
    rms_after: float = float("nan")
    noise_ar: tuple = (1.0,)
    initial_states: list = field(default_factory=list)
    residual_test: object = None
    numerical_error: np.ndarray | None = None
