"""Deprecated: the compiled engine's state-carrying interface, now :mod:`algid.estimation._core`.

Kept for a release as a thin layer over the estimator core with the numba backend:
``make_state(module, quadrature_points, filter_order, step=dt)`` is
``algid.estimation._core.new_state(module, points=..., filter_order=..., dt=...)`` and
``run_chunk(state, f, x)`` is ``algid.estimation._core.advance(state, (f, x), backend="numba")``
(channels in the module's ``CHANNELS`` order).
"""

from __future__ import annotations

import warnings

from algid.estimation import _core as core
from algid.estimation._backends import INSTALL_HINT, choose_engine, numba_available

__all__ = ["available", "prepare", "EngineState", "make_state", "run_chunk",
           "estimate_arrays", "check_experiment", "INSTALL_HINT"]

#: The state of the estimator core (:class:`algid.estimation._core.EstimatorState`).
EngineState = core.EstimatorState


def _deprecated(name, instead):
    warnings.warn(f"algid.engine.{name} is deprecated: use {instead}", DeprecationWarning,
                  stacklevel=3)


def available() -> bool:
    """Whether numba is installed (see :func:`algid.estimation._backends.numba_available`).

    Returns
    -------
    bool
        True if numba can be imported.
    """
    return numba_available()


def prepare(module, quadrature_points):
    """Compile (or load from numba's cache) the loop of a model now.

    Parameters
    ----------
    module : module
        Generated estimator module.
    quadrature_points : int
        Points of the quadrature rule (the loop serves every rule).
    """
    choose_engine("numba", 0, None)
    state = core.new_state(module, points=quadrature_points, filter_order=0, dt=1.0)
    channels = [[0.0] * (quadrature_points + 1)] * len(module.CHANNELS)
    core.advance(state, channels, backend="numba")


def make_state(module, quadrature_points, filter_order, *, step, input_divisor=1.0):
    """Deprecated: :func:`algid.estimation._core.new_state` (``input_divisor`` divides the input).

    Parameters
    ----------
    module : module
        Generated estimator module.
    quadrature_points : int
        Points of the quadrature rule.
    filter_order : int
        Order ``p`` of the invariant filter ``1/s**p``.
    step : float
        Sampling step [s].
    input_divisor : float, optional
        Divisor of the input channel (a known mass); the other channels are not divided.

    Returns
    -------
    EngineState
        A fresh state, with the time origin at the next sample.
    """
    _deprecated("make_state", "algid.estimation._core.new_state")
    choose_engine("numba", 0, None)
    divisors = [input_divisor if name == module.INPUT else 1.0 for name in module.CHANNELS]
    return core.new_state(module, points=quadrature_points, filter_order=filter_order,
                          dt=step, divisors=divisors)


def run_chunk(state, f, x, *, out=None):
    """Deprecated: :func:`algid.estimation._core.advance` with ``backend="numba"``.

    Parameters
    ----------
    state : EngineState
        From :func:`make_state`; advanced in place.
    f, x : ndarray
        The chunk of the input and output samples.
    out : ndarray, shape (n_parameters, m), optional
        Float64 array to write the estimates into.

    Returns
    -------
    ndarray, shape (n_parameters, m)
        Row ``i`` estimates ``PARAMETERS[i]`` (see :func:`algid.estimation._core.advance`).
    """
    _deprecated("run_chunk", "algid.estimation._core.advance")
    signals = {state.model.INPUT: f, state.model.OUTPUT: x}
    return core.advance(state, [signals[name] for name in state.model.CHANNELS],
                        backend="numba", out=out)[0]


def estimate_arrays(module, f, x, *, step, quadrature_points, filter_order,
                    input_divisor=1.0):
    """Deprecated: batch estimation on the numba backend (a fresh state, one chunk).

    Parameters
    ----------
    module : module
        Generated estimator module.
    f, x : ndarray
        Input and output samples.
    quadrature_points : int
        Points of the quadrature rule.
    filter_order : int
        Order ``p`` of the invariant filter ``1/s**p``.
    step : float
        Sampling step [s].
    input_divisor : float, optional
        Divisor of the input channel (a known mass); the other channels are not divided.

    Returns
    -------
    ndarray, shape (n_parameters, n)
        Row ``i`` estimates ``PARAMETERS[i]`` (see :func:`algid.estimation._core.advance`).
    """
    _deprecated("estimate_arrays", "algid.estimate(engine='numba')")
    state = make_state(module, quadrature_points, filter_order, step=step,
                       input_divisor=input_divisor)
    return run_chunk(state, f, x)


def check_experiment(t, f, x, *, min_samples=16):
    """Deprecated: :func:`algid._signal_checks_numba.check_experiment_compiled`.

    Parameters
    ----------
    t, f, x : array_like
        Time, input and output.
    min_samples : int, optional
        Smallest number of samples accepted.

    Returns
    -------
    t, f, x : ndarray
        The checked arrays.
    dt : float
        The sampling step.
    """
    _deprecated("check_experiment", "algid._signal_checks.check_experiment")
    from algid._signal_checks_numba import check_experiment_compiled
    return check_experiment_compiled(t, f, x, min_samples=min_samples)
