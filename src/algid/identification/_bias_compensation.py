"""Least squares with the bias that white output noise causes removed (Koopmans'
estimator), for the window equations of :func:`algid.identify` and its systems.

:class:`algid.Tracker` solves the same estimator window after window in its loops
(``_tracker_solve._koopmans``: the same equilibration, eligibility, top eigenpair and
correction of the bound, its generalised eigenproblem by a Cholesky reduction and
Jacobi rotations where this module calls LAPACK's ``sygvd``); the two agree to
round-off, which the Tracker's tests check against identify."""

from __future__ import annotations

import numpy as np

__all__ = ["bias_compensated", "least_squares", "koopmans", "koopmans_stack",
           "solve_equilibrated"]


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
        return least_squares(A, b, grams, bound)
    theta = theta_bar[:p]
    scores = A * (b - A @ theta)[:, None] + variance * (grams @ theta_bar)[:, :p]
    return theta, scores, A.T @ A - variance * noise[:p, :p], variance, capped


def least_squares(A, b, grams=None, bound=None):
    """Plain least squares, with the returns of :func:`bias_compensated` (no correction).

    Parameters
    ----------
    A : numpy.ndarray, shape (windows, p)
        Regressors of the window equations.
    b : numpy.ndarray, shape (windows,)
        Their known side.
    grams, bound : object
        Unused: the signature of :func:`bias_compensated`.

    Returns
    -------
    theta, scores, jacobian : numpy.ndarray
        The estimate, its estimating equations per window and their derivative.
    variance : None
    capped : bool
        False.
    """
    theta = np.linalg.lstsq(A, b, rcond=None)[0]
    return theta, A * (b - A @ theta)[:, None], A.T @ A, None, False


def koopmans(normal, noise, bound=np.inf):
    """The solve of :func:`bias_compensated` from the sums of its equations.

    :func:`koopmans_stack` on a stack of one, its generalised eigenproblem solved by
    LAPACK's ``sygvd`` (:func:`scipy.linalg.eigh`).

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
    theta_bar, variance, capped = koopmans_stack(normal[None], noise[None],
                                                 np.array([bound], dtype=float))
    if np.isnan(variance[0]):
        return None, None, False
    return theta_bar[0], variance[0], bool(capped[0])


def koopmans_stack(normal, noise, bound):
    """Koopmans' estimator on a stack of problems.

    Per problem: the top eigenpair ``(mu, v)`` of the pencil ``(noise, normal)``, both
    equilibrated by the square roots of ``diag(normal)``, gives ``theta_bar = -v /
    v[-1]`` and the variance ``1 / mu`` when that is at most ``bound``; above it, the
    correction of ``bound`` (least squares with a known variance); no correction where
    the noise is zero, ``bound`` is not positive or ``normal`` is not positive definite.
    Each problem's result is independent of the others in the stack.

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
    capped : numpy.ndarray of bool, shape (k,)
        Whether the variance is the cap ``bound``.

    Examples
    --------
    >>> import numpy as np
    >>> normal = np.array([[[2.0, 1.0], [1.0, 2.0]]])
    >>> theta_bar, variance, capped = koopmans_stack(normal, np.eye(2)[None],
    ...                                              np.array([np.inf]))
    >>> theta_bar.round(6).tolist(), variance.round(6).tolist(), capped.tolist()
    ([[1.0, -1.0]], [1.0], [False])
    """
    k, q1, _ = normal.shape
    p = q1 - 1
    theta_bar = np.full((k, q1), np.nan)
    variance = np.full(k, np.nan)
    capped = np.zeros(k, bool)
    diagonal = np.sqrt(np.einsum("kii->ki", normal))
    diagonal[diagonal == 0] = 1.0
    eligible = np.any(noise != 0, axis=(1, 2)) & (bound > 0)
    top, v, ok = _pencil_lapack(normal, noise, diagonal, eligible)
    eligible &= ok
    if not np.any(eligible):
        return theta_bar, variance, capped
    with np.errstate(divide="ignore", invalid="ignore"):
        eigen = eligible & (top > 0) & (np.abs(v[:, -1]) * diagonal[:, -1] > 1e-8) \
            & (1.0 / top <= bound)
        theta_bar[eigen] = -v[eigen] / v[eigen, -1:]
        variance[eigen] = 1.0 / top[eigen]
    over = np.flatnonzero(eligible & ~eigen & (top > 0) & np.isfinite(bound))
    if over.size:   # the eigenvalue exceeds the bound: the correction of the bound
        cap = bound[over, None, None]
        H = normal[over, :p, :p] - cap * noise[over, :p, :p]
        g = normal[over, :p, p] - cap[:, :, 0] * noise[over, :p, p]
        d = np.sqrt(np.abs(np.einsum("kii->ki", H)))
        d[d == 0] = 1.0
        H = H / d[:, :, None] / d[:, None, :]
        solvable = np.isfinite(H).all(axis=(1, 2)) & np.isfinite(g).all(axis=1)
        H[~solvable] = np.eye(p)
        rhs = np.where(solvable[:, None], g / d, 0.0)[:, :, None]
        try:
            theta = np.linalg.solve(H, rhs)[:, :, 0] / d
        except np.linalg.LinAlgError:   # some singular: one at a time
            theta = np.zeros((len(over), p))
            for i in range(len(over)):
                try:
                    theta[i] = np.linalg.solve(H[i], rhs[i])[:, 0] / d[i]
                except np.linalg.LinAlgError:
                    solvable[i] = False
        keep = over[solvable]
        theta_bar[keep, :p] = theta[solvable]
        theta_bar[keep, p] = -1.0
        variance[keep] = bound[keep]
        capped[keep] = True
    return theta_bar, variance, capped


def _pencil_lapack(normal, noise, diagonal, eligible):
    """Top eigenpairs of the equilibrated pencils ``(noise, normal)`` of a stack, by
    LAPACK's ``sygvd`` one problem at a time.

    Returns the top eigenvalues, their eigenvectors in the unscaled columns and which
    problems were solved (``normal`` positive definite), for :func:`koopmans_stack`.
    """
    from scipy.linalg import eigh

    k, q1, _ = normal.shape
    top, v, ok = np.full(k, np.nan), np.full((k, q1), np.nan), np.zeros(k, bool)
    for i in np.flatnonzero(eligible):
        d = diagonal[i]
        try:
            mu, vectors = eigh(noise[i] / d[:, None] / d[None, :],
                               normal[i] / d[:, None] / d[None, :])
        except np.linalg.LinAlgError:     # exact equations (no noise): least squares
            continue
        top[i], v[i], ok[i] = mu[-1], vectors[:, -1] / d, True
    return top, v, ok


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
