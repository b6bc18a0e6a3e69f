"""Window integrals of signals against the modulating kernels of the algebraic method.

On a window ``[t0, t0 + T]`` a term ``D^k z`` of a model becomes the integral of the
plain signal ``z`` against the *term kernel* ``(-1)^k psi_a^(k)``, where
``psi_a(u) = u^a (1-u)^a / B(a+1, a+1)`` on the unit window ``u = (t - t0)/T`` and
``a`` is the *kernel multiplicity* (see :mod:`algid.symbolic._modulating`, which derives
the kernels from the s-domain steps; the table is generated into
:mod:`algid._generated.modulating`).  No boundary value of a signal remains, so the
equation holds on every window whatever the state at ``t0``.

The integral is the trapezoid sum of samples times kernel on the actual sample grid.
As the kernel vanishes to order ``a - k`` at both window ends, on a uniform grid this is
the plain sum of samples times kernel, whose error (Poisson summation) is the spectrum
of the integrand at multiples of the sampling rate: spectrally small for a smooth kernel
and a band-limited signal, even at 8-9 samples per period.

Each integral is normalised by ``T^(k+1)`` so that ``D^k z`` on a window of any length
is measured in the units of ``z^(k)`` (a weighted average).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.polynomial import chebyshev

from algid._generated.modulating import MAX_MULTIPLICITY, TERM_KERNELS
from algid.errors import ModelError

__all__ = ["term_kernel", "uniform_window_integrals", "block_window_integrals",
           "block_window_sums", "window_integrals",
           "window_noise_products", "window_sample_weights", "sign_changes",
           "step_window_integrals",
           "sign_samples", "MAX_MULTIPLICITY"]


def term_kernel(multiplicity: int, derivative: int, u):
    """Values of the term kernel ``(-1)^k psi_a^(k)(u)`` on the unit window.

    Parameters
    ----------
    multiplicity : int
        Kernel multiplicity ``a`` (``1 <= a <= MAX_MULTIPLICITY``).
    derivative : int
        Derivative order ``k`` of the term (``0 <= k <= a``).
    u : array_like
        Points of the unit window ``[0, 1]``.

    Returns
    -------
    numpy.ndarray
    """
    key = (int(multiplicity), int(derivative))
    if key not in TERM_KERNELS:
        raise ModelError(f"no kernel of multiplicity {multiplicity} for a derivative of "
                         f"order {derivative} (need {derivative} <= multiplicity <= "
                         f"{MAX_MULTIPLICITY})")
    return chebyshev.chebval(2.0 * np.asarray(u, dtype=float) - 1.0, TERM_KERNELS[key])


@lru_cache(maxsize=256)
def _unit_kernel(multiplicity, derivative, length):
    """Term kernel at the ``length`` points of a uniform unit window (cached: the window
    rule asks for the same ones many times)."""
    values = term_kernel(multiplicity, derivative, np.arange(length) / (length - 1))
    values.flags.writeable = False
    return values


def uniform_window_integrals(z, step, length, multiplicity, derivative, stride=1):
    """Integrals over every window of ``length`` samples on a uniform grid.

    Parameters
    ----------
    z : array_like
        Samples of the plain signal (factor) of the term.
    step : float
        Sampling step (s).
    length : int
        Samples per window (the window spans ``(length - 1) * step`` seconds).
    multiplicity, derivative : int
        Kernel multiplicity ``a`` and derivative order ``k``.
    stride : int
        Keep every ``stride``-th window start.

    Returns
    -------
    numpy.ndarray
        ``T^(-k-1) * integral of term_kernel * z`` for windows starting at samples
        ``0, stride, 2*stride, ...``.
    """
    z = np.asarray(z, dtype=float)
    g = window_sample_weights(None, step, length, multiplicity, derivative)
    if length <= 64:
        full = np.correlate(z, g, mode="valid")
    else:
        from scipy.signal import fftconvolve

        full = fftconvolve(z, g[::-1], mode="valid")
    return full[::stride]


def block_window_integrals(z, step, length, multiplicity, derivative, stride=1):
    """The integrals of :func:`uniform_window_integrals`, summed in blocks of ``stride``.

    The samples are cut into blocks of ``stride`` and the kernel's weights likewise, so
    that window ``w`` (blocks ``w`` to ``w + J - 1``) sums one column of a matrix
    product: about ``J * len(z)`` multiplications for ``J = ceil(length / stride)``
    (nine at the windows' usual overlap), whatever the window, and exact sums (no FFT
    round-off).  The windows of a record read in chunks are made this way.

    Parameters
    ----------
    z, step, length, multiplicity, derivative, stride
        As in :func:`uniform_window_integrals` (``z`` starts at a window's start).

    Returns
    -------
    numpy.ndarray
        The integrals of the windows starting at ``0, stride, 2 * stride, ...`` that
        end within ``z``.
    """
    return block_window_sums(z, window_sample_weights(None, step, length, multiplicity,
                                                      derivative), stride)


def block_window_sums(z, weights, stride=1):
    """``weights @ z[w * stride : w * stride + len(weights)]`` for every window ``w`` that
    ends within ``z``, summed in blocks (:func:`block_window_integrals`).

    Parameters
    ----------
    z : array_like
        Samples (starting at a window's start).
    weights : numpy.ndarray
        The weight of every sample of a window, or one row of them per kernel (the
        samples are then blocked once for all).
    stride : int
        Samples between the starts of consecutive windows.

    Returns
    -------
    numpy.ndarray
        One sum per window (a row per kernel for 2-D ``weights``).
    """
    z = np.asarray(z, dtype=float)
    g = np.asarray(weights, dtype=float)
    kernels = g.reshape(-1, g.shape[-1])
    m, length = kernels.shape
    count = (len(z) - length) // stride + 1 if len(z) >= length else 0
    if count == 0:
        return np.zeros(g.shape[:-1] + (0,))
    blocks = -(-length // stride)
    kernel = np.zeros((m, blocks * stride))
    kernel[:, :length] = kernels
    padded = np.zeros((count + blocks - 1) * stride)
    used = min(len(z), len(padded))
    padded[:used] = z[:used]
    products = (padded.reshape(-1, stride) @ kernel.reshape(m * blocks, stride).T) \
        .reshape(-1, m, blocks)
    out = products[:count, :, 0].copy()
    for j in range(1, blocks):
        out += products[j:j + count, :, j]
    return out.T.reshape(g.shape[:-1] + (count,))


def window_integrals(z, t, length, multiplicity, derivative, stride=1):
    """Integrals over windows of ``length`` samples on a non-uniform grid ``t``.

    Each window runs from one sample to the sample ``length - 1`` later; its span ``T``
    is the actual time between them, and the trapezoid weights are those of the actual
    sample times.

    Parameters
    ----------
    z, t : array_like
        Samples and their strictly increasing times.
    length, multiplicity, derivative, stride
        As in :func:`uniform_window_integrals`.

    Returns
    -------
    numpy.ndarray
    """
    zw = np.lib.stride_tricks.sliding_window_view(np.asarray(z, dtype=float),
                                                  length)[::stride]
    g = window_sample_weights(t, None, length, multiplicity, derivative, stride)
    return np.einsum("ij,ij->i", g, zw)


def window_sample_weights(t, step, length, multiplicity, derivative, stride=1):
    """Sample weights of the window integrals (those of :func:`window_integrals`).

    The integral of window ``w`` is ``weights[w] @ z[w * stride : w * stride + length]``
    (``weights @ ...`` on a uniform grid).

    Parameters
    ----------
    t : array_like or None
        Sample times (used when ``step`` is None).
    step : float or None
        Sampling step of a uniform segment.
    length, multiplicity, derivative, stride
        As in :func:`uniform_window_integrals`.

    Returns
    -------
    numpy.ndarray
        Shape ``(length,)`` on a uniform grid (the same in every window), else
        ``(windows, length)``.
    """
    if step is not None:
        return _uniform_weights(float(step), int(length), int(multiplicity), int(derivative))
    t = np.asarray(t, dtype=float)
    tw = np.lib.stride_tricks.sliding_window_view(t, length)[::stride]
    span = tw[:, -1] - tw[:, 0]
    dt = np.diff(tw, axis=1)
    weights = np.zeros_like(tw)
    weights[:, :-1] += dt / 2
    weights[:, 1:] += dt / 2
    u = (tw - tw[:, :1]) / span[:, None]
    return weights * term_kernel(multiplicity, derivative, u) \
        / span[:, None] ** (derivative + 1)


@lru_cache(maxsize=256)
def _uniform_weights(step, length, multiplicity, derivative):
    """:func:`window_sample_weights` on a uniform grid (read-only; cached: every segment
    and solve of a window length asks for the same)."""
    span = (length - 1) * step
    weights = np.full(length, step)
    weights[[0, -1]] = step / 2
    weights = weights * _unit_kernel(multiplicity, derivative, length) \
        / span ** (derivative + 1)
    weights.flags.writeable = False
    return weights


@lru_cache(maxsize=64)
def _kernel_primitive(multiplicity, derivative):
    """Chebyshev coefficients (in ``x = 2u - 1``) of the primitive of the term kernel
    in ``u``, zero at ``u = 0``."""
    return chebyshev.chebint(TERM_KERNELS[(multiplicity, derivative)], scl=0.5, lbnd=-1)


def step_window_integrals(t, level, times, steps, length, multiplicity, derivative,
                          stride=1, levels=None):
    """Exact window integrals of a piecewise-constant signal (``sign(v)``).

    The signal is ``level`` before ``times[0]`` and changes by ``steps[j]`` at
    ``times[j]``.  Its integral against the term kernel is a sum of the kernel's
    primitive ``P`` at the steps: ``level_w (P(1) - P(0)) + sum_j steps_j (P(1) -
    P(u_j))`` over the steps inside the window (``level_w`` the value at its start),
    times ``T^-k``.  The trapezoid sum of samples is spectrally accurate for smooth
    signals only: at a step it leaves an error of the order of the kernel's slope times
    the squared sampling step, even with the samples around the step corrected as in
    :func:`sign_samples` (on the synthetic friction loop, a bias of 3e-5 in the viscous
    friction and -7e-5 in the Coulomb friction).

    Parameters
    ----------
    t : array_like
        Sample times (uniform or not); windows start at every ``stride``-th sample.
    level : float
        The signal before the first step.
    times, steps : array_like
        Increasing times of the steps and their sizes.
    length, multiplicity, derivative, stride
        As in :func:`uniform_window_integrals`.
    levels : array_like, optional
        The signal at the start of each window, in place of ``level`` and the steps
        before it (a stream's windows: the same values however the stream is cut).

    Returns
    -------
    numpy.ndarray
    """
    t = np.asarray(t, dtype=float)
    times = np.asarray(times, dtype=float)
    steps = np.asarray(steps, dtype=float)
    n_win = (len(t) - length) // stride + 1
    t0 = t[0:(n_win - 1) * stride + 1:stride]
    span = t[length - 1:length - 1 + (n_win - 1) * stride + 1:stride] - t0
    primitive = _kernel_primitive(int(multiplicity), int(derivative))
    whole = chebyshev.chebval(1.0, primitive)
    if levels is None:
        before = np.concatenate([[0.0], np.cumsum(steps)])
        levels = level + before[np.searchsorted(times, t0, side="right")]
    total = np.asarray(levels, dtype=float) * whole
    if not times.size:
        return total / span ** derivative
    # the windows holding each step: from the first that ends after it to the last that
    # starts before it
    lo = np.searchsorted(t0 + span, times, side="right")
    counts = np.maximum(np.searchsorted(t0, times, side="left") - lo, 0)
    step_of = np.repeat(np.arange(len(times)), counts)
    window = np.repeat(lo, counts) + np.arange(counts.sum()) \
        - np.repeat(np.cumsum(counts) - counts, counts)
    u = (times[step_of] - t0[window]) / span[window]
    inside = steps[step_of] * (whole - chebyshev.chebval(2.0 * u - 1.0, primitive))
    total += np.bincount(window, weights=inside, minlength=n_win)
    return total / span ** derivative


def sign_changes(values):
    """Where samples change sign, and where linear interpolation puts the zero.

    Parameters
    ----------
    values : array_like
        Samples of ``v``.

    Returns
    -------
    index : numpy.ndarray of int
        Every ``i`` with ``v[i]`` and ``v[i + 1]`` of opposite signs (a zero sample is no
        change of sign).
    fraction : numpy.ndarray
        ``v[i] / (v[i] - v[i + 1])``: the zero's place within the interval, in ``(0, 1)``.
    """
    v = np.asarray(values, dtype=float)
    z = np.sign(v)
    index = np.flatnonzero(z[:-1] * z[1:] < 0)
    return index, v[index] / (v[index] - v[index + 1])


def sign_samples(values, t, crossings=None):
    """Samples of ``sign(v)`` whose trapezoid sums integrate it exactly to first order.

    Where ``v`` changes sign between two samples, the sign steps inside the interval,
    at the fraction ``phi`` of it found by linear interpolation of ``v``; the
    trapezoid rule on the plain samples ``sign(v)`` would place the step halfway,
    an error of ``(1/2 - phi)`` times the interval and the jump, per crossing, that does
    not shrink with noise and biases every parameter whose term correlates with it
    (Coulomb friction: ``Fc*sign(q')``).  The two samples around the crossing are both
    moved by the amount that makes the trapezoid sum over them count ``phi`` of the
    interval on one side and ``1 - phi`` on the other (for a kernel that changes little
    over one interval, as the window kernels do).

    Parameters
    ----------
    values : array_like
        Samples of ``v``.
    t : array_like
        Their (increasing) times.
    crossings : array_like, optional
        The times of the steps, one per change of sign of ``values`` and in the same
        order (e.g. from :func:`algid.identification._sign_crossings.refine_crossings`); a step may
        lie
        in another interval than the change of sign of the samples, and the samples
        between the two take the sign the step gives them.  By default, the linearly
        interpolated zeros of ``v``.

    Returns
    -------
    numpy.ndarray
        ``sign(v)``, corrected at the samples around each change of sign.
    """
    v = np.asarray(values, dtype=float)
    z = np.sign(v)
    crossing, phi = sign_changes(v)
    if crossing.size == 0:
        return z
    t = np.asarray(t, dtype=float)
    h = np.diff(t)
    if crossings is not None:
        crossings = np.asarray(crossings, dtype=float)
        if crossings.shape != crossing.shape:
            raise ValueError(f"{crossings.size} crossing times for {crossing.size} "
                             "changes of sign")
        # the interval holding each step; the samples between it and the change of
        # sign of v take the sign before (a later step) or after (an earlier one)
        moved = np.clip(np.searchsorted(t, crossings, side="right") - 1, 0, v.size - 2)
        for k, m in zip(crossing, moved):
            if m > k:
                z[k + 1:m + 1] = z[k]
            elif m < k:
                z[m + 1:k + 1] = z[k + 1]
        crossing = moved
        phi = np.clip((crossings - t[crossing]) / h[crossing], 0.0, 1.0)
    weight = np.empty(v.size)  # trapezoid weight of every sample
    weight[1:-1] = (h[:-1] + h[1:]) / 2
    weight[0], weight[-1] = h[0] / 2, h[-1] / 2
    defect = h[crossing] * (z[crossing + 1] - z[crossing]) * (0.5 - phi)
    delta = defect / (weight[crossing] + weight[crossing + 1])
    np.add.at(z, crossing, delta)
    np.add.at(z, crossing + 1, delta)
    return z


def window_noise_products(s, t, step, length, first, second, stride=1):
    """Window sums of ``s`` against the product of two term kernels' sample weights.

    White noise ``e`` of unit variance on the samples, entering two window integrals
    as ``s1 e`` and ``s2 e`` (through terms ``first = (a, k1)`` and
    ``second = (a, k2)``), gives them the covariance ``sum_n g1[n] g2[n] s1 s2 [n]``,
    where ``g`` are the sample weights of :func:`uniform_window_integrals` (kernel times
    trapezoid weight over ``T^(k+1)``).  This returns that sum for every window, with
    ``s = s1 s2``.

    Parameters
    ----------
    s : array_like
        Product of the two noise sensitivities at every sample.
    t : array_like
        Sample times (used when ``step`` is None).
    step : float or None
        Sampling step of a uniform segment.
    length, stride : int
        As in :func:`uniform_window_integrals`.
    first, second : tuple of int
        ``(multiplicity, derivative)`` of the two terms.

    Returns
    -------
    numpy.ndarray
    """
    s = np.asarray(s, dtype=float)
    g = window_sample_weights(t, step, length, *first, stride) \
        * window_sample_weights(t, step, length, *second, stride)
    sw = np.lib.stride_tricks.sliding_window_view(s, length)[::stride]
    if step is None:
        return np.einsum("ij,ij->i", g, sw)
    if np.all(s == s[0]):  # linear noise path: the same in every window
        return np.full(sw.shape[0], s[0] * np.sum(g))
    return sw @ g
