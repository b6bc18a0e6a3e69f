"""A tiny immutable expression tree for the factors of a user model.

A factor is what multiplies one unknown parameter (or a known coefficient) in a model
equation: a measured signal, the constant 1, time ``t``, or a known nonlinear function
of measured signals and of their derivatives (``y**3``, ``sign(q')``, ``y*u``).  The
tree is built by :mod:`algid.models._grammar` from the user's text, never by ``eval``.

Nodes are frozen dataclasses: equal factors compare and hash equal, so that one factor
written twice is one channel of the estimator.  Every node can

- ``evaluate(values, time=None)`` with NumPy, where ``values`` maps a signal name to its
  samples and ``(name, k)`` to samples of its ``k``-th derivative;
- print itself as text (``str``), in the grammar's own syntax;
- list the signals it reads (``signals()``) and the derivatives of order ``k >= 1`` it
  needs (``derivatives()``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from algid.errors import InputDataError

__all__ = ["Expr", "Signal", "Constant", "Time", "Call", "Sum", "Product", "Power",
           "FUNCTIONS", "ONE"]

#: Whitelisted functions: name in the grammar -> NumPy implementation.
FUNCTIONS = {
    "sign": np.sign,
    "abs": np.abs,
    "tanh": np.tanh,
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    "exp": np.exp,
    "log": np.log,
    "sqrt": np.sqrt,
    "sinh": np.sinh,
    "cosh": np.cosh,
    "arctan": np.arctan,
}


def _number_text(value: float) -> str:
    value = float(value)
    if value == int(value) and abs(value) < 1e15:
        return str(int(value))
    return repr(value)


def _sample_count(values, time):
    if time is not None:
        return np.shape(time)[0]
    for samples in values.values():
        return np.shape(samples)[0]
    raise InputDataError("no samples to evaluate a constant factor on")


class Expr:
    """Base class of the factor expression nodes."""

    #: binding strength for printing: higher binds tighter
    precedence = 100

    def evaluate(self, values, time=None):
        """Samples of the expression.

        Parameters
        ----------
        values : mapping
            Signal name -> samples; ``(name, k)`` -> samples of the ``k``-th derivative.
        time : array_like, optional
            Sample times, needed by :class:`Time`.

        Returns
        -------
        numpy.ndarray
            One value per sample.
        """
        raise NotImplementedError

    def signals(self) -> tuple:
        """Names of the measured signals read, in order of first appearance.

        Returns
        -------
        tuple of str
        """
        return tuple(dict.fromkeys(name for name, _ in self._reads()))

    def derivatives(self) -> tuple:
        """List the ``(name, k)`` pairs with ``k >= 1`` that the expression reads.

        Returns
        -------
        tuple of tuple
        """
        return tuple(dict.fromkeys(pair for pair in self._reads() if pair[1] > 0))

    def _reads(self):
        return ()

    def _wrapped(self, precedence):
        text = str(self)
        return f"({text})" if self.precedence < precedence else text


@dataclass(frozen=True)
class Signal(Expr):
    """A measured signal, or its ``derivative``-th time derivative.

    Attributes
    ----------
    name : str
        Signal name.
    derivative : int
        Order of the time derivative (0 for the signal itself).
    """

    name: str
    derivative: int = 0

    def evaluate(self, values, time=None):
        key = self.name if self.derivative == 0 else (self.name, self.derivative)
        if key not in values:
            raise InputDataError(f"no samples for {self}")
        return np.asarray(values[key], dtype=float)

    def _reads(self):
        return ((self.name, self.derivative),)

    def __str__(self):
        return self.name + "'" * self.derivative


@dataclass(frozen=True)
class Constant(Expr):
    """A known real number.

    Attributes
    ----------
    value : float
        The number.
    """

    value: float

    def evaluate(self, values, time=None):
        return np.full(_sample_count(values, time), float(self.value))

    def __str__(self):
        return _number_text(self.value)

    @property
    def precedence(self):
        """Binding strength for printing (a negative number prints as a sum)."""
        return 100 if self.value >= 0 else 5


@dataclass(frozen=True)
class Time(Expr):
    """Time ``t`` (for drifts such as ``d1*t``)."""

    def evaluate(self, values, time=None):
        if time is None:
            raise InputDataError("the model uses time t but no sample times were given")
        return np.asarray(time, dtype=float)

    def __str__(self):
        return "t"


@dataclass(frozen=True)
class Call(Expr):
    """A whitelisted function (:data:`FUNCTIONS`) of sub-expressions.

    Attributes
    ----------
    function : str
        Name of the function, a key of :data:`FUNCTIONS`.
    args : tuple of Expr
        Its arguments.
    """

    function: str
    args: tuple

    def __post_init__(self):
        if self.function not in FUNCTIONS:
            raise ValueError(f"unknown function {self.function!r}")

    def evaluate(self, values, time=None):
        return FUNCTIONS[self.function](*(a.evaluate(values, time) for a in self.args))

    def _reads(self):
        return tuple(pair for a in self.args for pair in a._reads())

    def __str__(self):
        return f"{self.function}({', '.join(str(a) for a in self.args)})"


@dataclass(frozen=True)
class Sum(Expr):
    """A sum of sub-expressions.

    Attributes
    ----------
    terms : tuple of Expr
        The terms.
    """

    terms: tuple
    precedence = 10

    def evaluate(self, values, time=None):
        total = self.terms[0].evaluate(values, time)
        for term in self.terms[1:]:
            total = total + term.evaluate(values, time)
        return total

    def _reads(self):
        return tuple(pair for a in self.terms for pair in a._reads())

    def __str__(self):
        text = str(self.terms[0])
        for term in self.terms[1:]:
            piece = str(term)
            text += f" - {piece[1:]}" if piece.startswith("-") else f" + {piece}"
        return text


@dataclass(frozen=True)
class Product(Expr):
    """A product of sub-expressions.

    Attributes
    ----------
    factors : tuple of Expr
        The factors.
    """

    factors: tuple
    precedence = 20

    def evaluate(self, values, time=None):
        total = self.factors[0].evaluate(values, time)
        for factor in self.factors[1:]:
            total = total * factor.evaluate(values, time)
        return total

    def _reads(self):
        return tuple(pair for a in self.factors for pair in a._reads())

    def __str__(self):
        return "*".join(f._wrapped(21) for f in self.factors)


@dataclass(frozen=True)
class Power(Expr):
    """``base ** exponent`` with a numeric exponent.

    Attributes
    ----------
    base : Expr
        The base.
    exponent : float
        The exponent.
    """

    base: Expr
    exponent: float
    precedence = 30

    def evaluate(self, values, time=None):
        base = self.base.evaluate(values, time)
        exponent = float(self.exponent)
        if exponent == int(exponent):
            # integer powers of negative samples are well defined
            return base ** int(exponent) if exponent >= 0 else 1.0 / base ** int(-exponent)
        return base ** exponent

    def _reads(self):
        return self.base._reads()

    def __str__(self):
        exponent = _number_text(self.exponent)
        if self.exponent < 0:
            exponent = f"({exponent})"
        return f"{self.base._wrapped(31)}**{exponent}"


for _node in (Signal, Constant, Time, Call, Sum, Product, Power):
    _node.evaluate.__doc__ = Expr.evaluate.__doc__

#: The factor of an offset term.
ONE = Constant(1.0)
