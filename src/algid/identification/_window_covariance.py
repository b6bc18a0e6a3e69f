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

:func:`sandwich` takes the noise's where the two agree, else the smallest middle at
least both (:func:`upper_envelope`): the output noise's covariance is the least the
residuals can have, and a HAC sum over few windows can fall far below it in some
directions while it is far above in another (the flat-top lag weights can even make it
indefinite, leaving a combination a variance of 0 that the window rule would prefer).
A round-off floor is added to every variance.
"""

from __future__ import annotations

import numpy as np

from algid.identification._window_kernels import term_kernel, window_sample_weights

__all__ = ["noise_meat", "lagged_products", "hac_meat", "sandwich", "upper_envelope",
           "positive_definite", "INDEFINITE_RTOL"]

#: A middle of the sandwich whose smallest eigenvalue is below this fraction of its
#: largest counts as indefinite.
INDEFINITE_RTOL = 1e-10


def noise_meat(problem, length, multiplicity, theta_bar, scores, stride):
    """Covariance of ``sum_w scores_w e_w`` for white output noise of unit variance.

    ``e_w`` is the noise that enters window ``w``'s equation ``[A | b]_w @ theta_bar``:
    to first order, the sum over the samples of the noise times its weight in the
    window, ``e_w = sum_n W[w, n] noise_n``.  A sample's weight is its factor's
    sensitivity to the output times the term kernel's sample weight, over the terms;
    and where the steps of a ``sign(q')`` sit at crossings refined from the position
    (:mod:`algid.identification._sign_crossings`), the samples of each crossing's fit also move the
    step, by the derivative of its time with respect to them, which moves the window
    integral by minus the step times the kernel at the crossing.  Then ``sum_w scores_w
    e_w = sum_n G_n noise_n`` with ``G_n = sum_w scores_w W[w, n]``, and the result is
    ``sum_n G_n G_n^T``: for the direct weights, a sum over the lags of windows that
    share samples (their correlation is in it), plus the terms of the samples whose
    noise also moves a crossing.

    Parameters
    ----------
    problem : object
        The windowed problem of :func:`algid.identify`: its ``segments`` (each with
        ``t``, ``step`` and a length), ``parameters``, ``model.terms``,
        ``sensitivity(factor)`` (per segment, the derivative of the factor with
        respect to the output samples, or None where it does not read them) and
        ``crossings`` (``(factor, segment)`` -> ``(time, step, first, weights)`` per
        refined crossing), and ``term_scale(term)`` (the factor of a term within its
        column of the rows, a power of two).
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
        product = np.empty_like(weights)     # one term's (no temporary per term)
        moved = np.zeros((len(seg), scores.shape[1]))   # G_n through the crossings
        t0 = seg.t[0:n_win * stride:stride]
        span = seg.t[length - 1:length - 1 + n_win * stride:stride] - t0
        for term in problem.model.terms:
            if term.parameter is None:  # the known side: b -= coefficient * integral
                factor = -theta_bar[p] * term.coefficient
            else:
                factor = theta_bar[index[term.parameter]] * term.coefficient
            factor *= problem.term_scale(term)   # the term's power of two in its column
            for time, step, start, moves in problem.crossings.get((term.factor, s), ()):
                inside = (t0 < time) & (time < t0 + span)
                u = (time - t0[inside]) / span[inside]
                shift = -step * term_kernel(multiplicity, term.derivative, u) \
                    / span[inside] ** (term.derivative + 1)
                moved[start:start + len(moves)] += np.outer(moves,
                                                            factor * (shift @ g[inside]))
            sensitivity = problem.sensitivity(term.factor)
            if sensitivity is None:
                continue
            kernel = window_sample_weights(seg.t, seg.step, length, multiplicity,
                                           term.derivative, stride)
            windows = np.lib.stride_tricks.sliding_window_view(sensitivity[s],
                                                               length)[::stride]
            np.multiply(windows, kernel, out=product)
            product *= factor
            weights += product
        # sum_n G_n G_n^T of the direct weights: windows that share samples, lag by lag
        for lag in range(min(n_win, -(-length // stride))):
            c = lagged_products(weights, weights, lag, stride)
            cross = (g[:n_win - lag] * c[:, None]).T @ g[lag:]
            meat += cross if lag == 0 else cross + cross.T
        rows = np.flatnonzero(np.any(moved != 0, axis=1))
        if rows.size:   # and the terms of the samples that move crossings
            direct = np.zeros((rows.size, scores.shape[1]))
            for m in range(length):   # window w holds sample n at m = n - w * stride
                w, fits = np.divmod(rows - m, stride)
                use = (fits == 0) & (w >= 0) & (w < n_win)
                direct[use] += g[w[use]] * weights[w[use], m][:, None]
            x = moved[rows]
            meat += direct.T @ x + x.T @ direct + x.T @ x
    return meat


def lagged_products(first, second, lag, stride):
    """Per window ``w``, the sum over the samples it shares with window ``w + lag`` of
    ``first[w]`` times ``second[w + lag]`` (window ``w + lag`` starts ``lag * stride``
    samples later): with both the noise weights of the samples, the covariance of the
    two windows' noise.

    Parameters
    ----------
    first, second : numpy.ndarray, shape (windows, length)
        Per window, a weight per sample.
    lag, stride : int

    Returns
    -------
    numpy.ndarray, shape (windows - lag,)
    """
    shift = lag * stride
    n = first.shape[0] - lag
    return np.einsum("ij,ij->i", first[:n, shift:], second[lag:, :first.shape[1] - shift])


def hac_meat(scores, ids, overlap):
    """HAC sum of score outer products over window lags, within each segment.

    Flat-top (trapezoid) lag weights: 1 up to ``overlap`` lags (overlapping windows
    under white noise give residuals correlated over exactly that many windows; the
    Bartlett weights of Newey-West would underestimate), then a linear taper to zero at
    twice that (coloured noise).  Unlike Bartlett's, these weights do not make the sum
    positive semi-definite: :func:`sandwich` deals with an indefinite one.

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
    return meat


def positive_definite(meat, rtol=INDEFINITE_RTOL):
    """Whether a symmetric matrix's eigenvalues are all above ``rtol`` times the largest.

    Parameters
    ----------
    meat : numpy.ndarray
        Symmetric matrix.
    rtol : float
        Relative floor.

    Returns
    -------
    bool
    """
    values = np.linalg.eigvalsh(meat)
    return bool(values[-1] > 0 and values[0] > rtol * values[-1])


def upper_envelope(hac, noise):
    """A positive definite middle at least both ``hac`` and ``noise`` (Loewner order).

    In the coordinates where ``noise`` is the identity, the eigenvalues of ``hac`` are
    raised to at least 1: directions where the residuals' covariance is below that of
    the output noise (or negative, an indefinite HAC sum) take the noise's.

    Parameters
    ----------
    hac, noise : numpy.ndarray
        Symmetric matrices, ``noise`` positive semi-definite.

    Returns
    -------
    numpy.ndarray
    """
    k = noise.shape[0]
    regular = noise + INDEFINITE_RTOL * max(np.trace(noise) / k, np.finfo(float).tiny) \
        * np.eye(k)
    lower = np.linalg.cholesky(regular)
    inverse = np.linalg.inv(lower)
    values, vectors = np.linalg.eigh(inverse @ hac @ inverse.T)
    raised = lower @ vectors
    return (raised * np.maximum(values, 1.0)) @ raised.T


def sandwich(bread, hac, noise=None, agreement=4.0, floor=0.0, middle=False):
    """Covariance ``J^-1 S J^-T`` of the windowed estimate, never indefinite nor zero.

    The middle ``S`` is the output noise's (``noise``) where the HAC one gives variances
    at most ``agreement`` times the noise's for every parameter; else the
    :func:`upper_envelope` of the two (the HAC sum alone, kept where it was positive
    definite, gave B and G of a linear model on 4 s records standard errors about half
    their spread in a tenth of the records, ±2σ coverage 90.5-91 %: one parameter's
    disagreement chose it for all).  Without a noise model, the HAC sum, its negative
    eigenvalues reflected where it is indefinite.  ``floor**2`` is added to every
    variance (the round-off of the solution).

    Parameters
    ----------
    bread : numpy.ndarray
        ``J^-1``.
    hac : numpy.ndarray
        :func:`hac_meat`.
    noise : numpy.ndarray or None
        :func:`noise_meat` times the noise variance.
    agreement : float
        Largest ratio of HAC to noise variances at which the noise's is used.
    floor : float
        Round-off standard error.
    middle : bool
        Also return which middle was used.

    Returns
    -------
    numpy.ndarray
        The covariance.
    str
        With ``middle``: ``"noise"``, ``"envelope"`` or, without a noise model,
        ``"hac"``.
    """
    values, vectors = np.linalg.eigh(hac)
    clipped = bread @ ((vectors * np.maximum(values, 0.0)) @ vectors.T) @ bread.T
    used = "hac"
    if noise is not None:
        analytic = bread @ noise @ bread.T
        if np.all(np.diag(clipped) <= agreement * np.diag(analytic)):
            clipped, used = analytic, "noise"
        else:
            clipped, used = bread @ upper_envelope(hac, noise) @ bread.T, "envelope"
    elif not positive_definite(hac):
        clipped = bread @ ((vectors * np.abs(values)) @ vectors.T) @ bread.T
    covariance = (clipped + clipped.T) / 2 + floor ** 2 * np.eye(len(clipped))
    return (covariance, used) if middle else covariance
