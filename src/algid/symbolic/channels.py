"""A user :class:`~algid.model.Model` as the derivation engine sees it: named channels.

The derivation (:func:`algid.symbolic.derivation.derive`) needs a model as terms
``(coefficient, channel, derivative)`` that sum to zero, where each channel is a signal
the estimator integrates.  For a user model the channels are its factors: a measured
signal keeps its name; the constant 1 of an offset term is the channel ``one``; time
is ``time``; a nonlinear factor (``V2**3``, ``sign(q')``) is a channel ``z1``, ``z2``,
... whose samples the runtime computes from the data before integrating.  Whatever the
factor, the Laplace transform of ``D^k z`` is ``s^k Z(s)`` minus a polynomial of degree
``k - 1`` in ``s`` made of initial values, so the annihilation of the initial
conditions, the multiplication by ``s^-N`` and the operator table work unchanged.
"""

from __future__ import annotations

import sympy as sp

from algid.expression import Constant, Signal, Time
from algid.model import Model

__all__ = ["ChannelModel", "channel_names"]


def channel_names(model: Model) -> dict:
    """Channel name of every factor of ``model``, in order of appearance.

    Parameters
    ----------
    model : Model

    Returns
    -------
    dict
        Factor (:class:`algid.expression.Expr`) -> identifier: the signal's name for a
        plain measured signal, ``one`` for the constant 1, ``time`` for time and ``z1``,
        ``z2``, ... for the other factors (skipping names taken by signals).
    """
    taken = set(model.signals)
    names = {}
    counter = 0
    for factor in model.channels:
        if isinstance(factor, Signal) and factor.derivative == 0:
            name = factor.name
        elif isinstance(factor, Constant) and factor.value == 1:
            name = "one"
        elif isinstance(factor, Time):
            name = "time"
        else:
            counter += 1
            name = f"z{counter}"
            while name in taken:
                counter += 1
                name = f"z{counter}"
        if name in names.values() or (name in taken and not isinstance(factor, Signal)):
            # a signal called 'one', 'time' or 'z1' keeps its name; the factor moves on
            counter += 1
            name = f"z{counter}"
        names[factor] = name
    return names


def _exact(value: float):
    """A float coefficient as an exact rational when it is one (0.5, 2, -3)."""
    rational = sp.nsimplify(value, rational=True)
    return rational if float(rational) == float(value) else sp.Float(value)


class ChannelModel:
    """A user model prepared for :func:`~algid.symbolic.derivation.derive`.

    Parameters
    ----------
    model : Model
        From :func:`algid.grammar.parse_equation`.
    description : str, optional
        One line shown in reports and generated code.

    Attributes
    ----------
    model : Model
    name : str
    parameters : tuple of sympy.Symbol
    channels : tuple of str
        Channel identifiers, in order of appearance.
    factors : dict
        Channel identifier -> factor expression (:class:`algid.expression.Expr`).
    order : int
        Highest derivative applied to a channel.
    """

    def __init__(self, model: Model, *, description: str = ""):
        self.model = model
        self.name = model.name
        self.description = description
        self.parameters = tuple(sp.Symbol(p) for p in model.parameters)
        names = channel_names(model)
        self.channels = tuple(names.values())
        self.factors = {name: factor for factor, name in names.items()}
        self._names = names
        self.order = model.order

    def channel_terms(self) -> tuple:
        """The equation as ``(coefficient, channel, derivative)`` terms summing to zero."""
        terms = []
        for term in self.model.terms:
            coefficient = _exact(term.coefficient)
            if term.parameter is not None:
                coefficient = coefficient * sp.Symbol(term.parameter)
            terms.append((coefficient, self._names[term.factor], term.derivative))
        return tuple(terms)

    def equation_text(self) -> str:
        """The equation as the user wrote it."""
        return self.model.equation

    def __repr__(self):
        return f"ChannelModel({self.model.equation!r}, channels={self.channels})"
