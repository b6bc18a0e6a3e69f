"""Checks of the arguments of :func:`algid.simulate`: each bad value gets an
:class:`~algid.errors.InputDataError` naming it."""

from __future__ import annotations

import numbers
from collections.abc import Callable
from typing import Any

import numpy as np

from algid._memory import check_fits
from algid._record_input import (
    read_column,
    refuse_nonfinite_sample,
    refuse_not_increasing,
    refuse_too_few,
)
from algid.errors import InputDataError

__all__ = ["SIMULATION_BYTES_PER_SAMPLE", "format_value", "real_number", "check_parameters",
           "time_grid", "initial_state_vector", "callable_samples", "array_samples",
           "seed_generator"]


#: Peak memory of :func:`algid.simulate` per time point [bytes] (measured: 120-132 for
#: the step and sine inputs with noise), checked before the grid is allocated.
SIMULATION_BYTES_PER_SAMPLE = 160


def format_value(value: Any) -> str:
    """Format a value compactly, on one line, for an error message.

    Parameters
    ----------
    value : object
        The value to show.

    Returns
    -------
    str
        ``repr(int(value))`` for an integer, ``repr(float(value))`` for another real
        number, else its ``repr`` on one line, shortened to 60 characters.
    """
    if isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_)):
        return repr(int(value))
    if isinstance(value, numbers.Real) and not isinstance(value, bool):
        return repr(float(value))
    text = repr(value)
    text = " ".join(text.split())
    return text if len(text) <= 60 else text[:57] + "..."


def real_number(name: str, value: Any) -> float:
    """Convert a scalar argument to a finite float.

    Parameters
    ----------
    name : str
        The argument's name, for the error message.
    value : object
        The value given.

    Returns
    -------
    float
        The value.

    Raises
    ------
    InputDataError
        If the value is not a real number, or not finite.
    """
    if isinstance(value, (bool, np.bool_)) or isinstance(value, (str, bytes)):
        raise InputDataError(f"{name} must be a real number, got {format_value(value)}")
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise InputDataError(f"{name} must be a real number, got {format_value(value)}") from None
    if not np.isfinite(out):
        raise InputDataError(f"{name} must be finite, got {format_value(value)}")
    return out


def check_parameters(m: Any, c: Any, k: Any) -> tuple[float, float, float]:
    """Check the physical parameters of the plant.

    Parameters
    ----------
    m, c, k : object
        Mass (> 0), damping and stiffness (>= 0).

    Returns
    -------
    tuple of float
        ``(m, c, k)``.

    Raises
    ------
    InputDataError
        If a parameter is not a finite real number or out of its range.
    """
    m_, c_, k_ = real_number("m", m), real_number("c", c), real_number("k", k)
    if m_ <= 0.0:
        raise InputDataError(f"m must be > 0 (mass in kg), got {format_value(m)}")
    if c_ < 0.0:
        raise InputDataError(f"c must be >= 0 (damping in N*s/m), got {format_value(c)}")
    if k_ < 0.0:
        raise InputDataError(f"k must be >= 0 (stiffness in N/m), got {format_value(k)}")
    return m_, c_, k_


def time_grid(timepts: Any, duration: Any, rate: Any) -> np.ndarray:
    """The time grid of an experiment, checked.

    Parameters
    ----------
    timepts : array_like or None
        Time points, 1-D and strictly increasing; ``None`` to build the grid from
        ``duration`` and ``rate``.
    duration : object
        Length of the experiment in s (> 0), used when ``timepts`` is ``None``.
    rate : object
        Sampling rate in Hz (> 0), used when ``timepts`` is ``None``.

    Returns
    -------
    numpy.ndarray
        A new 1-D float64 array of at least 2 time points.

    Raises
    ------
    InputDataError
        For a bad duration or rate, fewer than 2 points, more points than the memory
        available can simulate (:data:`SIMULATION_BYTES_PER_SAMPLE` each), or time
        points that are not finite and strictly increasing.
    """
    if timepts is None:
        duration_ = real_number("duration", duration)
        rate_ = real_number("rate", rate)
        if duration_ <= 0.0:
            raise InputDataError(f"duration must be > 0 s, got {format_value(duration)}")
        if rate_ <= 0.0:
            raise InputDataError(f"rate must be > 0 Hz, got {format_value(rate)}")
        n_float = duration_ * rate_ + 1.0
        check_fits(n_float, SIMULATION_BYTES_PER_SAMPLE,
                   what=f"duration {duration_:g} s at rate {rate_:g} Hz")
        n = int(round(duration_ * rate_)) + 1
        if n < 2:
            raise InputDataError(
                f"duration*rate = {duration_ * rate_!r} gives {n} sample; at least 2 "
                "samples are needed (increase duration or rate)"
            )
        return np.arange(n, dtype=np.float64) / rate_

    t = read_column(timepts, "timepts")
    refuse_too_few(t.size, 2, "timepts")
    check_fits(t.size, SIMULATION_BYTES_PER_SAMPLE, what="timepts")
    refuse_nonfinite_sample(t, "timepts")
    refuse_not_increasing(t, "timepts")
    return t


def initial_state_vector(initial_state: Any) -> np.ndarray:
    """The initial state ``[x0, v0]``, checked.

    Parameters
    ----------
    initial_state : object
        A pair of finite real numbers.

    Returns
    -------
    numpy.ndarray
        Float64 array of shape ``(2,)``.

    Raises
    ------
    InputDataError
        If it is not a pair of finite real numbers.
    """
    try:
        x0 = np.array(initial_state, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputDataError(
            "initial_state must be a pair (x0, v0) of real numbers, got "
            f"{format_value(initial_state)}"
        ) from None
    if x0.shape != (2,):
        raise InputDataError(
            f"initial_state must be a pair (x0, v0), got shape {x0.shape}"
        )
    if not np.all(np.isfinite(x0)):
        shown = format_value(tuple(x0.tolist()))
        raise InputDataError(f"initial_state must be finite, got {shown}")
    return x0


def callable_samples(func: Callable, t: np.ndarray) -> np.ndarray:
    """Samples of a vectorised input function on the grid, checked.

    Parameters
    ----------
    func : callable
        ``F(t)``, called with the array of time points.
    t : numpy.ndarray
        The time grid.

    Returns
    -------
    numpy.ndarray
        ``func(t)`` as float64, of the shape of ``t``.

    Raises
    ------
    InputDataError
        If ``func`` fails on an array, returns the wrong shape or non-finite values.
    """
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


def array_samples(values: Any, t: np.ndarray) -> np.ndarray:
    """An array of force samples, checked against the time grid.

    Parameters
    ----------
    values : array_like
        One force sample per time point.
    t : numpy.ndarray
        The time grid.

    Returns
    -------
    numpy.ndarray
        The samples as float64.

    Raises
    ------
    InputDataError
        If the samples are not numbers, not one per time point, or not finite.
    """
    if isinstance(values, (str, bytes)) or not hasattr(values, "__len__"):
        raise InputDataError(f"inputs must be 'step', 'sine', a callable or an array of "
                             f"numbers, got {format_value(values)}")
    f = read_column(values, "inputs")
    if f.shape != t.shape:
        raise InputDataError(
            f"inputs has shape {np.shape(values)} but the time grid has {t.size} points; "
            f"give one force sample per time point")
    refuse_nonfinite_sample(f, "inputs", "force samples must be finite")
    return f


def seed_generator(seed: Any) -> np.random.Generator:
    """The noise generator of a seed, checked.

    Parameters
    ----------
    seed : None, int, numpy.random.SeedSequence or numpy.random.Generator
        As for :func:`numpy.random.default_rng`; a non-negative integer.

    Returns
    -------
    numpy.random.Generator

    Raises
    ------
    InputDataError
        For any other seed (a negative integer, a float, a string, a boolean).
    """
    if isinstance(seed, (bool, np.bool_)) or not (
            seed is None or isinstance(seed, (numbers.Integral, np.random.SeedSequence,
                                              np.random.BitGenerator, np.random.Generator))):
        raise InputDataError(f"seed must be a non-negative integer, a SeedSequence or a "
                             f"Generator, got {format_value(seed)}")
    try:
        return np.random.default_rng(seed)
    except (TypeError, ValueError):
        raise InputDataError(f"seed must be a non-negative integer, a SeedSequence or a "
                             f"Generator, got {format_value(seed)}") from None
