"""Least squares with the bias that white output noise causes removed (Koopmans'
estimator), for the window equations of :func:`algid.identify` and its systems.

The estimator itself is written once, in loops,
:func:`algid.identification._tracker_solve.koopmans`, which :class:`algid.Tracker` runs
window after window (compiled by numba when installed); :func:`koopmans` here calls it
on a problem's sums, as Python unless a tracker has compiled it in the process, or the
problem is large (:data:`COMPILE_FROM`): the same operations in the same order, the
same numbers."""

from __future__ import annotations

import numpy as np

__all__ = ["bias_compensated", "least_squares", "koopmans", "solve_equilibrated",
           "COMPILE_FROM"]

#: Columns from which identify has the loops compiled (when numba is installed): as
#: Python a solve costs about 7 ms at 10 columns and grows as their cube, so past this
#: size a few dozen solves outweigh numba's import (about 0.35 s, once per process).
COMPILE_FROM = 10


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
    """
    p = A.shape[1]
    phi = np.column_stack([A, b])
    noise = grams.sum(axis=0)
    theta_bar, variance = koopmans(phi.T @ phi, noise, bound)
    if theta_bar is None:
        return least_squares(A, b, grams, bound)
    theta = theta_bar[:p]
    scores = A * (b - A @ theta)[:, None] + variance * (grams @ theta_bar)[:, :p]
    return theta, scores, A.T @ A - variance * noise[:p, :p], variance


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
    """
    theta = np.linalg.lstsq(A, b, rcond=None)[0]
    return theta, A * (b - A @ theta)[:, None], A.T @ A, None


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

    Examples
    --------
    >>> import numpy as np
    >>> theta_bar, variance = koopmans(np.array([[2.0, 1.0], [1.0, 2.0]]), np.eye(2))
    >>> theta_bar.round(6).tolist(), round(variance, 6)
    ([1.0, -1.0], 1.0)
    """
    # looked up at each call: Python until a tracker or a large problem compiles the
    # loops in this process, compiled from then on (the same numbers either way)
    if normal.shape[0] >= COMPILE_FROM:
        from algid.identification._tracker_kernels import compile_loops

        compile_loops()
    from algid.identification._tracker_solve import koopmans as koopmans_loops

    normal = np.ascontiguousarray(normal, dtype=float)
    noise = np.ascontiguousarray(noise, dtype=float)
    theta_bar = np.empty(normal.shape[0])
    variance = koopmans_loops(normal, noise, float(bound), theta_bar)
    if np.isnan(variance):
        return None, None
    return theta_bar, float(variance)


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
