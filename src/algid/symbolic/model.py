"""Linear constant-coefficient ODE models, the input of the derivation engine.

A model is one scalar equation

    a_n y^(n) + ... + a_1 y' + a_0 y = b_m u^(m) + ... + b_0 u

between a measured input ``u`` and a measured output ``y``, whose coefficients are
affine in a set of unknown parameters ``theta``.  The engine in
:mod:`algid.symbolic.derivation` turns such a model into an algebraic estimator
``P(t) theta = Q(t)``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import sympy as sp

from algid.errors import ModelError

__all__ = ["LinearODEModel", "TIME", "LAPLACE"]

#: The time variable of every model.
TIME = sp.Symbol("t", nonnegative=True)
#: The Laplace variable.
LAPLACE = sp.Symbol("s")

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_FUNCTIONS = {"sqrt", "exp", "log", "sin", "cos", "pi"}
_PRIMES = re.compile(r"\b([A-Za-z][A-Za-z0-9_]*)('+)")


def _as_expr(value, where):
    try:
        return sp.sympify(value)
    except (sp.SympifyError, TypeError, SyntaxError) as exc:
        raise ModelError(f"cannot read {where} {value!r}: {exc}") from None


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
        if not _NAME.match(self.name or ""):
            raise ModelError(f"model name {self.name!r} is not an identifier")
        for sig in (self.output, self.input):
            if not _NAME.match(sig or "") or sig in ("t", "s"):
                raise ModelError(f"signal name {sig!r} is not a usable identifier")
        if self.output == self.input:
            raise ModelError(f"input and output are both named {self.output!r}")
        params = tuple(sp.Symbol(str(p)) for p in self.parameters)
        if not params:
            raise ModelError(f"model {self.name!r} has no unknown parameters")
        if len(set(params)) != len(params):
            raise ModelError(f"model {self.name!r} lists a parameter twice")
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
        ``lhs - rhs = 0``); this is the form :func:`~algid.symbolic.derivation.derive`
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
        """This model as an :class:`algid.model.Model`.

        Returns
        -------
        Model
            The representation of user equations used by :func:`algid.identify`.
        """
        from algid.grammar import parse_equation

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
        if isinstance(parameters, str):
            parameters = [p for p in re.split(r"[\s,]+", parameters) if p]
        if equation.count("=") != 1:
            raise ModelError(f"equation {equation!r} must have exactly one '='")
        for sig in (output, input):
            if not _NAME.match(sig or ""):
                raise ModelError(f"signal name {sig!r} is not a usable identifier")
        left, right = equation.split("=")

        def derivative_symbol(match):
            sig, primes = match.group(1), match.group(2)
            if sig not in (output, input):
                raise ModelError(f"equation {equation!r}: {sig!r} is differentiated but is not "
                                 f"the output {output!r} or the input {input!r}")
            return f"{sig}__d{len(primes)}"

        lhs_text, rhs_text = (_PRIMES.sub(derivative_symbol, side) for side in (left, right))
        expr_text = f"({lhs_text}) - ({rhs_text})"
        names = {p: sp.Symbol(p) for p in parameters}
        local = dict(names)
        for sig in (output, input):
            local[sig] = sp.Symbol(f"{sig}__d0")
            for k in range(1, 10):
                local[f"{sig}__d{k}"] = sp.Symbol(f"{sig}__d{k}")
        # every other identifier is a plain symbol (not SymPy's Q, S, E, N, ...), so
        # that an unknown name is reported as such
        for ident in set(re.findall(r"\b[A-Za-z_][A-Za-z0-9_]*\b", expr_text)):
            if ident not in local and ident not in _FUNCTIONS:
                local[ident] = sp.Symbol(ident)
        try:
            expr = sp.expand(sp.sympify(expr_text, locals=local))
        except (sp.SympifyError, TypeError, SyntaxError) as exc:
            raise ModelError(f"cannot read equation {equation!r}: {exc}") from None
        sig_syms = {sig: [local[f"{sig}__d{k}"] if k else local[sig] for k in range(10)]
                    for sig in (output, input)}
        all_sig = set(sig_syms[output] + sig_syms[input])
        for u in all_sig:
            for v in all_sig:
                if sp.diff(expr, u, v) != 0:
                    raise ModelError(f"equation {equation!r} is not linear in {output!r} and "
                                     f"{input!r}")
        stray = expr.free_symbols - all_sig - set(names.values())
        if stray:
            raise ModelError(f"equation {equation!r} uses unknown names {sorted(map(str, stray))}")

        def coefficients(sig, sign):
            coeffs = [sign * expr.coeff(sym) for sym in sig_syms[sig]]
            while coeffs and coeffs[-1] == 0:
                coeffs.pop()
            return tuple(reversed(coeffs))

        a, b = coefficients(output, 1), coefficients(input, -1)
        rest = expr - sum(expr.coeff(sym) * sym for sym in all_sig)
        if sp.expand(rest) != 0:
            raise ModelError(f"equation {equation!r} has a term {sp.expand(rest)} that is not "
                             f"proportional to {output!r}, {input!r} or a derivative")
        for coeff in a + b:
            if coeff.free_symbols & all_sig:
                raise ModelError(f"equation {equation!r} is not linear in {output!r} and {input!r}")
        if not a:
            raise ModelError(f"equation {equation!r} does not involve the output {output!r}")
        if not b:
            raise ModelError(f"equation {equation!r} does not involve the input {input!r}")
        return cls(name=name, output_coefficients=a, input_coefficients=b,
                   parameters=tuple(names.values()), output=output, input=input,
                   description=description)
