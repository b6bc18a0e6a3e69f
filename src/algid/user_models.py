"""User equations in the algebraic estimator: from text to a generated estimator.

:func:`compile_equation` reads an equation with the restricted grammar of
:mod:`algid.grammar`, derives its estimator with the symbolic engine (the same
derivation and generator as the built-in models, run in memory) and returns the
generated module, which :func:`algid.estimate` takes as ``model``.  Its channels are the
model's factors: measured signals, the constant 1 of an offset, time, and nonlinear
factors such as ``V2**3`` or ``sign(q')``.  :func:`channel_samples` computes their
samples from the measured signals; a derivative inside a nonlinear factor is estimated
by the algebraic differentiator (:func:`algid.differentiation.algebraic_derivative`),
which looks ahead by half its window: such models are for records, not streams.

Compiling needs SymPy (``algid[derive]``); estimating with the result needs NumPy only.
"""

from __future__ import annotations

import numpy as np

from algid.errors import InputDataError, ModelError
from algid.grammar import parse_equation
from algid.model import channel_names

__all__ = ["compile_equation", "channel_samples", "model_of"]


def compile_equation(equation, parameters, *, output=None, name="custom"):
    """The generated estimator of a user equation, built in memory.

    Parameters
    ----------
    equation : str
        The model, e.g. ``"y'' + B*y' + K*y + K3*y**3 = G*u + d"``; see
        :func:`algid.grammar.parse_equation`.
    parameters : str or sequence of str
        The unknown parameters.
    output : str, optional
        The output signal (default: the signal of highest derivative order).
    name : str, optional
        Label of the model (an identifier).

    Returns
    -------
    module
        The generated estimator (``CHANNELS``, ``FACTORS``, ``PARAMETERS``, the algebra);
        pass it as ``model`` to :func:`algid.estimate` with ``signals=``.

    Raises
    ------
    ModelError
        A bad equation, or SymPy is missing.

    Examples
    --------
    >>> from algid.user_models import compile_equation
    >>> module = compile_equation("y'' + B*y' + K*y + K3*y**3 = G*u + d", "B K K3 G d")
    >>> module.CHANNELS, module.FACTORS
    (('y', 'z1', 'u', 'one'), {'z1': 'y**3', 'one': '1'})
    """
    model = parse_equation(equation, parameters, output=output, name=name)
    try:
        from algid.symbolic.channels import ChannelModel
        from algid.symbolic.codegen import compile_model
        from algid.symbolic.derivation import derive
    except ImportError:
        raise ModelError("compiling an equation needs SymPy: pip install 'algid[derive]'") \
            from None
    return compile_model(derive(ChannelModel(model)))


def model_of(module):
    """The user :class:`~algid.model.Model` behind a generated estimator module.

    Parameters
    ----------
    module : module
        A generated estimator (built-in or from :func:`compile_equation`).

    Returns
    -------
    Model
        Read again from the module's equation and parameters (the generated text is
        self-describing).
    """
    return parse_equation(module.EQUATION, module.PARAMETERS, output=module.OUTPUT,
                          name=module.MODEL)


def channel_samples(module, signals, time, dt):
    """Samples of the channels of a generated estimator, in ``CHANNELS`` order.

    Parameters
    ----------
    module : module
        A generated estimator.
    signals : mapping
        Measured signal name -> samples (1-D, checked, uniformly sampled).
    time : numpy.ndarray
        Sample times (for the channel ``time``).
    dt : float
        Sampling step (for derivatives inside nonlinear factors).

    Returns
    -------
    tuple of numpy.ndarray

    Raises
    ------
    InputDataError
        A signal the model needs is missing.
    """
    factors = getattr(module, "FACTORS", {})
    missing = [name for name in module.CHANNELS if name not in factors and name not in signals]
    if missing:
        raise InputDataError(f"model {module.MODEL!r} needs the signal {missing[0]!r} "
                             f"(given: {', '.join(map(str, signals)) or 'none'})")
    if not factors:
        return tuple(np.asarray(signals[name], dtype=float) for name in module.CHANNELS)
    model = model_of(module)
    values = {name: np.asarray(samples, dtype=float) for name, samples in signals.items()}
    for name, k in model.needs_derivatives:
        from algid.differentiation import algebraic_derivative
        values[(name, k)] = algebraic_derivative(values[name], dt, derivative=k)
    factor_of = {channel: factor for factor, channel in channel_names(model).items()}
    return tuple(values[name] if name not in factors
                 else np.broadcast_to(factor_of[name].evaluate(values, time), np.shape(time))
                 for name in module.CHANNELS)
