"""Parse a model equation written by the user into a :class:`~algid.models.Model`.

The grammar is Python's expression syntax restricted to a whitelist of node types
(numbers, names, ``+ - * / **``, unary signs and calls of the functions of
:data:`algid.models._expression.FUNCTIONS`), read with :mod:`ast`: user text is never
evaluated.  Derivatives are written with primes (``q''``); before parsing, a prime
sequence after a name becomes a reserved name (``__d2__q``).  Every other name is a
measured signal, a parameter, time ``t`` or the constant ``pi``.

Each side is expanded into a sum of terms ``coefficient * parameter * factor`` while
it is read; a product of two parameters, a parameter inside a function, a power or a
denominator, and a derivative of anything but a measured signal are refused with a
one-line :class:`~algid.errors.ModelError`.

The text is untrusted: only ASCII letters, digits, ``_``, whitespace and
``+ - * / ( ) . , = '`` are read (no comments, quotes or brackets), and the size of the
text, the nesting of its expressions, the number of their nodes and terms, the
exponents, the derivative orders and the number of parameters are bounded
(:data:`LIMITS`), each checked before the work it bounds.  Every constant, as written
or computed from other constants, must be a finite double.
"""

from __future__ import annotations

import ast
import keyword
import math
import re
import string

import numpy as np

from algid.errors import ModelError
from algid.models._expression import (
    FUNCTIONS,
    ONE,
    Call,
    Constant,
    Expr,
    Power,
    Product,
    Signal,
    Sum,
    Time,
)
from algid.models._model import Model, Term

__all__ = ["parse_equation", "parse_expression", "chain_operands", "check_name",
           "check_text",
           "RESERVED_NAMES", "LIMITS"]

#: Names with a fixed meaning in an equation.
RESERVED_NAMES = ("t", "pi")

#: Bounds on an equation (each refused with a one-line ModelError).
LIMITS = {
    "length": 10_000,     # characters of the equation
    "nesting": 50,        # nested parentheses, calls, signs and powers
    "nodes": 2_000,       # numbers, names and operations of one side
    "terms": 500,         # terms of a side once expanded
    "exponent": 16,       # |exponent| of a power of a signal expression
    "derivative": 8,      # primes after a name
    "parameters": 12,     # unknown parameters
    "system_parameters": 96,   # unknown parameters of a system (12 in each equation)
    "channels": 64,       # distinct factors (signals, 1, t, nonlinear factors)
    "name": 64,           # characters of a name
}

_PRIMES = re.compile(r"([A-Za-z_][A-Za-z_0-9]*)\s*('+)")
_DERIVATIVE_NAME = re.compile(r"__d(\d+)__([A-Za-z_][A-Za-z_0-9]*)")
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z_0-9]*")
_ALLOWED = frozenset(string.ascii_letters + string.digits + "_+-*/().,='" + " \t\n\r")
#: Operators of a left-associative chain (``a + b - c``, ``a * b / c``): reading such a
#: chain is iterative, and it counts as one level of nesting.
_CHAINS = ((ast.Add, ast.Sub), (ast.Mult, ast.Div))


def _shown(equation):
    """The equation for a message: one line, at most 80 characters."""
    return equation if len(equation) <= 80 else equation[:77] + "..."


def _fail(equation, message):
    raise ModelError(f"equation {_shown(equation)!r}: {message}")


def check_name(name, what="name"):
    """Check that ``name`` is an ASCII identifier of at most ``LIMITS["name"]`` characters.

    Parameters
    ----------
    name : object
        The name to check.
    what : str
        What it names, for the message.

    Returns
    -------
    str
        ``name``.

    Raises
    ------
    ModelError
        One line naming the problem.
    """
    if not isinstance(name, str) or not _IDENTIFIER.fullmatch(name):
        raise ModelError(f"{what} {name!r} is not an identifier (ASCII letters, digits "
                         f"and _, not starting with a digit)")
    if len(name) > LIMITS["name"]:
        raise ModelError(f"{what} {name[:20]!r}... is longer than {LIMITS['name']} "
                         f"characters")
    return name


def _chain(op):
    return next((i for i, ops in enumerate(_CHAINS) if isinstance(op, ops)), None)


def _is_chain_link(node, parent):
    """``node`` is the left operand of ``parent`` in one chain of ``+ -`` or ``* /``."""
    return (isinstance(parent, ast.BinOp) and node is parent.left
            and isinstance(node, ast.BinOp) and _chain(parent.op) is not None
            and _chain(node.op) == _chain(parent.op))


def _check_characters(equation):
    for character in equation:
        if character in _ALLOWED:
            continue
        if character == "#":
            _fail(equation, "'#' is not allowed: an equation has no comments")
        if ord(character) > 127:
            _fail(equation, f"non-ASCII character {character!r} (U+{ord(character):04X}) is "
                            f"not allowed: names are ASCII letters, digits and _")
        _fail(equation, f"character {character!r} is not allowed (use names, numbers, "
                        f"+ - * / ** ( ), primes and one =)")


def _check_parentheses(equation):
    """Refuse deep nesting before the parser recurses on it."""
    depth = deepest = 0
    for character in equation:
        if character == "(":
            depth += 1
            deepest = max(deepest, depth)
        elif character == ")":
            depth -= 1
    if deepest > LIMITS["nesting"]:
        _fail(equation, f"parentheses nested {deepest} deep (at most {LIMITS['nesting']})")


def _check_tree(equation, tree):
    """Count the expression nodes and their nesting, without recursion."""
    count = 0
    stack = [(tree.body, None, 1)]
    while stack:
        node, parent, depth = stack.pop()
        if not isinstance(node, ast.expr):
            continue
        if _is_chain_link(node, parent):
            depth -= 1
        count += 1
        if count > LIMITS["nodes"]:
            _fail(equation, f"a side has more than {LIMITS['nodes']} numbers, names and "
                            f"operations")
        if depth > LIMITS["nesting"]:
            _fail(equation, f"expressions nested more than {LIMITS['nesting']} deep")
        stack.extend((child, node, depth + 1) for child in ast.iter_child_nodes(node))


def _finite(value):
    """``value`` as a float if it is a finite real number, else None."""
    if isinstance(value, complex):
        return None
    try:
        value = float(value)
    except (OverflowError, TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


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
        self.text = ""

    def fail(self, message):
        _fail(self.equation, message)

    def snippet(self, node):
        """The text of ``node`` as the user wrote it (primes restored), shortened."""
        piece = self.text[node.col_offset:node.end_col_offset]
        piece = _DERIVATIVE_NAME.sub(lambda m: m.group(2) + "'" * int(m.group(1)), piece)
        return piece if len(piece) <= 60 else piece[:57] + "..."

    def checked(self, form, node):
        """``form`` if every coefficient is a finite double, else a one-line error."""
        for coefficient, _, _ in form:
            if _finite(coefficient) is None:
                self.fail(f"{self.snippet(node)!r} gives a constant that is not a finite "
                          f"real double")
        return form

    def read(self, text, tree):
        self.text = text
        try:
            return self.form(tree.body)
        except RecursionError:  # pragma: no cover - the nesting is bounded beforehand
            self.fail("the expression is nested too deep")

    def form(self, node):
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                self.fail(f"{self.snippet(node)!r} is not a real number")
            value = _finite(node.value)
            if value is None:
                self.fail(f"the constant {self.snippet(node)} is not a finite double")
            return [(value, None, ONE)]
        if isinstance(node, ast.Name):
            return self.name(node.id)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.UAdd, ast.USub)):
            sign = -1.0 if isinstance(node.op, ast.USub) else 1.0
            return [(sign * c, p, f) for c, p, f in self.form(node.operand)]
        if isinstance(node, ast.BinOp) and _chain(node.op) is not None:
            return self.chain(node)
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            return self.power(self.form(node.left), self.form(node.right), node)
        if isinstance(node, ast.Call):
            return self.call(node)
        self.fail(f"{self.snippet(node)!r} is not allowed (use numbers, names, + - * / **, "
                  f"primes and the functions {', '.join(FUNCTIONS)})")

    def chain(self, node):
        """``a + b - c ...`` or ``a * b / c ...``, read left to right without recursion."""
        links = []
        while _is_chain_link(node.left, node):
            links.append(node)
            node = node.left
        links.append(node)
        out = self.form(node.left)
        for link in reversed(links):
            right = self.form(link.right)
            if isinstance(link.op, ast.Add):
                out = out + right
            elif isinstance(link.op, ast.Sub):
                out = out + [(-c, p, f) for c, p, f in right]
            elif isinstance(link.op, ast.Mult):
                out = self.multiply(out, right, link)
            else:
                out = self.divide(out, right, link)
            if len(out) > LIMITS["terms"]:
                self.fail(f"{self.snippet(link)!r} expands to more than {LIMITS['terms']} "
                          f"terms")
        return out

    def name(self, identifier):
        match = _DERIVATIVE_NAME.fullmatch(identifier)
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
        if len(name) > LIMITS["name"]:
            self.fail(f"name {name[:20]}... is longer than {LIMITS['name']} characters")
        if self.signals is not None and name not in self.signals:
            self.fail(f"unknown name {name} (not a parameter nor one of the signals "
                      f"{', '.join(self.signals)})")

    def multiply(self, left, right, node):
        if len(left) * len(right) > LIMITS["terms"]:
            self.fail(f"{self.snippet(node)!r} expands to more than {LIMITS['terms']} terms")
        out = []
        for cl, pl, fl in left:
            for cr, pr, fr in right:
                if pl is not None and pr is not None:
                    self.fail(f"parameters {pl} and {pr} are multiplied together: the "
                              f"model must be linear in its parameters")
                out.append((cl * cr, pl if pl is not None else pr, _multiply_factors(fl, fr)))
        return self.checked(out, node)

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

    def number(self, form, node):
        """The value of a form that is a plain number, else None."""
        if all(p is None and f == ONE for _, p, f in form):
            value = _finite(math.fsum(c for c, _, _ in form))
            if value is None:
                self.fail(f"{self.snippet(node)!r} gives a constant that is not a finite "
                          f"real double")
            return value
        return None

    def divide(self, left, right, node):
        denominator = self.known_expression(right, "in a denominator")
        value = self.number(right, node.right)
        if value is not None:
            if value == 0:
                self.fail(f"division by zero in {self.snippet(node)!r}")
            return self.checked([(c / value, p, f) for c, p, f in left], node)
        return self.multiply(left, [(1.0, None, Power(denominator, -1.0))], node)

    def power(self, base, exponent, node):
        value = self.number(exponent, node.right)
        if value is None:
            self.fail(f"the exponent of {self.snippet(node)!r} must be a number")
        base_expr = self.known_expression(base, "in a power")
        if value == 1:
            return base
        number = self.number(base, node.left)
        try:
            if number is not None:
                return self.checked([(number ** value, None, ONE)], node)
            if abs(value) > LIMITS["exponent"]:
                self.fail(f"the exponent of {self.snippet(node)!r} is beyond "
                          f"{LIMITS['exponent']} in magnitude")
            if len(base) == 1 and base[0][2] != ONE:
                coefficient, _, factor = base[0]
                return self.checked([(coefficient ** value, None, Power(factor, value))], node)
        except (OverflowError, ZeroDivisionError):
            self.fail(f"{self.snippet(node)!r} gives a constant that is not a finite real "
                      f"double")
        return [(1.0, None, Power(base_expr, value))]

    def call(self, node):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            self.fail(f"unknown function {self.snippet(node.func)} (allowed: "
                      f"{', '.join(FUNCTIONS)})")
        if node.keywords:
            self.fail(f"{node.func.id}() takes no keyword arguments")
        if len(node.args) != 1:
            self.fail(f"{node.func.id}() takes exactly one argument")
        argument = self.form(node.args[0])
        expr = self.known_expression(argument, f"inside {node.func.id}()")
        value = self.number(argument, node.args[0])
        if value is not None:
            with np.errstate(all="ignore"):
                result = FUNCTIONS[node.func.id](value)
            return self.checked([(result, None, ONE)], node)
        return [(1.0, None, Call(node.func.id, (expr,)))]


def _replace_primes(equation):
    typed = re.search(r"\b__\w*", equation)  # (the derivatives' internal names among them,
    if typed:                                 # whose orders only the primes' check bounds)
        _fail(equation, f"name {typed.group(0)} is reserved (names starting with __)")
    if re.search(r"\)\s*'", equation):
        _fail(equation, "a derivative of a parenthesised expression is not allowed: only "
                        "a measured signal can be differentiated (write y' not (y**3)')")

    def derivative_name(match):
        order = len(match.group(2))
        if order > LIMITS["derivative"]:
            _fail(equation, f"{match.group(1)} is differentiated {order} times (at most "
                            f"{LIMITS['derivative']})")
        return f"__d{order}__{match.group(1)}"

    text = _PRIMES.sub(derivative_name, equation)
    if "'" in text:
        _fail(equation, "a prime must follow a signal name, as in y' or y''")
    return text


def _syntax_tree(equation, text):
    text = text.strip()
    try:
        tree = ast.parse(text, mode="eval")
    except (SyntaxError, ValueError):
        # shown as the user wrote it (y'' for its internal name)
        written = _DERIVATIVE_NAME.sub(lambda m: m.group(2) + "'" * int(m.group(1)), text)
        _fail(equation, f"cannot read {_shown(written)!r} as an expression")
    except (RecursionError, MemoryError):
        _fail(equation, f"expressions nested more than {LIMITS['nesting']} deep")
    _check_tree(equation, tree)
    return text, tree


def _parse_side(equation, text, reader):
    return reader.read(*_syntax_tree(equation, text))


def parse_expression(text):
    """The syntax tree of an expression, with the limits and characters of an equation.

    For other readers of user text (such as the coefficients of
    :class:`algid.symbolic.LinearODEModel`): the tree is only checked, not
    interpreted; read it with a whitelist of node types, and its chains of ``+ -`` and
    ``* /`` with :func:`chain_operands` (they may be longer than the nesting limit).

    Parameters
    ----------
    text : str
        The expression, e.g. ``"2*B + 1"``.

    Returns
    -------
    ast.Expression

    Raises
    ------
    ModelError
        One line naming the problem.
    """
    if not isinstance(text, str) or not text.strip():
        raise ModelError(f"expression {text!r} is empty or not text")
    if len(text) > LIMITS["length"]:
        raise ModelError(f"expression of {len(text)} characters (at most {LIMITS['length']})")
    expression = " ".join(text.split())
    _check_characters(expression)
    _check_parentheses(expression)
    if "'" in expression or "=" in expression:
        _fail(expression, "an expression has no primes and no '='")
    return _syntax_tree(expression, expression)[1]


def chain_operands(node):
    """A chain ``a + b - c ...`` (or ``a * b / c ...``) as its first operand and the rest.

    Parameters
    ----------
    node : ast.BinOp
        The last operation of the chain.

    Returns
    -------
    first : ast.expr
    rest : list of (ast.operator, ast.expr)
        The operations, left to right.
    """
    links = []
    while _is_chain_link(node.left, node):
        links.append(node)
        node = node.left
    links.append(node)
    return node.left, [(link.op, link.right) for link in reversed(links)]


def _check_parameters(parameters, equation, most):
    if isinstance(parameters, str):
        parameters = parameters.replace(",", " ").split()
    if not isinstance(parameters, (list, tuple)):
        _fail(equation, f"parameters must be a string or a sequence of names, got "
                        f"{type(parameters).__name__}")
    parameters = tuple(parameters)
    if not parameters:
        _fail(equation, "no unknown parameters given")
    if len(parameters) > most:
        _fail(equation, f"{len(parameters)} parameters (at most {most})")
    for name in parameters:
        if not isinstance(name, str) or not _IDENTIFIER.fullmatch(name):
            _fail(equation, f"parameter name {name!r} is not an identifier")
        if len(name) > LIMITS["name"]:
            _fail(equation, f"parameter name {name[:20]}... is longer than "
                            f"{LIMITS['name']} characters")
        if name in RESERVED_NAMES or name in FUNCTIONS or name.startswith("__"):
            _fail(equation, f"parameter name {name} is reserved")
        if keyword.iskeyword(name):
            _fail(equation, f"parameter name {name} is a Python keyword, which an equation "
                            f"cannot hold: choose another name")
    if len(set(parameters)) != len(parameters):
        _fail(equation, "a parameter is listed twice")
    return parameters


def _to_terms(form, equation):
    combined = {}
    for coefficient, parameter, factor in form:
        derivative = 0
        if isinstance(factor, Signal) and factor.derivative > 0:
            derivative, factor = factor.derivative, Signal(factor.name)
        key = (parameter, derivative, factor)
        combined[key] = combined.get(key, 0.0) + coefficient
    if any(_finite(c) is None for c in combined.values()):
        _fail(equation, "a coefficient sums to a constant that is not a finite double")
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


def check_text(text):
    """The checks of an equation's text that come before reading it.

    Parameters
    ----------
    text : str
        The equation.

    Returns
    -------
    str
        The text on one line (runs of whitespace made one space).

    Raises
    ------
    ModelError
        Not a text (a list: a system, named as such), empty, too long, a character
        outside the grammar (``#``, quotes, brackets,
        non-ASCII), or parentheses nested beyond ``LIMITS["nesting"]``.
    """
    if isinstance(text, (list, tuple)):
        raise ModelError(f"an equation is one text, got a {type(text).__name__} of "
                         f"{len(text)}: a system of equations goes to algid.identify, "
                         f"algid.Tracker, algid.compile_equation or algid.symbolic.derive "
                         f"(algid.models.parse_system)")
    if not isinstance(text, str):
        raise ModelError(f"an equation is a text such as \"y' + a*y = u\", got "
                         f"{type(text).__name__}")
    if not text.strip():
        raise ModelError("the equation is empty")
    if len(text) > LIMITS["length"]:
        raise ModelError(f"equation {_shown(' '.join(text[:200].split()))!r}: "
                         f"{len(text)} characters (at most {LIMITS['length']})")
    equation = " ".join(text.split())
    _check_characters(equation)
    _check_parentheses(equation)
    return equation


def parse_equation(text, parameters, *, output=None, name="custom", signals=None,
                   within_system=False) -> Model:
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
    within_system : bool
        The equation is one of a system (:func:`algid.models.parse_system`): the
        parameters are those of the whole system, of which the model keeps the ones that
        appear (none: a fully known equation), and the equation may have no known term
        (another equation of the system fixes the scale of the parameters it shares).

    Returns
    -------
    Model

    Raises
    ------
    ModelError
        One line naming the problem.

    Examples
    --------
    >>> from algid.models import parse_equation
    >>> model = parse_equation("V2'' + B*V2' + K*V2 + K3*V2**3 = G*V1 + d", "B K K3 G d")
    >>> model.output, model.signals, model.parameters
    ('V2', ('V2', 'V1'), ('B', 'K', 'K3', 'G', 'd'))
    >>> [str(term) for term in model.terms]
    ["V2''", "B*V2'", 'K*V2', 'K3*V2**3', '-G*V1', '-d']
    """
    equation = check_text(text)
    check_name(name, "model name")
    parameters = _check_parameters(parameters, equation, LIMITS[
        "system_parameters" if within_system else "parameters"])
    if signals is not None:
        signals = tuple(check_name(signal, "signal name") for signal in signals)
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
    terms = _to_terms(left + [(-c, p, f) for c, p, f in right], equation)
    used = {term.parameter for term in terms}
    if within_system:   # (an equation of the system may be fully known)
        parameters = tuple(p for p in parameters if p in used)
        if len(parameters) > LIMITS["parameters"]:
            _fail(equation, f"{len(parameters)} parameters in this equation (at most "
                            f"{LIMITS['parameters']} in each equation of a system)")
    for parameter in parameters:
        if parameter not in used:
            _fail(equation, f"parameter {parameter} does not appear (or its terms cancel)")
    if not within_system and not any(term.parameter is None for term in terms):
        _fail(equation, "no known term: every term has a parameter, so the scale is not "
                        "fixed (give one term a known coefficient, e.g. y'' + ...)")
    found = tuple(dict.fromkeys(s for term in terms for s in term.factor.signals()))
    if not found:
        _fail(equation, "no measured signal appears")
    channels = len({term.factor for term in terms})
    if channels > LIMITS["channels"]:
        _fail(equation, f"{channels} distinct factors (at most {LIMITS['channels']})")
    return Model(name=name, equation=equation, parameters=parameters, terms=terms,
                 signals=found, output=_output(terms, found, output, equation))
