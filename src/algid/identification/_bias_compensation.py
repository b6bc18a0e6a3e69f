"""Least squares with the bias that white output noise causes removed (Koopmans'
estimator), for the window equations of :func:`algid.identify`."""

from __future__ import annotations

import numpy as np

__all__ = ["bias_compensated", "koopmans", "koopmans_stack", "solve_equilibrated"]


def bias_compensated(A, b, grams, bound=np.inf):
    """Least squares with the output-noise bias removed (Koopmans' estimator).

    With ``Phi = [A | b]`` and ``theta_bar = (theta, -1)``, the noise-free rows satisfy
    ``Phi_0 theta_bar = 0``, and white output noise of variance ``sigma^2`` adds
    ``sigma^2 Q`` to the expectation of ``Phi^T Phi``, where ``Q`` is the sum of the
    per-window noise covariances ``grams`` (known from the kernels).  Hence
    ``(Phi^T Phi - sigma^2 Q) theta_bar = 0``: ``theta_bar`` is the generalised
    eigenvector of the pencil ``(Phi^T Phi, Q)`` of smallest eigenvalue, and that
    eigenvalue estimates ``sigma^2``.

    The eigenvalue counts every misfit of the equations as output noise (quadrature
    error, a misestimated ``sign(q')``, input noise); it is therefore capped by
    ``bound``, an upper bound on the output noise variance from the data alone (the
    one :func:`algid.identify` takes from the samples' differences), and with the cap
    the correction is that of ``sigma^2 = bound`` (bias-compensated least squares with
    a known variance).  When the output noise is negligible, the result is plain least
    squares.

    The estimating equations per window are ``A_j r_j + sigma^2 (G_j theta_bar)_A``
    (summing to zero), whose derivative is ``-(A^T A - sigma^2 Q_AA)``: the sandwich
    covariance uses them (``sigma^2`` held fixed: its own error moves the correction by
    a few per cent of it).

    Parameters
    ----------
    A : numpy.ndarray, shape (windows, p)
        Regressors of the window equations.
    b : numpy.ndarray, shape (windows,)
        Their known side.
    grams : numpy.ndarray, shape (windows, p + 1, p + 1)
        Per window, the covariance that white output noise of unit variance puts into
        ``[A | b]``.
    bound : float
        Upper bound on the output noise variance.

    Returns
    -------
    theta, scores, jacobian : numpy.ndarray
        The estimate, its estimating equations per window and their derivative.
    variance : float or None
        The noise variance of the correction: the eigenvalue, or ``bound`` where the
        eigenvalue exceeds it (the misfit is not only output noise); None where no
        correction was made (plain least squares).
    capped : bool
        Whether the variance is the cap ``bound``.
    """
    p = A.shape[1]
    phi = np.column_stack([A, b])
    noise = grams.sum(axis=0)
    theta_bar, variance, capped = koopmans(phi.T @ phi, noise, bound)
    if theta_bar is None:
        theta = np.linalg.lstsq(A, b, rcond=None)[0]
        return theta, A * (b - A @ theta)[:, None], A.T @ A, None, False
    theta = theta_bar[:p]
    scores = A * (b - A @ theta)[:, None] + variance * (grams @ theta_bar)[:, :p]
    return theta, scores, A.T @ A - variance * noise[:p, :p], variance, capped


def koopmans(normal, noise, bound=np.inf):
    """The solve of :func:`bias_compensated` from the sums of its equations.

    Parameters
    ----------
    normal : numpy.ndarray, shape (p + 1, p + 1)
        ``Phi^T Phi`` of the window equations ``Phi = [A | b]``.
    noise : numpy.ndarray, shape (p + 1, p + 1)
        The sum of their per-window noise covariances.
    bound : float
        Upper bound on the output noise variance.

    Returns
    -------
    theta_bar : numpy.ndarray or None
        ``(theta, -1)``; None where no correction applies (plain least squares).
    variance : float or None
        As in :func:`bias_compensated`.
    capped : bool
        Whether the variance is the cap ``bound``.
    """
    from scipy.linalg import eigh

    p = normal.shape[0] - 1
    d = np.sqrt(np.diag(normal))
    d[d == 0] = 1.0
    if not (np.any(noise != 0) and bound > 0):
        return None, None, False
    try:
        mu, vectors = eigh(noise / d[:, None] / d[None, :], normal / d[:, None] / d[None, :])
    except np.linalg.LinAlgError:     # exact equations (no noise): least squares
        return None, None, False
    v = vectors[:, -1] / d
    if mu[-1] > 0 and abs(v[-1]) * d[-1] > 1e-8 and 1.0 / mu[-1] <= bound:
        return -v / v[-1], 1.0 / mu[-1], False
    if mu[-1] > 0 and np.isfinite(bound):
        theta = solve_equilibrated(normal[:p, :p] - bound * noise[:p, :p],
                                   normal[:p, p] - bound * noise[:p, p])
        return np.append(theta, -1.0), bound, True
    return None, None, False


def koopmans_stack(normal, noise, bound):
    """:func:`koopmans` on a stack of problems (one batched call per step).

    The generalised eigenproblem is reduced by the Cholesky factor of the equilibrated
    ``normal`` (as LAPACK's ``sygv`` does): the results equal :func:`koopmans`'s to
    round-off, each problem's independently of the others in the stack.

    Parameters
    ----------
    normal, noise : numpy.ndarray, shape (k, p + 1, p + 1)
        As in :func:`koopmans`, per problem.
    bound : numpy.ndarray, shape (k,)
        Upper bounds on the output noise variance.

    Returns
    -------
    theta_bar : numpy.ndarray, shape (k, p + 1)
        ``(theta, -1)``, NaN where no correction applies.
    variance : numpy.ndarray, shape (k,)
        The noise variance of the correction, NaN where none.

    Examples
    --------
    >>> import numpy as np
    >>> normal = np.array([[[2.0, 1.0], [1.0, 2.0]]])
    >>> theta_bar, variance = koopmans_stack(normal, np.eye(2)[None], np.array([np.inf]))
    >>> theta_bar.round(6).tolist(), variance.round(6).tolist()
    ([[1.0, -1.0]], [1.0])
    """
    k, q1, _ = normal.shape
    p = q1 - 1
    theta_bar = np.full((k, q1), np.nan)
    variance = np.full(k, np.nan)
    diagonal = np.sqrt(np.einsum("kii->ki", normal))
    diagonal[diagonal == 0] = 1.0
    scale = diagonal[:, :, None] * diagonal[:, None, :]
    eligible = np.any(noise != 0, axis=(1, 2)) & (bound > 0)
    scaled = np.where(eligible[:, None, None], normal / scale, np.eye(q1))
    lower, ok = _cholesky_stack(scaled)
    eligible &= ok
    if not np.any(eligible):
        return theta_bar, variance
    inverse = np.linalg.inv(lower)
    reduced = inverse @ (noise / scale) @ np.swapaxes(inverse, 1, 2)
    mu, vectors = np.linalg.eigh(reduced)
    v = (np.swapaxes(inverse, 1, 2) @ vectors[:, :, -1:])[:, :, 0] / diagonal
    top = mu[:, -1]
    with np.errstate(divide="ignore", invalid="ignore"):
        eigen = eligible & (top > 0) & (np.abs(v[:, -1]) * diagonal[:, -1] > 1e-8) \
            & (1.0 / top <= bound)
        theta_bar[eigen] = -v[eigen] / v[eigen, -1:]
        variance[eigen] = 1.0 / top[eigen]
    capped = np.flatnonzero(eligible & ~eigen & (top > 0) & np.isfinite(bound))
    if capped.size:   # the eigenvalue exceeds the bound: the correction of the bound
        cap = bound[capped, None, None]
        H = normal[capped, :p, :p] - cap * noise[capped, :p, :p]
        g = normal[capped, :p, p] - cap[:, :, 0] * noise[capped, :p, p]
        d = np.sqrt(np.abs(np.einsum("kii->ki", H)))
        d[d == 0] = 1.0
        H = H / d[:, :, None] / d[:, None, :]
        solvable = np.isfinite(H).all(axis=(1, 2)) & np.isfinite(g).all(axis=1)
        H[~solvable] = np.eye(p)
        rhs = np.where(solvable[:, None], g / d, 0.0)[:, :, None]
        try:
            theta = np.linalg.solve(H, rhs)[:, :, 0] / d
        except np.linalg.LinAlgError:   # some singular: one at a time
            theta = np.zeros((len(capped), p))
            for i in range(len(capped)):
                try:
                    theta[i] = np.linalg.solve(H[i], rhs[i])[:, 0] / d[i]
                except np.linalg.LinAlgError:
                    solvable[i] = False
        keep = capped[solvable]
        theta_bar[keep, :p] = theta[solvable]
        theta_bar[keep, p] = -1.0
        variance[keep] = bound[keep]
    return theta_bar, variance


def _cholesky_stack(matrices):
    """Lower Cholesky factors of a stack, and which matrices are positive definite."""
    try:
        return np.linalg.cholesky(matrices), np.ones(len(matrices), bool)
    except np.linalg.LinAlgError:
        lower = np.empty_like(matrices)
        ok = np.ones(len(matrices), bool)
        for i, matrix in enumerate(matrices):
            try:
                lower[i] = np.linalg.cholesky(matrix)
            except np.linalg.LinAlgError:
                lower[i] = np.eye(len(matrix))
                ok[i] = False
        return lower, ok


def solve_equilibrated(H, g):
    """Solve ``H x = g`` scaled by the square roots of ``|diag(H)|``.

    The scaling equilibrates regressors of very different magnitudes (``y''`` next to
    an offset).

    Parameters
    ----------
    H : numpy.ndarray, shape (p, p)
    g : numpy.ndarray, shape (p,)

    Returns
    -------
    numpy.ndarray, shape (p,)
    """
    d = np.sqrt(np.abs(np.diag(H)))
    d[d == 0] = 1.0
    return np.linalg.solve(H / d[:, None] / d[None, :], g / d) / d
