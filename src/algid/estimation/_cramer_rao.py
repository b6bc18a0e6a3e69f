"""Cramér–Rao lower bound for the parameters of ``x'' + B x' + K x = f``.

Measurement model: ``y_i = x(t_i; theta) + e_i`` with independent ``e_i ~ N(0, sigma**2)``
at the samples ``t_0 = 0, ..., t_N <= horizon`` and ``theta = (B, K, x0, v0)`` all
unknown (the algebraic estimator does not need the initial conditions, so the bound
that applies to it is the one with them unknown).  The Fisher information is

    FIM = S^T S / sigma**2,   S[i, j] = dx(t_i) / dtheta_j,

with the sensitivities of :func:`algid.estimation._sensitivity.output_sensitivities`, and every
unbiased estimator has ``var(theta_j) >= inv(FIM)[j, j]``.  The inverse is taken through
the QR factorisation of ``S`` (the columns differ in scale by orders of magnitude).
NumPy and SciPy only.
"""

from __future__ import annotations

import numpy as np

from algid.errors import InputDataError
from algid.estimation._sensitivity import SENSITIVITY_PARAMETERS, check_input, output_sensitivities

__all__ = ["crlb", "fisher_information", "covariance_from_sensitivities"]


def _noise(noise_std):
    try:
        sigma = float(noise_std)
    except (TypeError, ValueError):
        raise InputDataError(f"noise_std must be a positive number, got {noise_std!r}") \
            from None
    if not np.isfinite(sigma) or sigma <= 0:
        raise InputDataError(f"noise_std must be a positive number, got {noise_std!r}")
    return sigma


def covariance_from_sensitivities(S, noise_std):
    """``inv(S^T S) * noise_std**2``, computed from the QR factorisation of ``S``.

    Parameters
    ----------
    S : ndarray, shape (N, p)
        Sensitivity (Jacobian) matrix, full column rank.
    noise_std : float

    Returns
    -------
    ndarray, shape (p, p)

    Raises
    ------
    InputDataError
        If ``S`` is rank deficient (the parameters are not identifiable from the data).
    """
    S = np.asarray(S, dtype=float)
    scale = np.linalg.norm(S, axis=0)
    if np.any(scale == 0):
        name = SENSITIVITY_PARAMETERS[int(np.argmin(scale))] if S.shape[1] == 4 else \
            int(np.argmin(scale))
        raise InputDataError(f"the output does not depend on {name}: not identifiable "
                             f"from these data")
    R = np.linalg.qr(S / scale, mode="r")
    diag = np.abs(np.diag(R))
    if diag.min() <= 1e-13 * diag.max():
        raise InputDataError("the sensitivities are linearly dependent: the parameters "
                             "are not identifiable from these data (no excitation?)")
    from scipy.linalg import solve_triangular

    Rinv = solve_triangular(R, np.eye(R.shape[0]))
    cov_scaled = Rinv @ Rinv.T
    return cov_scaled / np.outer(scale, scale) * noise_std**2


def fisher_information(t, f, *, B, K, x0=0.0, v0=0.0, noise_std, horizon=None,
                       mass=None, quadrature_order=6):
    """Fisher information of ``(B, K, x0, v0)`` from noisy samples of ``x``.

    Parameters
    ----------
    t : array_like
        Uniformly spaced sample times [s]; the initial state is at ``t[0]``.
    f : array_like
        Input samples, as for :func:`crlb`.
    B, K : float
        True parameters (``c/m`` and ``k/m``).
    x0, v0 : float, optional
        True initial displacement and velocity.  Default 0.
    noise_std : float
        Standard deviation of the white Gaussian noise on each sample of ``x``.
    horizon : float, optional
        Use the samples with ``t - t[0] <= horizon`` (default: all).
    mass : float, optional
        Known mass: ``f`` is then the force.
    quadrature_order : int, optional
        Points of the input interpolation.  Default 6.

    Returns
    -------
    ndarray, shape (4, 4)
        ``S^T S / noise_std**2`` in the order ``B, K, x0, v0``.
    """
    sigma = _noise(noise_std)
    t, f, _ = check_input(t, f, horizon=horizon, order=quadrature_order)
    u = f / _mass(mass) if mass is not None else f
    _, S = output_sensitivities(t, u, B=B, K=K, x0=x0, v0=v0, order=quadrature_order)
    return S.T @ S / sigma**2


def _mass(mass):
    try:
        m = float(mass)
    except (TypeError, ValueError):
        raise InputDataError(f"mass must be a positive number, got {mass!r}") from None
    if not np.isfinite(m) or m <= 0:
        raise InputDataError(f"mass must be a positive number, got {mass!r}")
    return m


def crlb(t, f, *, B, K, x0=0.0, v0=0.0, noise_std, horizon=None, mass=None,
         quadrature_order=6):
    """Cramér–Rao lower bound on the standard deviation of estimates of ``B`` and ``K``.

    Parameters
    ----------
    t : array_like
        Uniformly spaced sample times [s]; the initial state is at ``t[0]``.
    f : array_like
        Input samples: the force per unit mass, or the force if ``mass`` is given.  The
        input between samples is interpolated as by the quadrature rule of
        ``quadrature_order`` points (exact for a step, ``O(h**q)`` for a smooth input).
    B, K : float
        True parameters (``c/m`` and ``k/m``).
    x0, v0 : float, optional
        True initial displacement and velocity (unknown to the estimator).  Default 0.
    noise_std : float
        Standard deviation of the white Gaussian noise on each sample of ``x``.
    horizon : float, optional
        Use the samples with ``t - t[0] <= horizon`` (default: all).
    mass : float, optional
        Known mass: ``f`` is then the force and the bounds on ``c = B m`` and
        ``k = K m`` are added.
    quadrature_order : int, optional
        Points of the input interpolation.  Default 6.

    Returns
    -------
    dict
        ``{"B": std, "K": std, "x0": std, "v0": std}`` (plus ``"c"``, ``"k"`` with
        ``mass``): the square roots of the diagonal of ``inv(FIM)``.

    Raises
    ------
    InputDataError
        Bad signals or options, or parameters not identifiable from the data.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(5001) * 1e-3
    >>> bound = crlb(t, np.ones_like(t), B=2.0, K=3.0, noise_std=0.01)
    >>> sorted(bound)
    ['B', 'K', 'v0', 'x0']
    """
    sigma = _noise(noise_std)
    t, f, _ = check_input(t, f, horizon=horizon, order=quadrature_order)
    u = f / _mass(mass) if mass is not None else f
    _, S = output_sensitivities(t, u, B=B, K=K, x0=x0, v0=v0, order=quadrature_order)
    std = np.sqrt(np.diag(covariance_from_sensitivities(S, sigma)))
    out = {name: float(s) for name, s in zip(SENSITIVITY_PARAMETERS, std)}
    if mass is not None:
        out["c"] = out["B"] * float(mass)
        out["k"] = out["K"] * float(mass)
    return out
