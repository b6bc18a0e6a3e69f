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
from functools import lru_cache

import numba  # noqa: F401  (ImportError here: the backend is not available)

from algid.generated import MODULES, NUMBA_MODULES
from algid.quadrature import integrator_weights

__all__ = ["advance", "compiled_loop"]


@lru_cache(maxsize=None)
def _loop_of(module):
    if MODULES.get(module.MODEL) == module.__name__:
        return importlib.import_module(NUMBA_MODULES[module.MODEL]).advance
    from algid.symbolic.codegen import module_from_source
    return module_from_source(module.NUMBA_SOURCE, module.__name__ + "_numba").advance


def compiled_loop(module):
    """The compiled ``advance`` loop of a generated module."""
    return _loop_of(module)


@lru_cache(maxsize=64)
def _weights(points, dt):
    return integrator_weights(points, dt)[0]


def advance(state, layout, channels, out):
    """Estimates of a chunk that continues the stream (after the start-up) into
    ``out``, in one compiled pass."""
    loop = _loop_of(state.model)
    loop(*channels, out, state.integrals, state.history, state.n_seen, state.dt,
         state.divisors, _weights(state.points, state.dt), state.filter_order)
    state.n_seen += channels[0].size
