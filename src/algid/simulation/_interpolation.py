"""Sampled signals interpolated between their samples, for the model simulator.

:class:`Interpolant` evaluates a sampled input at any time of an integrator's step: by a
cubic spline through the samples, or (``"bandlimited"``) through the samples
upsampled by a Kaiser-windowed sinc filter, the record being first continued at both
ends by linear prediction (:func:`extrapolate`) so that the filter sees plausible
samples instead of a padding.
"""

from __future__ import annotations

import bisect

import numpy as np

from algid.errors import InputDataError

__all__ = ["Interpolant", "extrapolate", "bandlimited_samples", "UPSAMPLING",
           "FILTER_HALF_LENGTH"]

#: Band-limited interpolation: upsampling factor and filter half-length (input samples).
UPSAMPLING = 16
FILTER_HALF_LENGTH = 96
_KAISER_BETA = 13.0


def extrapolate(values, count, *, order=32, span=512):
    """The samples extended by ``count`` linear-prediction samples at both ends.

    A band-limited signal is predictable: a least-squares linear predictor of ``order``
    taps, fitted on the ``span`` samples next to each end, continues it, so that the
    interpolation filter sees plausible samples beyond the record instead of a padding
    (measured on a sine at 9 samples per period: 1e-6 error at the first samples
    against 1e-2 with odd-reflection padding).  If a prediction runs away (more than
    four times the record's largest value) the record is returned unextended.

    Parameters
    ----------
    values : numpy.ndarray
        The samples.
    count : int
        Samples to add at each end.
    order : int
        Taps of the linear predictor.
    span : int
        Samples next to each end that the predictor is fitted on.

    Returns
    -------
    numpy.ndarray
        ``count + len(values) + count`` samples, or ``values`` itself.
    """
    limit = 4.0 * np.max(np.abs(values)) + 1e-300

    def forward(v):
        v = v[-span:]
        p = min(order, len(v) // 4)
        if p < 2:
            return None
        rows = np.lib.stride_tricks.sliding_window_view(v[:-1], p)
        coefficients = np.linalg.lstsq(rows, v[p:], rcond=None)[0]
        out = list(v[-p:])
        for _ in range(count):
            out.append(float(np.dot(coefficients, out[-p:])))
        tail = np.array(out[p:])
        return tail if np.all(np.abs(tail) <= limit) else None

    before, after = forward(values[::-1]), forward(values)
    if before is None or after is None:
        return values
    return np.concatenate([before[::-1], values, after])


def _too_large(values):
    raise InputDataError(
        f"a signal of the model (largest |value| {np.max(np.abs(values)):.4g}) is too large "
        f"to interpolate in floating point: express it in other units")


def bandlimited_samples(values):
    """Uniform samples upsampled :data:`UPSAMPLING` times as a band-limited signal.

    A Kaiser-windowed sinc filter on the samples continued at both ends by linear
    prediction (:func:`extrapolate`).

    Parameters
    ----------
    values : numpy.ndarray
        The samples (uniform in time).

    Returns
    -------
    numpy.ndarray
        ``(len(values) - 1) * UPSAMPLING + 1`` samples, every ``UPSAMPLING``-th one at a
        sample time.

    Raises
    ------
    InputDataError
        If the samples are too large to interpolate in floating point.
    """
    from scipy.signal import firwin, resample_poly

    taps = firwin(2 * FILTER_HALF_LENGTH * UPSAMPLING + 1, 1.0 / UPSAMPLING,
                  window=("kaiser", _KAISER_BETA))
    margin = FILTER_HALF_LENGTH + 16
    with np.errstate(all="ignore"):  # out of range: refused below
        extended = extrapolate(values, margin)
        fine = resample_poly(extended, UPSAMPLING, 1, window=taps, padtype="antireflect")
    if not np.isfinite(fine).all():
        _too_large(values)
    skip = (margin if len(extended) > len(values) else 0) * UPSAMPLING
    return fine[skip:skip + (len(values) - 1) * UPSAMPLING + 1]


class Interpolant:
    """A sampled signal interpolated between samples, evaluated fast at scalar times.

    Parameters
    ----------
    t : numpy.ndarray
        Sample times, increasing.
    values : numpy.ndarray
        The samples.
    interpolation : {"bandlimited", "cubic"}
        Through the samples upsampled by a sinc filter, or a cubic spline through them.
    scalar : bool
        Prepare the fast evaluation at scalar times (``interpolant(time)``); without it
        only :attr:`spline` (vectorised) and :meth:`derivative_samples` are available.

    Raises
    ------
    InputDataError
        If the samples are too large to interpolate in floating point.
    """

    def __init__(self, t, values, interpolation, scalar=True):
        from scipy.interpolate import CubicSpline

        if interpolation == "bandlimited":
            step = (t[-1] - t[0]) / (len(t) - 1)
            fine = bandlimited_samples(values)
            grid = t[0] + np.arange(len(fine)) * (step / UPSAMPLING)
            grid[-1] = t[-1]
        else:
            grid, fine = t, values
        try:
            with np.errstate(all="ignore"):
                spline = CubicSpline(grid, fine)
        except ValueError:  # its slopes overflow
            _too_large(values)
        if not np.isfinite(spline.c).all():
            _too_large(values)
        self.spline = spline
        if not scalar:   # (vectorised use only: the lists below cost 2.5 kB per sample)
            return
        self.knots = spline.x.tolist()
        # polynomial pieces c0 (t - x_i)**3 + c1 (...)**2 + c2 (...) + c3, as lists
        self.coefficients = [row.tolist() for row in spline.c]

    def __call__(self, time):
        i = min(max(bisect.bisect_right(self.knots, time) - 1, 0), len(self.knots) - 2)
        h = time - self.knots[i]
        c = self.coefficients
        return ((c[0][i] * h + c[1][i]) * h + c[2][i]) * h + c[3][i]

    def derivative_samples(self, t, order):
        """The interpolant's derivative of ``order`` at the times ``t``.

        Parameters
        ----------
        t : numpy.ndarray
            Times.
        order : int
            Derivative order.

        Returns
        -------
        numpy.ndarray
        """
        return self.spline(t, order)
