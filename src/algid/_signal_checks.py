"""Checks on measured signals before they reach the estimator.

The algebraic estimator integrates the signals numerically over a uniform grid, so it
needs finite, one-dimensional, equally long, uniformly sampled signals with some
excitation.  The functions here turn anything else into an
:class:`~algid.errors.InputDataError` whose one-line message names the signal and the
first offending row (0-based).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from algid._record_input import (
    read_column,
    refuse_missing,
    refuse_nonfinite_sample,
    refuse_not_increasing,
    refuse_too_few,
    refuse_unequal_lengths,
)
from algid.errors import InputDataError

__all__ = ["integer_value", "as_signal", "check_experiment", "positive_number", "step_tolerance",
           "rounding_quantum", "UNIFORM_RTOL", "UNIFORM_ULPS"]

#: Largest relative deviation of a sampling step from the mean step that still counts
#: as uniform sampling (unless the representation or the rounding of the times
#: explains more: see :func:`step_tolerance` and :func:`rounding_quantum`).
UNIFORM_RTOL = 1e-4
#: Units in the last place of the largest ``|t|`` that a step may deviate by: each
#: time is stored to half an ulp, so a step to one ulp, and a mean step to about one.
UNIFORM_ULPS = 4


def step_tolerance(t_magnitude, h) -> float:
    """Largest deviation of a step from ``h`` that counts as uniform sampling.

    ``UNIFORM_RTOL * h``, or :data:`UNIFORM_ULPS` units in the last place of the
    largest time if that is more: absolute times (Unix time at 1 kHz, ``|t| ~ 1.7e9``,
    ulp ``2.4e-7``) cannot hold their steps closer than that.

    Parameters
    ----------
    t_magnitude : float
        Largest ``|t|`` of the samples checked.
    h : float
        The sampling step.

    Returns
    -------
    float
        The tolerance [s].
    """
    return max(UNIFORM_RTOL * h, UNIFORM_ULPS * float(np.spacing(abs(t_magnitude))))


def rounding_quantum(t, h) -> float:
    """The decimal rounding of the times, if it explains more than :func:`step_tolerance`.

    Times written with a fixed number of decimals (microseconds, say) carry a rounding
    error of half a quantum ``q``; their steps deviate from the true step by up to
    ``q``.  This finds the coarsest power of ten ``q > UNIFORM_RTOL * h`` of which every
    time is a multiple (within its representation error).  A rounding coarser than
    1 % of the step does not show that the sampling is uniform: then 0.0.

    Parameters
    ----------
    t : ndarray
        The times, float64.
    h : float
        The sampling step.

    Returns
    -------
    float
        ``q``, or 0.0 if the times are not rounded to such a quantum or to one coarser
        than ``h / 100``.
    """
    if not (h > 0 and t.size and np.isfinite(h)):
        return 0.0
    magnitude = float(np.max(np.abs(t)))
    k = int(np.floor(-np.log10(h))) - 1  # from ten steps down
    while True:
        q = 10.0 ** -k
        if not q > UNIFORM_RTOL * h:
            return 0.0
        scaled = t / q
        slack = (UNIFORM_ULPS * float(np.spacing(magnitude)) / q
                 + UNIFORM_ULPS * float(np.spacing(magnitude / q)))
        if float(np.max(np.abs(scaled - np.rint(scaled)))) <= slack:
            return q if q <= h / 100.0 else 0.0
        k += 1


def _fmt(value) -> str:
    """Format a number compactly for an error message."""
    return f"{float(value):.10g}"


def as_signal(values, *, name, time=False, of="") -> np.ndarray:
    """Convert a sampled signal to a 1-D float64 array, refusing unusable data.

    The record layer's reading of a column (:func:`algid._record_input.read_column`),
    with its words, for a signal that needs every sample.

    Parameters
    ----------
    values : array_like
        The samples of the signal.
    name : str
        Name of the signal used in error messages (e.g. a column name).
    time : bool, optional
        The signal is the time axis (named ``time 't'`` in the messages).
    of : str, optional
        Where the signal is, after its name in the messages (``"the chunk starting at
        stream sample 10"``).

    Returns
    -------
    numpy.ndarray
        The samples as a new or existing 1-D ``float64`` array.

    Raises
    ------
    InputDataError
        If the values are not one array of numbers (2-D, a single number, text), are
        empty, are complex or booleans (a boolean is not a measurement), have masked
        samples (a :class:`numpy.ma.MaskedArray`), or contain NaN or infinite values.
        The message names the signal and the first bad row (0-based), e.g.
        ``signal 'x' has NaN at row 17; ...``.
    """
    what = (f"time {name!r}" if time else f"signal {name!r}") + (f" of {of}" if of else "")
    if type(values) is np.ndarray and values.dtype == np.float64 and values.ndim == 1:
        arr = values   # (the paper's arrays are not copied)
    else:
        arr = read_column(values, what, every_sample=True, time=time)
    if arr.size == 0:
        raise InputDataError(f"{what} is empty")
    if time:
        refuse_nonfinite_sample(arr, what)
    refuse_missing(arr, what)
    return arr


def check_experiment(t, f, x, *, names=("t", "f", "x"), min_samples=16):
    """Check one identification experiment and return its arrays and sampling step.

    Parameters
    ----------
    t : array_like
        Sampling instants, strictly increasing and uniformly spaced.
    f : array_like
        Input signal (force) at the instants ``t``.
    x : array_like
        Output signal (displacement) at the instants ``t``.
    names : tuple of str, optional
        Names of ``t``, ``f`` and ``x`` used in error messages (e.g. column names).
    min_samples : int, optional
        Smallest number of samples accepted.  At least 2 is always required.

    Returns
    -------
    t, f, x : numpy.ndarray
        The signals as 1-D ``float64`` arrays.
    h : float
        The sampling step ``(t[-1] - t[0]) / (n - 1)``.

    Raises
    ------
    InputDataError
        If a signal is unusable (see :func:`as_signal`), the lengths differ, there are
        fewer than ``min_samples`` samples, time is not strictly increasing, the sampling
        is not uniform (a step deviates from ``h`` by more than ``1e-4 * h``, or than
        the representation of the times (:func:`step_tolerance`) and their decimal
        rounding (:func:`rounding_quantum`) allow; the message names the step farthest
        from the median step), or input and output are both identically zero.
    """
    t_name, f_name, x_name = names
    given = getattr(t, "dtype", None)  # (float32 times round to uneven steps)
    t = as_signal(t, name=t_name, time=True)
    f = as_signal(f, name=f_name)
    x = as_signal(x, name=x_name)
    refuse_unequal_lengths({t_name: t, f_name: f, x_name: x})
    n = t.size
    refuse_too_few(n, max(int(min_samples), 2))
    refuse_not_increasing(t, f"time {t_name!r}")
    dt = np.diff(t)

    h = float((t[-1] - t[0]) / (n - 1))
    deviation = float(np.max(np.abs(dt - h)))
    tolerance = step_tolerance(max(abs(t[0]), abs(t[-1])), h)
    if deviation > tolerance and deviation > tolerance + rounding_quantum(t, h):
        # Point at the step that differs most from the typical (median) step: for a
        # single gap or late sample that is the gap itself, whereas every step differs
        # from the mean step h.
        typical = float(np.median(dt))
        i = int(np.argmax(np.abs(dt - typical)))
        cause = (f"its {given} values round the steps unevenly: give the times as float64"
                 if given is not None and given.kind == "f" and given.itemsize < 8 else
                 "the estimator needs uniform sampling (resample first)")
        raise InputDataError(
            f"time {t_name!r} is not uniformly sampled: step {_fmt(dt[i])} at row {i + 1} "
            f"where {_fmt(typical)} is expected; {cause}"
        )

    if not f.any() and not x.any():
        raise InputDataError(
            f"no excitation: input {f_name!r} and output {x_name!r} are both zero"
        )
    return t, f, x, h


def positive_number(value, *, name) -> float:
    """``value`` as a float if it is a finite real number > 0.

    Parameters
    ----------
    value : object
        The value given.
    name : str
        Its name, for the error message.

    Returns
    -------
    float
        The value.

    Raises
    ------
    InputDataError
        Otherwise (booleans and strings included); the message names ``name``.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real) \
            or not np.isfinite(value) or value <= 0:
        raise InputDataError(f"{name} must be a positive number, got {value!r}")
    return float(value)


def integer_value(value):
    """``value`` as a Python int if it is an integer, else None.

    Integers (also NumPy's) and floats with an integral value (``6.0``) are accepted;
    booleans, strings, non-integral and non-finite numbers are not.

    Parameters
    ----------
    value : object
        The value given.

    Returns
    -------
    int or None
        The integer, or None if ``value`` is not one.
    """
    if isinstance(value, (bool, np.bool_)):
        return None
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)) and math.isfinite(value) \
            and float(value).is_integer():
        return int(value)
    return None
