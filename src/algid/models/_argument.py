"""The model argument shared by :func:`algid.estimate`, :class:`algid.OnlineEstimator`
and :func:`algid.identify`: a built-in model's name, equation text with its parameters,
or a compiled model (:func:`algid.compile_equation`).  One shape everywhere, so that a
model moves from identification on records to on-line estimation unchanged.
"""

from __future__ import annotations

import types

from algid.errors import ModelError
from algid.models._registry import available_models, load_model

__all__ = ["estimator_module", "measured_signals", "takes_pair"]


def estimator_module(model, parameters=None, *, output=None):
    """The generated estimator of a model argument.

    Parameters
    ----------
    model : str, list of str or module
        A built-in model's name (``"msd"``), equation text (with ``parameters``), a list
        of equations sharing ``parameters`` (a system), or a generated module (built-in
        or from :func:`algid.compile_equation`).
    parameters : str or sequence of str, optional
        The unknown parameters of equation text; with a module, they must be its own.
    output : str or list of str, optional
        The output signal of equation text (one per equation of a system).

    Returns
    -------
    module
        The generated estimator.

    Raises
    ------
    ModelError
        Equation text without parameters, parameters that are not the module's, or a
        bad equation.
    """
    if isinstance(model, types.ModuleType):
        if parameters is not None:
            given = tuple(parameters.split() if isinstance(parameters, str) else parameters)
            if given != tuple(model.PARAMETERS):
                raise ModelError(f"parameters {' '.join(map(str, given))!r} are not those "
                                 f"of the compiled model ({' '.join(model.PARAMETERS)})")
        return model
    if isinstance(model, str) and parameters is None:
        if model in available_models() or "=" not in model:
            return load_model(model)
        raise ModelError(f"the equation {model!r} needs its parameters after it, "
                         f"e.g. \"B K\"")
    if isinstance(model, (str, list, tuple)):  # (a list: a system of equations)
        from algid.models._compiled import compile_equation

        return compile_equation(model, parameters, output=output)
    raise ModelError(f"model must be a built-in model's name, equation text (a list of them "
                     f"for a system) or a compiled model, got {type(model).__name__}")


def takes_pair(module) -> bool:
    """Whether a model reads exactly one input and one output, without factors (the
    paper's form ``estimate(t, f, x)``, which also takes ``mass=`` and ``lowpass=``)."""
    return (not getattr(module, "FACTORS", None)
            and set(module.CHANNELS) == {module.INPUT, module.OUTPUT})


def measured_signals(module) -> tuple:
    """The measured signals a generated estimator reads, in the order of its channels."""
    if takes_pair(module):
        return (module.INPUT, module.OUTPUT)
    from algid.models._compiled import ChannelStream

    return tuple(ChannelStream(module, 1.0).signals)
