"""A model solved for the highest derivative of its output, as a right-hand side.

:class:`OutputEquation` evaluates ``y^(n) = -(sum of the other terms) / (c * theta)`` on
given state and input values (floats, by closures built from the expression tree: no
code is generated or evaluated); :meth:`IdentificationResult.to_nlsys` exports it to
python-control.

Simulation over sampled inputs is :mod:`algid.simulation._model` (the one simulator:
DOP853 or fixed-step RK4, band-limited or cubic-spline input).
"""

from __future__ import annotations

import math

from algid.errors import ModelError
from algid.models._expression import Call, Constant, Power, Product, Signal, Sum, Time

__all__ = ["OutputEquation", "scalar_function"]

_SCALAR_FUNCTIONS = {
    "sign": lambda v: (v > 0) - (v < 0),
    "abs": abs, "tanh": math.tanh, "sin": math.sin, "cos": math.cos, "tan": math.tan,
    "exp": math.exp, "log": math.log, "sqrt": math.sqrt, "sinh": math.sinh,
    "cosh": math.cosh, "arctan": math.atan,
}


def scalar_function(expr, slot):
    """A function ``(x, u, t) -> float`` evaluating ``expr``.

    Parameters
    ----------
    expr : algid.models._expression.Expression
        A factor of a model term.
    slot : callable
        ``slot(signal)`` -> ``("x", index)`` for a signal read from the state, or
        ``("u", index)`` for one read from the inputs.

    Returns
    -------
    callable
    """
    if isinstance(expr, Constant):
        value = float(expr.value)
        return lambda x, u, t: value
    if isinstance(expr, Time):
        return lambda x, u, t: t
    if isinstance(expr, Signal):
        kind, index = slot(expr)
        if kind == "x":
            return lambda x, u, t: x[index]
        return lambda x, u, t: u[index]
    if isinstance(expr, Call):
        f, arg = _SCALAR_FUNCTIONS[expr.function], scalar_function(expr.args[0], slot)
        return lambda x, u, t: f(arg(x, u, t))
    if isinstance(expr, Power):
        base, exponent = scalar_function(expr.base, slot), float(expr.exponent)
        if exponent == int(exponent):
            e = int(exponent)
            return lambda x, u, t: base(x, u, t) ** e
        # (math.pow: a ValueError for a negative base, where ** gives a complex number)
        return lambda x, u, t: math.pow(base(x, u, t), exponent)
    if isinstance(expr, (Sum, Product)):
        parts = [scalar_function(p, slot)
                 for p in (expr.terms if isinstance(expr, Sum) else expr.factors)]
        if isinstance(expr, Sum):
            return lambda x, u, t: sum(p(x, u, t) for p in parts)

        def product(x, u, t):
            value = 1.0
            for p in parts:
                value *= p(x, u, t)
            return value
        return product
    raise ModelError(f"cannot simulate the factor {expr}")


class OutputEquation:
    """The model solved for the highest derivative of its output.

    Parameters
    ----------
    model : Model
    parameters : mapping
        Parameter name -> value.

    Attributes
    ----------
    order : int
        Number of states (output and its derivatives below the top one).
    inputs : tuple
        ``(signal, k)`` pairs of inputs (and input derivatives) the equation reads.
    """

    def __init__(self, model, parameters):
        self.model = model
        self.parameters = dict(parameters)
        output = model.output
        top = [term for term in model.terms if term.factor == Signal(output)
               and term.derivative == max(t.derivative for t in model.terms
                                          if t.factor == Signal(output))]
        if not top or top[0].derivative == 0:
            raise ModelError(f"cannot simulate {model.equation!r}: the output {output} "
                             f"is not differentiated")
        self.order = top[0].derivative
        top = top[0]
        self.scale = top.coefficient * (1.0 if top.parameter is None
                                        else float(parameters[top.parameter]))
        if self.scale == 0:
            raise ModelError("cannot simulate: the coefficient of the highest derivative "
                             "of the output is zero")
        inputs = {}

        def slot(signal):
            if signal.name == output:
                if signal.derivative >= self.order:
                    raise ModelError(f"cannot simulate {model.equation!r}: {signal} appears "
                                     f"inside a nonlinear factor")
                return ("x", signal.derivative)
            key = (signal.name, signal.derivative)
            return ("u", inputs.setdefault(key, len(inputs)))

        self.terms = []
        for term in model.terms:
            if term is top:
                continue
            weight = term.coefficient * (1.0 if term.parameter is None
                                         else float(parameters[term.parameter]))
            factor = term.factor
            if term.derivative:
                if not isinstance(factor, Signal):
                    raise ModelError(f"cannot simulate a derivative of {factor}")
                factor = Signal(factor.name, term.derivative)
            self.terms.append((-weight / self.scale, scalar_function(factor, slot)))
        self.inputs = tuple(inputs)

    def __call__(self, x, u, t):
        """The highest derivative of the output at state ``x``, inputs ``u``, time ``t``."""
        return sum(w * f(x, u, t) for w, f in self.terms)

    def derivative(self, t, x, u):
        """State derivative (for python-control and SciPy integrators).

        Parameters
        ----------
        t : float
            Time.
        x : sequence of float
            State: the output and its derivatives below the model order.
        u : sequence of float
            Inputs, in the order of :attr:`inputs`.

        Returns
        -------
        list of float
            NaN where a function is outside its domain (``u**0.5`` of a negative
            input), which stops an integrator.
        """
        try:
            top = self(x, u, t)
        except (ArithmeticError, ValueError):
            top = math.nan
        return list(x[1:]) + [top]

