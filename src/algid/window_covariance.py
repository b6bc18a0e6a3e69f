"""Covariance of the windowed estimate of :func:`algid.identify`: the middle of its
sandwich.

The stacked window equations are solved by estimating equations ``sum_w g_w r_w = 0``
(``g_w`` a window's regressors or instruments, ``r_w`` its residual); the covariance of
the estimate is ``J^-1 S J^-T`` with ``S`` the covariance of ``sum_w g_w r_w``.  Two
estimates of ``S``:

- :func:`noise_meat`, where the residuals are white output noise passed through the
  window kernels: ``S`` is then known up to the noise variance, including the
  correlation of overlapping windows (they share samples);
- :func:`hac_meat`, the residuals' own covariance over window lags (heteroscedasticity
  and autocorrelation consistent), for a misfit that is not output noise.
"""

from __future__ import annotations

import numpy as np

from algid.window_kernels import window_sample_weights

__all__ = ["noise_meat", "hac_meat"]


def noise_meat(problem, length, multiplicity, theta_bar, scores, stride):
    """Covariance of ``sum_w scores_w e_w`` for white output noise of unit variance.

    ``e_w`` is the noise that enters window ``w``'s equation ``[A | b]_w @ theta_bar``:
    to first order, the sum over the window's samples of the noise times the factor's
    sensitivity to the output times the term kernel's sample weight, over the terms.
    Overlapping windows share samples, so ``cov(e_w, e_v)`` is the sum over their
    common samples of the product of their noise weights, and the result is
    ``sum_{w, v} cov(e_w, e_v) scores_w scores_v^T``.

    Parameters
    ----------
    problem : object
        The windowed problem of :func:`algid.identify`: its ``segments`` (each with
        ``t``, ``step`` and a length), ``parameters``, ``model.terms`` and
        ``sensitivity(factor)`` (per segment, the derivative of the factor with
        respect to the output samples, or None where it does not read them).
    length, multiplicity : int
        Samples per window and kernel multiplicity.
    theta_bar : ndarray, shape (p + 1,)
        The parameters followed by -1 (the coefficient of the known side).
    scores : ndarray, shape (windows, k)
        The weights ``g_w`` of every window, segment after segment (segments shorter
        than a window have none).
    stride : int
        Samples between the starts of consecutive windows.

    Returns
    -------
    ndarray, shape (k, k)
    """
    p = len(problem.parameters)
    index = {q: i for i, q in enumerate(problem.parameters)}
    meat = np.zeros((scores.shape[1], scores.shape[1]))
    first = 0
    for s, seg in enumerate(problem.segments):
        if len(seg) < length:
            continue
        n_win = (len(seg) - length) // stride + 1
        g = scores[first:first + n_win]
        first += n_win
        weights = np.zeros((n_win, length))  # noise weight of every sample of every window
        for term in problem.model.terms:
            sensitivity = problem.sensitivity(term.factor)
            if sensitivity is None:
                continue
            if term.parameter is None:  # the known side: b -= coefficient * integral
                factor = -theta_bar[p] * term.coefficient
            else:
                factor = theta_bar[index[term.parameter]] * term.coefficient
            kernel = window_sample_weights(seg.t, seg.step, length, multiplicity,
                                           term.derivative, stride)
            windows = np.lib.stride_tricks.sliding_window_view(sensitivity[s],
                                                               length)[::stride]
            weights += factor * windows * kernel
        for lag in range(min(n_win, -(-length // stride))):  # windows that overlap
            shift = lag * stride
            c = np.einsum("ij,ij->i", weights[:n_win - lag, shift:],
                          weights[lag:, :length - shift])
            cross = (g[:n_win - lag] * c[:, None]).T @ g[lag:]
            meat += cross if lag == 0 else cross + cross.T
    return meat


def hac_meat(scores, ids, overlap):
    """HAC sum of score outer products over window lags, within each segment.

    Flat-top (trapezoid) lag weights: 1 up to ``overlap`` lags (overlapping windows
    under white noise give residuals correlated over exactly that many windows; the
    Bartlett weights of Newey-West would underestimate), then a linear taper to zero at
    twice that (coloured noise).  The result is projected on the positive semi-definite
    matrices.

    Parameters
    ----------
    scores : ndarray, shape (windows, k)
        Estimating equations of every window (weights times residual).
    ids : ndarray, shape (windows,)
        Segment of every window (lags do not cross segments).
    overlap : int
        Number of windows a window overlaps.

    Returns
    -------
    ndarray, shape (k, k)
    """
    p = scores.shape[1]
    meat = np.zeros((p, p))
    lags = 2 * overlap
    for s in np.unique(ids):
        g = scores[ids == s]
        meat += g.T @ g
        for lag in range(1, min(lags, len(g) - 1) + 1):
            weight = 1.0 if lag <= overlap else 1.0 - (lag - overlap) / (lags - overlap + 1.0)
            cross = g[lag:].T @ g[:-lag]
            meat += weight * (cross + cross.T)
    values, vectors = np.linalg.eigh(meat)
    return (vectors * np.maximum(values, 0.0)) @ vectors.T
