"""Exact responses of the mass-spring-damper plant.

Step and sine inputs: the plant and the signal generator form one autonomous linear
system, evaluated at every time point independently (a Sylvester equation and the
transition matrix in closed form, or matrix exponentials near resonance).  Sampled
inputs: the first-order hold of ``control.forced_response``, extended to non-uniform
grids.  Callable inputs: DOP853 integration.
"""

from __future__ import annotations

from collections.abc import Callable

import control
import numpy as np
import scipy.linalg
from scipy.integrate import solve_ivp

from algid.errors import InputDataError

__all__ = ["is_uniform", "plant_matrices", "free_response", "transition_matrices",
           "exosystem_response", "foh_response", "callable_response"]

#: Relative tolerance of the integrator used for callable inputs.
_CALLABLE_RTOL = 1e-13

#: Absolute tolerance of that integrator, relative to the size of each state.
_CALLABLE_ATOL = 1e-15

#: Number of time points whose matrix exponentials are computed in one batch.
_EXPM_CHUNK = 4096


def is_uniform(t: np.ndarray) -> bool:
    """Tell whether ``t`` is uniformly spaced up to a few units of round-off.

    A grid counts as uniform if every point lies within 8 ulp of the largest time of
    ``t[0] + i * dt`` with ``dt = (t[-1] - t[0]) / (n - 1)`` (grids built as
    ``t0 + np.arange(n) / rate`` or with ``np.linspace`` deviate by at most about 2
    ulp).  Treating such a grid as exactly uniform changes the response by at most the
    deviation times the speed, which is round-off.

    Parameters
    ----------
    t : numpy.ndarray
        Increasing time points.

    Returns
    -------
    bool
        Whether the grid is uniform.
    """
    n = t.size
    if n < 3:
        return True
    dt = (t[-1] - t[0]) / (n - 1)
    ideal = t[0] + np.arange(n) * dt
    tol = 8.0 * np.finfo(np.float64).eps * max(abs(t[0]), abs(t[-1]))
    return bool(np.max(np.abs(t - ideal)) <= tol)



def plant_matrices(sys: control.StateSpace) -> tuple[np.ndarray, np.ndarray]:
    """The matrices ``A`` and ``b`` of the plant as float64 arrays.

    Parameters
    ----------
    sys : control.StateSpace
        The plant (one input).

    Returns
    -------
    A : numpy.ndarray
        Shape ``(2, 2)``.
    b : numpy.ndarray
        The input column, shape ``(2,)``.
    """
    A = np.asarray(sys.A, dtype=np.float64)
    b = np.asarray(sys.B, dtype=np.float64)[:, 0]
    return A, b


def free_response(M: np.ndarray, z0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Evaluate ``z(t_i) = expm(M (t_i - t_0)) z0`` at every time point.

    Every value comes from at most two matrix exponentials, never from stepping
    through the grid, so no error accumulates over long records.  On a uniform grid
    the points are split into blocks of ``L ~ sqrt(n)``; with anchors
    ``z_j = expm(M (t_{jL} - t_0)) z0`` and ``Phi_i = expm(M i dt)`` the value at
    point ``jL + i`` is ``Phi_i z_j`` (about ``2 sqrt(n)`` exponentials in all).  Any
    other grid gets one exponential per point.

    Parameters
    ----------
    M : numpy.ndarray
        System matrix of ``z' = M z``, shape ``(q, q)``.
    z0 : numpy.ndarray
        State at ``t[0]``, shape ``(q,)``.
    t : numpy.ndarray
        Increasing time points.

    Returns
    -------
    numpy.ndarray
        The states, shape ``(len(t), q)``.
    """
    n = t.size
    tau = t - t[0]
    if n == 1:
        return z0[None, :].astype(float)
    if is_uniform(t):
        dt = (t[-1] - t[0]) / (n - 1)
        L = int(np.ceil(np.sqrt(n)))
        idx = np.arange(0, n, L)
        anchors = _expm_times(M, tau[idx]) @ z0  # (nb, q)
        phi = _expm_times(M, np.arange(L) * dt)  # (L, q, q)
        z = np.einsum("iab,jb->jia", phi, anchors).reshape(-1, z0.size)
        return np.ascontiguousarray(z[:n])
    out = np.empty((n, z0.size))
    for start in range(0, n, _EXPM_CHUNK):
        block = tau[start:start + _EXPM_CHUNK]
        out[start:start + block.size] = _expm_times(M, block) @ z0
    return out


def _expm_times(M: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Return the stack ``expm(M * times[i])``, shape ``(len(times),) + M.shape``."""
    out = np.empty((times.size,) + M.shape)
    for start in range(0, times.size, _EXPM_CHUNK):
        block = times[start:start + _EXPM_CHUNK]
        out[start:start + block.size] = scipy.linalg.expm(M[None] * block[:, None, None])
    return out


def transition_matrices(A: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """State-transition matrices ``expm(A tau_i)`` of the plant, in closed form.

    With ``A = [[0, 1], [-K, -B]]``, ``s = -B/2`` and ``q = B**2/4 - K``,
    ``expm(A tau) = E I + F (A - s I)`` where ``E = exp(s tau) cos(w tau)``,
    ``F = exp(s tau) sin(w tau) / w`` with ``w = sqrt(-q)`` if ``q < 0`` (hyperbolic
    functions with ``sqrt(q)`` if ``q > 0``, ``E = exp(s tau)``, ``F = tau exp(s tau)``
    if ``q = 0``).  Trigonometric functions of ``w tau`` keep the phase exact for any
    ``tau``, where a scaling-and-squaring matrix exponential loses about
    ``eps * ||A tau||``.

    Parameters
    ----------
    A : numpy.ndarray
        The plant matrix ``[[0, 1], [-K, -B]]``.
    tau : numpy.ndarray
        Time offsets, 1-D.

    Returns
    -------
    numpy.ndarray
        Shape ``(len(tau), 2, 2)``.
    """
    K, B = -A[1, 0], -A[1, 1]
    sig = -0.5 * B
    q = 0.25 * B * B - K
    decay = np.exp(sig * tau)
    if q < 0.0:  # underdamped
        w = np.sqrt(-q)
        E = decay * np.cos(w * tau)
        F = decay * np.sin(w * tau) / w
        p11, p22 = E - sig * F, E + sig * F
    elif q > 0.0:  # overdamped: real eigenvalues lam1 > lam2
        r = np.sqrt(q)
        lam2 = sig - r
        lam1 = K / lam2  # sig + r without cancellation
        F = np.empty_like(tau)
        p11 = np.empty_like(tau)
        p22 = np.empty_like(tau)
        # r tau < 1: hyperbolic form (no cancellation in sinh(r tau) / r)
        near = r * tau < 1.0
        tn, dn = tau[near], decay[near]
        En = dn * np.cosh(r * tn)
        F[near] = dn * np.sinh(r * tn) / r
        p11[near] = En - sig * F[near]
        p22[near] = En + sig * F[near]
        # r tau >= 1: modal form (exp(lam2 tau) <= exp(-2 r tau) exp(lam1 tau))
        tf = tau[~near]
        e1, e2 = np.exp(lam1 * tf), np.exp(lam2 * tf)
        F[~near] = (e1 - e2) / (2.0 * r)
        p11[~near] = (lam1 * e2 - lam2 * e1) / (2.0 * r)
        p22[~near] = (lam1 * e1 - lam2 * e2) / (2.0 * r)
    else:  # critically damped (or B = K = 0)
        F = tau * decay
        p11, p22 = decay - sig * F, decay + sig * F
    out = np.empty((tau.size, 2, 2))
    out[:, 0, 0] = p11
    out[:, 0, 1] = F
    out[:, 1, 0] = -K * F
    out[:, 1, 1] = p22
    return out


def exosystem_response(
    A: np.ndarray, b: np.ndarray, S: np.ndarray, h: np.ndarray, W: np.ndarray,
    x0: np.ndarray, t: np.ndarray,
) -> np.ndarray:
    """Exact response to an input ``F = h @ w`` generated by ``w' = S w``.

    If the spectra of ``A`` and ``S`` are well apart, the solution ``P`` of
    ``A P - P S = -b h`` gives the exact forced solution ``P w(t)`` and
    ``x(t) = P w(t) + expm(A (t - t0)) (x0 - P w(t0))``, with the transition matrix in
    closed form (:func:`transition_matrices`).  At or near resonance (an eigenvalue gap
    smaller than ``1 / (t[-1] - t[0])``), the plant and the generator are instead merged
    into one autonomous system ``[x; w]' = [[A, b h], [0, S]] [x; w]`` whose free
    response is evaluated with matrix exponentials (:func:`free_response`).

    Parameters
    ----------
    A : numpy.ndarray
        Plant matrix, shape ``(2, 2)``.
    b : numpy.ndarray
        Input column of the plant, shape ``(2,)``.
    S : numpy.ndarray
        Generator matrix, shape ``(q, q)``.
    h : numpy.ndarray
        Output row of the generator, shape ``(q,)``.
    W : numpy.ndarray
        Generator states ``w(t_i)``, evaluated directly, shape ``(q, len(t))``.
    x0 : numpy.ndarray
        Plant state at ``t[0]``.
    t : numpy.ndarray
        Increasing time points.

    Returns
    -------
    numpy.ndarray
        The plant states, shape ``(2, len(t))``.
    """
    n, q = A.shape[0], S.shape[0]
    tau = t - t[0]
    M = np.zeros((n + q, n + q))
    M[:n, :n] = A
    M[:n, n:] = np.outer(b, h)
    M[n:, n:] = S
    gap = np.min(np.abs(np.linalg.eigvals(A)[:, None] - np.linalg.eigvals(S)[None, :]))
    if gap * tau[-1] >= 1.0:
        P = scipy.linalg.solve_sylvester(A, -S, -np.outer(b, h))
        if np.all(np.isfinite(P)):
            phi = transition_matrices(A, tau)
            out = P @ W + np.einsum("kij,j->ik", phi, x0 - P @ W[:, 0])
            # Just after t0 the response is a small difference of the forced and free
            # parts (x ~ t**3 from rest under a sine): there the sum loses relative
            # accuracy, while the matrix exponential of the merged system keeps it
            # (its Pade series for ||M tau|| < 1 has no cancellation).
            early = tau * np.linalg.norm(M, 1) < 1.0
            if np.any(early):
                z0 = np.concatenate([x0, W[:, 0]])
                out[:, early] = free_response(M, z0, t[early])[:, :n].T
            return out
    z = free_response(M, np.concatenate([x0, W[:, 0]]), t)
    return z[:, :n].T


def foh_response(
    sys: control.StateSpace, u: np.ndarray, x0: np.ndarray, t: np.ndarray
) -> np.ndarray:
    """States for an input interpolated linearly between samples (first-order hold).

    On a uniform grid this is ``control.forced_response``.  On a non-uniform grid (which
    ``control.forced_response`` refuses) the same exact per-interval formula is applied
    with each interval's own length.

    Parameters
    ----------
    sys : control.StateSpace
        The plant.
    u : numpy.ndarray
        Input samples at the time points.
    x0 : numpy.ndarray
        State at ``t[0]``.
    t : numpy.ndarray
        Increasing time points.

    Returns
    -------
    numpy.ndarray
        The states, shape ``(2, len(t))``.
    """
    if is_uniform(t):
        resp = control.forced_response(
            sys, timepts=t, inputs=u, initial_state=x0, return_states=True,
            squeeze=True,
        )
        states = np.asarray(resp.states, dtype=np.float64)
        if states.shape != (x0.size, t.size):  # pragma: no cover - defensive
            raise RuntimeError(f"unexpected state array shape {states.shape}")
        return states

    A, b = plant_matrices(sys)
    n = A.shape[0]
    # Over one interval of length h, with u(s) = u0 + d s / h and d = u1 - u0,
    #   [x; u; d]' = [[A, b, 0], [0, 0, 1/h], [0, 0, 0]] [x; u; d],
    # so [x; u; d](h) = expm([[A h, b h, 0], [0, 0, 1], [0, 0, 0]]) [x0; u0; d].
    G = np.zeros((n + 2, n + 2))
    G[:n, :n] = A
    G[:n, n] = b
    G[n, n + 1] = 1.0
    h = np.diff(t)
    Ad = np.empty((h.size, n, n))
    g0 = np.empty((h.size, n))
    g1 = np.empty((h.size, n))
    for start in range(0, h.size, _EXPM_CHUNK):
        hh = h[start:start + _EXPM_CHUNK]
        Mk = G[None] * hh[:, None, None]
        Mk[:, n, n + 1] = 1.0
        E = scipy.linalg.expm(Mk)
        sl = slice(start, start + hh.size)
        Ad[sl] = E[:, :n, :n]
        g1[sl] = E[:, :n, n + 1]
        g0[sl] = E[:, :n, n] - E[:, :n, n + 1]
    states = np.empty((n, t.size))
    states[:, 0] = x0
    x = x0.copy()
    for i in range(h.size):
        x = Ad[i] @ x + g0[i] * u[i] + g1[i] * u[i + 1]
        states[:, i + 1] = x
    return states


#: Largest difference, relative to a state's magnitude, between the integrated response
#: to a callable input and the first-order hold's on its samples before the integration
#: is taken as having stepped over a feature of the input (the hold is accurate to
#: ``dt**2`` of the input's curvature: 1e-7 for a sine at 1 kHz).
_FOH_AGREEMENT = 1e-2


def callable_response(
    sys: control.StateSpace, func: Callable, f: np.ndarray, x0: np.ndarray, t: np.ndarray
) -> np.ndarray:
    """States for a smooth input given as a function of time (DOP853 integration).

    The absolute tolerance of each state is 1e-15 times that state's magnitude,
    estimated from the first-order-hold response to the sampled input, so that the
    tolerance is set by ``rtol`` in any units.

    Parameters
    ----------
    sys : control.StateSpace
        The plant.
    func : callable
        The input ``F(t)``, vectorised.
    f : numpy.ndarray
        ``func`` sampled at the time points.
    x0 : numpy.ndarray
        State at ``t[0]``.
    t : numpy.ndarray
        Increasing time points.

    Returns
    -------
    numpy.ndarray
        The states, shape ``(2, len(t))``.

    Raises
    ------
    InputDataError
        If the integration fails or the response is not finite.
    """
    A, b = plant_matrices(sys)
    rough = foh_response(sys, f, x0, t)
    scale = np.max(np.abs(rough), axis=1)
    floor = max(float(np.max(scale)), float(np.max(np.abs(x0))), np.finfo(float).tiny)
    scale = np.maximum(scale, 1e-6 * floor)
    atol = _CALLABLE_ATOL * scale

    def rhs(time, z):
        force = np.asarray(func(np.array([time])), dtype=np.float64).reshape(-1)[0]
        return A @ z + b * force

    sol = solve_ivp(
        rhs, (t[0], t[-1]), x0, method="DOP853", t_eval=t, rtol=_CALLABLE_RTOL,
        atol=atol,
    )
    if sol.success and sol.y.shape == rough.shape and \
            np.any(np.abs(sol.y - rough) > _FOH_AGREEMENT * scale[:, None]):
        # an adaptive step that starts where the input is flat can pass over a pulse
        # that the samples show (the first-order hold sees it): again, with no step
        # longer than the sampling
        sol = solve_ivp(
            rhs, (t[0], t[-1]), x0, method="DOP853", t_eval=t, rtol=_CALLABLE_RTOL,
            atol=atol, max_step=float(np.max(np.diff(t))),
        )
    if not sol.success or sol.y.shape != (x0.size, t.size):
        raise InputDataError(f"inputs callable could not be integrated: {sol.message}")
    if not np.all(np.isfinite(sol.y)):
        raise InputDataError(
            "inputs callable gave a non-finite response (it returned NaN or inf between "
            "the time points)"
        )
    return np.ascontiguousarray(sol.y, dtype=np.float64)

