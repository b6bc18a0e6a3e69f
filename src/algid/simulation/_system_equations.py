"""A system of equations, linear or not in its signals, solved for the highest
derivatives of its outputs, as a right-hand side.

Every output ``y_j`` of order ``n_j`` (its highest derivative in a plain term of any
equation) gives the states ``y_j, ..., y_j^(n_j - 1)``.  The top derivatives enter
linearly, in plain terms: ``M y_top = -r(x, u, t)``, ``M`` their coefficients (one row
per equation, invertible) and ``r`` every other term, nonlinear factors included
(``x1**3``, ``tanh(x2')``, ``x1*x2``, ``sign(u)``), evaluated by closures over the
expression tree (:func:`algid.simulation._output_equation.scalar_function`).  A
``sign()`` of an output (friction, which sticks) is refused: one equation has the
switching integrator for it (:mod:`algid.simulation._switching`).  A linear system is
simulated exactly by :mod:`algid.simulation._system`; a nonlinear one by
:func:`simulate_nonlinear_system` (DOP853 on interpolated inputs, as
:func:`algid.simulation.simulate_model`), and both export to python-control through
:meth:`SystemEquations.derivative`.
"""

from __future__ import annotations

import math

import numpy as np

from algid.errors import InputDataError, ModelError
from algid.models._expression import Call, Power, Product, Signal, Sum
from algid.simulation._output_equation import scalar_function

__all__ = ["SystemStructure", "solve_tops", "SystemEquations", "simulate_nonlinear_system",
           "fit_nonlinear_initial_state"]


class SystemStructure:
    """A system's states and its terms sorted for solving the top derivatives: what
    :class:`SystemEquations` and the fast simulator of systems
    (:class:`algid.simulation._fast_simulation.FastSystemSimulation`) share.

    Parameters
    ----------
    system : algid.models.SystemModel

    Attributes
    ----------
    outputs, inputs : tuple of str
    orders : dict
        Output -> the order of its highest derivative.
    states : list of (str, int)
        Per state, the output and its derivative order (output by output).
    tops : list of int
        Per output, the state whose derivative is its top derivative.
    chains : list of (int, int)
        ``(i, j)``: state ``i``'s derivative is state ``j``.
    top_terms : list of (int, int, float, str or None)
        ``(equation, output, coefficient, parameter)`` of every term in a top
        derivative.
    other_terms : list of (int, float, str or None, Expr)
        ``(equation, coefficient, parameter, factor)`` of every other term, a term's
        derivative of an output taken into its factor.

    Raises
    ------
    ModelError
        An output never differentiated in a plain term, a ``sign()`` of an output, a top
        derivative inside a nonlinear factor, or a derivative of an input.
    """

    def __init__(self, system):
        self.outputs = tuple(system.outputs)
        self.inputs = tuple(system.inputs)
        orders = {y: 0 for y in self.outputs}
        for model in system.equations:
            for term in model.terms:
                if isinstance(term.factor, Signal) and term.factor.name in orders:
                    name = term.factor.name
                    orders[name] = max(orders[name], term.derivative + term.factor.derivative)
        for y, n in orders.items():
            if n == 0:
                raise ModelError(f"the output {y} is not differentiated in a plain term: "
                                 f"an algebraic equation has no state to simulate")
        self.orders = orders
        self.states = [(y, k) for y in self.outputs for k in range(orders[y])]
        self._where = where = {s: i for i, s in enumerate(self.states)}
        self.tops = [where[(y, orders[y] - 1)] for y in self.outputs]
        self.chains = [(i, where[(y, k + 1)]) for (y, k), i in where.items()
                       if k + 1 < orders[y]]

        switched = set()   # signals read inside a sign()
        for model in system.equations:
            for term in model.terms:
                _signed(term.factor, switched)
        for y in self.outputs:
            if y in switched:
                raise ModelError(f"cannot simulate: sign() of the output {y} in a system "
                                 f"(friction: its sticking needs the switching integrator "
                                 f"that simulates one equation)")
        self.top_terms, self.other_terms = [], []
        for i, model in enumerate(system.equations):
            for term in model.terms:
                factor = term.factor
                if term.derivative:
                    if not isinstance(factor, Signal):
                        raise ModelError(f"cannot simulate a derivative of {factor}")
                    factor = Signal(factor.name, factor.derivative + term.derivative)
                if isinstance(factor, Signal) and factor.name in orders \
                        and factor.derivative == orders[factor.name]:
                    self.top_terms.append((i, self.outputs.index(factor.name),
                                           term.coefficient, term.parameter))
                else:
                    for signal in _signals_of(factor):
                        self.slot(signal)   # (refuses what cannot be simulated)
                    self.other_terms.append((i, term.coefficient, term.parameter, factor))

    def slot(self, signal):
        """Where a signal of a factor is read: ``("x", state)`` or ``("u", input)``.

        Parameters
        ----------
        signal : algid.models._expression.Signal

        Returns
        -------
        tuple of (str, int)

        Raises
        ------
        ModelError
            A top derivative of an output, or a derivative of an input.
        """
        if signal.name in self.orders:
            if signal.derivative >= self.orders[signal.name]:
                raise ModelError(f"cannot simulate: {signal} appears inside a nonlinear "
                                 f"factor (the top derivatives enter in plain terms only)")
            return ("x", self._where[(signal.name, signal.derivative)])
        if signal.derivative:
            raise ModelError(f"cannot simulate: {signal} is a derivative of an input (a "
                             f"system is simulated from its inputs only)")
        return ("u", self.inputs.index(signal.name))


def solve_tops(top, outputs):
    """``-inv(top)``: the top derivatives from the other terms' sums, one per equation.

    Parameters
    ----------
    top : numpy.ndarray, shape (m, m)
        The top derivatives' coefficients, one row per equation.
    outputs : sequence of str

    Returns
    -------
    numpy.ndarray

    Raises
    ------
    ModelError
        A singular (or not finite) ``top``.
    """
    if not np.all(np.isfinite(top)) or np.linalg.cond(top) > 1e12:
        raise ModelError("the equations do not determine the highest derivatives of "
                         f"{', '.join(outputs)} at these parameters (their "
                         f"coefficients form a singular matrix)")
    return -np.linalg.inv(top)


def _value(parameter, values):
    return 1.0 if parameter is None else float(values[parameter])


def _signals_of(factor):
    """Every signal (and derivative of one) that ``factor`` reads."""
    return [Signal(name) for name in factor.signals()] \
        + [Signal(name, k) for name, k in factor.derivatives()]


class SystemEquations:
    """A system of equations solved for the highest derivatives of its outputs.

    Parameters
    ----------
    system : algid.models.SystemModel
    values : mapping
        Parameter name -> value.

    Attributes
    ----------
    states : list of (str, int)
        Per state, the output and its derivative order (output by output).
    inputs : tuple of str
        The measured inputs, in the order :meth:`derivative` reads them.
    outputs : tuple of str

    Raises
    ------
    ModelError
        An output never differentiated in a plain term, a top derivative inside a
        nonlinear factor, a derivative of an input, or top derivatives that the
        equations do not determine.

    Examples
    --------
    >>> from algid.models import parse_system
    >>> system = parse_system(["x1' + a*x1**3 = u", "x2' + x2 = x1"], ["a"])
    >>> equations = SystemEquations(system, {"a": 2.0})
    >>> equations.states, equations.inputs
    ([('x1', 0), ('x2', 0)], ('u',))
    >>> equations.derivative(0.0, [1.0, 0.5], [3.0])
    [1.0, 0.5]
    """

    def __init__(self, system, values):
        structure = SystemStructure(system)
        self.outputs, self.inputs = structure.outputs, structure.inputs
        self.states = structure.states
        self._tops, self._chains = structure.tops, structure.chains
        m = len(self.outputs)
        top = np.zeros((m, m))
        self._terms = [[] for _ in range(m)]   # per equation: (weight, closure)
        for i, j, coefficient, parameter in structure.top_terms:
            top[i, j] += coefficient * _value(parameter, values)
        for i, coefficient, parameter, factor in structure.other_terms:
            self._terms[i].append((coefficient * _value(parameter, values),
                                   scalar_function(factor, structure.slot)))
        self._solve = solve_tops(top, self.outputs)

    def derivative(self, t, x, u):
        """The state's derivative (for python-control and SciPy's integrators).

        Parameters
        ----------
        t : float
            Time.
        x : sequence of float
            The state, as :attr:`states`.
        u : sequence of float
            The inputs, as :attr:`inputs`.

        Returns
        -------
        list of float
        """
        x, u, t = [float(v) for v in x], [float(v) for v in u], float(t)
        try:
            rest = np.array([sum(w * f(x, u, t) for w, f in terms)
                             for terms in self._terms], dtype=float)
        except (ArithmeticError, ValueError):   # outside a function's domain
            return [math.nan] * len(self.states)
        derivative = [0.0] * len(self.states)
        for i, j in self._chains:
            derivative[i] = float(x[j])
        for i, value in zip(self._tops, self._solve @ rest):
            derivative[i] = float(value)
        return derivative


def simulate_nonlinear_system(equations, t, inputs, initial_state=None, rtol=1e-8,
                              atol=1e-12):
    """Simulate a system of equations by DOP853, its inputs interpolated.

    Parameters
    ----------
    equations : SystemEquations
    t : numpy.ndarray
        Sample times (increasing).
    inputs : mapping
        Input name -> samples at ``t``.
    initial_state : numpy.ndarray, optional
        As :attr:`SystemEquations.states` (zero by default).
    rtol, atol : float
        Tolerances of the integrator.

    Returns
    -------
    numpy.ndarray, shape (outputs, samples)
        NaN from where the integration failed (a diverging system, or one that leaves
        a function's domain, such as the square root of a negative number).

    Raises
    ------
    ModelError
        An integration stopped by its bound on evaluations (a stiff system, or one that
        switches too often).
    """
    from algid.simulation._model import as_floats

    n = len(equations.states)
    x0 = np.zeros(n) if initial_state is None else \
        as_floats(initial_state, "initial_state").ravel()
    if x0.shape != (n,) or not np.all(np.isfinite(x0)):
        raise InputDataError(f"initial_state must hold {n} finite values "
                             f"({', '.join(y + chr(39) * k for y, k in equations.states)})")
    return _outputs(equations, _splines(equations, t, inputs), t, x0, rtol, atol)


def _splines(equations, t, inputs):
    """The inputs' interpolants on the whole record (band-limited on a uniform grid)."""
    from algid.simulation._interpolation import Interpolant
    from algid.simulation._model import is_uniform

    kind = "bandlimited" if is_uniform(t) else "cubic"
    return [Interpolant(t, np.asarray(inputs[u], dtype=float), kind)
            for u in equations.inputs]


def _outputs(equations, splines, t, x0, rtol=1e-8, atol=1e-12):
    """The simulated outputs at ``t`` (DOP853 on the interpolants ``splines``)."""
    from algid.simulation._model import integrate

    states = integrate(_Sampled(equations, splines), t, x0, "DOP853", rtol, atol,
                       remedy="check that the system is stable with these parameters, or "
                              "express time in other units")
    return states[[equations.states.index((y, 0)) for y in equations.outputs]]


def fit_nonlinear_initial_state(equations, t, inputs, measured, fit_samples):
    """The initial state whose simulation best fits the measured outputs on the first
    samples: least squares over the measured outputs, each weighted by the inverse of
    its spread, started from a polynomial fit of each output's first samples.

    Parameters
    ----------
    equations : SystemEquations
    t : numpy.ndarray
    inputs : mapping
    measured : mapping
        Output name -> measured samples (of some or all outputs; an unmeasured output
        starts from rest).
    fit_samples : int

    Returns
    -------
    numpy.ndarray
        As :attr:`SystemEquations.states`.
    """
    import math

    from scipy.optimize import least_squares

    head = t[:fit_samples]
    guess = np.zeros(len(equations.states))
    for i, (y, k) in enumerate(equations.states):
        if y in measured:
            degree = min(max(kk for yy, kk in equations.states if yy == y) + 2,
                         fit_samples - 1)
            start = np.polynomial.polynomial.polyfit(head - head[0],
                                                     measured[y][:fit_samples], degree)
            guess[i] = start[k] * math.factorial(k) if k <= degree else 0.0
    scales = {y: float(np.std(v)) or 1.0 for y, v in measured.items()}
    rows = {y: equations.outputs.index(y) for y in measured}
    splines = _splines(equations, t, inputs)   # on the whole record, as it is simulated

    def residual(state):
        simulated = _outputs(equations, splines, head, state)
        r = np.concatenate([(simulated[rows[y]] - measured[y][:fit_samples]) / scales[y]
                            for y in measured])
        return np.where(np.isfinite(r), r, 1e6)

    return least_squares(residual, guess, x_scale="jac").x


class _Sampled:
    """:class:`SystemEquations` driven by interpolated inputs, as
    :func:`algid.simulation._model.integrate` integrates an equation."""

    plain_switches = ()

    def __init__(self, equations, splines):
        self.equations, self.splines = equations, splines
        self.order = len(equations.states)

    def __call__(self, time, state):
        return np.array(self.equations.derivative(time, state,
                                                  [s(time) for s in self.splines]))


def _signed(expression, found):
    """Add to ``found`` the signals read inside a ``sign()`` of ``expression``."""
    if isinstance(expression, Call) and expression.function == "sign":
        found.update(expression.args[0].signals())
    for part in _parts(expression):
        _signed(part, found)


def _parts(expression):
    if isinstance(expression, Call):
        return expression.args
    if isinstance(expression, Power):
        return (expression.base,)
    if isinstance(expression, (Sum, Product)):
        return expression.terms if isinstance(expression, Sum) else expression.factors
    return ()
