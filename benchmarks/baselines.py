"""Baselines: the estimators a user would pick instead of ``algid``, from scratch.

Every baseline estimates ``B`` and ``K`` of ``x'' + B x' + K x = f`` from uniformly
sampled ``t``, ``f``, ``x`` and uses NumPy and SciPy only (nothing from ``algid``), so
that the benchmark compares ``algid`` with independent implementations.

``naive_algebraic``
    The paper's estimator written directly from its formulas, with
    :func:`scipy.integrate.cumulative_trapezoid` for every integral (the throughput
    baseline of the benchmark).
``StateVariableFilter``, ``svf_least_squares``
    The classical state-variable-filter method: ``x`` and ``f`` pass through
    ``G(s) = lam**3 / (s + lam)**3`` started at rest, which yields ``x_f``, ``x_f'``,
    ``x_f''`` and ``f_f``; least squares of ``x_f'' + B x_f' + K x_f = f_f`` over the
    record.  The filter starts at rest while the plant may not, so the filtered
    equation holds only up to the transient ``e(t) = L^-1{G(s) ((s + B) x0 + v0)}``,
    which biases the estimate (:func:`svf_transient_bias` predicts the bias).
``SVFRecursiveLeastSquares``, ``svf_rls``
    Recursive least squares on the same regressors, forgetting factor 1, fed chunk by
    chunk (on-line).
``output_error_nls``
    Output-error nonlinear least squares with :func:`scipy.optimize.least_squares`
    over ``(B, K, x0, v0)``, simulating the model exactly for the input interpolated
    linearly between samples: the maximum-likelihood estimate for white Gaussian noise
    on ``x`` (statistically efficient), started from a fixed guess.

Choices
-------
``lam = 5 rad/s`` for the state-variable filter: about three times the natural
frequency ``sqrt(K) = 1.7 rad/s`` of the paper's system, the usual rule of thumb (a
filter much faster passes more noise into ``x_f''``, a filter much slower removes the
dynamics of interest and lengthens the start-up transient ``t**2 exp(-lam t)``).
The recursive least squares starts from ``theta = (0, 0)`` with covariance
``1e8 I`` (the signals are of order 1, so the prior weighs like ``1e-8`` of one
sample).  The output-error fit starts from ``B = K = 1``, ``x0 = x[0]``, ``v0 = 0``:
what a user who knows nothing about the plant would try.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.signal
from scipy.integrate import cumulative_trapezoid

__all__ = [
    "SVF_LAMBDA", "RLS_P0", "OE_START",
    "naive_algebraic", "StateVariableFilter", "svf_regressors", "svf_least_squares",
    "svf_transient_bias", "SVFRecursiveLeastSquares", "svf_rls", "rls_covariance_form",
    "OutputErrorModel", "output_error_nls", "BaselineFit",
]

#: Pole of the state-variable filter ``lam**3 / (s + lam)**3`` [rad/s].
SVF_LAMBDA = 5.0
#: Initial covariance ``p0 * I`` of the recursive least squares.
RLS_P0 = 1e8
#: Starting point ``(B, K)`` of the output-error fit (``x0 = x[0]``, ``v0 = 0``).
OE_START = (1.0, 1.0)


def _step(t):
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 3:
        raise ValueError(f"t must be 1-D with at least 3 samples, got shape {t.shape}")
    return (t[-1] - t[0]) / (t.size - 1)


@dataclass
class BaselineFit:
    """Estimates of ``B`` and ``K`` from a baseline.

    Attributes
    ----------
    B, K : float
        Final estimates.
    extra : dict
        Method-specific details (initial state, iterations, ...).
    """

    B: float
    K: float
    extra: dict

    def final(self) -> dict:
        """``{"B": B, "K": K}``."""
        return {"B": self.B, "K": self.K}


# --------------------------------------------------------------------------------------
# (a) the paper's formulas with the cumulative trapezoid
# --------------------------------------------------------------------------------------


def naive_algebraic(t, f, x, *, filter_order=0):
    """The paper's algebraic estimator, written directly with the trapezoid rule.

    With ``I^k`` the ``k``-fold integral from the first sample (time origin), the two
    equations ``P [B, K]^T = Q`` are

    - ``p11 = -2 I^2(t x) + I(t^2 x)``, ``p12 = I^2(t^2 x)``,
      ``q1 = I^2(t^2 f) - 2 I^2 x + 4 I(t x) - t^2 x``,
    - ``p21 = -2 I^3(t x) + I^2(t^2 x)``, ``p22 = I^3(t^2 x)``,
      ``q2 = I^3(t^2 f) - 2 I^3 x + 4 I^2(t x) - I(t^2 x)``,

    solved by Cramer's rule; numerators and determinant are first integrated
    ``filter_order`` more times (the invariant filter ``1/s**p``).

    Parameters
    ----------
    t, f, x : array_like
        Uniformly sampled time [s], input (force per unit mass) and displacement.
    filter_order : int, optional
        ``p`` of the invariant filter.  Default 0 (none).

    Returns
    -------
    B, K : ndarray
        Estimates at every sample (NaN at the first sample, where ``det P = 0``).
    """
    h = _step(t)
    f = np.asarray(f, dtype=float)
    x = np.asarray(x, dtype=float)
    tau = np.asarray(t, dtype=float) - t[0]

    def integral(y):
        return cumulative_trapezoid(y, dx=h, initial=0.0)

    tx, t2x, t2f = tau * x, tau * tau * x, tau * tau * f
    i1_tx = integral(tx)
    i2_tx = integral(i1_tx)
    i3_tx = integral(i2_tx)
    i1_t2x = integral(t2x)
    i2_t2x = integral(i1_t2x)
    i3_t2x = integral(i2_t2x)
    i2_t2f = integral(integral(t2f))
    i3_t2f = integral(i2_t2f)
    i2_x = integral(integral(x))
    i3_x = integral(i2_x)

    p11 = -2.0 * i2_tx + i1_t2x
    p12 = i2_t2x
    p21 = -2.0 * i3_tx + i2_t2x
    p22 = i3_t2x
    q1 = i2_t2f - 2.0 * i2_x + 4.0 * i1_tx - t2x
    q2 = i3_t2f - 2.0 * i3_x + 4.0 * i2_tx - i1_t2x
    num_b = q1 * p22 - p12 * q2
    num_k = p11 * q2 - q1 * p21
    det = p11 * p22 - p12 * p21
    for _ in range(filter_order):
        num_b, num_k, det = integral(num_b), integral(num_k), integral(det)
    with np.errstate(divide="ignore", invalid="ignore"):
        B = np.where(det != 0.0, num_b / det, np.nan)
        K = np.where(det != 0.0, num_k / det, np.nan)
    return B, K


# --------------------------------------------------------------------------------------
# (b) state-variable filter and least squares
# --------------------------------------------------------------------------------------


class StateVariableFilter:
    """``lam**3 / (s + lam)**3`` and its first two derivatives, exactly discretised.

    The filter state ``z = (u_f, u_f', u_f'')`` obeys ``z1' = z2``, ``z2' = z3``,
    ``z3' = -lam**3 z1 - 3 lam**2 z2 - 3 lam z3 + lam**3 u``.  For an input interpolated
    linearly between samples (first-order hold) one step is exactly
    ``z[n+1] = Phi z[n] + G0 u[n] + G1 u[n+1]``.  Each output is run as an IIR filter
    (:func:`scipy.signal.lfilter`, compiled code) with the common denominator
    ``(z - exp(-lam h))**3``; the initial filter states are set so that ``z = 0`` at
    the first sample (the filter starts at rest).  A smooth signal sampled at step
    ``h`` is filtered with an error of order ``h**2`` (the first-order hold).

    Parameters
    ----------
    lam : float
        Filter pole [rad/s], > 0.
    h : float
        Sampling step [s], > 0.
    """

    def __init__(self, lam, h):
        if not (lam > 0 and h > 0):
            raise ValueError(f"lam and h must be positive, got lam={lam!r}, h={h!r}")
        self.lam, self.h = float(lam), float(h)
        lam = self.lam
        A = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0],
                      [-lam**3, -3.0 * lam**2, -3.0 * lam]])
        b = np.array([0.0, 0.0, lam**3])
        self._A = A
        # [z; u; d]' = [[A, b, 0], [0, 0, 1/h], [0, 0, 0]] [z; u; d] with u(s) = u0 + d s/h
        M = np.zeros((5, 5))
        M[:3, :3] = A * h
        M[:3, 3] = b * h
        M[3, 4] = 1.0
        E = scipy.linalg.expm(M)
        self.Phi = E[:3, :3]
        self.G1 = E[:3, 4]
        self.G0 = E[:3, 3] - self.G1
        # xi = z - G1 u obeys xi[n+1] = Phi xi[n] + (Phi G1 + G0) u[n]; z = xi + G1 u
        num, _ = scipy.signal.ss2tf(self.Phi, (self.Phi @ self.G1 + self.G0)[:, None],
                                    np.eye(3), self.G1[:, None])
        pole = np.exp(-lam * h)
        self.a = np.poly([pole, pole, pole])
        self.b = [np.asarray(row, dtype=float) for row in num]

    def _power(self, n):
        """``Phi**n`` for integer ``n`` (negative allowed), in closed form."""
        # A + lam I is nilpotent: expm(A t) = exp(-lam t) (I + t N + t**2 N**2 / 2)
        N = self._A + self.lam * np.eye(3)
        tn = n * self.h
        return np.exp(-self.lam * tn) * (np.eye(3) + tn * N + 0.5 * tn * tn * (N @ N))

    def initial_states(self, u0):
        """``lfilter`` states of the three outputs for ``z = 0`` at a sample ``u0``.

        Parameters
        ----------
        u0 : float
            First sample of the signal.

        Returns
        -------
        list of ndarray
            One state vector (length 3) per output.
        """
        xi0 = -self.G1 * float(u0)  # z[0] = xi[0] + G1 u[0] = 0
        # a free response continued backwards, with zero past input, sets lfilter's state
        past = np.array([self._power(-j) @ xi0 for j in (1, 2, 3)])  # (3 past, 3 outputs)
        return [scipy.signal.lfiltic(self.b[k], self.a, past[:, k], [0.0, 0.0, 0.0])
                for k in range(3)]

    def apply(self, u, states=None):
        """Filter a signal.

        Parameters
        ----------
        u : ndarray
            Samples.
        states : list of ndarray, optional
            Filter states to continue from (from a previous call); default: start at
            rest at ``u[0]``.

        Returns
        -------
        z : ndarray, shape (3, len(u))
            ``u_f``, ``u_f'``, ``u_f''``.
        states : list of ndarray
            Final states, to continue with the next samples.
        """
        u = np.asarray(u, dtype=float)
        if states is None:
            states = self.initial_states(u[0])
        out = np.empty((3, u.size))
        final = []
        for k in range(3):
            out[k], zf = scipy.signal.lfilter(self.b[k], self.a, u, zi=states[k])
            final.append(zf)
        return out, final


def svf_regressors(t, f, x, *, lam=SVF_LAMBDA):
    """Regressors of the state-variable-filter method.

    Parameters
    ----------
    t, f, x : array_like
        Uniformly sampled time [s], input (force per unit mass) and displacement.
    lam : float, optional
        Filter pole [rad/s].  Default :data:`SVF_LAMBDA`.

    Returns
    -------
    phi : ndarray, shape (N, 2)
        ``[x_f', x_f]`` at each sample.
    y : ndarray, shape (N,)
        ``f_f - x_f''``, so that ``y = phi @ [B, K]`` (plus the start-up transient).
    """
    svf = StateVariableFilter(lam, _step(t))
    xf, _ = svf.apply(x)
    ff, _ = svf.apply(f)
    return np.column_stack((xf[1], xf[0])), ff[0] - xf[2]


def svf_least_squares(t, f, x, *, lam=SVF_LAMBDA):
    """Least squares of ``x_f'' + B x_f' + K x_f = f_f`` over the whole record.

    Parameters
    ----------
    t, f, x : array_like
        Uniformly sampled time [s], input (force per unit mass) and displacement.
    lam : float, optional
        Filter pole [rad/s].  Default :data:`SVF_LAMBDA`.

    Returns
    -------
    BaselineFit
        ``extra`` holds ``lam``.
    """
    phi, y = svf_regressors(t, f, x, lam=lam)
    theta, *_ = np.linalg.lstsq(phi, y, rcond=None)
    return BaselineFit(B=float(theta[0]), K=float(theta[1]), extra={"lam": lam})


def svf_transient_bias(t, f, x_true, *, B, K, x0, v0, lam=SVF_LAMBDA):
    """Bias of :func:`svf_least_squares` predicted from the initial conditions.

    The filter starts at rest, so the filtered derivatives miss the initial-condition
    terms of ``L{x'} = s X - x0`` and ``L{x''} = s**2 X - s x0 - v0``; the filtered
    equation is ``y = phi @ theta - e`` with
    ``e(t) = L^-1{lam**3 ((s + B) x0 + v0) / (s + lam)**3}
    = lam**3 exp(-lam t) (x0 (t - lam t**2 / 2) + (B x0 + v0) t**2 / 2)``,
    and least squares returns ``theta - (phi^T phi)^-1 phi^T e``.

    Parameters
    ----------
    t, f, x_true : array_like
        The noise-free experiment.
    B, K, x0, v0 : float
        True parameters and initial state.
    lam : float, optional
        Filter pole [rad/s].

    Returns
    -------
    dict
        ``{"B": predicted bias, "K": predicted bias}`` (estimate minus truth).
    """
    phi, _ = svf_regressors(t, f, x_true, lam=lam)
    tau = np.asarray(t, dtype=float) - t[0]
    e = lam**3 * np.exp(-lam * tau) * (x0 * (tau - 0.5 * lam * tau**2)
                                       + 0.5 * (B * x0 + v0) * tau**2)
    bias, *_ = np.linalg.lstsq(phi, -e, rcond=None)
    return {"B": float(bias[0]), "K": float(bias[1])}


# --------------------------------------------------------------------------------------
# (c) recursive least squares on the same regressors
# --------------------------------------------------------------------------------------


class SVFRecursiveLeastSquares:
    """Recursive least squares on the state-variable-filter regressors, on-line.

    Forgetting factor 1, initial estimate ``theta0`` with covariance ``p0 I``.  The
    recursion is kept in information form, ``R_n = I/p0 + sum phi phi^T``,
    ``r_n = theta0/p0 + sum phi y``, ``theta_n = R_n^-1 r_n``: algebraically the same
    estimates as the covariance-form update ``K = P phi / (1 + phi^T P phi)``,
    ``theta += K (y - phi^T theta)``, ``P -= K phi^T P``
    (:func:`rls_covariance_form`), but a chunk is processed with cumulative sums
    instead of a loop over samples.

    Parameters
    ----------
    lam : float, optional
        Pole of the state-variable filter [rad/s].  Default :data:`SVF_LAMBDA`.
    p0 : float, optional
        Initial covariance scale.  Default :data:`RLS_P0`.
    theta0 : (float, float), optional
        Initial ``(B, K)``.  Default ``(0, 0)``.
    """

    def __init__(self, *, lam=SVF_LAMBDA, p0=RLS_P0, theta0=(0.0, 0.0)):
        self.lam, self.p0 = float(lam), float(p0)
        self.theta0 = np.asarray(theta0, dtype=float)
        self.reset()

    def reset(self):
        """Forget the stream."""
        self._svf = None
        self._states = None
        self._t_last = None
        self._info = np.array([1.0 / self.p0, 0.0, 1.0 / self.p0])  # R11, R12, R22
        self._rhs = self.theta0 / self.p0

    def update(self, t, f, x):
        """Take the next samples and return the estimates at each of them.

        Parameters
        ----------
        t, f, x : float or array_like
            Samples continuing the stream (uniform step, taken from the first two
            samples of the stream).

        Returns
        -------
        B, K : ndarray
            Estimates after each sample (NaN while the step is not known).
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        f = np.atleast_1d(np.asarray(f, dtype=float))
        x = np.atleast_1d(np.asarray(x, dtype=float))
        if self._svf is None:
            if self._t_last is None and t.size == 1:  # step not known yet
                self._t_last, self._first = float(t[0]), (float(f[0]), float(x[0]))
                return np.full(1, np.nan), np.full(1, np.nan)
            if self._t_last is not None:
                h = float(t[0]) - self._t_last
                t = np.concatenate(([self._t_last], t))
                f = np.concatenate(([self._first[0]], f))
                x = np.concatenate(([self._first[1]], x))
                skip = 1
            else:
                h = float(t[1] - t[0])
                skip = 0
            self._svf = StateVariableFilter(self.lam, h)
            self._states = {"x": self._svf.initial_states(x[0]),
                            "f": self._svf.initial_states(f[0])}
        else:
            skip = 0
        self._t_last = float(t[-1])
        xf, self._states["x"] = self._svf.apply(x, self._states["x"])
        ff, self._states["f"] = self._svf.apply(f, self._states["f"])
        p1, p2, y = xf[1], xf[0], ff[0] - xf[2]
        r11 = self._info[0] + np.cumsum(p1 * p1)
        r12 = self._info[1] + np.cumsum(p1 * p2)
        r22 = self._info[2] + np.cumsum(p2 * p2)
        s1 = self._rhs[0] + np.cumsum(p1 * y)
        s2 = self._rhs[1] + np.cumsum(p2 * y)
        self._info = np.array([r11[-1], r12[-1], r22[-1]])
        self._rhs = np.array([s1[-1], s2[-1]])
        det = r11 * r22 - r12 * r12
        B = (r22 * s1 - r12 * s2) / det
        K = (r11 * s2 - r12 * s1) / det
        if skip:  # the first sample was answered (with NaN) by the previous call
            B, K = B[1:], K[1:]
        return B, K


def svf_rls(t, f, x, *, lam=SVF_LAMBDA, p0=RLS_P0, theta0=(0.0, 0.0)):
    """Recursive least squares over a whole record (one chunk).

    Parameters
    ----------
    t, f, x : array_like
        Uniformly sampled time [s], input (force per unit mass) and displacement.
    lam, p0, theta0
        See :class:`SVFRecursiveLeastSquares`.

    Returns
    -------
    B, K : ndarray
        Estimates after each sample.
    """
    return SVFRecursiveLeastSquares(lam=lam, p0=p0, theta0=theta0).update(t, f, x)


def rls_covariance_form(phi, y, *, p0=RLS_P0, theta0=(0.0, 0.0)):
    """Textbook covariance-form recursive least squares, one sample at a time.

    The reference for :class:`SVFRecursiveLeastSquares` (slow: a Python loop).

    Parameters
    ----------
    phi : ndarray, shape (N, p)
    y : ndarray, shape (N,)
    p0 : float, optional
    theta0 : sequence of float, optional

    Returns
    -------
    ndarray, shape (N, p)
        Estimate after each sample.
    """
    theta = np.array(theta0, dtype=float)
    P = p0 * np.eye(theta.size)
    out = np.empty((len(y), theta.size))
    for n, (p, yn) in enumerate(zip(phi, y)):
        Pp = P @ p
        gain = Pp / (1.0 + p @ Pp)
        theta = theta + gain * (yn - p @ theta)
        P = P - np.outer(gain, Pp)
        out[n] = theta
    return out


# --------------------------------------------------------------------------------------
# (d) output-error nonlinear least squares
# --------------------------------------------------------------------------------------


class OutputErrorModel:
    """Exact sampled response of ``x'' + B x' + K x = f`` for a piecewise-linear input.

    For given ``(B, K, x0, v0)``, one step of the state ``z = (x, v)`` is
    ``z[n+1] = Phi z[n] + G0 f[n] + G1 f[n+1]`` (the input interpolated linearly
    between samples, integrated exactly).  The response is run as two second-order IIR
    filters (:func:`scipy.signal.lfilter`): the forced part and the free response of
    the state, so one evaluation costs two passes of compiled code over the record.

    Parameters
    ----------
    t, f : array_like
        Uniformly sampled time [s] and input (force per unit mass).
    """

    def __init__(self, t, f):
        self.h = _step(t)
        self.f = np.asarray(f, dtype=float)
        self._impulse = np.zeros(self.f.size)
        self._impulse[0] = 1.0

    def _discretise(self, B, K):
        h = self.h
        M = np.zeros((4, 4))
        M[:2, :2] = np.array([[0.0, 1.0], [-K, -B]]) * h
        M[1, 2] = h
        M[2, 3] = 1.0
        E = scipy.linalg.expm(M)
        Phi, G1 = E[:2, :2], E[:2, 3]
        G0 = E[:2, 2] - G1
        return Phi, G0, G1

    def response(self, theta):
        """Model output ``x`` at the samples.

        Parameters
        ----------
        theta : sequence of float
            ``(B, K, x0, v0)``.

        Returns
        -------
        ndarray
        """
        B, K, x0, v0 = (float(v) for v in theta)
        Phi, G0, G1 = self._discretise(B, K)
        a = np.array([1.0, -np.trace(Phi), np.linalg.det(Phi)])
        # x of the forced part: C adj(zI - Phi) (G0 + G1 z) / det(zI - Phi)
        b = np.array([G1[0],
                      G0[0] - Phi[1, 1] * G1[0] + Phi[0, 1] * G1[1],
                      -Phi[1, 1] * G0[0] + Phi[0, 1] * G0[1]])
        forced = scipy.signal.lfilter(b, a, self.f)
        # lfilter lets the input enter at n = -1 too (G1 f[0] at n = 0); the state at
        # sample 0 must be (x0, v0): the rest is a free response from z0 - G1 f[0]
        z0 = np.array([x0, v0]) - G1 * self.f[0]
        y0 = z0[0]
        y1 = (Phi @ z0)[0]
        free = scipy.signal.lfilter([y0, y1 + a[1] * y0], a, self._impulse)
        return forced + free


def output_error_nls(t, f, x, *, start=None, method="lm", tol=1e-12, max_nfev=None):
    """Output-error least squares over ``(B, K, x0, v0)`` with scipy.

    Minimises ``sum (x_i - xhat(t_i; B, K, x0, v0))**2`` with
    :func:`scipy.optimize.least_squares` (finite-difference Jacobian), the model
    simulated by :class:`OutputErrorModel`.

    Parameters
    ----------
    t, f, x : array_like
        Uniformly sampled time [s], input (force per unit mass) and displacement.
    start : sequence of float, optional
        ``(B, K)`` or ``(B, K, x0, v0)``.  Default ``(1, 1, x[0], 0)``
        (:data:`OE_START`).
    method : str, optional
        Method of :func:`scipy.optimize.least_squares`.  Default ``"lm"``
        (Levenberg-Marquardt, MINPACK).
    tol : float, optional
        ``ftol``, ``xtol`` and ``gtol``.  Default 1e-12.
    max_nfev : int, optional
        Largest number of model evaluations.

    Returns
    -------
    BaselineFit
        ``extra`` holds ``x0``, ``v0``, ``nfev``, ``status``, ``success``, ``start``.
    """
    x = np.asarray(x, dtype=float)
    model = OutputErrorModel(t, f)
    if start is None:
        start = OE_START
    start = [float(v) for v in start]
    if len(start) == 2:
        start = start + [float(x[0]), 0.0]

    def residual(theta):
        return model.response(theta) - x

    sol = scipy.optimize.least_squares(residual, start, method=method, ftol=tol,
                                       xtol=tol, gtol=tol, max_nfev=max_nfev,
                                       x_scale="jac")
    B, K, x0, v0 = sol.x
    return BaselineFit(B=float(B), K=float(K),
                       extra={"x0": float(x0), "v0": float(v0), "nfev": int(sol.nfev),
                              "status": int(sol.status), "success": bool(sol.success),
                              "start": start})
