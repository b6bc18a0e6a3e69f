"""Linear time-invariant filters of sampled signals, discretised to high order.

The algebraic estimate is a quotient ``theta_i(t) = n_i(t) / d(t)`` of signals that
satisfy ``n_i(t) = theta_i d(t)`` for every ``t``.  Any linear filter ``F`` applied to
the numerators and to the denominator alike keeps that identity,
``F[n_i] = theta_i F[d]``, so the quotient of the filtered signals is still the exact
parameter, while the filter attenuates the measurement noise.  Besides the invariant
filter ``1/s**p`` (iterated integrals, :mod:`algid.signals._quadrature`), ``as_lowpass``
accepts any strictly proper, stable, continuous-time transfer function, and
:meth:`LowpassFilter.apply` filters a sampled signal with zero initial state at the
time origin (the first sample).

Discretisation (:func:`lti_response`): between samples the input is taken as the
polynomial of degree ``q - 1`` through ``q`` neighbouring samples, exactly as the
cumulative quadrature rule of ``q`` points does (the current and ``q - 1`` past
samples; the first ``q - 1`` samples at the start-up), and the state equation
``z' = A z + b u`` is integrated over each sampling interval exactly for that
polynomial, with matrix exponentials of an augmented matrix.  The error of the
response to a smooth input is therefore ``O(h**q)``; a polynomial input of degree
``< q`` (a step, for instance) gives the exact response up to round-off.  For
``A = 0`` the rule reduces to the quadrature rule of :mod:`algid.signals._quadrature`;
``q = 2`` is the first-order hold (linear interpolation) of ``control.forced_response``.

The recursion ``z[j] = Phi z[j-1] + w[j]`` is evaluated as a prefix scan in
``log2(n)`` vectorised passes (``z[j] += Phi**m z[j-m]`` for ``m = 1, 2, 4, ...``):
each value is a sum of terms from its own past only, so early, small values keep
their relative accuracy.  NumPy and SciPy only.
"""

from __future__ import annotations

import numbers
import sys
from functools import cache

import numpy as np

from algid.errors import InputDataError
from algid.signals._quadrature import check_quadrature_points

__all__ = ["LowpassFilter", "as_lowpass", "lti_response", "interval_input_matrices",
           "expm_small"]


# --------------------------------------------------------------------------------------
# exact discretisation for piecewise-polynomial inputs
# --------------------------------------------------------------------------------------


#: Terms of the Taylor series of the matrix exponential (after scaling to norm <= 1/2
#: the remainder is below ``0.5**17 / 17! < 1e-17``).
_TAYLOR_TERMS = 17


def expm_small(M):
    """Matrix exponential of a small matrix, by scaling, Taylor series and squaring.

    NumPy products only.  For the matrices of this module (a few tens of rows, norm of
    order one) it is as accurate as :func:`scipy.linalg.expm` and, when the BLAS runs
    multi-threaded on a busy machine, much faster.

    Parameters
    ----------
    M : ndarray, shape (n, n)

    Returns
    -------
    ndarray, shape (n, n)
    """
    M = np.asarray(M, dtype=float)
    norm = np.linalg.norm(M, 1)
    squarings = int(max(0, np.ceil(np.log2(norm / 0.5)))) if norm > 0.5 else 0
    X = M / 2.0**squarings
    term = np.eye(M.shape[0])
    out = term.copy()
    for k in range(1, _TAYLOR_TERMS + 1):
        term = term @ X / k
        out += term
    for _ in range(squarings):
        out = out @ out
    return out


@cache
def _shifted_lagrange(order: int, lo: int) -> np.ndarray:
    """Coefficients ``beta[i, d]`` with ``l_i(lo + v) = sum_d beta[i, d] v**d``.

    ``l_i`` is the Lagrange basis polynomial of the nodes ``0, ..., order - 1``
    (``l_i(j) = delta_ij``); exact rational arithmetic, rounded once at the end.
    """
    from fractions import Fraction  # (exact weights; imported on first use)

    nodes = range(order)
    out = np.empty((order, order))
    for i in nodes:
        poly = [Fraction(1)]  # coefficients in v, lowest degree first
        for j in nodes:
            if j == i:
                continue
            # factor (lo + v - j) / (i - j)
            root = Fraction(lo - j, i - j)
            slope = Fraction(1, i - j)
            new = [Fraction(0)] * (len(poly) + 1)
            for d, coef in enumerate(poly):
                new[d] += coef * root
                new[d + 1] += coef * slope
            poly = new
        out[i] = [float(c) for c in poly]
    return out


def interval_input_matrices(A, b, h, *, points=6):
    """Exact one-step matrices of ``z' = A z + b u`` for a polynomially interpolated input.

    Parameters
    ----------
    A : array_like, shape (n, n)
    b : array_like, shape (n,)
    h : float
        Sampling step.
    points : int, optional
        Number ``q`` of samples the input polynomial passes through.  Default 6.

    Returns
    -------
    Phi : ndarray, shape (n, n)
        ``expm(A h)``.
    regular : ndarray, shape (n, q)
        ``z[j] = Phi z[j-1] + regular @ u[j-q+1 : j+1]`` for ``j >= q - 1``.
    startup : ndarray, shape (q - 2, n, q)
        ``z[j] = Phi z[j-1] + startup[j-1] @ u[0 : q]`` for ``j = 1, ..., q - 2``.
    """
    check_quadrature_points(points, name="points (of the interpolation)")
    A = np.atleast_2d(np.asarray(A, dtype=float))
    b = np.asarray(b, dtype=float).reshape(-1)
    n, q = A.shape[0], points
    # xi = [z; w_0 .. w_{q-1}] over v in [0, 1] (t = t0 + v h):
    #   dz/dv = h A z + b w_0,  dw_d/dv = w_{d+1},  dw_{q-1}/dv = 0,
    # so with z(0) = 0 and w(0) = e_d: z(1) = int_0^1 expm(h A (1 - v)) b v**d / d! dv.
    M = np.zeros((n + q, n + q))
    M[:n, :n] = A * h
    M[:n, n] = b
    M[n + np.arange(q - 1), n + 1 + np.arange(q - 1)] = 1.0
    E = expm_small(M)
    Phi = E[:n, :n]
    factorial = np.cumprod(np.r_[1.0, np.arange(1, q)])  # d!
    moments = E[:n, n:] * factorial  # column d: int_0^1 expm(hA(1-v)) b v**d dv

    def weights(lo):
        return h * moments @ _shifted_lagrange(q, lo).T  # (n, q)

    regular = weights(q - 2)
    startup = np.array([weights(lo) for lo in range(q - 2)]).reshape(q - 2, n, q)
    return Phi, regular, startup


def _prefix_scan(Phi, w):
    """Solve ``z[0] = w[0]``, ``z[j] = Phi z[j-1] + w[j]`` in place (w: (N, n)).

    Pass ``m`` adds ``Phi**m z[j-m]`` (``m = 1, 2, 4, ...``; the powers by repeated
    squaring), after which ``z[j]`` holds the sum over the last ``2 m`` inputs.
    """
    z = w
    n_samples = z.shape[0]
    power = Phi
    shift = 1
    while shift < n_samples:
        z[shift:] = z[shift:] + z[:-shift] @ power.T
        shift *= 2
        if shift < n_samples:
            power = power @ power
    return z


def lti_response(A, b, u, h, *, initial_state=None, points=6):
    """States of ``z' = A z + b u`` at the samples, for a sampled input ``u``.

    The input between samples is the local interpolating polynomial of degree
    ``points - 1`` (the stencil of the cumulative quadrature rule of ``points`` points);
    the response to it is exact.  The error for a smooth input is ``O(h**points)``, and
    a polynomial input of degree ``< points`` (e.g. a constant) is reproduced exactly.

    Parameters
    ----------
    A : array_like, shape (n, n)
    b : array_like, shape (n,)
    u : array_like, shape (N,)
        Input samples on a uniform grid of step ``h``, ``N >= points``.
    h : float
        Sampling step.
    initial_state : array_like, shape (n,), optional
        State at the first sample (default zero).
    points : int, optional
        Number of points of the interpolation (2 = first-order hold).  Default 6.

    Returns
    -------
    ndarray, shape (N, n)
        State at each sample.

    Examples
    --------
    >>> import numpy as np
    >>> from algid.signals import lti_response
    >>> double_integrator = [[0.0, 1.0], [0.0, 0.0]], [0.0, 1.0]
    >>> states = lti_response(*double_integrator, np.ones(101), 0.01)   # u = 1 for 1 s
    >>> states.shape, states[-1]                                      # (t**2 / 2, t)
    ((101, 2), array([0.5, 1. ]))
    """
    A = np.atleast_2d(np.asarray(A, dtype=float))
    u = np.asarray(u, dtype=float)
    n_samples, n = u.shape[0], A.shape[0]
    if n_samples < points:
        raise InputDataError(f"{n_samples} samples are too few for an interpolation of "
                             f"{points} points")
    Phi, regular, startup = interval_input_matrices(A, b, h, points=points)
    w = np.empty((n_samples, n))
    w[0] = 0.0 if initial_state is None else np.asarray(initial_state, dtype=float)
    if points > 2:
        w[1:points - 1] = startup @ u[:points]
    windows = np.lib.stride_tricks.sliding_window_view(u, points)  # (N - q + 1, q)
    w[points - 1:] = windows @ regular.T
    return _prefix_scan(Phi, w)


# --------------------------------------------------------------------------------------
# filter specifications
# --------------------------------------------------------------------------------------


def _coefficients(values, what):
    try:
        arr = np.atleast_1d(np.squeeze(np.asarray(values)))
    except (TypeError, ValueError):
        raise InputDataError(f"lowpass {what} must be a 1-D array of real coefficients, "
                             f"got {values!r}") from None
    if arr.ndim != 1 or arr.dtype.kind not in "biuf":
        raise InputDataError(f"lowpass {what} must be a 1-D array of real coefficients, "
                             f"got {values!r}")
    arr = arr.astype(float)
    if not np.all(np.isfinite(arr)):
        raise InputDataError(f"lowpass {what} has a non-finite coefficient: {arr.tolist()}")
    nonzero = np.flatnonzero(arr)
    return arr[nonzero[0]:] if nonzero.size else arr[:0]


def _continuous(spec):
    dt = getattr(spec, "dt", None)
    if dt is None or dt is False or (isinstance(dt, numbers.Real) and dt == 0):
        return
    raise InputDataError(f"lowpass must be a continuous-time filter, got a discrete-time "
                         f"system with dt={dt!r}")


class LowpassFilter:
    """A validated strictly proper, stable, continuous-time SISO filter.

    Build it with ``as_lowpass``.

    Attributes
    ----------
    A : ndarray, shape (n, n)
    b : ndarray, shape (n,)
    c : ndarray, shape (n,)
        State-space realisation ``z' = A z + b u``, ``y = c z`` (no feedthrough).
    poles : ndarray
        Eigenvalues of ``A``, all with negative real part.

    Examples
    --------
    >>> import numpy as np
    >>> from algid.signals import LowpassFilter
    >>> lowpass = LowpassFilter([[-10.0]], [10.0], [1.0])    # 10 / (s + 10)
    >>> lowpass, lowpass.dc_gain()
    (<LowpassFilter filter_order=1 poles=[-10.0]>, 1.0)
    >>> step = lowpass.apply(np.ones(1001), 1e-3)           # 1 - exp(-10 t)
    >>> round(float(step[-1]), 6)
    0.999955
    """

    def __init__(self, A, b, c):
        self.A = np.asarray(A, dtype=float)
        self.b = np.asarray(b, dtype=float).reshape(-1)
        self.c = np.asarray(c, dtype=float).reshape(-1)
        self.poles = np.linalg.eigvals(self.A) if self.A.size else np.empty(0)

    @property
    def filter_order(self) -> int:
        """Order of the filter: its number of states (poles)."""
        return self.A.shape[0]

    def dc_gain(self) -> float:
        """Static gain ``-c A^-1 b``.

        Returns
        -------
        float
            The gain at zero frequency.
        """
        return float(-self.c @ np.linalg.solve(self.A, self.b))

    def apply(self, y, h, *, points=6):
        """Filter a sampled signal, with zero initial state at the first sample.

        Parameters
        ----------
        y : array_like, shape (N,)
            Samples on a uniform grid of step ``h``.
        h : float
            Sampling step.
        points : int, optional
            Points of the input interpolation (as the quadrature rule).  Default 6.

        Returns
        -------
        ndarray, shape (N,)
            The filter output at the samples (``0`` at the first one).
        """
        return lti_response(self.A, self.b, y, h, points=points) @ self.c

    def __repr__(self):
        poles = np.round(self.poles, 6).tolist()
        return f"<LowpassFilter filter_order={self.filter_order} poles={poles}>"


def _from_state_space(A, B, C, D):
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.atleast_2d(np.asarray(B, dtype=float))
    C = np.atleast_2d(np.asarray(C, dtype=float))
    D = np.atleast_2d(np.asarray(D, dtype=float))
    n = A.shape[0]
    if n == 0 or A.shape != (n, n):
        raise InputDataError(f"lowpass state matrix A must be square and non-empty, "
                             f"got shape {A.shape}")
    if B.shape != (n, 1) or C.shape != (1, n):
        raise InputDataError(f"lowpass must be single-input single-output, got B of shape "
                             f"{B.shape} and C of shape {C.shape} for {n} states")
    for name, mat in (("A", A), ("B", B), ("C", C), ("D", D)):
        if not np.all(np.isfinite(mat)):
            raise InputDataError(f"lowpass matrix {name} has a non-finite entry")
    if np.any(D != 0):
        raise InputDataError(f"lowpass is not strictly proper: feedthrough D = "
                             f"{D.ravel().tolist()} must be 0 (a low-pass filter needs "
                             f"more poles than zeros)")
    return A, B[:, 0], C[0]


def as_lowpass(spec):
    """Validate a filter specification and return a :class:`LowpassFilter`.

    Parameters
    ----------
    spec : tuple, scipy.signal.lti, control.TransferFunction, control.StateSpace or LowpassFilter
        A continuous-time SISO transfer function: ``(num, den)`` polynomial
        coefficients in decreasing powers of ``s`` (as ``scipy.signal`` and
        python-control write them), a ``scipy.signal.lti`` system (transfer function,
        zeros-poles-gain or state space), or a python-control ``TransferFunction`` or
        ``StateSpace`` with ``dt = 0``.

    Returns
    -------
    LowpassFilter

    Raises
    ------
    InputDataError
        If the filter is not a continuous-time SISO system, not strictly proper (as many
        zeros as poles, or a feedthrough), not stable (a pole with real part ``>= 0``,
        counting the roots of the denominator as given, cancelled or not), has a zero
        numerator or non-finite coefficients.

    Examples
    --------
    >>> F = as_lowpass(([100.0], [1.0, 20.0, 100.0]))  # 100 / (s + 10)**2
    >>> F.filter_order, round(F.dc_gain(), 12)
    (2, 1.0)
    """
    if isinstance(spec, LowpassFilter):
        return spec
    # a scipy.signal system comes from an imported scipy.signal (not imported otherwise:
    # it costs half a second)
    signal = sys.modules.get("scipy.signal")
    if signal is not None and isinstance(spec, signal.dlti):
        raise InputDataError(f"lowpass must be a continuous-time filter, got a discrete-time "
                             f"system with dt={spec.dt!r}")
    if signal is not None and isinstance(spec, signal.lti):
        if isinstance(spec, signal.StateSpace):
            A, b, c = _from_state_space(spec.A, spec.B, spec.C, spec.D)
            return _checked(LowpassFilter(A, b, c), None)
        tf = spec.to_tf()
        num, den = tf.num, tf.den
    elif all(hasattr(spec, name) for name in ("A", "B", "C", "D")):  # control.StateSpace
        _continuous(spec)
        A, b, c = _from_state_space(spec.A, spec.B, spec.C, spec.D)
        return _checked(LowpassFilter(A, b, c), None)
    elif hasattr(spec, "num") and hasattr(spec, "den"):  # control.TransferFunction
        _continuous(spec)
        num, den = spec.num, spec.den
        if isinstance(num, list):
            if len(num) != 1 or len(num[0]) != 1:
                raise InputDataError("lowpass must be single-input single-output, got a "
                                     f"{len(num)}x{len(num[0]) if num else 0} transfer function")
            num, den = num[0][0], den[0][0]
    elif isinstance(spec, (tuple, list)) and len(spec) == 2:
        num, den = spec
    else:
        raise InputDataError(f"lowpass must be (num, den) coefficients, a scipy.signal.lti "
                             f"or a python-control system, got {type(spec).__name__}")
    num = _coefficients(num, "numerator")
    den = _coefficients(den, "denominator")
    if den.size < 2:
        raise InputDataError(f"lowpass denominator {den.tolist()} has no pole (degree 0); "
                             f"a low-pass filter needs at least one pole")
    if num.size == 0:
        raise InputDataError("lowpass numerator is zero: the filter would erase every signal")
    if num.size >= den.size:
        raise InputDataError(f"lowpass is not strictly proper: numerator degree "
                             f"{num.size - 1} >= denominator degree {den.size - 1} "
                             f"(a low-pass filter needs more poles than zeros)")
    roots = np.roots(den)
    _check_stable(roots)
    from scipy.signal import tf2ss

    A, B, C, _ = tf2ss(num / den[0], den / den[0])
    return _checked(LowpassFilter(A, B[:, 0], C[0]), roots)


def _check_stable(poles):
    bad = [p for p in np.atleast_1d(poles) if not p.real < 0]
    if bad:
        p = complex(bad[0])
        raise InputDataError(f"lowpass is not stable: pole {p.real:.6g}{p.imag:+.6g}j has "
                             f"real part >= 0 (all poles must have negative real part)")


def _checked(filt, roots):
    if roots is None:
        _check_stable(filt.poles)
        if not np.any(filt.c) or not np.any(filt.b):
            raise InputDataError("lowpass has a zero input or output matrix: the filter "
                                 "would erase every signal")
    return filt
