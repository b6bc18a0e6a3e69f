"""A user model: one scalar equation, linear in its unknown parameters.

Moved to one side the equation reads ``sum_i c_i * theta(i) * D^{k_i} z_i(t) = 0``:
each :class:`Term` holds the unknown parameter ``theta(i)`` (``None`` for a known
term), the known coefficient ``c_i``, the derivative order ``k_i`` applied to the whole
factor (only for a plain signal, the constant 1 or time) and the factor ``z_i``, an
:mod:`algid.models._expression` tree.  Built by :func:`algid.models.parse_equation`.
"""

from __future__ import annotations

from dataclasses import dataclass

from algid.models._expression import Constant, Expr, Signal, Time

__all__ = ["Term", "Model", "channel_names"]


@dataclass(frozen=True)
class Term:
    """One term ``coefficient * parameter * D^derivative factor`` of a model.

    Attributes
    ----------
    parameter : str or None
        The unknown parameter multiplying the term; ``None`` for a known term.
    coefficient : float
        Known real multiplier.
    derivative : int
        Order of the time derivative applied to the factor (``>= 1`` only for a plain
        signal, the constant 1 or time).
    factor : Expr
        The factor (channel): a signal, ``Constant(1)``, ``Time()`` or a nonlinear
        expression of signals.

    Examples
    --------
    >>> from algid.models import parse_equation
    >>> term = parse_equation("x'' + B*x' + K*x = f", "B K").terms[1]
    >>> term
    Term(parameter='B', coefficient=1.0, derivative=1, factor=Signal(name='x', derivative=0))
    >>> str(term), term.is_known
    ("B*x'", False)
    """

    parameter: str | None
    coefficient: float
    derivative: int
    factor: Expr

    @property
    def is_known(self) -> bool:
        """True for a term without an unknown parameter."""
        return self.parameter is None

    def __str__(self):
        factor = str(self.factor) if self.derivative == 0 else (
            f"{self.factor}" + "'" * self.derivative if isinstance(self.factor, Signal)
            else f"D{self.derivative}({self.factor})")
        pieces = [] if abs(self.coefficient) == 1 else [f"{self.coefficient:g}"]
        if self.parameter is not None:
            pieces.append(self.parameter)
        if not (isinstance(self.factor, Constant) and self.factor.value == 1 and pieces):
            pieces.append(factor)
        sign = "-" if self.coefficient == -1 else ""
        return sign + "*".join(pieces)


def _is_plain(factor: Expr) -> bool:
    return (isinstance(factor, (Signal, Time))
            or (isinstance(factor, Constant) and factor.value == 1))


@dataclass(frozen=True)
class Model:
    """A model equation ``sum_i c_i theta(i) D^{k_i} z_i = 0``.

    Attributes
    ----------
    name : str
        Label of the model.
    equation : str
        The equation as the user wrote it.
    parameters : tuple of str
        Unknown parameters, in the order given by the user.
    terms : tuple of Term
        The terms, all moved to the left-hand side.
    signals : tuple of str
        Measured signals, in order of first appearance.
    output : str
        The output signal (simulation and instrumental variables need it).

    Examples
    --------
    >>> from algid.models import parse_equation
    >>> model = parse_equation("x'' + B*x' + K*x = f", "B K")
    >>> print(model)
    custom: x'' + B*x' + K*x = f
    >>> model.parameters, model.inputs, model.output, model.order
    (('B', 'K'), ('f',), 'x', 2)
    """

    name: str
    equation: str
    parameters: tuple
    terms: tuple
    signals: tuple
    output: str

    @property
    def order(self) -> int:
        """Highest derivative order applied to a term."""
        return max(term.derivative for term in self.terms)

    @property
    def channels(self) -> tuple:
        """Distinct factors ``z_i`` in order of appearance."""
        return tuple(dict.fromkeys(term.factor for term in self.terms))

    @property
    def needs_derivatives(self) -> tuple:
        """``(signal, k)`` pairs to estimate numerically (inside nonlinear factors).

        A derivative of a plain signal moves onto the kernel instead.
        """
        pairs = {}
        for term in self.terms:
            for pair in term.factor.derivatives():
                pairs[pair] = None
        return tuple(pairs)

    @property
    def is_linear(self) -> bool:
        """True when every factor is a plain signal, the constant 1 or time."""
        return all(_is_plain(term.factor) for term in self.terms)

    @property
    def known_terms(self) -> tuple:
        """Terms without an unknown parameter (they fix the scale)."""
        return tuple(term for term in self.terms if term.parameter is None)

    def parameter_terms(self, parameter: str) -> tuple:
        """The terms multiplied by ``parameter``.

        Parameters
        ----------
        parameter : str
            A parameter name.

        Returns
        -------
        tuple of Term
        """
        return tuple(term for term in self.terms if term.parameter == parameter)

    @property
    def inputs(self) -> tuple:
        """Measured signals other than the output."""
        return tuple(name for name in self.signals if name != self.output)

    def __str__(self):
        return f"{self.name}: {self.equation}"


def channel_names(model: Model) -> dict:
    """Channel identifier of every factor of ``model``, in order of appearance.

    Parameters
    ----------
    model : Model or algid.models.SystemModel
        For a system, the factors of all its equations, named once for the system (a
        factor keeps its identifier in every equation; two factors never share one).

    Returns
    -------
    dict
        Factor (:class:`algid.models._expression.Expr`) -> identifier: the signal's name for a
        plain measured signal, ``one`` for the constant 1, ``time`` for time and ``z1``,
        ``z2``, ... for the other factors (skipping names taken by signals).
    """
    taken = set(model.signals)
    names = {}
    counter = 0

    def fresh():
        nonlocal counter
        counter += 1
        while f"z{counter}" in taken:
            counter += 1
        return f"z{counter}"

    for factor in model.channels:
        if isinstance(factor, Signal) and factor.derivative == 0:
            name = factor.name
        elif isinstance(factor, Constant) and factor.value == 1 and "one" not in taken:
            name = "one"
        elif isinstance(factor, Time) and "time" not in taken:
            name = "time"
        else:
            name = fresh()
        names[factor] = name
    return names
