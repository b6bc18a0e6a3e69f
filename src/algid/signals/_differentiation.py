"""Algebraic numerical differentiation (Mboup, Join and Fliess; Jacobi kernels).

The n-th derivative of a sampled signal is estimated from an integral of the signal
against a polynomial kernel over a sliding window of duration ``T``:

    y^(n)(t0) ~= T**-n * int_0^1 h(u) y(t0 + u T) du,

where ``h`` comes from the annihilation, in the Laplace domain, of the truncated Taylor
expansion of ``y`` (derived with SymPy in :mod:`algid.symbolic._differentiator`; the
kernels are read from the generated table :mod:`algid._generated.differentiator_kernels`).
``h(u) = u**kappa (1 - u)**mu q(u)``: the integers ``kappa`` and ``mu`` set how fast the
kernel vanishes at the window's ends.

The minimal estimator (``truncation = n``) is exactly a weighted average of the true
derivative over the window (the weight a Beta density): a low-pass filter of ``y^(n)``,
exact for polynomials of degree ``n + 1`` at its centre.  The causal form
(``causal=True``, :class:`CausalDifferentiator` on a stream, in any chunking) uses past
samples only and delays the derivative by a fixed fraction of ``T``; a truncation order
``N > n`` removes the delay for polynomials of degree ``N`` at the price of more noise.
Longer windows reject more noise and cut lower (:func:`differentiator_response` gives
the response of any setting).  On a uniform grid the integral is a plain sum of samples
times kernel (one :func:`numpy.correlate` with taps built once per setting); on a
non-uniform grid, the trapezoid rule on the samples.

The user guide, "Noise and filters", gives the delay, the cut-off frequencies and the
sampling error in full.
"""

from __future__ import annotations

import functools
import math
from fractions import Fraction

import numpy as np

from algid._generated.differentiator_kernels import DERIVATIVES, EXTRA_ORDERS, KAPPA, KERNELS, MU
from algid._memory import check_fits
from algid.errors import InputDataError

__all__ = ["algebraic_derivative", "CausalDifferentiator", "differentiator_response",
           "differentiator_delay", "DEFAULT_WINDOW_STEPS", "DEFAULT_KAPPA", "DEFAULT_MU"]

#: Default window length, in sampling steps (``window = DEFAULT_WINDOW_STEPS * dt``).
DEFAULT_WINDOW_STEPS = 20
#: Default kernel exponents: the kernel vanishes like ``u**2`` and ``(1-u)**2``.
DEFAULT_KAPPA = 2
DEFAULT_MU = 2
#: Windows integrated at once on a non-uniform grid (bounds the working memory).
_CHUNK_ROWS = 4096
#: Peak memory of the taps of a window [bytes per step] (measured: about 100 for the
#: causal differentiator, most of it the least-squares correction of the taps).
_BYTES_PER_WINDOW_STEP = 256
#: Largest step allowed on a non-uniform grid, as a fraction of the window.
_MAX_GAP = 0.25
_MAX_DERIVATIVE = DERIVATIVES.stop - 1 - (EXTRA_ORDERS.stop - 1)


def _settings(derivative, kappa, mu, truncation):
    for name, value, allowed in (("derivative", derivative, range(0, _MAX_DERIVATIVE + 1)),
                                 ("kappa", kappa, KAPPA), ("mu", mu, MU)):
        if not isinstance(value, (int, np.integer)) or value not in allowed:
            raise InputDataError(f"{name} must be an integer in {allowed.start}.."
                                 f"{allowed.stop - 1}, got {value!r}")
    n = int(derivative)
    N = n if truncation is None else truncation
    if not isinstance(N, (int, np.integer)) or not n <= N <= n + EXTRA_ORDERS.stop - 1:
        raise InputDataError(f"truncation must be an integer in {n}..{n + EXTRA_ORDERS.stop - 1} "
                             f"(derivative {n}), got {truncation!r}")
    return n, int(kappa), int(mu), int(N)


def _centre(n, kappa, mu):
    """``xi``: the centre of the minimal estimator's weight on the window."""
    return (kappa + n + 1) / (kappa + mu + 2 * n + 2)


def _kernel(u, n, kappa, mu, N, at):
    """Kernel values ``h(u)`` estimating ``T**n y^(n)(at T)`` from ``y`` on ``[0, T]``.

    For ``N > n`` the Taylor series is re-expanded at ``at``:
    ``y^(n)(at T) = sum_{i=n..N} (at T)**(i-n)/(i-n)! y^(i)(0)``, each ``y^(i)(0)``
    from the kernel of truncation ``N`` (exact for polynomials of degree ``N``).
    """
    u = np.asarray(u, dtype=float)
    total = np.zeros(np.broadcast(u, np.asarray(at, dtype=float)).shape)
    for i in range(n, N + 1):
        q = np.polynomial.polynomial.polyval(u, KERNELS[(i, kappa, mu, N)])
        weight = np.asarray(at, dtype=float) ** (i - n) / math.factorial(i - n)
        total = total + weight * q
    return u ** kappa * (1.0 - u) ** mu * total


def _build_taps(steps, n, kappa, mu, N, at):
    """Weights of the samples of a window of ``steps`` steps (estimating ``T**n y^(n)``),
    one row per expansion point in ``at`` (a 1-D array of fractions of the window).

    The plain sum of samples times kernel, corrected (least change, in the 2-norm) so
    that it integrates exactly every polynomial of degree up to ``max(N, n + 1) + 2``
    against the kernel: the sampled estimator is then exact on the polynomials the
    continuous one is exact on, instead of within ``O((dt/T)**(min(kappa, mu) + 2))``.
    """
    u = np.arange(steps + 1) / steps
    at = np.asarray(at, dtype=float)[:, None]
    quadrature = np.full(steps + 1, 1.0 / steps)
    quadrature[[0, -1]] *= 0.5
    taps = quadrature * _kernel(u, n, kappa, mu, N, at)
    degree = min(max(N, n + 1) + 2, steps - 2)
    if degree < 0:
        return taps
    # exact moments against shifted Legendre polynomials (well conditioned on [0, 1])
    nodes, weights = np.polynomial.legendre.leggauss(64)
    x = 0.5 * (nodes + 1.0)
    basis_nodes = np.polynomial.legendre.legvander(nodes, degree)
    moments = (0.5 * weights * _kernel(x, n, kappa, mu, N, at)) @ basis_nodes
    basis = np.polynomial.legendre.legvander(2.0 * u - 1.0, degree)
    correction = np.linalg.lstsq(basis.T, (moments - taps @ basis).T, rcond=None)[0]
    return taps + correction.T


def _read_only(array):
    array.setflags(write=False)
    return array


@functools.lru_cache(maxsize=128)
def _uniform_taps(steps, n, kappa, mu, N, at):
    """The taps of :func:`_build_taps` at one expansion point ``at``, built once per
    setting and kept (read-only: callers share them)."""
    return _read_only(_build_taps(steps, n, kappa, mu, N, [at])[0])


@functools.lru_cache(maxsize=32)
def _edge_taps(steps, n, kappa, mu, N, centre):
    """Taps of the samples the centred window cannot be placed around, one row each:
    the first ``centre`` samples from the first full window, the last ``steps - centre``
    from the last one, each re-expanded at its own position (read-only)."""
    first = _build_taps(steps, n, kappa, mu, N, np.arange(centre) / steps)
    last = _build_taps(steps, n, kappa, mu, N, np.arange(centre + 1, steps + 1) / steps)
    return _read_only(first), _read_only(last)


def algebraic_derivative(y, dt=None, *, time=None, derivative=1, window=None,
                         kappa=DEFAULT_KAPPA, mu=DEFAULT_MU, truncation=None,
                         causal=False):
    """Estimate a derivative of a sampled signal with the algebraic differentiator.

    Parameters
    ----------
    y : array_like
        The samples, 1-D, finite.
    dt : float, optional
        The sampling step in seconds of a uniform grid.  Give either ``dt`` or ``time``.
    time : array_like, optional
        The sample times (strictly increasing, possibly non-uniform, with gaps no
        longer than a quarter of the window), same length as ``y``.
    derivative : int, optional
        The order ``n`` of the derivative, 0 (smoothing) to 3.  Default 1.
    window : float, optional
        The window duration ``T`` in seconds.  Default ``20 * dt`` (the median step on
        a non-uniform grid).  On a uniform grid it is rounded to a whole number of
        steps (an even number when not ``causal``, so that the window is centred).
        The cut-off frequency is ``0.782 / T`` with the default kernel for ``n = 1``
        (the user guide, "Noise and filters", gives it for other kernels).
    kappa, mu : int, optional
        Exponents of the kernel's zeros at the window's start and end, 0 to 6.
        Default 2 and 2.
    truncation : int, optional
        The order ``N`` of the Taylor expansion the estimate is exact for, ``n`` to
        ``n + 2``.  Default ``n`` (the minimal, least noisy estimator).
    causal : bool, optional
        If true, use only the samples up to each instant (window ``[t - T, t]``): the
        estimate lags by ``differentiator_delay(...)`` for ``truncation = n``, and the
        first window's samples, which have no full past window, are NaN.  If false
        (default), the window is centred on each sample (the minimal estimator's weight
        is centred on it), and near the record's ends, where it cannot be, the first or
        last full window is used with the truncation raised to at least ``n + 1`` so
        that the estimate is still exact at the sample for polynomials of degree
        ``n + 1``.

    Returns
    -------
    numpy.ndarray
        The estimated derivative at every sample, same length as ``y``.

    Raises
    ------
    InputDataError
        If ``y`` is not a finite 1-D array, ``dt``/``time`` are missing, both given or
        invalid, the settings are out of range, or the record is shorter than one
        window.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.arange(0, 1, 1e-3)
    >>> v = algebraic_derivative(np.sin(2 * np.pi * t), 1e-3)   # ~ 2 pi cos(2 pi t)
    """
    n, kappa, mu, N = _settings(derivative, kappa, mu, truncation)
    y = np.asarray(y, dtype=float)
    if y.ndim != 1 or not np.all(np.isfinite(y)):
        raise InputDataError("y must be a 1-D array of finite samples")
    if (dt is None) == (time is None):
        raise InputDataError("give exactly one of dt (uniform step) or time (sample times)")
    if dt is not None:
        if not (np.ndim(dt) == 0 and np.isfinite(dt) and dt > 0):
            raise InputDataError(f"dt must be a positive finite number, got {dt!r}")
        return _uniform(y, float(dt), n, kappa, mu, N, window, causal)
    t = np.asarray(time, dtype=float)
    if t.shape != y.shape:
        raise InputDataError(f"time has shape {t.shape}, y has shape {y.shape}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise InputDataError("time must be finite and strictly increasing")
    return _nonuniform(y, t, n, kappa, mu, N, window, causal)


def _window_steps(window, dt, causal, n, kappa, mu):
    if window is None:
        steps = DEFAULT_WINDOW_STEPS
    else:
        if isinstance(window, (bool, np.bool_, str, bytes)) or not (
                np.ndim(window) == 0 and np.isfinite(window) and window > 0):
            raise InputDataError(f"window must be a positive duration in seconds, got {window!r}")
        if not window / dt <= 2.0**53:  # also inf
            raise InputDataError(f"window {window:g} s is {window / dt:.4g} steps of {dt:g} s: "
                                 f"more than 2**53, beyond which sample counts are not exact")
        steps = max(int(round(window / dt)), 2)
    if not causal:
        # a whole number of steps before the centre xi = p/q: steps a multiple of q
        multiple = Fraction(kappa + n + 1, kappa + mu + 2 * n + 2).denominator
        steps = -(-steps // multiple) * multiple
    return steps


def _uniform(y, dt, n, kappa, mu, N, window, causal):
    steps = _window_steps(window, dt, causal, n, kappa, mu)
    if len(y) <= steps:
        raise InputDataError(f"the record ({len(y)} samples) is shorter than one window "
                             f"({steps + 1} samples)")
    T = steps * dt
    out = np.empty_like(y)
    if causal:
        return CausalDifferentiator(dt, derivative=n, window=window, kappa=kappa, mu=mu,
                                    truncation=N).update(y)
    centre = int(round(_centre(n, kappa, mu) * steps))  # exact: see _window_steps
    taps = _uniform_taps(steps, n, kappa, mu, N, centre / steps) / T ** n
    out[centre:len(y) - steps + centre] = np.correlate(y, taps, mode="valid")
    # the ends: the first / last full window, re-expanded at the sample itself
    first, last = _edge_taps(steps, n, kappa, mu, max(N, n + 1), centre)
    out[:centre] = first @ y[:steps + 1] / T ** n
    out[len(y) - steps + centre:] = last @ y[-(steps + 1):] / T ** n
    return out


class CausalDifferentiator:
    """The causal algebraic differentiator on a stream: chunks in, estimates out.

    The estimate at each sample uses the samples of the window ``[t - T, t]`` only (the
    kernel reversed, see :mod:`algid.signals._differentiation`); the last ``steps`` samples are
    carried from one chunk to the next, so the estimates do not depend on how the stream
    is cut into chunks: every estimate is the same sum, in the same order, of tap times
    sample (bit for bit equal to :func:`algebraic_derivative` with ``causal=True`` on
    the whole record, which uses this class).

    Parameters
    ----------
    dt : float
        Sampling step [s] of the uniform grid.
    derivative : int, optional
        Order ``n`` of the derivative, 0 to 3.  Default 1.
    window : float, optional
        Window ``T`` [s], rounded to a whole number ``steps`` of steps (at least 2).
        Default ``DEFAULT_WINDOW_STEPS * dt``.
    kappa, mu, truncation : int, optional
        As in :func:`algebraic_derivative`.

    Attributes
    ----------
    steps : int
        Steps in the window: the first ``steps`` samples of the stream have no full past
        window and get NaN.
    delay : float
        Delay [s] of the minimal estimator (``truncation = n``):
        ``T (kappa + n + 1) / (kappa + mu + 2n + 2)``, ``T / 2`` for ``kappa = mu``
        (see ``differentiator_delay``); 0 for polynomials of degree ``truncation``
        when ``truncation > n``.

    Raises
    ------
    InputDataError
        A bad step, window or setting.

    Examples
    --------
    >>> import numpy as np
    >>> d = CausalDifferentiator(1e-3)
    >>> t = np.arange(100) * 1e-3
    >>> v = np.concatenate([d.update(3 * t[:30]), d.update(3 * t[30:])])
    >>> bool(np.isnan(v[:20]).all()), round(float(v[-1]), 9)
    (True, 3.0)
    """

    def __init__(self, dt, *, derivative=1, window=None, kappa=DEFAULT_KAPPA, mu=DEFAULT_MU,
                 truncation=None):
        n, kappa, mu, N = _settings(derivative, kappa, mu, truncation)
        if not (np.ndim(dt) == 0 and np.isfinite(dt) and dt > 0):
            raise InputDataError(f"dt must be a positive finite number, got {dt!r}")
        self.steps = steps = _window_steps(window, float(dt), True, n, kappa, mu)
        check_fits(steps + 1, _BYTES_PER_WINDOW_STEP, what=f"window {steps * dt:g} s at step "
                   f"{dt:g} s", unit="steps")
        T = steps * float(dt)
        # reversed window: u measured backwards from the current sample, d/dt -> -d/du
        self._taps = (-1.0) ** n * _uniform_taps(steps, n, kappa, mu, N, 0.0) / T ** n
        self._reversed_taps = np.ascontiguousarray(self._taps[::-1])
        self.delay = T * _centre(n, kappa, mu) if N == n else 0.0
        self._history = np.empty(0)
        self._seen = 0

    def reset(self):
        """Forget the stream: the next sample is the first."""
        self._history = np.empty(0)
        self._seen = 0

    def state(self):
        """What the differentiator carries from one chunk to the next, for :meth:`restore`.

        Returns
        -------
        tuple
            Not to be modified (:meth:`update` replaces it, never changes it).
        """
        return self._history, self._seen

    def restore(self, state):
        """Go back to a :meth:`state` taken before: the samples since are forgotten.

        Parameters
        ----------
        state : tuple
            From :meth:`state`.
        """
        self._history, self._seen = state

    def update(self, y):
        """Estimates of the derivative at the next samples of the stream.

        Parameters
        ----------
        y : array_like
            The next samples, 1-D (finite, as the caller checked).

        Returns
        -------
        numpy.ndarray
            One estimate per sample; NaN for the first ``steps`` samples of the stream.
        """
        y = np.asarray(y, dtype=float)
        steps = self.steps
        buffer = np.concatenate((self._history, y))
        first = max(steps - self._seen, 0)  # samples of y without a full past window
        out = np.empty(y.size)
        out[:min(first, y.size)] = np.nan
        if first < y.size:
            # sample i of the buffer: sum over j of taps[j] * buffer[i - j], j = 0 .. steps,
            # each a dot product of the same window with the reversed taps
            begin = buffer.size - (y.size - first)
            out[first:] = np.correlate(buffer[begin - steps:], self._reversed_taps, "valid")
        self._history = buffer[-steps:].copy()
        self._seen += y.size
        return out


def _nonuniform(y, t, n, kappa, mu, N, window, causal):
    step = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    T = DEFAULT_WINDOW_STEPS * step if window is None else window
    if not (np.ndim(T) == 0 and np.isfinite(T) and T > 0):
        raise InputDataError(f"window must be a positive duration in seconds, got {window!r}")
    T = float(T)
    if t[-1] - t[0] < T:
        raise InputDataError(f"the record ({t[-1] - t[0]:g} s) is shorter than one window "
                             f"({T:g} s)")
    steps = np.diff(t)
    if np.any(steps > _MAX_GAP * T):
        i = int(np.argmax(steps))
        raise InputDataError(f"the gap between t = {t[i]:g} s and t = {t[i + 1]:g} s is longer "
                             f"than {_MAX_GAP:g} of the window ({T:g} s): use a longer window "
                             "or differentiate the pieces separately")
    if causal:
        # backwards from each sample; samples with no full past window are NaN
        start = t - T
        at = np.zeros_like(t)
        order = np.full(len(t), N)
        valid = start >= t[0]
        sign = (-1.0) ** n
    else:
        start = t - _centre(n, kappa, mu) * T
        start = np.clip(start, t[0], t[-1] - T)
        at = (t - start) / T
        # re-expanded at the sample where the window cannot be placed around it
        moved = np.abs(at - _centre(n, kappa, mu)) > 1e-12
        order = np.where(moved, max(N, n + 1), N)
        valid = np.ones(len(t), dtype=bool)
        sign = 1.0
    out = np.full(len(t), np.nan)
    for truncation in np.unique(order):
        selected = np.flatnonzero(valid & (order == truncation))
        # in chunks: each row holds a window's samples times the polynomial basis
        for rows in np.array_split(selected, max(1, len(selected) // _CHUNK_ROWS)):
            if rows.size:
                out[rows] = sign * _window_integrals(y, t, start[rows], T, at[rows], n, kappa,
                                                     mu, int(truncation), reverse=causal)
    return out


def _window_integrals(y, t, start, T, at, n, kappa, mu, N, reverse):
    """Integrals of kernel times signal over ``[start, start + T]``, row-wise.

    Trapezoid weights on the samples inside each window, corrected (least change) so
    that every polynomial of degree up to ``max(N, n + 1) + 2`` is integrated exactly
    against the kernel, as on uniform grids (the plain trapezoid on a jittered grid is
    only second order, with a large constant for these oscillating kernels).
    """
    lo = np.searchsorted(t, start, side="left")
    hi = np.searchsorted(t, start + T, side="right")  # samples in the window: lo..hi-1
    count = hi - lo
    degree = max(N, n + 1) + 2
    if np.any(count < degree + 2):
        row = int(np.argmax(count < degree + 2))
        raise InputDataError(
            f"the window at t = {start[row]:g} s holds {count[row]} samples, fewer than the "
            f"{degree + 2} needed: a gap in the time axis, or a window shorter than a few steps")
    width = int(count.max())
    rows = np.arange(len(lo))
    index = lo[:, None] + np.arange(width)[None, :]
    inside = np.arange(width)[None, :] < count[:, None]
    index = np.where(inside, index, lo[:, None])
    pos = np.where(inside, (t[index] - start[:, None]) / T, 0.0)
    # trapezoid weights over the samples (the kernel's ends are beyond them)
    previous = np.concatenate([pos[:, :1], pos[:, :-1]], axis=1)
    following = np.concatenate([pos[:, 1:], pos[:, -1:]], axis=1)
    last = pos[rows, count - 1]
    following = np.where(np.arange(width)[None, :] >= (count - 1)[:, None], last[:, None],
                         following)
    weights = np.where(inside, 0.5 * (following - previous), 0.0)
    kernel_u = 1.0 - pos if reverse else pos
    taps = weights * _kernel(kernel_u, n, kappa, mu, N, at[:, None])
    # exact moments of the kernel against shifted Legendre polynomials, per window
    nodes, gauss = np.polynomial.legendre.leggauss(64)
    x = 0.5 * (nodes + 1.0)
    kernel_nodes = _kernel(x, n, kappa, mu, N, at[:, None])           # rows x 64
    basis_nodes = np.polynomial.legendre.legvander(nodes, degree)      # 64 x (d+1)
    if reverse:
        basis_nodes = np.polynomial.legendre.legvander(-nodes, degree)  # in pos = 1 - u
    moments = (0.5 * gauss * kernel_nodes) @ basis_nodes                # rows x (d+1)
    basis = np.polynomial.legendre.legvander(2.0 * pos - 1.0, degree) * inside[..., None]
    gram = np.einsum("rjk,rjl->rkl", basis, basis)
    residual = moments - np.einsum("rjk,rj->rk", basis, taps)
    taps = taps + np.einsum("rjk,rk->rj", basis, np.linalg.solve(gram, residual[..., None])[..., 0])
    return np.sum(np.where(inside, taps * y[index], 0.0), axis=1) / T ** n


def differentiator_delay(window, *, derivative=1, kappa=DEFAULT_KAPPA, mu=DEFAULT_MU):
    """Delay of the causal minimal estimator: ``T (kappa+n+1) / (kappa+mu+2n+2)``.

    Parameters
    ----------
    window : float
        The window duration ``T`` in seconds.
    derivative, kappa, mu : int, optional
        As in :func:`algebraic_derivative`.

    Returns
    -------
    float
        The delay in seconds.
    """
    n, kappa, mu, _ = _settings(derivative, kappa, mu, None)
    return float(window) * _centre(n, kappa, mu)


def differentiator_response(frequency, window, *, derivative=1, kappa=DEFAULT_KAPPA,
                            mu=DEFAULT_MU, truncation=None, causal=False):
    """Frequency response of the continuous-time differentiator, relative to ``(i w)**n``.

    Parameters
    ----------
    frequency : array_like
        Frequencies in Hz.
    window : float
        The window duration ``T`` in seconds.
    derivative, kappa, mu, truncation, causal
        As in :func:`algebraic_derivative` (for ``causal=False`` the window is placed
        with the minimal estimator's centre on the sample).

    Returns
    -------
    numpy.ndarray of complex
        ``H(f) / (i 2 pi f)**n``: 1 for a perfect differentiator, ``Phi(2 pi f T)``
        (real) for the centred minimal estimator with ``kappa = mu``, and
        ``Phi(...) exp(-i 2 pi f delay)`` for the causal one.  Computed with 64-point
        Gauss-Legendre quadrature of the kernel (exact for these polynomial kernels
        up to the oscillating factor; accurate for ``f T`` up to about 10).
    """
    n, kappa, mu, N = _settings(derivative, kappa, mu, truncation)
    f = np.asarray(frequency, dtype=float)
    nodes, weights = np.polynomial.legendre.leggauss(64)
    u, weights = 0.5 * (nodes + 1.0), 0.5 * weights
    omega_T = 2.0 * np.pi * f[..., None] * float(window)
    if causal:
        h = (-1.0) ** n * _kernel(u, n, kappa, mu, N, 0.0)
        phase = np.exp(-1j * omega_T * u)                 # samples at t - u T
    else:
        at = _centre(n, kappa, mu)
        h = _kernel(u, n, kappa, mu, N, at)
        phase = np.exp(1j * omega_T * (u - at))
    response = np.sum(weights * h * phase, axis=-1)
    w = 1j * omega_T[..., 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        relative = np.where(w == 0, 1.0 + 0j, response / np.where(w == 0, 1.0, w) ** n)
    return relative
