"""Which backend runs the estimator core: NumPy always, numba when installed."""

from __future__ import annotations

import importlib.util

from algid.errors import InputDataError

__all__ = ["ENGINES", "AUTO_ENGINE_MIN_SAMPLES", "INSTALL_HINT", "numba_available",
           "choose_engine", "require_backend"]

#: Values of the ``engine`` option.
ENGINES = ("auto", "numpy", "numba")
#: ``engine="auto"`` of :func:`algid.estimate` uses numba from this many samples on:
#: below it NumPy takes a few tens of milliseconds, less than importing numba (about
#: half a second) and loading the compiled loop.
AUTO_ENGINE_MIN_SAMPLES = 100_000
#: How to install the optional dependency of the compiled backend.
INSTALL_HINT = 'pip install "algid[fast]" (or: pip install "numba>=0.59")'


def numba_available() -> bool:
    """Whether numba is installed, i.e. whether the compiled backend can run.

    Returns
    -------
    bool
        True if numba can be imported.
    """
    try:
        return importlib.util.find_spec("numba") is not None
    except ValueError:  # numba in sys.modules as None (import blocked)
        return False


def _numba_missing():
    return InputDataError(f"engine='numba' needs numba, which is not installed: {INSTALL_HINT}")


def choose_engine(engine, n, lowpass, *, min_samples=None) -> str:
    """``"numpy"`` or ``"numba"`` for an ``engine`` option.

    Parameters
    ----------
    engine : {"auto", "numpy", "numba"}
        The option.
    n : int
        Number of samples to process.
    lowpass : object or None
        An extra low-pass filter, which only the NumPy backend applies.
    min_samples : int, optional
        ``"auto"`` takes numba when it is installed, there is no ``lowpass`` and there
        are at least this many samples (default :data:`AUTO_ENGINE_MIN_SAMPLES`, read at
        call time; a stream passes 0: there the cost per call matters).

    Returns
    -------
    str

    Raises
    ------
    InputDataError
        An unknown option, ``"numba"`` without numba or with ``lowpass``.
    """
    if min_samples is None:
        min_samples = AUTO_ENGINE_MIN_SAMPLES
    if not isinstance(engine, str) or engine not in ENGINES:
        raise InputDataError(f"engine must be one of {', '.join(map(repr, ENGINES))}, "
                             f"got {engine!r}")
    if engine == "numpy":
        return "numpy"
    if engine == "numba":
        if not numba_available():
            raise _numba_missing()
        if lowpass is not None:
            raise InputDataError("engine='numba' does not support lowpass; use "
                                 "engine='numpy' (or 'auto')")
        return "numba"
    use = lowpass is None and n >= min_samples and numba_available()
    return "numba" if use else "numpy"


def require_backend(name):
    """The ``advance(state, layout, channels, out)`` function of backend ``name``.

    Parameters
    ----------
    name : {"numpy", "numba"}
        The backend.

    Returns
    -------
    callable
        ``advance`` of :mod:`algid.estimation._core_numpy` or :mod:`algid.estimation._core_numba`.

    Raises
    ------
    InputDataError
        An unknown backend, or numba not installed.
    """
    if name == "numpy":
        import algid.estimation._core_numpy as core_numpy
        return core_numpy.advance
    if name == "numba":
        try:
            import algid.estimation._core_numba as core_numba
        except ImportError:
            raise _numba_missing() from None
        return core_numba.advance
    raise InputDataError(f"backend must be 'numpy' or 'numba', got {name!r}")
