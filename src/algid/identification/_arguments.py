"""Checks of the arguments of :func:`algid.identify` before any work is done.

Every argument of the wrong type or out of range is refused with a one-line
:class:`~algid.errors.AlgidError` naming it (instead of a ``TypeError`` from deep
inside), and a request whose arrays would not fit in the memory available is refused
with the numbers (:mod:`algid._memory`) before anything is allocated.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from algid._memory import check_fits
from algid.errors import InputDataError, ModelError
from algid.models._expression import Signal

__all__ = ["check_arguments", "check_model_columns", "check_memory", "identify_bytes"]


def _is_integer(value):
    return isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))


def _is_real(value):
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _optional_name(value, what):
    if value is not None and not isinstance(value, str):
        raise InputDataError(f"{what} must be a column name (a string), got {value!r}")


def check_arguments(equation, parameters, *, time, rate, output, window, method,
                    methods, multiplicities, name, iterations):
    """Check the types and ranges of :func:`algid.identify`'s arguments.

    Parameters
    ----------
    equation, parameters, time, rate, output, window : object
        As given to :func:`algid.identify`.
    method, multiplicities, name, iterations : object
        As given to :func:`algid.identify`.
    methods : tuple of str
        The methods known.

    Returns
    -------
    tuple of int
        The kernel multiplicities.

    Raises
    ------
    ModelError
        A bad equation, parameter list or name.
    InputDataError
        A bad option.
    """
    from algid.models._model import Model

    if not isinstance(equation, (str, Model)):
        raise ModelError(f"equation must be a text equation or a Model, got "
                         f"{type(equation).__name__}")
    if isinstance(equation, str):
        if parameters is None:
            raise ModelError("parameters: name the unknown parameters of the equation "
                             "(e.g. \"B K G\")")
        if not isinstance(parameters, str) and not (
                isinstance(parameters, (list, tuple)) and parameters):
            raise ModelError(f"parameters must be a string of names or a list of names, "
                             f"got {parameters!r}")
    if not isinstance(name, str):
        raise ModelError(f"name must be a string, got {name!r}")
    _optional_name(time, "time")
    _optional_name(output, "output")
    if rate is not None and not _is_real(rate):
        raise InputDataError(f"rate must be a number of Hz, got {rate!r}")
    if window is not None and not _is_real(window):
        raise InputDataError(f"window must be a number of seconds, got {window!r}")
    if window is not None and not (math.isfinite(window) and window > 0):
        raise InputDataError(f"window must be a positive number of seconds, got {window!r}")
    if not isinstance(method, str) or method not in methods:
        raise InputDataError(f"unknown method {method!r} (choose from {', '.join(methods)})")
    if isinstance(multiplicities, (str, bytes)) or not hasattr(multiplicities, "__iter__"):
        raise InputDataError(f"multiplicities must be a sequence of integers such as "
                             f"(8, 12), got {multiplicities!r}")
    multiplicities = tuple(multiplicities)
    from algid.identification._window_kernels import MAX_MULTIPLICITY

    for a in multiplicities:
        if not _is_integer(a) or not 1 <= a <= MAX_MULTIPLICITY:
            raise InputDataError(f"kernel multiplicity {a!r} is not an integer from 1 to "
                                 f"{MAX_MULTIPLICITY}")
    if not _is_integer(iterations) or iterations < 1:
        raise InputDataError(f"iterations must be a positive integer, got {iterations!r}")
    return multiplicities


def check_seconds(**values):
    """Refuse values that are not positive numbers of seconds.

    Parameters
    ----------
    **values
        Name -> value; a name ending in ``_or_none`` may also be None (the suffix is
        left out of the message).

    Raises
    ------
    InputDataError
        Naming the first bad value.
    """
    for key, value in values.items():
        optional = key.endswith("_or_none")
        name = key.removesuffix("_or_none")
        if value is None and optional:
            continue
        if isinstance(value, (bool, str, np.bool_)) \
                or not isinstance(value, (int, float, np.integer, np.floating)) \
                or not (math.isfinite(value) and value > 0):
            unit = "per second" if name.endswith("_rate") else "of seconds"
            raise InputDataError(f"{name} must be a positive number {unit}"
                                 f"{' or None' if optional else ''}, got {value!r}")


def check_model_columns(model, time):
    """Refuse a time column that is also a signal of the model.

    Parameters
    ----------
    model : algid.models._model.Model
        The parsed model.
    time : str or None
        The time column given.

    Raises
    ------
    InputDataError
    """
    if time is not None and time in model.signals:
        raise InputDataError(f"time column {time!r} is also a signal of the equation; "
                             f"give the column of the sample times")


#: Peak memory of :func:`algid.identify` per sample [bytes] is about
#: ``BYTES_PER_SAMPLE + BYTES_PER_TERM * terms + BYTES_PER_GRAM_ENTRY * (parameters +
#: 1)**2``: the factors' samples and sensitivities per term, noise matrices per window.
#: Peaks measured with tracemalloc on 6e4 samples, automatic window: 270-400 for 4
#: terms and 3 parameters, 430 for 5 and 4 (390 with a sign(q') term), 480 for 6 and 5,
#: 1120 for 10 and 9; the formula is 1.3 to 1.7 times those.
BYTES_PER_SAMPLE = 128
#: See :data:`BYTES_PER_SAMPLE`.
BYTES_PER_TERM = 64
#: See :data:`BYTES_PER_SAMPLE`.
BYTES_PER_GRAM_ENTRY = 8

#: Peak bytes per sample of the fast simulator's spline of an input's derivative while
#: it is made (16 points per sample; measured 2.3 kB on the friction loop).
DERIVATIVE_SPLINE_BYTES = 2400


def identify_bytes(model):
    """Peak memory of :func:`algid.identify` per sample of the records [bytes].

    Parameters
    ----------
    model : algid.models._model.Model

    Returns
    -------
    int
    """
    algebraic = (BYTES_PER_SAMPLE + BYTES_PER_TERM * len(model.terms)
                 + BYTES_PER_GRAM_ENTRY * (len(model.parameters) + 1) ** 2)
    return algebraic + refinement_bytes(model)


def refinement_bytes(model):
    """Peak memory of the output-error refinement per sample [bytes] (0 for a model it
    does not refine).

    Per input channel, its points at 16 per sample and stacked per step, for two
    interpolations (33 x 8 bytes each); the complex recursions of the forced and free
    responses; the Jacobian, scaled once; the residual test's directions.

    Parameters
    ----------
    model : algid.models._model.Model

    Returns
    -------
    int
    """
    from algid.identification._output_error import refinement_unavailable

    if refinement_unavailable(model) is not None:
        return 0
    if not model.is_linear:
        return _nonlinear_refinement_bytes(model)
    channels = len({t.factor for t in model.terms if not (
        isinstance(t.factor, Signal) and t.factor.name == model.output)}) + 1
    order = model.order
    return (2 * 33 * 8 * channels + 40 * order * (order + 1)
            + 24 * len(model.parameters) + 400)


def _nonlinear_refinement_bytes(model):
    """Per sample, the fast simulator's points (8 per sample) of the forcing terms and
    the inputs the state terms read, for two interpolations; an interpolating spline
    at 16 points per sample while they are made; the Jacobians in the parameters and
    the initial state (the fit's and the polishing's).  Then the residual test's
    simulation with the candidate terms: the forcing terms again, a constant, time, and
    each input and its derivative, whose spline while it is made takes
    :data:`DERIVATIVE_SPLINE_BYTES`."""
    output = model.output
    known = sum(1 for t in model.terms if output not in t.factor.signals())
    inputs = len({pair for t in model.terms if output in t.factor.signals()
                  for pair in t.factor.derivatives() + tuple(
                      (name, 0) for name in t.factor.signals()) if pair[0] != output})
    columns = len(model.parameters) + model.order
    test = 64 * (known + inputs + 4 + 2 * len(model.inputs)) \
        + (DERIVATIVE_SPLINE_BYTES if model.inputs else 0)
    return 2 * 64 * (known + inputs + 2) + 1600 + 48 * columns + 400 + test


def check_memory(data, model):
    """Refuse records whose identification would not fit in the memory available.

    The samples are counted from the lengths of the output's columns, before any
    conversion.

    Parameters
    ----------
    data : mapping or list of mappings
        The records.
    model : algid.models._model.Model

    Raises
    ------
    InputDataError
        With the samples, the memory needed and the memory available.
    """
    records = [data] if hasattr(data, "keys") else data
    if not isinstance(records, (list, tuple)):
        return
    count = 0
    for record in records:
        try:
            count += len(record[model.output])
        except (KeyError, TypeError, IndexError):
            continue   # reported by the records' checks
    check_fits(count, identify_bytes(model), what="identify")
