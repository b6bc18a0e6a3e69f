"""The algebraic derivation: from a linear ODE to ``P(t) theta = Q(t)``.

The steps are those of Fliess and Sira-Ramirez, each kept as a field of
:class:`Derivation` so that reports and tests can look at every one of them:

1. Laplace transform with symbolic initial conditions.
2. ``d^n/ds^n`` (``n`` the order of the model): the initial conditions enter as a
   polynomial of degree ``n - 1`` in ``s`` and are annihilated.
3. Multiplication by ``s^-N`` (``N`` the highest remaining power of ``s``), so that only
   integrations remain.
4. Back to the time domain through the operator table ``d/ds -> x(-t)`` and
   ``1/s -> integral from 0``; never through an inverse Laplace transform.
5. Further integration of the equation until there are as many equations as unknowns.
6. The linear system ``P theta = Q`` and its Cramer solution: for at most
   ``EXPANDED_CRAMER_MAX`` unknowns the numerators and the denominator are expanded
   polynomials of the entries of ``P`` and ``Q``; beyond, whose expansion grows as the
   factorial of the unknowns, a straight-line program computes them from the minors of
   ``[P | Q]`` on the first rows, each minor once (:meth:`Derivation.cramer_program`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import sympy as sp

from algid.errors import ModelError
from algid.models._model import Model, channel_names
from algid.models._system import SystemModel
from algid.symbolic._channels import ChannelModel
from algid.symbolic._linear_system import (
    EXPANDED_CRAMER_MAX,
    cramer_program,
    entry_symbols,
    expanded_cramer,
    kernel_chains,
    kernel_symbols,
)
from algid.symbolic._model import LAPLACE, TIME, LinearODEModel
from algid.symbolic._system_derivation import stack_system

__all__ = ["IteratedIntegral", "Kernel", "Derivation", "derive", "evaluate_kernel",
           "EXPANDED_CRAMER_MAX"]

s, t = LAPLACE, TIME

class IteratedIntegral(sp.Function):
    """``IteratedIntegral(g, k)``: the ``k``-fold integral of ``g`` from 0 to ``t``.

    ``k = 0`` is ``g`` itself.  Kept unevaluated: it names a filter of the measured
    signals, not something SymPy should integrate.

    Parameters
    ----------
    *args : sympy.Expr, int
        The integrand ``g`` and the number of integrations ``k``.

    Examples
    --------
    >>> from algid.symbolic import TIME, IteratedIntegral
    >>> integral = IteratedIntegral(TIME**2, 2)
    >>> integral, integral.args, IteratedIntegral(TIME, 0)
    (int^2(t**2), (t**2, 2), t)
    """

    nargs = 2

    def _latex(self, printer):
        integrand, order = self.args
        body = printer._print(integrand)
        if order == 0:
            return body
        if order == 1:
            return rf"\int {_paren(integrand, body)}"
        return rf"\int^{{({printer._print(order)})}} {_paren(integrand, body)}"

    def _sympystr(self, printer):
        integrand, order = self.args
        if order == 0:
            return printer._print(integrand)
        power = "" if order == 1 else f"^{order}"
        return f"int{power}({printer._print(integrand)})"


def _paren(expr, text):
    return f"\\left({text}\\right)" if expr.is_Add or expr.is_Mul else text


@dataclass(frozen=True, order=True)
class Kernel:
    """One filtered signal: ``k``-fold integral of ``t**power * signal``.

    Parameters
    ----------
    signal : str
        Name of the signal.
    power : int
        Power of ``t`` multiplying it.
    order : int
        Number of integrations from 0.

    Examples
    --------
    >>> from algid.symbolic import Kernel
    >>> kernel = Kernel("x", power=1, order=2)
    >>> kernel.name, kernel.expression()
    ('x_t1_i2', int^2(t*x(t)))
    """

    signal: str
    power: int
    order: int

    @property
    def name(self) -> str:
        """Identifier used in generated code, e.g. ``x_t2_i1``."""
        return f"{self.signal}_t{self.power}_i{self.order}"

    def expression(self):
        """The kernel as a SymPy :class:`IteratedIntegral` of ``t**power * signal(t)``.

        Returns
        -------
        IteratedIntegral
            The kernel expression.
        """
        return IteratedIntegral(t**self.power * sp.Function(self.signal)(t), self.order)


@dataclass(frozen=True)
class Derivation:
    """Every step of the algebraic derivation for one model.

    Attributes
    ----------
    model : LinearODEModel
    initial_conditions : tuple of sympy.Symbol
        Symbols for the initial values of the signals and their derivatives.
    laplace : sympy.Expr
        The model in the Laplace domain, ``lhs - rhs`` (equal to zero), with the
        initial conditions.
    n_derivatives : int
        How often the equation is differentiated with respect to ``s``.
    differentiated : list of sympy.Expr
        The equation after each differentiation (``differentiated[-1]`` is free of the
        initial conditions).
    s_power : int
        ``N``: the equation is multiplied by ``s**-N``.
    multiplied : sympy.Expr
        The equation after that multiplication (only non-positive powers of ``s``).
    time_equations : list of sympy.Expr
        The equations in the time domain (each equal to zero), the first one and its
        successive integrals.
    P, Q : sympy.Matrix
        The linear system ``P theta = Q``; entries are linear combinations of kernels.
    kernels : tuple of Kernel
        Every filtered signal that appears in ``P`` and ``Q``, sorted.

    Examples
    --------
    >>> from algid.symbolic import builtin_model, derive
    >>> derivation = derive(builtin_model("msd"))
    >>> derivation.initial_conditions, derivation.n_derivatives, derivation.s_power
    ((x0, x_d0), 2, 2)
    >>> derivation.differentiated[-1].has(*derivation.initial_conditions)
    False
    >>> derivation.P[0, 1]
    int^2(t**2*x(t))
    """

    model: LinearODEModel
    initial_conditions: tuple
    laplace: sp.Expr
    n_derivatives: int
    differentiated: list
    s_power: int
    multiplied: sp.Expr
    time_equations: list
    P: sp.Matrix
    Q: sp.Matrix
    kernels: tuple

    @property
    def parameters(self):
        """The unknown parameters, in the model's order."""
        return self.model.parameters

    @property
    def transforms(self):
        """The Laplace-domain functions of the output and the input, ``X(s)``, ``F(s)``."""
        return _transform(self.model.output), _transform(self.model.input)

    def chains(self) -> tuple:
        """The integrator chains that realise the kernels, sorted.

        Returns
        -------
        tuple of (str, int, int)
            ``(channel, power, depth)``: level ``l`` of a chain is the ``l``-fold
            integral of ``t**power`` times the channel; ``depth`` is the deepest level
            a kernel needs.
        """
        return kernel_chains(self.kernels)

    def kernel_symbols(self):
        """Map each kernel expression to a plain symbol named after the kernel.

        Returns
        -------
        dict
            :class:`IteratedIntegral` -> :class:`sympy.Symbol` (``x_t2_i1``, ...).
        """
        return kernel_symbols(self.kernels)

    def entry_symbols(self):
        """Symbols ``p_i_j`` and ``q_i`` standing for the entries of ``P`` and ``Q``.

        Returns
        -------
        P, Q : sympy.Matrix
            Matrices of symbols of the shapes of ``P`` and ``Q``.
        """
        return entry_symbols(self.P.shape)

    def cramer(self):
        """Cramer's rule on symbolic entries.

        ``theta_i = numerators[i] / denominator``, expressed in ``p_i_j`` and ``q_i``.
        Only for square systems.

        Returns
        -------
        numerators : tuple of sympy.Expr
            One per parameter.
        denominator : sympy.Expr
            ``det P``.

        Raises
        ------
        ModelError
            More than ``EXPANDED_CRAMER_MAX`` unknowns (see :meth:`cramer_program`).
        """
        Ps, Qs = self.entry_symbols()
        if Ps.shape[0] != Ps.shape[1]:
            raise ValueError("Cramer's rule needs as many equations as unknowns")
        if Ps.shape[1] > EXPANDED_CRAMER_MAX:
            raise ModelError(f"the expanded Cramer solution of {Ps.shape[1]} unknowns has "
                             f"{math.factorial(Ps.shape[1])} products per determinant; use "
                             f"cramer_program()")
        return expanded_cramer(Ps, Qs)

    def cramer_program(self):
        """Cramer's rule as a straight-line program on the entries ``p_i_j``, ``q_i``.

        Up to ``EXPANDED_CRAMER_MAX`` unknowns there are no steps and the result is
        :meth:`cramer`.  Beyond, the minors of ``[P | Q]`` on its first ``k`` rows are
        computed level by level, each by expansion along its last row from the minors
        of the level before (``m<k>_<columns as bits>``); the denominator and the
        numerators are the minors of all ``n`` rows.  Every minor is computed once: about
        ``(n + 1) 2**n`` products, where the expanded determinants have ``n! n``.  Only
        ``+``, ``-`` and ``*``, as the expanded form.

        Returns
        -------
        steps : tuple of (sympy.Symbol, sympy.Expr)
            Assignments, in order.
        numerators : tuple of sympy.Expr
            One per parameter, in the entries and the symbols of ``steps``.
        denominator : sympy.Expr
            ``det P``.
        """
        return cramer_program(*self.entry_symbols())

    def solution(self):
        """The closed-form estimate of each parameter in terms of the kernels.

        Returns
        -------
        dict
            Parameter symbol -> quotient of kernel combinations.
        """
        nums, den = self.cramer()
        Ps, Qs = self.entry_symbols()
        subs = {Ps[i, j]: self.P[i, j] for i in range(Ps.shape[0]) for j in range(Ps.shape[1])}
        subs.update({Qs[i]: self.Q[i] for i in range(Qs.shape[0])})
        return tuple(sp.Eq(p, num.subs(subs) / den.subs(subs))
                     for p, num in zip(self.parameters, nums))


def _transform(signal: str):
    return sp.Function(signal.upper() if signal.upper() != signal else signal + "_L")(s)


def _laplace_of_derivative(signal: str, order: int, ics: dict):
    """``L[y^(order)] = s^order Y - sum_k s^(order-1-k) y^(k)(0)`` with symbolic ``y^(k)(0)``."""
    Y = _transform(signal)
    expr = s**order * Y
    for k in range(order):
        expr -= s ** (order - 1 - k) * ics[(signal, k)]
    return expr


def _initial_condition_symbols(model):
    """Symbols for ``z^(k)(0)``, ``k`` below the highest derivative of each channel ``z``."""
    highest = {}
    for _, channel, derivative in model.channel_terms():
        highest[channel] = max(highest.get(channel, 0), derivative)
    ics = {}
    for channel in model.channels:
        for k in range(highest.get(channel, 0)):
            ics[(channel, k)] = sp.Symbol(f"{channel}{'_' + 'd' * k if k else ''}0")
    return ics


def derive(model, *, extra_equations: int = 0) -> Derivation:
    """Derive the algebraic estimator of ``model``.

    Parameters
    ----------
    model : LinearODEModel, ChannelModel, algid.models.Model or algid.models.SystemModel
        Any model that lists its terms as ``(coefficient, channel, derivative)`` with
        :meth:`~LinearODEModel.channel_terms` and its channels as ``channels`` (a parsed
        equation, :func:`algid.models.parse_equation`, is taken as such); or a
        system of equations (:func:`algid.models.parse_system`), each equation derived
        on its own and their linear systems stacked in the system's unknowns.
    extra_equations : int, optional
        Equations beyond the number of unknowns (each one more integration), for a
        least-squares solution.  ``0`` gives a square system (per equation, for a
        system).

    Returns
    -------
    Derivation or SystemDerivation
        A :class:`~algid.symbolic.SystemDerivation` for a system.

    Examples
    --------
    >>> from algid.symbolic import builtin_model, derive
    >>> model = builtin_model("msd")
    >>> derive(model).P.shape, derive(model, extra_equations=1).P.shape
    ((2, 2), (3, 2))
    >>> sorted({kernel.signal for kernel in derive(model).kernels})
    ['f', 'x']
    """
    if extra_equations < 0:
        raise ValueError("extra_equations must be >= 0")
    if isinstance(model, SystemModel):
        names = channel_names(model)  # one identifier per factor in the whole system
        return stack_system(model, [derive(ChannelModel(m, names=names),
                                           extra_equations=extra_equations)
                                    if m.parameters else None for m in model.equations])
    if isinstance(model, Model):
        model = ChannelModel(model)
    if not hasattr(model, "channel_terms"):
        raise ModelError(f"derive takes a model (LinearODEModel, algid.models.parse_equation) "
                         f"or a system (algid.models.parse_system), got "
                         f"{type(model).__name__}")
    if any(str(p) == str(s) for p in model.parameters):
        raise ModelError(f"parameter name {s} is the Laplace variable of the derivation: "
                         f"rename it")
    ics = _initial_condition_symbols(model)
    laplace = sp.Add(*(coeff * _laplace_of_derivative(channel, derivative, ics)
                       for coeff, channel, derivative in model.channel_terms()))

    # The initial conditions form a polynomial of degree order-1 in s: d^order/ds^order
    # removes it whatever the values.
    n = model.order
    differentiated = [laplace]
    for _ in range(n):
        differentiated.append(sp.expand(sp.diff(differentiated[-1], s)))
    final = differentiated[-1]
    leftover = final.free_symbols & set(ics.values())
    if leftover:  # pragma: no cover - impossible for a linear model, kept as a guard
        raise AssertionError(f"initial conditions {leftover} survived differentiation")

    terms = _split_terms(final, model)
    N = max(power for (_, _, power) in terms)
    multiplied = sp.expand(final * s**(-N))

    first = sum(coeff * Kernel(sig, b, N - power).expression() * (-1) ** b
                for (sig, b, power), coeff in terms.items())
    n_eq = len(model.parameters) + extra_equations
    time_equations = [_integrate_equation(first, r) for r in range(n_eq)]
    P, Q = sp.linear_eq_to_matrix([sp.expand(e) for e in time_equations], list(model.parameters))
    P, Q = P.applyfunc(sp.expand), Q.applyfunc(sp.expand)
    integrals = P.atoms(IteratedIntegral) | Q.atoms(IteratedIntegral)
    kernels = sorted({_kernel_of(a) for a in integrals})
    return Derivation(model=model, initial_conditions=tuple(ics.values()), laplace=laplace,
                      n_derivatives=n, differentiated=differentiated, s_power=N,
                      multiplied=multiplied, time_equations=time_equations, P=P, Q=Q,
                      kernels=tuple(kernels))


def _split_terms(expr, model):
    """Write ``expr`` as ``sum coeff * s**power * d^b/ds^b SIGNAL(s)``.

    Returns ``{(signal, b, power): coeff}`` with coefficients free of ``s``.
    """
    out = {}
    for sig in model.channels:
        Y = _transform(sig)
        derivs = {b: (Y if b == 0 else sp.Derivative(Y, (s, b))) for b in range(model.order + 1)}
        dummies = {b: sp.Dummy(f"{sig}{b}") for b in derivs}
        e = sp.expand(expr.subs({derivs[b]: dummies[b] for b in sorted(derivs, reverse=True)}))
        for b, d in dummies.items():
            c = sp.expand(e.coeff(d))
            if c == 0:
                continue
            for term in sp.Add.make_args(c):
                coeff, power = term.as_coeff_exponent(s)
                if coeff.has(s) or not power.is_integer:
                    raise AssertionError(f"unexpected term {term}")  # pragma: no cover
                key = (sig, b, int(power))
                out[key] = out.get(key, 0) + coeff
    return {k: v for k, v in out.items() if v != 0}


def _kernel_of(ii):
    integrand, order = ii.args
    fn = next(iter(integrand.atoms(sp.core.function.AppliedUndef)))
    power = sp.degree(sp.powsimp(integrand / fn), t)
    return Kernel(fn.func.__name__, int(power), int(order))


def _integrate_equation(expr, times):
    """Integrate a time-domain equation ``times`` more times (raise every kernel order)."""
    if times == 0:
        return expr
    return expr.replace(IteratedIntegral, lambda g, k: IteratedIntegral(g, k + times))


def evaluate_kernel(kernel: Kernel, signals: dict):
    """Evaluate a kernel exactly for closed-form signals.

    Parameters
    ----------
    kernel : Kernel
    signals : dict
        Signal name -> SymPy expression in ``t``.

    Returns
    -------
    sympy.Expr
        The ``kernel.order``-fold integral from 0 to ``t`` of ``t**power * signal``.

    Examples
    --------
    >>> from algid.symbolic import TIME, Kernel, evaluate_kernel
    >>> evaluate_kernel(Kernel("f", power=1, order=2), {"f": TIME})   # twice int of t * t
    t**4/12
    """
    tau = sp.Dummy("tau", nonnegative=True)
    g = t**kernel.power * signals[kernel.signal]
    for _ in range(kernel.order):
        g = sp.integrate(g.subs(t, tau), (tau, 0, t))
    return g
