"""The compiled backend of the estimator core (:mod:`algid.core`); needs numba.

Runs the loop generated for the model at derivation time
(``algid/generated/<model>_numba.py``, written by ``python -m derivation``; numba
caches its machine code beside it), or, for a model compiled in memory
(:func:`algid.symbolic.codegen.compile_model`), the loop built from its
``NUMBA_SOURCE``.  The loop performs the operations of the NumPy backend in the same
order (see :mod:`algid.symbolic.codegen_numba`).
"""

from __future__ import annotations

import importlib
from functools import cache, lru_cache

import numba  # noqa: F401  (ImportError here: the backend is not available)
import numpy as np

from algid.generated import MODULES, NUMBA_MODULES
from algid.quadrature import integrator_weights
from algid.registry import module_from_source

__all__ = ["advance", "compiled_loop"]


@cache
def _loop_of(module):
    if MODULES.get(module.MODEL) == module.__name__:
        return importlib.import_module(NUMBA_MODULES[module.MODEL]).advance
    return module_from_source(module.NUMBA_SOURCE, module.__name__ + "_numba").advance


def compiled_loop(module):
    """The compiled ``advance`` loop of a generated module.

    Parameters
    ----------
    module : module
        Generated estimator module: a built-in one, or one with ``NUMBA_SOURCE``
        (:func:`algid.symbolic.codegen.compile_model`).

    Returns
    -------
    callable
        The numba-compiled loop (cached per module).
    """
    return _loop_of(module)


@lru_cache(maxsize=64)
def _weights(points, dt):
    return integrator_weights(points, dt)


def advance(state, layout, channels, out, *, from_origin=False):
    """Estimates of a chunk into ``out``, in one compiled pass.

    The chunk continues the stream, or with ``from_origin`` it holds the first samples
    after the time origin (at least ``points`` of them; the estimates of samples
    ``0 .. points - 2`` are NaN).

    Parameters
    ----------
    state : EstimatorState
        The state (:func:`algid.core.new_state`); advanced in place.
    layout : IntegratorLayout
        Layout of the state's model (:func:`algid.core.integrator_layout`).
    channels : tuple of ndarray
        The chunk: one float64 1-D array per channel, all of length ``m``, in the
        model's ``CHANNELS`` order.
    out : ndarray, shape (n_parameters, m)
        Float64 array the estimates are written into.
    from_origin : bool, optional
        The chunk starts at the time origin (the state holds no sample yet).
    """
    loop = _loop_of(state.model)
    weights, startup = _weights(state.points, state.dt)
    if from_origin:
        state.n_seen = 0
    loop(*channels, out, state.integrals, state.history, state.n_seen, state.dt,
         state.divisors, weights, startup, state.filter_order, bool(from_origin))
    if from_origin:
        out[:, :state.points - 1] = np.nan
    state.n_seen += channels[0].size
