"""Exceptions raised by algid.

Every error a user can cause is a :class:`ValueError` subclass whose message is one
line naming the offending input (file, column, row or value), so that the command line
can print it as it is and exit with code 2.
"""

__all__ = ["AlgidError", "InputDataError", "DataFileError", "ModelError"]


class AlgidError(ValueError):
    """Base class of every error algid raises on bad input."""


class InputDataError(AlgidError):
    """Signals that cannot be used: NaN/inf, mismatched lengths, bad time axis, ..."""


class DataFileError(AlgidError):
    """A data file that cannot be read: missing, empty, missing or non-numeric column."""


class ModelError(AlgidError):
    """An unknown model name or a model specification the engine cannot handle."""
