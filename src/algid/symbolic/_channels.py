"""A user :class:`~algid.models.Model` as the derivation engine sees it: named channels.

The derivation (:func:`algid.symbolic.derive`) needs a model as terms
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

from algid.models._model import Model, channel_names
from algid.symbolic._model import exact_number

__all__ = ["ChannelModel", "channel_names"]


class ChannelModel:
    """A user model prepared for :func:`~algid.symbolic.derive`.

    Parameters
    ----------
    model : Model
        From :func:`algid.models.parse_equation`.
    description : str, optional
        One line shown in reports and generated code.
    names : dict, optional
        Factor -> channel identifier, for an equation of a system: the system's names
        (:func:`algid.models._model.channel_names` of the system), so that a channel
        means one factor in every equation.  Default: the equation's own.

    Attributes
    ----------
    model : Model
    name : str
    parameters : tuple of sympy.Symbol
    channels : tuple of str
        Channel identifiers, in order of appearance.
    factors : dict
        Channel identifier -> factor expression (:class:`algid.models._expression.Expr`).
    order : int
        Highest derivative applied to a channel.
    """

    def __init__(self, model: Model, *, description: str = "", names=None):
        self.model = model
        self.name = model.name
        self.description = description
        self.parameters = tuple(sp.Symbol(p) for p in model.parameters)
        names = channel_names(model) if names is None else \
            {factor: names[factor] for factor in model.channels}
        self.channels = tuple(names.values())
        self.factors = {name: factor for factor, name in names.items()}
        self._names = names
        self.order = model.order
        self.output = model.output
        self.input = model.inputs[0] if model.inputs else model.output
        #: the channels in the order the generated estimator takes them
        self.estimator_channels = self.channels

    def factor_texts(self) -> dict:
        """The channels that are not a measured signal, with their factor as text.

        Returns
        -------
        dict
            Channel identifier -> factor (``"V2**3"``, ``"1"``, ``"t"``).
        """
        return {name: str(factor) for name, factor in self.factors.items()
                if name not in self.model.signals}

    def channel_terms(self) -> tuple:
        """The equation as ``(coefficient, channel, derivative)`` terms summing to zero.

        Returns
        -------
        tuple of (sympy.Expr, str, int)
        """
        terms = []
        for term in self.model.terms:
            coefficient = exact_number(term.coefficient)
            if term.parameter is not None:
                coefficient = coefficient * sp.Symbol(term.parameter)
            terms.append((coefficient, self._names[term.factor], term.derivative))
        return tuple(terms)

    def equation_text(self) -> str:
        """The equation as the user wrote it.

        Returns
        -------
        str
        """
        return self.model.equation

    def __repr__(self):
        return f"ChannelModel({self.model.equation!r}, channels={self.channels})"
