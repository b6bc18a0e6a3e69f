"""Simulated experiments on the mass-spring-damper plant.

The plant is

.. math:: m \\ddot x + c \\dot x + k x = F,

with force :math:`F` in N, displacement :math:`x` in m, mass :math:`m` in kg, damping
:math:`c` in N s/m and stiffness :math:`k` in N/m.  Divided by the mass it reads
:math:`\\ddot x + B \\dot x + K x = f` with :math:`B = c/m`, :math:`K = k/m` and
:math:`f = F/m`; the transfer function from :math:`F` to :math:`x` is
:math:`1/(m s^2 + c s + k)`.

:func:`simulate` produces noise-free responses that are exact up to floating-point
round-off for the built-in step and sine inputs (about 1e-16 absolute for the default
plant on the default grid, with no growth over long records), accurate to the
integrator tolerance (about 1e-13 relative) for a callable input, and exact for the
piecewise-linear interpolation of an array of input samples.  Measurement noise, if
requested, is added to the measured displacement only.

This module needs the ``control`` package (``pip install algid[simulate]``).
"""

from __future__ import annotations

import numbers
import os
import pathlib
from dataclasses import dataclass
from typing import Any, Callable, Iterator

import numpy as np
import scipy.linalg
from scipy.integrate import solve_ivp

try:
    import control
except ImportError as exc:  # pragma: no cover - depends on the environment
    raise ImportError(
        "algid.simulation needs the 'control' package; install it with "
        "'pip install algid[simulate]'"
    ) from exc

from .errors import InputDataError

__all__ = ["plant", "simulate", "SimulationResult", "INPUT_NAMES"]

#: Names of the built-in input signals accepted by :func:`simulate`.
INPUT_NAMES = ("step", "sine")

#: Relative tolerance of the integrator used for callable inputs.
_CALLABLE_RTOL = 1e-13

#: Absolute tolerance of that integrator, relative to the size of each state.
_CALLABLE_ATOL = 1e-15

#: Number of time points whose matrix exponentials are computed in one batch.
_EXPM_CHUNK = 4096


# --------------------------------------------------------------------------------------
# argument checks
# --------------------------------------------------------------------------------------


def _fmt(value: Any) -> str:
    """Format a value compactly (and on one line) for an error message."""
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return repr(float(value))
    text = repr(value)
    text = " ".join(text.split())
    return text if len(text) <= 60 else text[:57] + "..."


def _real(name: str, value: Any) -> float:
    """Convert a scalar argument to a finite float or raise :class:`InputDataError`."""
    if isinstance(value, (bool, np.bool_)) or isinstance(value, (str, bytes)):
        raise InputDataError(f"{name} must be a real number, got {_fmt(value)}")
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise InputDataError(f"{name} must be a real number, got {_fmt(value)}") from None
    if not np.isfinite(out):
        raise InputDataError(f"{name} must be finite, got {_fmt(value)}")
    return out


def _check_parameters(m: Any, c: Any, k: Any) -> tuple[float, float, float]:
    """Validate the physical parameters and return them as floats."""
    m_, c_, k_ = _real("m", m), _real("c", c), _real("k", k)
    if m_ <= 0.0:
        raise InputDataError(f"m must be > 0 (mass in kg), got {_fmt(m)}")
    if c_ < 0.0:
        raise InputDataError(f"c must be >= 0 (damping in N*s/m), got {_fmt(c)}")
    if k_ < 0.0:
        raise InputDataError(f"k must be >= 0 (stiffness in N/m), got {_fmt(k)}")
    return m_, c_, k_


def _time_grid(timepts: Any, duration: Any, rate: Any) -> np.ndarray:
    """Return the validated time grid as a new 1-D float64 array."""
    if timepts is None:
        duration_ = _real("duration", duration)
        rate_ = _real("rate", rate)
        if duration_ <= 0.0:
            raise InputDataError(f"duration must be > 0 s, got {_fmt(duration)}")
        if rate_ <= 0.0:
            raise InputDataError(f"rate must be > 0 Hz, got {_fmt(rate)}")
        n = int(round(duration_ * rate_)) + 1
        if n < 2:
            raise InputDataError(
                f"duration*rate = {duration_ * rate_!r} gives {n} sample; at least 2 "
                "samples are needed (increase duration or rate)"
            )
        return np.arange(n, dtype=np.float64) / rate_

    try:
        t = np.array(timepts, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputDataError("timepts must be a 1-D array of real numbers") from None
    if t.ndim != 1:
        raise InputDataError(f"timepts must be 1-D, got shape {t.shape}")
    if t.size < 2:
        raise InputDataError(f"timepts has {t.size} sample(s); at least 2 samples are needed")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        i = int(bad[0])
        raise InputDataError(f"timepts[{i}] is {float(t[i])!r}; time points must be finite")
    bad = np.flatnonzero(np.diff(t) <= 0.0)
    if bad.size:
        i = int(bad[0]) + 1
        raise InputDataError(
            f"timepts must be strictly increasing, but timepts[{i}] = {float(t[i])!r} <= "
            f"timepts[{i - 1}] = {float(t[i - 1])!r}"
        )
    return t


def _initial_state(initial_state: Any) -> np.ndarray:
    """Validate ``initial_state`` and return it as a float64 array ``[x0, v0]``."""
    try:
        x0 = np.array(initial_state, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputDataError(
            f"initial_state must be a pair (x0, v0) of real numbers, got {_fmt(initial_state)}"
        ) from None
    if x0.shape != (2,):
        raise InputDataError(
            f"initial_state must be a pair (x0, v0), got shape {x0.shape}"
        )
    if not np.all(np.isfinite(x0)):
        raise InputDataError(f"initial_state must be finite, got {_fmt(tuple(x0.tolist()))}")
    return x0


def _is_uniform(t: np.ndarray) -> bool:
    """Tell whether ``t`` is uniformly spaced up to a few units of round-off.

    A grid counts as uniform if every point lies within 8 ulp of the largest time of
    ``t[0] + i * dt`` with ``dt = (t[-1] - t[0]) / (n - 1)`` (grids built as
    ``t0 + np.arange(n) / rate`` or with ``np.linspace`` deviate by at most about 2
    ulp).  Treating such a grid as exactly uniform changes the response by at most the
    deviation times the speed, which is round-off.
    """
    n = t.size
    if n < 3:
        return True
    dt = (t[-1] - t[0]) / (n - 1)
    ideal = t[0] + np.arange(n) * dt
    tol = 8.0 * np.finfo(np.float64).eps * max(abs(t[0]), abs(t[-1]))
    return bool(np.max(np.abs(t - ideal)) <= tol)


# --------------------------------------------------------------------------------------
# the plant and its exact responses
# --------------------------------------------------------------------------------------


def plant(*, m: float = 1.0, c: float = 2.0, k: float = 3.0) -> control.StateSpace:
    """State-space model of the mass-spring-damper ``m x'' + c x' + k x = F``.

    Parameters
    ----------
    m : float, default 1.0
        Mass in kg, must be positive.
    c : float, default 2.0
        Viscous damping coefficient in N s/m, must be non-negative.
    k : float, default 3.0
        Spring stiffness in N/m, must be non-negative.

    Returns
    -------
    control.StateSpace
        Continuous-time system with states ``[x, v]`` (displacement in m and velocity
        in m/s), input ``F`` (force in N) and output ``x``:
        ``A = [[0, 1], [-k/m, -c/m]]``, ``B = [[0], [1/m]]``, ``C = [[1, 0]]``,
        ``D = [[0]]``.

    Raises
    ------
    InputDataError
        If a parameter is not a finite real number, ``m <= 0``, ``c < 0`` or ``k < 0``.

    Examples
    --------
    >>> sys = plant(m=2.0, c=4.0, k=6.0)
    >>> sys.A
    array([[ 0.,  1.],
           [-3., -2.]])
    """
    m, c, k = _check_parameters(m, c, k)
    A = np.array([[0.0, 1.0], [-k / m, -c / m]])
    B = np.array([[0.0], [1.0 / m]])
    C = np.array([[1.0, 0.0]])
    D = np.array([[0.0]])
    return control.ss(
        A, B, C, D, inputs=["F"], outputs=["x"], states=["x", "v"],
        name="mass_spring_damper",
    )


def _matrices(sys: control.StateSpace) -> tuple[np.ndarray, np.ndarray]:
    """Return ``A`` (2, 2) and ``b`` (2,) of the plant as float64 arrays."""
    A = np.asarray(sys.A, dtype=np.float64)
    b = np.asarray(sys.B, dtype=np.float64)[:, 0]
    return A, b


def _free_response(M: np.ndarray, z0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Evaluate ``z(t_i) = expm(M (t_i - t_0)) z0`` at every time point.

    Every value comes from at most two matrix exponentials, never from stepping
    through the grid, so no error accumulates over long records.  On a uniform grid
    the points are split into blocks of ``L ~ sqrt(n)``; with anchors
    ``z_j = expm(M (t_{jL} - t_0)) z0`` and ``Phi_i = expm(M i dt)`` the value at
    point ``jL + i`` is ``Phi_i z_j`` (about ``2 sqrt(n)`` exponentials in all).  Any
    other grid gets one exponential per point.  Returns shape ``(len(t), len(z0))``.
    """
    n = t.size
    tau = t - t[0]
    if n == 1:
        return z0[None, :].astype(float)
    if _is_uniform(t):
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


def _transition(A: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """State-transition matrices ``expm(A tau_i)`` of the plant, in closed form.

    With ``A = [[0, 1], [-K, -B]]``, ``s = -B/2`` and ``q = B**2/4 - K``,
    ``expm(A tau) = E I + F (A - s I)`` where ``E = exp(s tau) cos(w tau)``,
    ``F = exp(s tau) sin(w tau) / w`` with ``w = sqrt(-q)`` if ``q < 0`` (hyperbolic
    functions with ``sqrt(q)`` if ``q > 0``, ``E = exp(s tau)``, ``F = tau exp(s tau)``
    if ``q = 0``).  Trigonometric functions of ``w tau`` keep the phase exact for any
    ``tau``, where a scaling-and-squaring matrix exponential loses about
    ``eps * ||A tau||``.  Returns shape ``(len(tau), 2, 2)``.
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


def _exosystem_response(
    A: np.ndarray, b: np.ndarray, S: np.ndarray, h: np.ndarray, W: np.ndarray,
    x0: np.ndarray, t: np.ndarray,
) -> np.ndarray:
    """Exact response to an input ``F = h @ w`` generated by ``w' = S w``.

    ``W`` holds the generator state ``w(t_i)`` evaluated directly (shape
    ``(q, len(t))``).  If the spectra of ``A`` and ``S`` are well apart, the solution
    ``P`` of ``A P - P S = -b h`` gives the exact forced solution ``P w(t)`` and

        x(t) = P w(t) + expm(A (t - t0)) (x0 - P w(t0)),

    with the transition matrix in closed form (:func:`_transition`).  At or near
    resonance (an eigenvalue gap smaller than ``1 / (t[-1] - t[0])``), the plant and the
    generator are instead merged into one autonomous system
    ``[x; w]' = [[A, b h], [0, S]] [x; w]`` whose free response is evaluated with
    matrix exponentials (:func:`_free_response`).  Returns the plant states, shape
    ``(2, len(t))``.
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
            phi = _transition(A, tau)
            out = P @ W + np.einsum("kij,j->ik", phi, x0 - P @ W[:, 0])
            # Just after t0 the response is a small difference of the forced and free
            # parts (x ~ t**3 from rest under a sine): there the sum loses relative
            # accuracy, while the matrix exponential of the merged system keeps it
            # (its Pade series for ||M tau|| < 1 has no cancellation).
            early = tau * np.linalg.norm(M, 1) < 1.0
            if np.any(early):
                z0 = np.concatenate([x0, W[:, 0]])
                out[:, early] = _free_response(M, z0, t[early])[:, :n].T
            return out
    z = _free_response(M, np.concatenate([x0, W[:, 0]]), t)
    return z[:, :n].T


def _foh_response(
    sys: control.StateSpace, u: np.ndarray, x0: np.ndarray, t: np.ndarray
) -> np.ndarray:
    """States for an input interpolated linearly between samples (first-order hold).

    On a uniform grid this is ``control.forced_response``.  On a non-uniform grid (which
    ``control.forced_response`` refuses) the same exact per-interval formula is applied
    with each interval's own length.  Returns shape ``(2, len(t))``.
    """
    if _is_uniform(t):
        resp = control.forced_response(
            sys, timepts=t, inputs=u, initial_state=x0, return_states=True,
            squeeze=True,
        )
        states = np.asarray(resp.states, dtype=np.float64)
        if states.shape != (x0.size, t.size):  # pragma: no cover - defensive
            raise RuntimeError(f"unexpected state array shape {states.shape}")
        return states

    A, b = _matrices(sys)
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


def _callable_response(
    sys: control.StateSpace, func: Callable, f: np.ndarray, x0: np.ndarray, t: np.ndarray
) -> np.ndarray:
    """States for a smooth input given as a function of time (DOP853 integration).

    The absolute tolerance of each state is 1e-15 times that state's magnitude,
    estimated from the first-order-hold response to the sampled input, so that the
    tolerance is set by ``rtol`` in any units.
    """
    A, b = _matrices(sys)
    rough = _foh_response(sys, f, x0, t)
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
    if not sol.success or sol.y.shape != (x0.size, t.size):
        raise InputDataError(f"inputs callable could not be integrated: {sol.message}")
    if not np.all(np.isfinite(sol.y)):
        raise InputDataError(
            "inputs callable gave a non-finite response (it returned NaN or inf between "
            "the time points)"
        )
    return np.ascontiguousarray(sol.y, dtype=np.float64)


# --------------------------------------------------------------------------------------
# the result
# --------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class SimulationResult:
    """A simulated experiment on the mass-spring-damper.

    Unpacks as ``t, f, x = result``.

    Attributes
    ----------
    t : numpy.ndarray
        Time points in s.
    f : numpy.ndarray
        Applied force ``F`` in N at the time points.
    x : numpy.ndarray
        Measured displacement in m: ``x_true`` plus measurement noise, if any.
    x_true : numpy.ndarray
        Noise-free displacement in m.
    v_true : numpy.ndarray
        Noise-free velocity ``x'`` in m/s.
    m, c, k : float
        Mass (kg), damping (N s/m) and stiffness (N/m) used.
    noise_std : float
        Standard deviation of the noise added to ``x``, in m.
    seed : object
        Seed passed to :func:`numpy.random.default_rng` (``None`` if not given).
    """

    t: np.ndarray
    f: np.ndarray
    x: np.ndarray
    x_true: np.ndarray
    v_true: np.ndarray
    m: float
    c: float
    k: float
    noise_std: float = 0.0
    seed: Any = None

    @property
    def B(self) -> float:
        """Normalised damping ``c/m`` in 1/s."""
        return self.c / self.m

    @property
    def K(self) -> float:
        """Normalised stiffness ``k/m`` in 1/s**2."""
        return self.k / self.m

    def __iter__(self) -> Iterator[np.ndarray]:
        """Yield ``t``, ``f`` and ``x`` so that ``t, f, x = result`` works."""
        yield self.t
        yield self.f
        yield self.x

    def to_csv(self, path: str | os.PathLike) -> pathlib.Path:
        """Write the columns ``t, f, x`` to a comma-separated file.

        The first line is the header ``t,f,x``.  Every number is written as the
        shortest decimal string that reads back as the same float64 (Python's
        ``repr``), so reading the file recovers the arrays exactly.

        Parameters
        ----------
        path : str or os.PathLike
            File to write (overwritten if it exists).

        Returns
        -------
        pathlib.Path
            The path written.
        """
        p = pathlib.Path(path)
        lines = ["t,f,x"]
        lines.extend(
            f"{a!r},{b!r},{c!r}"
            for a, b, c in zip(self.t.tolist(), self.f.tolist(), self.x.tolist())
        )
        p.write_text("\n".join(lines) + "\n", encoding="utf-8")
        return p

    def to_timeresponse(self) -> control.TimeResponseData:
        """Return the experiment as a :class:`control.TimeResponseData`.

        Returns
        -------
        control.TimeResponseData
            With ``time = t``, ``outputs = x`` (measured) and ``inputs = f``.
        """
        return control.TimeResponseData(
            time=self.t, outputs=self.x, inputs=self.f, issiso=True,
            output_labels=["x"], input_labels=["F"], sysname="mass_spring_damper",
        )


# --------------------------------------------------------------------------------------
# the simulator
# --------------------------------------------------------------------------------------


def simulate(
    inputs: str | Callable | Any = "step",
    *,
    m: float = 1.0,
    c: float = 2.0,
    k: float = 3.0,
    duration: float = 5.0,
    rate: float = 1000.0,
    timepts: Any = None,
    amplitude: float = 1.0,
    frequency: float = 1.0,
    initial_state: Any = (0.0, 0.0),
    noise_std: float = 0.0,
    seed: Any = None,
) -> SimulationResult:
    """Simulate an experiment on the mass-spring-damper ``m x'' + c x' + k x = F``.

    Parameters
    ----------
    inputs : {"step", "sine"}, callable or array_like, default "step"
        The applied force ``F`` in N:

        - ``"step"``: ``F = amplitude`` from the first time point on (constant, not a
          ramp over the first interval).
        - ``"sine"``: ``F = amplitude * sin(frequency * t)``.

          For both, the plant and the signal generator (a constant, or an oscillator
          with states ``amplitude sin(frequency t)``, ``amplitude cos(frequency t)``)
          form one autonomous linear system, whose solution is evaluated at every
          time point independently, never by stepping through the grid: the exact
          forced solution (from a Sylvester equation) plus the free response in
          closed form, or, at or near resonance, the matrix exponential of the
          4-state system.  The response is exact up to round-off, also for long
          records and non-uniform grids.
        - a callable ``F(t)``, vectorised: called with a 1-D float array of times it
          must return a float array of the same shape.  The response is integrated
          with ``scipy.integrate.solve_ivp`` (DOP853, ``rtol=1e-13``, ``atol`` 1e-15
          times the size of each state, values at the time points from the dense
          output), accurate to about 1e-13 relative for smooth inputs;
          discontinuities reduce the accuracy locally.
        - an array of samples of ``F`` at the time points: the force is interpolated
          linearly between samples (first-order hold, as ``control.forced_response``
          does) and the response to that piecewise-linear force is exact.  A smooth
          force given this way carries an interpolation error of order ``dt**2``.
    m : float, default 1.0
        Mass in kg, > 0.
    c : float, default 2.0
        Damping in N s/m, >= 0.
    k : float, default 3.0
        Stiffness in N/m, >= 0.
    duration : float, default 5.0
        Length of the experiment in s (ignored if ``timepts`` is given).
    rate : float, default 1000.0
        Sampling rate in Hz (ignored if ``timepts`` is given).  The grid is
        ``np.arange(n) / rate`` with ``n = round(duration * rate) + 1``.
    timepts : array_like, optional
        Time points in s, 1-D and strictly increasing, starting anywhere; uniform
        spacing is not required.
    amplitude : float, default 1.0
        Amplitude of the ``"step"`` and ``"sine"`` inputs in N.
    frequency : float, default 1.0
        Angular frequency of the ``"sine"`` input in rad/s.
    initial_state : (float, float), default (0.0, 0.0)
        Displacement (m) and velocity (m/s) at the first time point.
    noise_std : float, default 0.0
        Standard deviation in m of white Gaussian noise added to the measured
        displacement ``x`` (not to ``x_true``, ``v_true`` or ``f``).
    seed : int, numpy.random.SeedSequence or numpy.random.Generator, optional
        Seed for :func:`numpy.random.default_rng`; the same seed gives the same noise.
        The global random state is never used.

    Returns
    -------
    SimulationResult
        Time points, force, measured and noise-free displacement, noise-free velocity
        and the parameters; unpacks as ``t, f, x``.

    Raises
    ------
    InputDataError
        For a non-finite parameter, ``m <= 0``, ``c < 0``, ``k < 0``,
        ``duration <= 0``, ``rate <= 0``, fewer than 2 time points, ``timepts`` not
        strictly increasing, an unknown input name, a callable returning the wrong
        shape or non-finite values, an input array of the wrong length or with NaN/inf,
        a bad ``initial_state`` or ``noise_std < 0``.

    Examples
    --------
    >>> t, f, x = simulate("sine", frequency=2.0, duration=1.0, rate=100.0)
    >>> t.shape, f.shape, x.shape
    ((101,), (101,), (101,))
    """
    m, c, k = _check_parameters(m, c, k)
    noise = _real("noise_std", noise_std)
    if noise < 0.0:
        raise InputDataError(f"noise_std must be >= 0 m, got {_fmt(noise_std)}")
    t = _time_grid(timepts, duration, rate)
    x0 = _initial_state(initial_state)
    sys = plant(m=m, c=c, k=k)
    A, b = _matrices(sys)

    if isinstance(inputs, str):
        if inputs == "step":
            amp = _real("amplitude", amplitude)
            f = np.full(t.size, amp)
            states = _exosystem_response(
                A, b, np.zeros((1, 1)), np.array([1.0]), f[None, :], x0, t
            )
        elif inputs == "sine":
            amp = _real("amplitude", amplitude)
            w = _real("frequency", frequency)
            f = amp * np.sin(w * t)
            S = np.array([[0.0, w], [-w, 0.0]])
            W = amp * np.stack([np.sin(w * t), np.cos(w * t)])
            states = _exosystem_response(A, b, S, np.array([1.0, 0.0]), W, x0, t)
        else:
            valid = ", ".join(repr(name) for name in INPUT_NAMES)
            raise InputDataError(
                f"inputs={inputs!r} is not a known input; valid names are {valid} "
                "(or pass a callable F(t) or an array of force samples)"
            )
    elif callable(inputs):
        f = _callable_samples(inputs, t)
        states = _callable_response(sys, inputs, f, x0, t)
    else:
        f = _array_samples(inputs, t)
        states = _foh_response(sys, f, x0, t)

    x_true = np.ascontiguousarray(states[0], dtype=np.float64)
    v_true = np.ascontiguousarray(states[1], dtype=np.float64)
    if noise > 0.0:
        rng = np.random.default_rng(seed)
        x = x_true + rng.normal(0.0, noise, size=t.size)
    else:
        x = x_true.copy()
    return SimulationResult(
        t=t, f=np.ascontiguousarray(f, dtype=np.float64), x=x, x_true=x_true,
        v_true=v_true, m=m, c=c, k=k, noise_std=noise, seed=seed,
    )


def _callable_samples(func: Callable, t: np.ndarray) -> np.ndarray:
    """Evaluate a vectorised input function on the grid and check the result."""
    try:
        f = np.array(func(t.copy()), dtype=np.float64)
    except (TypeError, ValueError) as exc:
        detail = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise InputDataError(
            "inputs callable must be vectorised and return real numbers for an array "
            f"of times ({detail})"
        ) from None
    if f.shape != t.shape:
        raise InputDataError(
            f"inputs callable returned shape {f.shape} for {t.size} time points; it must "
            f"be vectorised and return shape {t.shape}"
        )
    bad = np.flatnonzero(~np.isfinite(f))
    if bad.size:
        i = int(bad[0])
        raise InputDataError(
            f"inputs callable returned {float(f[i])!r} at t[{i}] = {float(t[i])!r}; "
            "forces must be finite"
        )
    return f


def _array_samples(values: Any, t: np.ndarray) -> np.ndarray:
    """Check an array of force samples against the time grid."""
    try:
        f = np.array(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputDataError(
            f"inputs must be 'step', 'sine', a callable or an array of numbers, got "
            f"{_fmt(values)}"
        ) from None
    if f.shape != t.shape:
        raise InputDataError(
            f"inputs has shape {f.shape} but the time grid has {t.size} points; give one "
            "force sample per time point"
        )
    bad = np.flatnonzero(~np.isfinite(f))
    if bad.size:
        i = int(bad[0])
        raise InputDataError(f"inputs[{i}] is {float(f[i])!r}; force samples must be finite")
    return f
