"""Parse a model equation written by the user into a :class:`~algid.model.Model`.

The grammar is Python's expression syntax restricted to a whitelist of node types
(numbers, names, ``+ - * / **``, unary signs and calls of the functions of
:data:`algid.expression.FUNCTIONS`), read with :mod:`ast`: user text is never
evaluated.  Derivatives are written with primes (``q''``); before parsing, a prime
sequence after a name becomes a reserved name (``__d2__q``).  Every other name is a
measured signal, a parameter, time ``t`` or the constant ``pi``.

Each side is expanded into a sum of terms ``coefficient * parameter * factor`` while
it is read; a product of two parameters, a parameter inside a function, a power or a
denominator, and a derivative of anything but a measured signal are refused with a
one-line :class:`~algid.errors.ModelError`.
"""

from __future__ import annotations

import ast
import math
import re

from algid.errors import ModelError
from algid.expression import FUNCTIONS, ONE, Call, Constant, Expr, Power, Product, Signal, Sum, Time
from algid.model import Model, Term

__all__ = ["parse_equation", "RESERVED_NAMES"]

#: Names with a fixed meaning in an equation.
RESERVED_NAMES = ("t", "pi")

_PRIMES = re.compile(r"([A-Za-z_][A-Za-z_0-9]*)\s*('+)")
_DERIVATIVE_NAME = re.compile(r"^__d(\d+)__([A-Za-z_][A-Za-z_0-9]*)$")
_IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z_0-9]*$")


def _fail(equation, message):
    raise ModelError(f"equation {equation!r}: {message}")


# A "form" is the expanded side of an equation: a list of (coefficient, parameter or
# None, factor) with the factor an Expr (ONE for a pure number).


def _multiply_factors(a: Expr, b: Expr) -> Expr:
    pieces = []
    for factor in (a, b):
        if isinstance(factor, Product):
            pieces.extend(factor.factors)
        elif factor != ONE:
            pieces.append(factor)
    if not pieces:
        return ONE
    if len(pieces) == 1:
        return pieces[0]
    # a canonical order so that y*u and u*y are one channel
    return Product(tuple(sorted(pieces, key=str)))


class _Reader:
    def __init__(self, equation, parameters, signals):
        self.equation = equation
        self.parameters = parameters
        self.signals = signals

    def fail(self, message):
        _fail(self.equation, message)

    def form(self, node):
        if isinstance(node, ast.Expression):
            return self.form(node.body)
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                self.fail(f"{node.value!r} is not a real number")
            return [(float(node.value), None, ONE)]
        if isinstance(node, ast.Name):
            return self.name(node.id)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
            sign = -1.0 if isinstance(node.op, ast.USub) else 1.0
            return [(sign * c, p, f) for c, p, f in self.form(node.operand)]
        if isinstance(node, ast.BinOp):
            left, right = self.form(node.left), self.form(node.right)
            if isinstance(node.op, ast.Add):
                return left + right
            if isinstance(node.op, ast.Sub):
                return left + [(-c, p, f) for c, p, f in right]
            if isinstance(node.op, ast.Mult):
                return self.multiply(left, right)
            if isinstance(node.op, ast.Div):
                return self.divide(left, right, node)
            if isinstance(node.op, ast.Pow):
                return self.power(left, right, node)
        if isinstance(node, ast.Call):
            return self.call(node)
        text = ast.unparse(node) if hasattr(ast, "unparse") else type(node).__name__
        self.fail(f"{text!r} is not allowed (use numbers, names, + - * / **, primes "
                  f"and the functions {', '.join(FUNCTIONS)})")

    def name(self, identifier):
        match = _DERIVATIVE_NAME.match(identifier)
        if match:
            order, base = int(match.group(1)), match.group(2)
            if base in self.parameters:
                self.fail(f"parameter {base} cannot be differentiated")
            if base in RESERVED_NAMES or base in FUNCTIONS:
                self.fail(f"{base}{chr(39) * order}: only a measured signal can be "
                          f"differentiated")
            self.check_signal(base)
            return [(1.0, None, Signal(base, order))]
        if identifier.startswith("__"):
            self.fail(f"name {identifier} is reserved")
        if identifier in self.parameters:
            return [(1.0, identifier, ONE)]
        if identifier == "t":
            return [(1.0, None, Time())]
        if identifier == "pi":
            return [(math.pi, None, ONE)]
        if identifier in FUNCTIONS:
            self.fail(f"function {identifier} must be called, as {identifier}(...)")
        self.check_signal(identifier)
        return [(1.0, None, Signal(identifier))]

    def check_signal(self, name):
        if self.signals is not None and name not in self.signals:
            self.fail(f"unknown name {name} (not a parameter nor one of the signals "
                      f"{', '.join(self.signals)})")

    def multiply(self, left, right):
        out = []
        for cl, pl, fl in left:
            for cr, pr, fr in right:
                if pl is not None and pr is not None:
                    self.fail(f"parameters {pl} and {pr} are multiplied together: the "
                              f"model must be linear in its parameters")
                out.append((cl * cr, pl if pl is not None else pr, _multiply_factors(fl, fr)))
        return out

    def known_expression(self, form, where):
        """A parameter-free form as one Expr."""
        for _, parameter, _ in form:
            if parameter is not None:
                self.fail(f"parameter {parameter} appears {where}: the model must be "
                          f"linear in its parameters")
        pieces = []
        for coefficient, _, factor in form:
            if coefficient == 0:
                continue
            if factor == ONE:
                pieces.append(Constant(coefficient))
            elif coefficient == 1:
                pieces.append(factor)
            else:
                pieces.append(Product((Constant(coefficient), factor)))
        if not pieces:
            return Constant(0.0)
        return pieces[0] if len(pieces) == 1 else Sum(tuple(pieces))

    @staticmethod
    def number(form):
        """The value of a form that is a plain number, else None."""
        if all(p is None and f == ONE for _, p, f in form):
            return float(sum(c for c, _, _ in form))
        return None

    def divide(self, left, right, node):
        denominator = self.known_expression(right, "in a denominator")
        value = self.number(right)
        if value is not None:
            if value == 0:
                self.fail(f"division by zero in {ast.unparse(node)!r}")
            return [(c / value, p, f) for c, p, f in left]
        return self.multiply(left, [(1.0, None, Power(denominator, -1.0))])

    def power(self, base, exponent, node):
        value = self.number(exponent)
        if value is None:
            self.fail(f"the exponent of {ast.unparse(node)!r} must be a number")
        base_expr = self.known_expression(base, "in a power")
        if value == 1:
            return base
        number = self.number(base)
        if number is not None:
            return [(number ** value, None, ONE)]
        if len(base) == 1 and base[0][2] != ONE:
            coefficient, _, factor = base[0]
            return [(coefficient ** value, None, Power(factor, value))]
        return [(1.0, None, Power(base_expr, value))]

    def call(self, node):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            name = ast.unparse(node.func)
            self.fail(f"unknown function {name} (allowed: {', '.join(FUNCTIONS)})")
        if node.keywords:
            self.fail(f"{node.func.id}() takes no keyword arguments")
        if len(node.args) != 1:
            self.fail(f"{node.func.id}() takes exactly one argument")
        argument = self.form(node.args[0])
        expr = self.known_expression(argument, f"inside {node.func.id}()")
        if self.number(argument) is not None:
            return [(float(FUNCTIONS[node.func.id](self.number(argument))), None, ONE)]
        return [(1.0, None, Call(node.func.id, (expr,)))]


def _replace_primes(equation):
    if re.search(r"\)\s*'", equation):
        _fail(equation, "a derivative of a parenthesised expression is not allowed: only "
                        "a measured signal can be differentiated (write y' not (y**3)')")
    text = _PRIMES.sub(lambda m: f"__d{len(m.group(2))}__{m.group(1)}", equation)
    if "'" in text:
        _fail(equation, "a prime must follow a signal name, as in y' or y''")
    return text


def _parse_side(equation, text, reader):
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError:
        _fail(equation, f"cannot read {text.strip()!r} as an expression")
    return reader.form(tree)


def _check_parameters(parameters, equation):
    if isinstance(parameters, str):
        parameters = parameters.replace(",", " ").split()
    parameters = tuple(parameters)
    if not parameters:
        _fail(equation, "no unknown parameters given")
    for name in parameters:
        if not isinstance(name, str) or not _IDENTIFIER.match(name):
            _fail(equation, f"parameter name {name!r} is not an identifier")
        if name in RESERVED_NAMES or name in FUNCTIONS or name.startswith("__"):
            _fail(equation, f"parameter name {name} is reserved")
    if len(set(parameters)) != len(parameters):
        _fail(equation, "a parameter is listed twice")
    return parameters


def _to_terms(form):
    combined = {}
    for coefficient, parameter, factor in form:
        derivative = 0
        if isinstance(factor, Signal) and factor.derivative > 0:
            derivative, factor = factor.derivative, Signal(factor.name)
        key = (parameter, derivative, factor)
        combined[key] = combined.get(key, 0.0) + coefficient
    return tuple(Term(p, c, k, f) for (p, k, f), c in combined.items() if c != 0)


def _output(terms, signals, output, equation):
    if output is not None:
        if output not in signals:
            _fail(equation, f"output {output} is not a signal of the equation "
                            f"({', '.join(signals)})")
        return output
    orders = {}
    for term in terms:
        if isinstance(term.factor, Signal):
            name = term.factor.name
            orders[name] = max(orders.get(name, 0), term.derivative)
    if not orders:
        _fail(equation, "no plain measured signal to take as the output; give output=")
    top = max(orders.values())
    candidates = [name for name, order in orders.items() if order == top]
    if len(candidates) > 1:
        _fail(equation, f"the output is ambiguous ({', '.join(candidates)} have the "
                        f"highest derivative order); give output=")
    return candidates[0]


def parse_equation(text, parameters, *, output=None, name="custom", signals=None) -> Model:
    """Read a model equation.

    Parameters
    ----------
    text : str
        The equation, e.g. ``"V2'' + B*V2' + K*V2 + K3*V2**3 = G*V1 + d"``.
    parameters : sequence of str or str
        Unknown parameters (a string is split on spaces and commas).
    output : str, optional
        The output signal; by default the signal of highest derivative order.
    name : str
        Label of the model.
    signals : sequence of str, optional
        Names of the available measured signals; when given, any other name is refused.

    Returns
    -------
    Model

    Raises
    ------
    ModelError
        One line naming the problem.
    """
    if not isinstance(text, str) or not text.strip():
        raise ModelError("the equation is empty")
    equation = " ".join(text.split())
    parameters = _check_parameters(parameters, equation)
    if signals is not None:
        signals = tuple(signals)
        clash = set(signals) & set(parameters)
        if clash:
            _fail(equation, f"{sorted(clash)[0]} is both a signal and a parameter")
    prepared = _replace_primes(equation)
    sides = re.split(r"(?<![=!<>])=(?!=)", prepared)
    if len(sides) != 2 or any(op in prepared for op in ("==", "<", ">", "!")):
        _fail(equation, "write exactly one '=' between the two sides")
    reader = _Reader(equation, parameters, signals)
    left = _parse_side(equation, sides[0], reader)
    right = _parse_side(equation, sides[1], reader)
    terms = _to_terms(left + [(-c, p, f) for c, p, f in right])
    used = {term.parameter for term in terms}
    for parameter in parameters:
        if parameter not in used:
            _fail(equation, f"parameter {parameter} does not appear (or its terms cancel)")
    if not any(term.parameter is None for term in terms):
        _fail(equation, "no known term: every term has a parameter, so the scale is not "
                        "fixed (give one term a known coefficient, e.g. y'' + ...)")
    found = tuple(dict.fromkeys(s for term in terms for s in term.factor.signals()))
    if not found:
        _fail(equation, "no measured signal appears")
    return Model(name=name, equation=equation, parameters=parameters, terms=terms,
                 signals=found, output=_output(terms, found, output, equation))
