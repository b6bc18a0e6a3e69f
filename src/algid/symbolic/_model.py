"""Linear constant-coefficient ODE models, the input of the derivation engine.

A model is one scalar equation

    a_n y^(n) + ... + a_1 y' + a_0 y = b_m u^(m) + ... + b_0 u

between a measured input ``u`` and a measured output ``y``, whose coefficients are
affine in a set of unknown parameters ``theta``.  The engine in
:mod:`algid.symbolic._derivation` turns such a model into an algebraic estimator
``P(t) theta = Q(t)``.
"""

from __future__ import annotations

import ast
import math
import re
from dataclasses import dataclass, field

import sympy as sp

from algid.errors import ModelError
from algid.models._expression import Signal
from algid.models._grammar import (
    LIMITS,
    chain_operands,
    check_name,
    check_text,
    parse_equation,
    parse_expression,
)

__all__ = ["LinearODEModel", "TIME", "LAPLACE", "exact_number"]

#: The time variable of every model.
TIME = sp.Symbol("t", nonnegative=True)
#: The Laplace variable.
LAPLACE = sp.Symbol("s")

_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
_DIFFERENTIATED = re.compile(r"\b([A-Za-z_][A-Za-z0-9_]*)\s*'")
_OPERATIONS = {ast.Add: sp.Add, ast.Sub: lambda a, b: a - b, ast.Mult: sp.Mul,
               ast.Div: lambda a, b: a / b}


def exact_number(value: float):
    """A finite float as an exact rational when it is one (0.5, 2, -3), else a Float.

    Parameters
    ----------
    value : float

    Returns
    -------
    sympy.Rational or sympy.Float
    """
    rational = sp.nsimplify(value, rational=True)
    return rational if float(rational) == float(value) else sp.Float(value)


def _check_finite(expr, where):
    """Every number in ``expr`` is a finite real double."""
    if expr.has(sp.I, sp.zoo, sp.oo, -sp.oo, sp.nan):
        raise ModelError(f"{where} {expr} is not finite and real")
    for number in expr.atoms(sp.Number, sp.NumberSymbol):
        try:
            value = float(number)
        except (TypeError, OverflowError):
            value = math.nan
        if not math.isfinite(value):
            raise ModelError(f"{where} {expr}: {number} is not a finite double")
    return expr


def _from_tree(node, where):
    """A SymPy expression from a checked syntax tree: numbers, names, ``+ - * /``,
    signs and powers by a number of magnitude at most ``LIMITS["exponent"]``."""
    if isinstance(node, ast.Constant):
        value = node.value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ModelError(f"{where}: {value!r} is not a real number")
        try:
            value = float(value)
        except OverflowError:
            value = math.inf
        if not math.isfinite(value):
            raise ModelError(f"{where}: a constant is not a finite double")
        return exact_number(value)
    if isinstance(node, ast.Name):
        check_name(node.id, "name")
        return sp.Symbol(node.id)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
        operand = _from_tree(node.operand, where)
        return -operand if isinstance(node.op, ast.USub) else operand
    if isinstance(node, ast.BinOp) and type(node.op) in _OPERATIONS:
        first, rest = chain_operands(node)
        out = _from_tree(first, where)
        for op, right in rest:
            out = _OPERATIONS[type(op)](out, _from_tree(right, where))
        return out
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
        exponent = _from_tree(node.right, where)
        if not exponent.is_Number or abs(exponent) > LIMITS["exponent"]:
            raise ModelError(f"{where}: an exponent must be a number of magnitude at most "
                             f"{LIMITS['exponent']}")
        return _from_tree(node.left, where) ** exponent
    raise ModelError(f"{where}: only numbers, names, + - * / and ** are allowed")


def _mentions(equation, name):
    """Whether ``name`` appears in ``equation`` as a whole word (a signal to pin as the
    output; otherwise the grammar reports what is missing)."""
    return isinstance(equation, str) and re.search(rf"\b{re.escape(name)}\b", equation) is not None


def _as_expr(value, where):
    """A coefficient as a SymPy expression; text is read with the restricted grammar."""
    if isinstance(value, str):
        expr = _from_tree(parse_expression(value).body, f"{where} {value!r}")
    elif isinstance(value, sp.Basic):
        expr = value
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        if not math.isfinite(value):
            raise ModelError(f"{where} {value!r} is not a finite double")
        expr = exact_number(value) if isinstance(value, float) else sp.Integer(value)
    else:
        raise ModelError(f"cannot read {where} {value!r}: give a number, a SymPy "
                         f"expression or text")
    return _check_finite(expr, where)


@dataclass(frozen=True)
class LinearODEModel:
    """A linear ODE whose coefficients are affine in the unknown parameters.

    Parameters
    ----------
    name : str
        Short identifier, used for generated file names and ``--model``.
    output_coefficients : sequence of sympy expressions
        ``a_n, ..., a_0``: coefficients of the output derivatives, highest first.
    input_coefficients : sequence of sympy expressions
        ``b_m, ..., b_0``: coefficients of the input derivatives, highest first.
    parameters : sequence of sympy.Symbol
        The unknowns, in the order the estimator reports them.
    output, input : str
        Names of the measured output and input signals.
    description : str
        One line shown in reports and generated files.

    Raises
    ------
    ModelError
        If a coefficient is not affine in the parameters, a parameter does not appear,
        or the equation is homogeneous in the parameters (no known coefficient fixes
        their scale).

    Examples
    --------
    >>> import sympy as sp
    >>> from algid.symbolic import LinearODEModel
    >>> a, b = sp.symbols("a b")
    >>> model = LinearODEModel("lag", output_coefficients=(1, a), input_coefficients=(b,),
    ...                        parameters=(a, b), output="y", input="u")
    >>> model.equation_text(), model.order
    ("y' + a*y = b*u", 1)
    """

    name: str
    output_coefficients: tuple
    input_coefficients: tuple
    parameters: tuple
    output: str = "x"
    input: str = "f"
    description: str = ""
    _symbols: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self):
        check_name(self.name, "model name")
        for sig in (self.output, self.input):
            if not isinstance(sig, str) or not _NAME.fullmatch(sig) or sig in ("t", "s"):
                raise ModelError(f"signal name {sig!r} is not a usable identifier")
        if self.output == self.input:
            raise ModelError(f"input and output are both named {self.output!r}")
        params = tuple(sp.Symbol(check_name(str(p), "parameter name"))
                       for p in self.parameters)
        if not params:
            raise ModelError(f"model {self.name!r} has no unknown parameters")
        if len(set(params)) != len(params):
            raise ModelError(f"model {self.name!r} lists a parameter twice")
        if len(params) > LIMITS["parameters"]:
            raise ModelError(f"model {self.name!r} has {len(params)} parameters (at most "
                             f"{LIMITS['parameters']})")
        if max(len(self.output_coefficients), len(self.input_coefficients)) > \
                LIMITS["derivative"] + 1:
            raise ModelError(f"model {self.name!r}: derivatives of order above "
                             f"{LIMITS['derivative']}")
        a = tuple(_as_expr(c, "output coefficient") for c in self.output_coefficients)
        b = tuple(_as_expr(c, "input coefficient") for c in self.input_coefficients)
        if not a or a[0] == 0:
            raise ModelError(f"model {self.name!r}: leading output coefficient is zero")
        object.__setattr__(self, "parameters", params)
        object.__setattr__(self, "output_coefficients", a)
        object.__setattr__(self, "input_coefficients", b)
        allowed = set(params)
        for coeff in a + b:
            stray = coeff.free_symbols - allowed
            if stray:
                raise ModelError(
                    f"model {self.name!r}: coefficient {coeff} uses {sorted(map(str, stray))}, "
                    f"which are not parameters {[str(p) for p in params]}"
                )
            for p in params:
                for q in params:
                    if sp.diff(coeff, p, q) != 0:
                        raise ModelError(
                            f"model {self.name!r}: coefficient {coeff} is not affine in the "
                            "parameters"
                        )
        used = set().union(*(c.free_symbols for c in a + b))
        missing = [str(p) for p in params if p not in used]
        if missing:
            raise ModelError(f"model {self.name!r}: parameters {missing} do not appear in the "
                             "equation")
        known = [c.subs({p: 0 for p in params}) for c in a + b]
        if all(k == 0 for k in known):
            raise ModelError(
                f"model {self.name!r} is homogeneous in its parameters: fix one coefficient "
                "(for example the one of the input) so that their scale is identifiable"
            )

    # ------------------------------------------------------------------ properties
    @property
    def order(self) -> int:
        """Highest derivative in the equation (of the output or of the input)."""
        return max(len(self.output_coefficients), len(self.input_coefficients)) - 1

    @property
    def channels(self) -> tuple:
        """The measured signals the estimator is driven by: ``(output, input)``."""
        return (self.output, self.input)

    @property
    def estimator_channels(self) -> tuple:
        """The channels in the order the generated estimator takes them: input, output."""
        return (self.input, self.output)

    def factor_texts(self) -> dict:
        """Channels that are not a measured signal: none for this model.

        Returns
        -------
        dict
            Empty.
        """
        return {}

    def channel_terms(self) -> tuple:
        """The equation as ``(coefficient, channel, derivative)`` terms summing to zero.

        Output terms carry their coefficient, input terms its negative (the equation
        ``lhs - rhs = 0``); this is the form :func:`~algid.symbolic.derive`
        works on, shared with models of several signals and nonlinear factors.

        Returns
        -------
        tuple of (sympy.Expr, str, int)
        """
        n, m = len(self.output_coefficients) - 1, len(self.input_coefficients) - 1
        return (tuple((c, self.output, n - i) for i, c in enumerate(self.output_coefficients))
                + tuple((-c, self.input, m - j) for j, c in enumerate(self.input_coefficients)))

    @property
    def output_function(self):
        """The output as a SymPy function of time, ``x(t)``."""
        return sp.Function(self.output)(TIME)

    @property
    def input_function(self):
        """The input as a SymPy function of time, ``f(t)``."""
        return sp.Function(self.input)(TIME)

    def ode(self) -> sp.Eq:
        """The model as a SymPy equation in the time domain.

        Returns
        -------
        sympy.Eq
            Output side equal to input side.
        """
        y, u = self.output_function, self.input_function
        n, m = len(self.output_coefficients) - 1, len(self.input_coefficients) - 1
        lhs = sum(c * y.diff(TIME, n - i) for i, c in enumerate(self.output_coefficients))
        rhs = sum(c * u.diff(TIME, m - j) for j, c in enumerate(self.input_coefficients))
        return sp.Eq(lhs, rhs)

    def equation_text(self) -> str:
        """The ODE in plain text, e.g. ``x'' + B*x' + K*x = f``.

        Returns
        -------
        str
            The equation.
        """

        def side(coeffs, sig):
            n = len(coeffs) - 1
            parts = []
            for i, c in enumerate(coeffs):
                if c == 0:
                    continue
                term = sig + "'" * (n - i)
                parts.append(term if c == 1 else f"({c})*{term}" if c.is_Add else f"{c}*{term}")
            return " + ".join(parts).replace("+ -", "- ") or "0"

        left = side(self.output_coefficients, self.output)
        return f"{left} = {side(self.input_coefficients, self.input)}"

    # ------------------------------------------------------------------ parsing
    def to_model(self):
        """This model as an :class:`algid.models.Model`.

        Returns
        -------
        Model
            The representation of user equations used by :func:`algid.identify`.
        """
        from algid.models._grammar import parse_equation

        return parse_equation(self.equation_text(), [str(p) for p in self.parameters],
                              output=self.output, name=self.name)

    @classmethod
    def from_equation(cls, equation: str, *, parameters, output="x", input="f", name="custom",
                      description=""):
        """Build a model from text such as ``"m*x'' + c*x' + k*x = F"``.

        Derivatives are written with primes (``x''``) after the signal name.

        Parameters
        ----------
        equation : str
            ``left = right``; both sides linear in the output, the input and their
            derivatives.
        parameters : str or sequence of str
            The unknowns (a string is split on whitespace or commas).
        output, input : str
            Names of the measured signals used in ``equation``.
        name, description : str
            As in :class:`LinearODEModel`.

        Examples
        --------
        >>> LinearODEModel.from_equation("x'' + B*x' + K*x = f", parameters="B K").order
        2
        """
        for sig in (output, input):
            if not isinstance(sig, str) or not _NAME.fullmatch(sig):
                raise ModelError(f"signal name {sig!r} is not a usable identifier")
        if output == input:
            raise ModelError(f"the input and the output are the same signal {input!r}: "
                             f"name two")
        # a derivative of another signal is the likely mistake: say so first
        for sig in _DIFFERENTIATED.findall(check_text(equation)):
            if sig not in (output, input):
                raise ModelError(f"equation {' '.join(equation.split())[:80]!r}: {sig!r} "
                                 f"is differentiated but is not the output {output!r} "
                                 f"or the input {input!r}")
        model = parse_equation(equation, parameters, name=name,
                               output=output if _mentions(equation, output) else None)
        shown = model.equation if len(model.equation) <= 80 else model.equation[:77] + "..."
        stray = [sig for sig in model.signals if sig not in (output, input)]
        if stray:
            raise ModelError(f"equation {shown!r} uses unknown names {sorted(stray)}")
        coefficients = {output: {}, input: {}}
        for term in model.terms:
            factor = term.factor
            if not isinstance(factor, Signal) or factor.derivative:
                problem = (f"has a term {term} that is not proportional to {output!r}, "
                           f"{input!r} or a derivative" if not factor.signals()
                           else f"is not linear in {output!r} and {input!r}")
                raise ModelError(f"equation {shown!r} {problem}")
            value = exact_number(term.coefficient)
            if term.parameter is not None:
                value = value * sp.Symbol(term.parameter)
            side = coefficients[factor.name]
            side[term.derivative] = side.get(term.derivative, 0) + value

        def highest_first(sig, sign):
            side = coefficients[sig]
            return tuple(sign * side.get(k, 0) for k in range(max(side), -1, -1)) if side else ()

        a, b = highest_first(output, 1), highest_first(input, -1)
        if not a:
            raise ModelError(f"equation {shown!r} does not involve the output {output!r}")
        if not b:
            raise ModelError(f"equation {shown!r} does not involve the input {input!r}")
        names = {p: sp.Symbol(p) for p in model.parameters}
        return cls(name=name, output_coefficients=a, input_coefficients=b,
                   parameters=tuple(names.values()), output=output, input=input,
                   description=description)
