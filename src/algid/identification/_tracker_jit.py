"""Whether the Tracker's per-window loops are compiled by numba, and the decorator that
marks them for compiling.

The choice is made once, at import: numba is used when it is installed, unless the
environment variable ``ALGID_TRACKER_PYTHON=1`` is set (the loops then run as Python,
the same operations in the same order, the same results).

The loops are compiled when the Tracker first needs them (:func:`compile_marked`), not
as their module is imported: :func:`algid.identify` calls one of them
(:func:`algid.identification._tracker_solve.koopmans`) without importing numba, as
Python until the Tracker has compiled it in the same process.
"""

from __future__ import annotations

import importlib.util
import os
import threading
from functools import cache

__all__ = ["USE_NUMBA", "declined", "numba_available", "jit", "compile_marked", "compiled"]


def declined():
    """Whether ``ALGID_TRACKER_PYTHON`` asks for the loops as Python (1, true or yes)."""
    return os.environ.get("ALGID_TRACKER_PYTHON", "").strip().lower() in ("1", "true", "yes")


def numba_available():
    """Whether numba is installed (found, not imported: importing it takes a third of a
    second, paid at the first compiled call instead) and not declined."""
    return not declined() and importlib.util.find_spec("numba") is not None


#: Whether the tracker's loops are compiled (fixed at import).
USE_NUMBA = numba_available()


#: The functions marked by :func:`jit`, in the order of their definition.
_MARKED = []
_lock = threading.Lock()


def jit(function):
    """Mark ``function`` (a loop of the tracker) to be compiled by :func:`compile_marked`.

    Returns ``function`` itself: until then it runs as Python.  Helpers called by
    compiled loops must be compiled too: mark every loop of the tracker with this.
    """
    _MARKED.append(function)
    return function


def compile_marked():
    """Replace every function marked by :func:`jit`, in its module, by its numba
    dispatcher (compiled at its first call, cached on disk) when :data:`USE_NUMBA`.

    Compiled code resolves the helpers it calls through its module's names, which then
    name dispatchers; callers that look a loop up in its module at call time run the
    compiled one from then on.  Idempotent.
    """
    if not USE_NUMBA:
        return
    with _lock:
        while _MARKED:
            function = _MARKED.pop(0)
            function.__globals__[function.__name__] = compiled(function)


def compiled(function):
    """``function`` compiled by numba (cached on disk), or itself without numba.

    Parameters
    ----------
    function : callable
        A loop whose helpers are compiled already (:func:`compile_marked`).

    Returns
    -------
    callable
    """
    if not USE_NUMBA:
        return function
    return _numba_jit()(function)
@cache
def _numba_jit():
    import numba

    from algid._compile_notice import watch

    watch()   # a line on stderr while numba compiles these for more than a second
    return numba.njit(cache=True, nogil=True)
