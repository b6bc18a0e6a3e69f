"""Exceptions raised by algid.

Every error a user can cause is a :class:`ValueError` subclass whose message is one
line naming the offending input (file, column, row or value), so that the command line
can print it as it is and exit with code 2.
"""

__all__ = ["AlgidError", "InputDataError", "DataFileError", "ModelError"]


class AlgidError(ValueError):
    """Base class of every error algid raises on bad input.

    Examples
    --------
    >>> from algid.paper import simulate_experiment
    >>> simulate_experiment("ramp")
    Traceback (most recent call last):
    ...
    algid.errors.AlgidError: unknown experiment 'ramp' (known: step, sine, step_noise, sine_noise)

    Every error of bad input is one, and a :class:`ValueError`:

    >>> from algid.errors import AlgidError, ModelError
    >>> issubclass(ModelError, AlgidError), issubclass(AlgidError, ValueError)
    (True, True)
    """


class InputDataError(AlgidError):
    """Signals that cannot be used: NaN/inf, mismatched lengths, bad time axis, ...

    Examples
    --------
    >>> import numpy as np
    >>> from algid.estimation import estimate
    >>> estimate(np.arange(3.0), np.ones(3), np.ones(2))
    Traceback (most recent call last):
    ...
    algid.errors.InputDataError: signals have different lengths (t: 3, f: 3, x: 2)
    """


class DataFileError(AlgidError):
    """A data file that cannot be read: missing, empty, missing or non-numeric column.

    Examples
    --------
    >>> from algid.io import read_columns
    >>> read_columns("missing.csv", ["t", "x"])
    Traceback (most recent call last):
    ...
    algid.errors.DataFileError: missing.csv: file not found
    """


class ModelError(AlgidError):
    """An unknown model name or a model specification the engine cannot handle.

    Examples
    --------
    >>> from algid.models import parse_equation
    >>> parse_equation("x' = B*f", "B C")
    Traceback (most recent call last):
    ...
    algid.errors.ModelError: equation "x' = B*f": parameter C does not appear (or its terms cancel)
    """
