"""Window equations weighted by the inverse covariance of their noise (``method="gls"``
of :func:`algid.identify`).

Overlapping windows share samples, so the output noise that enters their equations is
correlated: with a window starting every eighth of its length, each sample is in eight
windows, and the equation error ``e_w = [A | b]_w theta_bar`` of window ``w`` is a
weighted sum of the samples' noise, mostly through the second derivative of the
kernel.  Least squares weighs every window alike, which on the records of
``benchmarks.window_rule_study`` leaves the estimate 2 to 2.9 times the Cramér–Rao
bound; generalised least squares, ``A^T S^-1 A theta = A^T S^-1 b`` with ``S`` the
covariance of the equation errors (per unit noise variance), weighs the frequencies
of the record as the model's own dynamics filter the noise, and brought the same
records to 1.1 to 1.3 times the bound.

``S`` is banded: windows more than ``length / stride`` apart share no sample.  It is
factored ``S = L L^T`` (banded Cholesky, per segment), and the equations whitened by
``L^-1``; the bias that noise in the regressors causes is removed as in Koopmans'
estimator (:func:`algid.identification._bias_compensation.koopmans`), with the noise
covariance of the whitened equations ``sum_{w,v} (S^-1)_{wv} Cov([A | b]_v, [A | b]_w)``:
only the band of ``S^-1`` enters it, computed from ``L`` by Takahashi's recurrence
(:func:`inverse_band`).  ``S`` is made from a first estimate (bias-compensated least
squares): the weighting needs the parameters only roughly.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cholesky_banded, solve_banded

from algid.identification._bias_compensation import koopmans
from algid.identification._window_covariance import lagged_products
from algid.identification._window_kernels import window_sample_weights

__all__ = ["column_noise_weights", "equation_noise_band", "inverse_band",
           "whitened_equations", "WhitenedEquations"]


def column_noise_weights(problem, s, length, multiplicity, stride):
    """The weight of every sample's output noise in every window's columns of segment
    ``s``: ``{column: array (windows, length)}``, the columns of ``[A | b]`` whose
    terms read the output (in the units of the rows, :meth:`WindowProblem.rows`).

    To first order, unit output noise ``e`` puts ``sum_m H[w, m] e[w * stride + m]``
    into column ``c`` of window ``w``: the factor's sensitivity times the term kernel's
    sample weight, times the term's coefficient in that column (negated on the known
    side).

    Parameters
    ----------
    problem : WindowProblem
    s : int
        Segment index.
    length, multiplicity, stride : int
        Window length (samples), kernel multiplicity, samples between window starts.

    Returns
    -------
    dict
        Arrays of one row where every window weighs its samples alike (every term
        reads the output as itself on uniform segments: :attr:`WindowProblem.
        uniform_noise`).
    """
    seg = problem.segments[s]
    alike = problem.uniform_noise
    columns = {}
    for column, weight, derivative, factor, _ in problem.noise_paths():
        kernel = window_sample_weights(seg.t, seg.step, length, multiplicity, derivative,
                                       stride)
        if alike:
            product = weight * kernel[None, :]
        else:
            windows = np.lib.stride_tricks.sliding_window_view(
                problem.sensitivity(factor)[s], length)[::stride]
            product = weight * windows * kernel
        if column in columns:
            columns[column] += product
        else:
            columns[column] = product
    return columns


def equation_noise_band(weights, lags, stride, count):
    """The covariance of the windows' equation errors per unit noise variance, in the
    lower banded form of :func:`scipy.linalg.cholesky_banded`.

    Parameters
    ----------
    weights : numpy.ndarray, shape (windows, length) or (1, length)
        Each sample's noise weight in each window's equation error (one row: the same
        in every window).
    lags : int
        Window lags that share samples (the band's width, counting lag 0).
    stride : int
    count : int
        Windows.

    Returns
    -------
    numpy.ndarray, shape (lags, count)
        ``band[d, w] = Cov(e_{w + d}, e_w)`` (zero past the last window).
    """
    band = np.zeros((lags, count))
    for d in range(lags):
        if weights.shape[0] == 1:
            shift = d * stride
            band[d, :count - d] = weights[0, shift:] @ weights[0, :weights.shape[1] - shift]
        else:
            band[d, :count - d] = lagged_products(weights, weights, d, stride)
    return band


def inverse_band(lower):
    """The band of ``S^-1`` from the banded Cholesky factor ``L`` of ``S`` (Takahashi's
    recurrence, from ``L^T S^-1 = L^-1``, whose upper triangle holds only its diagonal).

    Parameters
    ----------
    lower : numpy.ndarray, shape (k + 1, n)
        ``L`` in lower banded form (``lower[d, j] = L[j + d, j]``).

    Returns
    -------
    numpy.ndarray, shape (k + 1, n)
        ``Z[j + d, j]`` of ``Z = S^-1`` in the same form.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.linalg import cholesky_banded
    >>> S = np.array([[4.0, 1.0, 0.0], [1.0, 3.0, 1.0], [0.0, 1.0, 2.0]])
    >>> band = np.array([[4.0, 3.0, 2.0], [1.0, 1.0, 0.0]])
    >>> Z = inverse_band(cholesky_banded(band, lower=True))
    >>> bool(np.allclose(Z[0], np.diag(np.linalg.inv(S))))
    True
    """
    k = lower.shape[0] - 1
    n = lower.shape[1]
    out = np.zeros_like(lower)
    block = np.zeros((k, k))   # Z over the k rows and columns after the current one
    for j in range(n - 1, -1, -1):
        m = min(k, n - 1 - j)
        pivot = lower[0, j]
        column = lower[1:m + 1, j]
        off = -(block[:m, :m] @ column) / pivot
        diagonal = (1.0 / pivot - column @ off) / pivot
        out[0, j] = diagonal
        out[1:m + 1, j] = off
        if k:
            block[1:, 1:] = block[:-1, :-1].copy()
            block[0, 0] = diagonal
            block[1:m + 1, 0] = block[0, 1:m + 1] = off[:k - 1] if m == k else off
    return out


class WhitenedEquations:
    """The window equations of one multiplicity whitened by their noise covariance.

    Parameters
    ----------
    problem : WindowProblem
    length, multiplicity : int
    theta_bar : numpy.ndarray
        A first estimate followed by -1, in the units of the rows (it weighs the terms'
        noise into each window's equation error).
    basis : WindowBasis
        The equations in their orthonormal basis (``basis.A``, ``basis.b``).
    ids : numpy.ndarray
        The segment of each window.
    stride : int

    Attributes
    ----------
    usable : bool
        Whether the covariance of the equation errors was positive definite (else the
        other attributes are not set).
    A, b : numpy.ndarray
        ``L^-1`` times the basis' regressors and known side.
    noise : numpy.ndarray, shape (p + 1, p + 1)
        The noise covariance of the whitened ``[A | b]`` per unit output noise variance,
        in the basis.
    """

    def __init__(self, problem, length, multiplicity, theta_bar, basis, ids, stride):
        lags = -(-length // stride)
        p = basis.A.shape[1]
        beta = np.ldexp(1.0, -basis.b_shift)
        self.usable = True
        self.A = np.empty_like(basis.A)
        self.b = np.empty_like(basis.b)
        self._factors = []
        noise = np.zeros((p + 1, p + 1))
        for s in np.unique(ids):
            rows = np.flatnonzero(ids == s)
            columns = column_noise_weights(problem, int(s), length, multiplicity, stride)
            weights = sum(theta_bar[c] * h for c, h in columns.items())
            width = min(lags, len(rows))
            band = equation_noise_band(weights, width, stride, len(rows)) * beta ** 2
            try:
                lower = cholesky_banded(band, lower=True)
            except np.linalg.LinAlgError:
                # the noise enters these equations too little to weigh them by it
                self.usable = False
                return
            self._factors.append((rows, lower))
            self.A[rows] = solve_banded((width - 1, 0), lower, basis.A[rows])
            self.b[rows] = solve_banded((width - 1, 0), lower, basis.b[rows])
            inverse = inverse_band(lower)
            noisy = list(columns)
            stack = np.stack([columns[c] for c in noisy])
            block = np.zeros((len(noisy), len(noisy)))
            for d in range(width):   # sum_w Z[w + d, w] Cov([A | b]_w, [A | b]_{w + d})
                shift = d * stride
                if stack.shape[1] == 1:   # every window alike
                    lagged = stack[:, 0, shift:] @ stack[:, 0, :length - shift].T \
                        * inverse[d, :len(rows) - d].sum()
                else:
                    first = stack[:, :len(rows) - d, shift:].reshape(len(noisy), -1)
                    later = (stack[:, d:, :length - shift]
                             * inverse[d, :len(rows) - d, None]).reshape(len(noisy), -1)
                    lagged = first @ later.T
                block += lagged if d == 0 else lagged + lagged.T
            noise[np.ix_(noisy, noisy)] += block
        self.noise = basis.change.T @ noise @ basis.change

    def solve(self, bound=np.inf):
        """Koopmans' estimator on the whitened equations (plain least squares where it
        makes no correction), with the returns of
        :func:`algid.identification._bias_compensation.bias_compensated` and the weights
        of the original windows in its estimating equations.

        Parameters
        ----------
        bound : float
            Upper bound on the output noise variance.

        Returns
        -------
        theta, scores, jacobian : numpy.ndarray
            The estimate (in the basis), its estimating equations per whitened window
            (the correction spread evenly over them) and their derivative.
        variance : float
            The noise variance of the correction, or of the misfit where none is made
            (at most ``bound``).
        weights : numpy.ndarray
            ``S^-1 A``: the weight of each original window's residual.
        """
        p = self.A.shape[1]
        rows = np.column_stack([self.A, self.b])
        theta_bar, variance = koopmans(rows.T @ rows, self.noise, bound)
        if theta_bar is None:
            theta = np.linalg.lstsq(self.A, self.b, rcond=None)[0]
            theta_bar = np.append(theta, -1.0)
            misfit = self.b - self.A @ theta
            weight = float(theta_bar @ self.noise @ theta_bar)
            variance = min(float(misfit @ misfit) / weight, bound) if weight > 0 else bound
            scores, jacobian = self.A * misfit[:, None], self.A.T @ self.A
        else:
            theta = theta_bar[:p]
            misfit = self.b - self.A @ theta
            correction = variance * (self.noise @ theta_bar)[:p]
            scores = self.A * misfit[:, None] + correction / len(misfit)
            jacobian = self.A.T @ self.A - variance * self.noise[:p, :p]
        return theta, scores, jacobian, variance, self.unwhitened_weights(self.A)

    def unwhitened_weights(self, Z):
        """``S^-1`` times the un-whitened rows of ``Z``: given ``Z = L^-1 X``, the
        weights ``L^-T Z`` of the original windows in ``X^T S^-1 r``.

        Parameters
        ----------
        Z : numpy.ndarray, shape (windows, k)

        Returns
        -------
        numpy.ndarray, shape (windows, k)
        """
        out = np.empty_like(Z)
        for rows, lower in self._factors:
            width = lower.shape[0]
            upper = np.zeros_like(lower)     # L^T in the upper form of solve_banded
            for d in range(width):
                upper[width - 1 - d, d:] = lower[d, :lower.shape[1] - d]
            out[rows] = solve_banded((0, width - 1), upper, Z[rows])
        return out


def whitened_equations(problem, length, multiplicity, theta_bar, basis, ids, stride):
    """:class:`WhitenedEquations`, or None where output noise enters no column, or
    too little for the covariance of the equations' errors to be positive definite
    (there is then no noise to weigh them by).

    Parameters
    ----------
    problem, length, multiplicity, theta_bar, basis, ids, stride
        As in :class:`WhitenedEquations`.

    Returns
    -------
    WhitenedEquations or None
    """
    if not problem.noise_paths():
        return None
    whitened = WhitenedEquations(problem, length, multiplicity, theta_bar, basis, ids,
                                 stride)
    return whitened if whitened.usable else None
