"""Time-varying state-space realisation of the kernels of a derivation.

Every entry of ``P(t)`` and ``Q(t)`` is a linear combination of kernels
``int^(k) (t**p u)`` (``k``-fold integrals from 0 to ``t`` of a measured signal ``u``
weighted by ``t**p``).  Such a combination is the output of a linear, time-varying
filter started from rest,

.. math::

    z' = A z + B(t) u, \\qquad y = C z + D(t) u, \\qquad z(0) = 0,

with ``A`` a constant nilpotent matrix (chains of integrators), an input matrix
``B(t)`` and a feed-through ``D(t)`` made of powers of ``t``, and ``u`` the measured
signals.  This module builds that realisation symbolically from a
:class:`~algid.symbolic.Derivation`, in two layouts:

``"entries"``
    One integrator chain per entry of ``P`` and ``Q`` (the observer form used in the
    literature: ``y = g_0 u + z_1``, ``z_l' = g_l u + z_(l+1)``, ``z_n' = g_n u``).
``"chains"``
    One chain per weighted signal ``t**p u``, shared by every entry; state ``l`` of a
    chain is the kernel ``int^(l)(t**p u)``.  This is the layout of ``CHAINS`` in the
    generated modules.

It also solves state equations back to the integral form (exactly, at the level of
kernels) and integrates them on closed-form signals, so that a realisation can be
checked against the integral form it is meant to implement.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from math import factorial

import sympy as sp
from sympy.core.function import AppliedUndef

from algid.symbolic._derivation import Derivation, IteratedIntegral, Kernel
from algid.symbolic._model import TIME
from algid.symbolic._printing import show

__all__ = ["Realization", "realize", "entry_names", "entries", "kernel_terms",
           "from_kernel_terms", "same_integral_form", "solve_state_equations",
           "integrate_from_zero"]

t = TIME


# ------------------------------------------------------------------ kernel algebra


def kernel_terms(expr) -> dict:
    """Write a linear combination of weighted, integrated signals in canonical form.

    Parameters
    ----------
    expr : sympy.Expr
        A sum of terms ``c * t**p * u(t)`` and ``c * IteratedIntegral(g, k)`` with
        ``c`` free of ``t``; integrands ``g`` may themselves be such sums (or nested
        integrals), which linearity resolves.

    Returns
    -------
    dict
        ``{(signal, power, order): coefficient}`` with zero coefficients dropped;
        ``order = 0`` is the signal itself.

    Raises
    ------
    ValueError
        If a term is not of that form (a weight multiplying an integral, a product of
        signals, a term without a signal).
    """
    out: dict = {}
    for term in sp.Add.make_args(sp.expand(expr)):
        if term == 0:
            continue
        coeff, rest = term.as_independent(t, as_Add=False)
        integrals = [f for f in sp.Mul.make_args(rest) if isinstance(f, IteratedIntegral)]
        if integrals:
            if len(integrals) != 1 or rest != integrals[0]:
                raise ValueError(f"{term} is not a constant times an integral")
            integrand, order = integrals[0].args
            for (sig, p, k), c in kernel_terms(integrand).items():
                _add(out, (sig, p, k + int(order)), coeff * c)
            continue
        power, signal = 0, None
        for factor in sp.Mul.make_args(rest):
            base, exp = factor.as_base_exp()
            if base == t and exp.is_Integer and exp >= 0:
                power += int(exp)
            elif isinstance(factor, AppliedUndef) and factor.args == (t,) and signal is None:
                signal = factor.func.__name__
            else:
                raise ValueError(f"{term} is not a weight t**p times one signal")
        if signal is None:
            raise ValueError(f"{term} contains no signal")
        _add(out, (signal, power, 0), coeff)
    return {k: v for k, v in out.items() if v != 0}


def _add(d, key, value):
    d[key] = sp.expand(d.get(key, 0) + value)


def from_kernel_terms(terms: dict):
    """Inverse of :func:`kernel_terms`: the canonical SymPy expression.

    Parameters
    ----------
    terms : dict
        ``(signal, power, order) -> coefficient``.

    Returns
    -------
    sympy.Expr
        The sum of the iterated integrals.
    """
    total = sp.Integer(0)
    for (sig, p, k), c in sorted(terms.items(), key=lambda kv: (kv[0][2], kv[0][0], kv[0][1])):
        g = t**p * sp.Function(sig)(t)
        total += c * (g if k == 0 else IteratedIntegral(g, k))
    return total


def same_integral_form(a, b) -> bool:
    """Whether two kernel combinations are the same filter (equal coefficients).

    Parameters
    ----------
    a, b : sympy.Expr
        Kernel combinations.

    Returns
    -------
    bool
        Whether their coefficients agree.
    """
    ta, tb = kernel_terms(a), kernel_terms(b)
    keys = set(ta) | set(tb)
    return all(sp.simplify(ta.get(k, 0) - tb.get(k, 0)) == 0 for k in keys)


def _integrate_once(expr):
    """``int_0^t expr``, for a kernel combination: every order goes up by one."""
    return from_kernel_terms({(sig, p, k + 1): c for (sig, p, k), c in kernel_terms(expr).items()})


# ----------------------------------------------------------- state equations


def _order(equations: dict) -> list:
    """States in an order where each one's equation uses only states before it."""
    done, visiting, order = set(), set(), []

    def visit(z):
        if z in done:
            return
        if z in visiting:
            raise ValueError("the state equations are not chains of integrators "
                             f"(cycle through {z}): A is not nilpotent")
        visiting.add(z)
        for w in sorted(equations[z].free_symbols - {t}, key=str):
            visit(w)
        visiting.discard(z)
        done.add(z)
        order.append(z)

    for z in sorted(equations, key=str):
        visit(z)
    return order


def undefined_states(equations: dict, outputs: dict) -> list:
    """States used by ``equations`` or ``outputs`` that have no equation of their own.

    Every free symbol other than ``t`` counts as a state.
    """
    used = set()
    for e in list(equations.values()) + list(outputs.values()):
        used |= e.free_symbols - {t}
    return sorted(used - set(equations), key=str)


def solve_state_equations(equations: dict, outputs: dict) -> dict:
    """Integral form of the outputs of ``z' = rhs(z, u, t)`` started from ``z = 0``.

    Parameters
    ----------
    equations : dict
        State symbol -> right-hand side of its equation: a constant combination of
        states plus weighted signals ``c t**p u(t)``.
    outputs : dict
        Output name -> expression in the states and the signals.

    Returns
    -------
    dict
        Output name -> canonical kernel combination (see :func:`from_kernel_terms`),
        and ``state symbol -> ...`` for every state as well.

    Raises
    ------
    ValueError
        If a state has no equation or the states feed back on each other (then the
        outputs are not finite combinations of iterated integrals).
    """
    missing = undefined_states(equations, outputs)
    if missing:
        raise ValueError(f"no state equation for {', '.join(map(str, missing))}")
    forms = {}
    for z in _order(equations):
        forms[z] = _integrate_once(equations[z].xreplace(forms))
    result = dict(forms)
    for name, y in outputs.items():
        result[name] = from_kernel_terms(kernel_terms(y.xreplace(forms)))
    return result


# ------------------------------------------------------------ exact integrals


def integrate_from_zero(expr):
    """``int_0^t expr(tau) dtau`` for sums of ``c t**n exp(a t)``, in closed form.

    Terms of another shape are handed to :func:`sympy.integrate`.

    Parameters
    ----------
    expr : sympy.Expr
        A function of ``t``.

    Returns
    -------
    sympy.Expr
        The integral from 0 to ``t``.
    """
    total = sp.Integer(0)
    tau = sp.Dummy("tau", nonnegative=True)
    for term in sp.Add.make_args(sp.expand(expr)):
        coeff, rest = term.as_independent(t, as_Add=False)
        n, a, ok = 0, sp.Integer(0), True
        for factor in sp.Mul.make_args(rest):
            base, exp = factor.as_base_exp()
            if base == t and exp.is_Integer and exp >= 0:
                n += int(exp)
            elif isinstance(factor, sp.exp) and sp.degree(factor.args[0], t) == 1 \
                    and factor.args[0].subs(t, 0) == 0:
                a += sp.diff(factor.args[0], t)
            elif factor != 1:
                ok = False
        if not ok:
            total += sp.integrate(term.subs(t, tau), (tau, 0, t))
        elif a == 0:
            total += coeff * t**(n + 1) / (n + 1)
        else:
            # int t^n e^{at} = e^{at} sum_j (-1)^j n!/(n-j)! t^(n-j) / a^(j+1)
            def antiderivative(v, a=a, n=n):
                return sp.exp(a * v) * sum((-1)**j * sp.Integer(factorial(n) // factorial(n - j))
                                           * v**(n - j) / a**(j + 1) for j in range(n + 1))
            total += coeff * (antiderivative(t) - antiderivative(sp.Integer(0)))
    return sp.expand(total)


# -------------------------------------------------------------- realisation


def entry_names(derivation: Derivation) -> tuple:
    """Names of the entries of ``P`` and ``Q``, one-based as in the literature.

    ``P[i, j]`` is ``p{i+1}{j+1}`` and ``Q[i]`` is ``q{i+1}``; ``P`` row by row first.

    Parameters
    ----------
    derivation : Derivation
        The derivation.

    Returns
    -------
    tuple of str
        The names.
    """
    n, m = derivation.P.shape
    return tuple(f"p{i + 1}{j + 1}" for i in range(n) for j in range(m)) + \
        tuple(f"q{i + 1}" for i in range(n))


def entries(derivation: Derivation) -> dict:
    """The entries of ``P`` and ``Q`` by name.

    Parameters
    ----------
    derivation : Derivation
        The derivation.

    Returns
    -------
    dict
        Entry name (see :func:`entry_names`) -> its kernel combination.
    """
    n, m = derivation.P.shape
    values = [derivation.P[i, j] for i in range(n) for j in range(m)] + list(derivation.Q)
    return dict(zip(entry_names(derivation), values))


@dataclass(frozen=True)
class Realization:
    """A time-varying linear filter ``z' = A z + B(t) u``, ``y = C z + D(t) u``, ``z(0) = 0``.

    Attributes
    ----------
    layout : str
        ``"entries"`` (one chain per output) or ``"chains"`` (one chain per weighted
        signal, shared).
    states : tuple of sympy.Symbol
    inputs : tuple of sympy.Expr
        The measured signals ``u`` as functions of ``t`` (output signal first).
    outputs : tuple of str
        Names of the realised entries (``p11``, ..., ``q1``, ...).
    A : sympy.Matrix
        Constant, nilpotent.
    B : sympy.Matrix
        Input matrix, polynomial in ``t``.
    C : sympy.Matrix
        Constant.
    D : sympy.Matrix
        Feed-through, polynomial in ``t``.
    targets : dict
        Output name -> the kernel combination it must reproduce (from the derivation).
    chains : tuple
        ``(signal, power, depth)`` of every chain (``"chains"`` layout; empty otherwise).
    """

    layout: str
    states: tuple
    inputs: tuple
    outputs: tuple
    A: sp.Matrix
    B: sp.Matrix
    C: sp.Matrix
    D: sp.Matrix
    targets: dict = field(default_factory=dict, compare=False)
    chains: tuple = ()

    def state_equations(self) -> dict:
        """The state equations.

        Returns
        -------
        dict
            State symbol -> right-hand side ``(A z + B(t) u)_i``.
        """
        z, u = sp.Matrix(self.states), sp.Matrix(self.inputs)
        rhs = self.A * z + self.B * u if self.states else sp.zeros(0, 1)
        return {zi: sp.expand(r) for zi, r in zip(self.states, rhs)}

    def output_equations(self) -> dict:
        """The output equations.

        Returns
        -------
        dict
            Output name -> ``(C z + D(t) u)_i``.
        """
        u = sp.Matrix(self.inputs)
        y = self.D * u
        if self.states:
            y += self.C * sp.Matrix(self.states)
        return {name: sp.expand(e) for name, e in zip(self.outputs, y)}

    def integral_form(self) -> dict:
        """What each filter computes, as a kernel combination.

        Returns
        -------
        dict
            Output name (and state) -> the kernel combination.
        """
        return solve_state_equations(self.state_equations(), self.output_equations())

    def check(self) -> bool:
        """Whether every output reproduces its target kernel combination exactly.

        Returns
        -------
        bool
            ``True`` if all outputs match.
        """
        form = self.integral_form()
        return all(same_integral_form(form[name], self.targets[name]) for name in self.outputs)

    def response(self, signals: dict) -> dict:
        """Outputs of the filter, started from rest, for closed-form signals.

        Parameters
        ----------
        signals : dict
            Signal name -> SymPy expression in ``t`` (sums of ``c t**n exp(a t)``
            integrate fastest).

        Returns
        -------
        dict
            Output name -> its value as an expression in ``t``; obtained by
            integrating the state equations one after the other.
        """
        values = {u: signals[u.func.__name__] for u in self.inputs}
        equations = self.state_equations()
        z = {}
        for zi in _order(equations):
            z[zi] = integrate_from_zero(equations[zi].xreplace(z).xreplace(values))
        return {name: sp.expand(y.xreplace(z).xreplace(values))
                for name, y in self.output_equations().items()}

    def where(self) -> dict:
        """Shared values of the ``"entries"`` layout.

        For each chain, its first state that carries the value of an earlier output or of a
        state of an earlier chain.

        Returns
        -------
        dict
            State -> name of the output (preferred) or state with the same value; the
            rest of the chain then repeats that one (the remarks "where ..." of the
            literature).
        """
        if self.layout != "entries":
            return {}
        form = self.integral_form()
        found = {}
        for i, name in enumerate(self.outputs):
            earlier = list(self.outputs[:i])
            others = earlier + [w for n in earlier for w in self._states_of(n)]
            for z in self._states_of(name):
                match = next((o for o in others if form[z] != 0 and same_integral_form(
                    form[z], self.targets[o] if isinstance(o, str) else form[o])), None)
                if match is not None:
                    found[z] = str(match)
                    break
        return found

    def _states_of(self, name):
        if self.layout != "entries":
            return ()
        return tuple(z for z in self.states if str(z).startswith(f"{name}_z"))

    def format(self, names=None) -> str:
        """State equations and outputs, one per line (primes are time derivatives).

        Parameters
        ----------
        names : iterable of str, optional
            Outputs to show (default: all).

        Returns
        -------
        str
            The lines.
        """
        names = self.outputs if names is None else tuple(names)
        eqs, outs = self.state_equations(), self.output_equations()
        where = self.where() if self.layout == "entries" else {}
        lines = []
        if self.layout == "entries":
            for name in names:
                lines.append(f"{name}(t) = {show(outs[name])}")
                for z in self._states_of(name):
                    lines.append(f"{z}' = {show(eqs[z])}")
                for z in self._states_of(name):
                    if z in where:
                        lines.append(f"where {z} = {where[z]}")
        else:
            for z in self.states:
                lines.append(f"{z}' = {show(eqs[z])}")
            for name in names:
                lines.append(f"{name}(t) = {show(outs[name])}")
        return "\n".join(lines)


def realize(derivation: Derivation, *, layout: str = "entries") -> Realization:
    """Build the time-varying state-space realisation of ``P`` and ``Q``.

    Parameters
    ----------
    derivation : Derivation
    layout : {"entries", "chains"}
        ``"entries"``: one integrator chain per entry (observer form, as printed in
        the literature); ``"chains"``: one shared chain per weighted signal
        ``t**p u`` (as ``CHAINS`` in the generated modules, fewer states).

    Returns
    -------
    Realization
    """
    model = derivation.model
    inputs = (model.output_function, model.input_function)
    index = {u.func.__name__: i for i, u in enumerate(inputs)}
    targets = entries(derivation)
    names = tuple(targets)
    terms = {name: kernel_terms(expr) for name, expr in targets.items()}

    if layout == "entries":
        states = []
        rows = {}
        for name in names:
            depth = max((k for (_, _, k) in terms[name]), default=0)
            rows[name] = [sp.Symbol(f"{name}_z{j}") for j in range(1, depth + 1)]
            states += rows[name]
        pos = {z: i for i, z in enumerate(states)}
        A = sp.zeros(len(states), len(states))
        B = sp.zeros(len(states), len(inputs))
        C = sp.zeros(len(names), len(states))
        D = sp.zeros(len(names), len(inputs))
        for r, name in enumerate(names):
            chain = rows[name]
            for (sig, p, k), c in terms[name].items():
                if k == 0:
                    D[r, index[sig]] += c * t**p
                else:
                    B[pos[chain[k - 1]], index[sig]] += c * t**p
            for j in range(len(chain) - 1):
                A[pos[chain[j]], pos[chain[j + 1]]] = 1
            if chain:
                C[r, pos[chain[0]]] = 1
        return Realization("entries", tuple(states), inputs, names, A, B, C, D, targets)

    if layout == "chains":
        depth = {}
        for kernel in derivation.kernels:
            key = (kernel.signal, kernel.power)
            depth[key] = max(depth.get(key, 0), kernel.order)
        chains = tuple((sig, p, d) for (sig, p), d in sorted(depth.items()) if d > 0)
        states = [sp.Symbol(Kernel(sig, p, level).name) for sig, p, d in chains
                  for level in range(1, d + 1)]
        pos = {z: i for i, z in enumerate(states)}
        A = sp.zeros(len(states), len(states))
        B = sp.zeros(len(states), len(inputs))
        for sig, p, d in chains:
            B[pos[sp.Symbol(Kernel(sig, p, 1).name)], index[sig]] = t**p
            for level in range(2, d + 1):
                here, before = (sp.Symbol(Kernel(sig, p, j).name) for j in (level, level - 1))
                A[pos[here], pos[before]] = 1
        C = sp.zeros(len(names), len(states))
        D = sp.zeros(len(names), len(inputs))
        for r, name in enumerate(names):
            for (sig, p, k), c in terms[name].items():
                if k == 0:
                    D[r, index[sig]] += c * t**p
                else:
                    C[r, pos[sp.Symbol(Kernel(sig, p, k).name)]] += c
        return Realization("chains", tuple(states), inputs, names, A, B, C, D, targets, chains)

    raise ValueError(f"layout must be 'entries' or 'chains', got {layout!r}")
