"""Whether the Tracker's per-window loops are compiled by numba, and the decorator that
compiles them.

The choice is made once, at import: numba is used when it is installed, unless the
environment variable ``ALGID_TRACKER_PYTHON=1`` is set (the loops then run as Python,
the same operations in the same order).
"""

from __future__ import annotations

import importlib.util
import os
from functools import cache

__all__ = ["USE_NUMBA", "declined", "numba_available", "jit"]


def declined():
    """Whether ``ALGID_TRACKER_PYTHON`` asks for the loops as Python (1, true or yes)."""
    return os.environ.get("ALGID_TRACKER_PYTHON", "").strip().lower() in ("1", "true", "yes")


def numba_available():
    """Whether numba is installed (found, not imported: importing it takes a third of a
    second, paid at the first compiled call instead) and not declined."""
    return not declined() and importlib.util.find_spec("numba") is not None


#: Whether :func:`jit` compiles (fixed at import: the loops of
#: :mod:`algid.identification._tracker_solve` are compiled as it is imported).
USE_NUMBA = numba_available()


def jit(function):
    """``function`` compiled by numba (cached on disk) when :data:`USE_NUMBA`, else itself.

    Helpers called by compiled loops must be compiled too: decorate every loop of the
    tracker with this.
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
