"""Accurate simulation of a :class:`~algid.models.Model` driven by sampled inputs.

The model ``sum_i c_i theta_i D^{k_i} z_i = 0`` is solved for the highest derivative of
its output ``y``: with the top terms ``c theta y^(n)``,

    y^(n) = -(forcing(t) + sum of the terms that read y) / (c theta),

where *forcing* gathers every term that does not read the output (inputs, their
derivatives, constants, time).  The state ``(y, y', ..., y^(n-1))`` is integrated by
:func:`scipy.integrate.solve_ivp` (DOP853 by default, relative tolerance 1e-8), so the
integration error is negligible next to any model error; ``method="RK4"`` is the
classical Runge-Kutta method with fixed sub-steps per sample, for loops that simulate
many times.  A ``sign()`` of the simulated state is integrated from switch to switch,
sliding on the switching surface where both flows point to it
(:mod:`algid.simulation._switching`).  The adaptive solvers are bounded in right-hand-side
evaluations (:data:`MAX_EVALUATIONS`, :data:`MAX_STALLED_EVALUATIONS`); beyond, a
:class:`~algid.errors.ModelError` suggests ``method="RK4"``.  This is the one simulator
of algid: :meth:`algid.IdentificationResult.simulate` uses it.

At few samples per period the interpolation of the forcing between samples matters more
than the integrator.  ``interpolation="bandlimited"`` (default on uniform grids) treats
it as a band-limited signal: upsampled 16 times by a long Kaiser-windowed sinc, the
record continued beyond its ends by linear prediction, the fine samples joined by a
cubic spline.  ``interpolation="cubic"`` is a spline through the samples (the only
choice on non-uniform grids).  Derivatives of an input inside a nonlinear factor
(``sign(u')``) come from the algebraic differentiator, as in identification.

The user guide, "How identify works", describes the simulator and its interpolation in
full.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from algid._memory import check_fits
from algid._record_input import (
    read_column,
    refuse_nonfinite_sample,
    refuse_not_increasing,
    refuse_too_few,
    refuse_unequal_lengths,
)
from algid.errors import InputDataError, ModelError
from algid.models._expression import Call, Constant, Power, Product, Signal, Sum, Time
from algid.models._model import Model
from algid.signals._differentiation import algebraic_derivative
from algid.simulation._interpolation import Interpolant
from algid.simulation._switching import integrate_switched

__all__ = ["simulate_model", "fit_initial_state", "differentiate", "known_term_values",
           "check_time_and_inputs", "as_floats", "integrate", "is_uniform",
           "METHODS", "MAX_EVALUATIONS", "MAX_STALLED_EVALUATIONS"]

#: Bound on the right-hand-side evaluations of the adaptive solvers, per sample on
#: average (DOP853 needs about 35 at 9 samples per period, 15 on the EMPS records).
MAX_EVALUATIONS = 1000
#: Bound on the evaluations without the solution advancing one sampling step.
MAX_STALLED_EVALUATIONS = 20000


_SCALAR = {
    "sign": lambda v: float((v > 0) - (v < 0)), "abs": abs, "tanh": math.tanh,
    "sin": math.sin, "cos": math.cos, "tan": math.tan, "exp": math.exp, "log": math.log,
    "sqrt": math.sqrt, "sinh": math.sinh, "cosh": math.cosh, "arctan": math.atan,
}


def _scalar(expr, slot, held=None):
    """A closure ``f(values, time) -> float`` for ``expr`` on scalars (fast per step).

    ``slot(name, k)`` is the index in ``values`` of a signal or derivative; ``held``
    maps a sub-expression to the index in ``values`` of a value that replaces it (the
    mode of a switch).
    """
    if held and expr in held:
        index = held[expr]
        return lambda v, t: v[index]
    if isinstance(expr, Constant):
        value = float(expr.value)
        return lambda v, t: value
    if isinstance(expr, Time):
        return lambda v, t: t
    if isinstance(expr, Signal):
        index = slot(expr.name, expr.derivative)
        return lambda v, t: v[index]
    if isinstance(expr, Call) and expr.function in _SCALAR and len(expr.args) == 1:
        function, arg = _SCALAR[expr.function], _scalar(expr.args[0], slot, held)
        return lambda v, t: function(arg(v, t))
    if isinstance(expr, Power):
        base, exponent = _scalar(expr.base, slot, held), float(expr.exponent)
        if exponent == int(exponent):
            exponent = int(exponent)
        return lambda v, t: base(v, t) ** exponent
    if isinstance(expr, Sum):
        parts = [_scalar(p, slot, held) for p in expr.terms]
        return lambda v, t: sum(p(v, t) for p in parts)
    if isinstance(expr, Product):
        parts = [_scalar(p, slot, held) for p in expr.factors]
        return lambda v, t: math.prod(p(v, t) for p in parts)
    raise ModelError(f"cannot simulate the factor {expr}")


def _switches(expr, output, found):
    """Append to ``found`` the ``sign()`` calls of ``expr`` whose argument reads the
    output (each once, in order of appearance)."""
    if isinstance(expr, Call):
        if expr.function == "sign" and output in expr.args[0].signals() and expr not in found:
            found.append(expr)
        children = expr.args
    else:
        children = getattr(expr, "terms", None) or getattr(expr, "factors", None) or ()
        if isinstance(expr, Power):
            children = (expr.base,)
    for child in children:
        _switches(child, output, found)
    return found


def _weight(term, parameters):
    if term.parameter is None:
        return float(term.coefficient)
    if term.parameter not in parameters:
        raise ModelError(f"no value for the parameter {term.parameter!r}")
    value = parameters[term.parameter]
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise ModelError(f"parameter {term.parameter!r} must be a real number, got "
                         f"{value!r:.40}")
    value = float(value)
    if not math.isfinite(value):
        raise ModelError(f"parameter {term.parameter!r} is not finite: {value!r}")
    return float(term.coefficient) * value


def as_floats(values, what):
    """``values`` as a float64 array, or a one-line error naming ``what``."""
    if isinstance(values, (str, bytes)) or values is None:
        raise InputDataError(f"{what} must be numbers, got {values!r:.40}")
    try:
        return np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise InputDataError(f"{what} must be numbers, got {values!r:.60}") from None


def check_time_and_inputs(time, inputs, names):
    """The sample times and the named inputs of a simulation, read as the record layer
    reads every signal (:func:`algid._record_input.read_column`: masked samples,
    booleans, complex numbers and text refused in the same words).

    Parameters
    ----------
    time : array_like
        At least 4 finite, strictly increasing times (durations: seconds from the first).
    inputs : mapping
        Input name -> samples at ``time``.
    names : sequence of str
        The inputs needed.

    Returns
    -------
    t : numpy.ndarray
    columns : dict
        Name -> float samples.

    Raises
    ------
    InputDataError
    """
    t = read_column(time, "time", time=True, every_sample=True)
    refuse_too_few(len(t), 4, "time")
    refuse_nonfinite_sample(t, "time")
    refuse_not_increasing(t, "time")
    if not hasattr(inputs, "items"):
        raise InputDataError(f"inputs must be a mapping of signal name -> samples, got "
                             f"{type(inputs).__name__}")
    columns = {}
    for name in names:
        if name not in inputs:
            raise InputDataError(f"no samples for the input {name!r}")
        what = f"input {name!r}"
        values = read_column(inputs[name], what, every_sample=True)
        refuse_unequal_lengths({"time": t, name: values})
        refuse_nonfinite_sample(values, what, "a simulation needs every input sample")
        columns[name] = values
    return t, columns


def is_uniform(t):
    """Whether the sample times are uniform (their steps equal to 1e-6 of their mean)."""
    steps = np.diff(t)
    return np.ptp(steps) <= 1e-6 * np.mean(steps)


def differentiate(values, t, order):
    """The algebraic differentiator's estimate (default settings) on the samples."""
    if is_uniform(t):
        return algebraic_derivative(values, (t[-1] - t[0]) / (len(t) - 1), derivative=order)
    return algebraic_derivative(values, time=t, derivative=order)


def known_term_values(term, columns, splines, t):
    """Samples of a term that does not read the output (without its weight).

    ``columns`` maps each input to its samples at ``t``, ``splines`` each to its
    :class:`~algid.simulation._interpolation.Interpolant` (for the derivative of a plain
    input).
    """
    factor = term.factor
    if term.derivative:
        # D^k of a plain input (derivative of its interpolant), of 1 or of t
        if isinstance(factor, Signal):
            return splines[factor.name].derivative_samples(t, term.derivative)
        if isinstance(factor, Time) and term.derivative == 1:
            return np.ones_like(t)
        return np.zeros_like(t)
    values = dict(columns)
    for name, k in factor.derivatives():
        values[(name, k)] = differentiate(columns[name], t, k)
    return np.broadcast_to(np.asarray(factor.evaluate(values, time=t), dtype=float),
                           t.shape)


class _OutputEquation:
    """The model solved for the highest derivative of ``output``, ready to integrate."""

    def __init__(self, model, parameters, t, columns, output, interpolation):
        # (the caller checked that the output is differentiated in a plain term)
        tops = [term for term in model.terms
                if term.factor == Signal(output) and term.derivative > 0]
        self.order = max(term.derivative for term in tops)
        top_terms = [term for term in tops if term.derivative == self.order]
        scale = sum(_weight(term, parameters) for term in top_terms)
        if scale == 0:
            raise ModelError("cannot simulate: the coefficient of the highest derivative "
                             "of the output is zero")
        if interpolation == "bandlimited" and not is_uniform(t):
            interpolation = "cubic"
        self.output, self.interpolation = output, interpolation
        splines = {name: Interpolant(t, values, interpolation)
                   for name, values in columns.items()}
        forcing = np.zeros_like(t)
        self.state_terms = []      # (weight, factor): the terms that read the output
        self.inputs = {}           # interpolants of what those terms read besides it
        for term in model.terms:
            if term in top_terms:
                continue
            weight = -_weight(term, parameters) / scale
            factor = term.factor
            if output in factor.signals():
                if term.derivative:
                    factor = Signal(output, term.derivative)
                for name, k in factor.derivatives():
                    if name == output and k >= self.order:
                        raise ModelError(f"cannot simulate {model.equation!r}: {output}"
                                         f"{chr(39) * k} appears inside a nonlinear factor")
                    if name != output:
                        self.inputs[(name, k)] = Interpolant(
                            t, differentiate(columns[name], t, k), interpolation)
                for name in factor.signals():
                    if name != output:
                        self.inputs[name] = splines[name]
                self.state_terms.append((weight, factor))
            else:
                with np.errstate(over="ignore", invalid="ignore"):
                    forcing += weight * known_term_values(term, columns, splines, t)
        if not np.isfinite(forcing).all():
            raise InputDataError(f"the known terms of {model.equation!r} overflow in "
                                 f"floating point with these parameters and inputs: express "
                                 f"them in other units")
        self.forcing = Interpolant(t, forcing, interpolation)
        # scalar closures over one list: the state, then the interpolated inputs
        keys = [(output, k) for k in range(self.order)] + list(self.inputs)
        index = {(key if isinstance(key, tuple) else (key, 0)): i for i, key in enumerate(keys)}
        self.input_interpolants = list(self.inputs.values())

        def slot(name, k):
            return index[(name, k)]

        self.compiled = [(w, _scalar(f, slot)) for w, f in self.state_terms]
        # sign() of the simulated state: a mode held between switches (algid.simulation._switching),
        # read from the values after the state and the inputs
        switches = []
        for _, factor in self.state_terms:
            _switches(factor, output, switches)
        held = {call: len(keys) + j for j, call in enumerate(switches)}
        self.switched = [(w, _scalar(f, slot, held)) for w, f in self.state_terms]
        self.switch_arguments = [_scalar(call.args[0], slot) for call in switches]
        self.plain_switches = [call.args[0].derivative
                               if isinstance(call.args[0], Signal)
                               and call.args[0].name == output else None
                               for call in switches]

    def _values(self, time, state):
        values = [float(x) for x in state]
        values.extend(f(time) for f in self.input_interpolants)
        return values

    def top(self, time, state, modes):
        """The highest derivative with each switch's ``sign()`` held at ``modes``."""
        values = self._values(time, state) + list(modes)
        top = self.forcing(time)
        try:
            for weight, f in self.switched:
                top += weight * f(values, time)
        except (ArithmeticError, ValueError):
            top = math.nan
        return top

    def switch_argument(self, j, time, state):
        """The argument of switch ``j``'s ``sign()`` (NaN outside its domain)."""
        try:
            return self.switch_arguments[j](self._values(time, state), time)
        except (ArithmeticError, ValueError):
            return math.nan

    def __call__(self, time, state):
        values = self._values(time, state)
        top = self.forcing(time)
        try:
            for weight, f in self.compiled:
                top += weight * f(values, time)
        except (ArithmeticError, ValueError):
            top = math.nan  # outside a function's domain, or overflow: the solver stops
        derivative = np.empty(self.order)
        derivative[:-1] = state[1:]
        derivative[-1] = top
        return derivative


def _prepare(model, parameters, time, inputs, output, interpolation):
    if not isinstance(model, Model):
        raise ModelError(f"model must be a Model (algid.models.parse_equation(equation, "
                         f"parameters)), got {type(model).__name__}")
    if interpolation not in ("bandlimited", "cubic"):
        raise InputDataError(f"interpolation must be 'bandlimited' or 'cubic', "
                             f"got {interpolation!r}")
    output = model.output if output is None else output
    if output not in model.signals:
        raise ModelError(f"{output!r} is not a signal of {model.equation!r}")
    if not any(term.factor == Signal(output) and term.derivative > 0 for term in model.terms):
        raise ModelError(f"cannot simulate {model.equation!r}: the output {output!r} "
                         "is not differentiated in a plain term")
    names = tuple(name for name in model.signals if name != output)
    t, columns = check_time_and_inputs(time, inputs, names)
    return _OutputEquation(model, parameters, t, columns, output, interpolation), t


def _integrate_rk4(equation, t, state, substeps):
    """Classical RK4 with ``substeps`` steps per sampling interval, on the same
    interpolants (evaluated once, vectorised, at every step and half step)."""
    up = 2 * substeps
    fraction = np.arange(up) / up
    fine = np.append((t[:-1, None] + np.diff(t)[:, None] * fraction).ravel(), t[-1])
    forcing = equation.forcing.spline(fine).tolist()
    columns = [f.spline(fine) for f in equation.input_interpolants]
    rows = np.column_stack(columns).tolist() if columns else [[] for _ in fine]
    times = fine.tolist()
    compiled = equation.compiled

    def top(x, i):
        values = x + rows[i]
        total = forcing[i]
        for weight, f in compiled:
            total += weight * f(values, times[i])
        return total

    x = [float(v) for v in state]
    out = np.full((equation.order, len(t)), np.nan)
    out[:, 0] = x
    try:
        for i in range(len(t) - 1):
            for j in range(substeps):
                base = 2 * (i * substeps + j)
                h = times[base + 2] - times[base]
                k1 = x[1:] + [top(x, base)]
                x2 = [a + 0.5 * h * b for a, b in zip(x, k1)]
                k2 = x2[1:] + [top(x2, base + 1)]
                x3 = [a + 0.5 * h * b for a, b in zip(x, k2)]
                k3 = x3[1:] + [top(x3, base + 1)]
                x4 = [a + h * b for a, b in zip(x, k3)]
                k4 = x4[1:] + [top(x4, base + 2)]
                x = [a + h / 6.0 * (b + 2 * c + 2 * d + e)
                     for a, b, c, d, e in zip(x, k1, k2, k3, k4)]
            if not all(math.isfinite(v) and abs(v) < 1e150 for v in x):
                break
            out[:, i + 1] = x
    except (ArithmeticError, ValueError):
        pass                     # outside a function's domain: NaN from here on
    return out


#: The integrators of :func:`simulate_model`: those of :func:`scipy.integrate.solve_ivp`,
#: and the classical Runge-Kutta method of fixed steps.
METHODS = ("RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA", "RK4")
#: Peak memory of ``method="RK4"`` per step and half step [bytes] (the interpolated
#: inputs and forcing as lists of floats), checked before the grid is made.
_RK4_BYTES_PER_POINT = 128


def _check_integrator(method, rtol, atol, substeps, n_samples):
    """Refuse an unknown method, tolerances that are not positive numbers, or sub-steps
    that are not a positive integer or whose grid does not fit in memory."""
    if not isinstance(method, str) or method not in METHODS:
        raise InputDataError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    for name, value in (("rtol", rtol), ("atol", atol)):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real) \
                or not 0 < value < math.inf:
            raise InputDataError(f"{name} must be a positive number, got {value!r:.40}")
    if method == "RK4":
        if isinstance(substeps, (bool, np.bool_)) or not isinstance(substeps, numbers.Integral) \
                or substeps < 1:
            raise InputDataError(f"substeps must be a positive integer, got {substeps!r}")
        check_fits(2 * int(substeps) * n_samples, _RK4_BYTES_PER_POINT,
                   what=f"RK4 with {substeps} substeps", unit="steps")


def integrate(equation, t, initial_state, method, rtol, atol, substeps=4,
              remedy="use method='RK4' (fixed steps) or a stiff method ('LSODA')"):
    """Integrate a right-hand side over the sample times.

    Parameters
    ----------
    equation : object
        ``order`` (states), ``plain_switches`` (switches located within the step, or
        none) and ``equation(time, state)`` -> the state's derivative; ``method="RK4"``
        needs :func:`simulate_model`'s equation.
    t : numpy.ndarray
        Sample times.
    initial_state : array_like or None
        The state at ``t[0]`` (zero by default).
    method, rtol, atol, substeps
        As in :func:`simulate_model`.
    remedy : str
        What the error says to try when the integration stops.

    Returns
    -------
    numpy.ndarray, shape (order, samples)
        The states; NaN from where the integration failed.

    Raises
    ------
    ModelError
        The integration stopped by its bound on evaluations.
    """
    _check_integrator(method, rtol, atol, substeps, len(t))
    state = np.zeros(equation.order) if initial_state is None else \
        as_floats(initial_state, "initial_state").ravel()
    if state.shape != (equation.order,) or not np.all(np.isfinite(state)):
        raise InputDataError(f"initial_state must hold {equation.order} finite values "
                             f"(the output and its derivatives up to order "
                             f"{equation.order - 1}), got {initial_state!r}")
    if method == "RK4":
        substeps = int(substeps)
        if substeps < 1:
            raise InputDataError(f"substeps must be a positive integer, got {substeps!r}")
        return _integrate_rk4(equation, t, state, substeps)
    budget = _Budget(t)
    try:
        if equation.plain_switches:
            return integrate_switched(equation, t, state, method, rtol, atol, budget.tick)

        def rhs(time, x):
            budget.tick(time)
            return equation(time, x)

        with np.errstate(over="ignore", invalid="ignore"):  # a diverging model: NaN below
            from scipy.integrate import solve_ivp

            solution = solve_ivp(rhs, (t[0], t[-1]), state, method=method, t_eval=t,
                                 rtol=rtol, atol=atol)
    except _Exhausted as stop:
        raise ModelError(
            f"simulation by {method} stopped at t = {stop.time:.6g} s after {stop.count} "
            f"right-hand-side evaluations ({stop.reason}): the model is stiff or switches "
            f"too often for it; {remedy}") from None
    out = np.full((equation.order, len(t)), np.nan)
    # a diverging model stops early (SciPy gives a list when no sample was reached): NaN after
    reached = np.asarray(solution.y, dtype=float).reshape(equation.order, -1)
    out[:, :reached.shape[1]] = reached
    return out


class _Exhausted(Exception):
    """The bound on the right-hand-side evaluations was reached."""

    def __init__(self, time, count, reason):
        super().__init__(reason)
        self.time, self.count, self.reason = time, count, reason


class _Budget:
    """Counts right-hand-side evaluations; raises :class:`_Exhausted` past the bounds:
    :data:`MAX_EVALUATIONS` per sample, or a block of :data:`MAX_STALLED_EVALUATIONS`
    whose median time is less than one mean sampling step past the previous block's (the
    median: a trial step, rejected or the first of a solver, may look far ahead)."""

    def __init__(self, t):
        self.limit = MAX_EVALUATIONS * len(t)
        self.step = (t[-1] - t[0]) / (len(t) - 1)
        self.count = 0
        self.block = []
        self.previous_median = -math.inf

    def tick(self, time):
        self.count += 1
        self.block.append(time)
        if len(self.block) == MAX_STALLED_EVALUATIONS:
            median = float(np.median(self.block))
            if median < self.previous_median + self.step:
                raise _Exhausted(time, self.count, f"{MAX_STALLED_EVALUATIONS} without "
                                                   f"advancing one sampling step")
            self.previous_median, self.block = median, []
        if self.count > self.limit:
            raise _Exhausted(time, self.count, f"{MAX_EVALUATIONS} per sample")


def simulate_model(model, parameters, time, inputs, *, initial_state=None, output=None,
                   method="DOP853", interpolation="bandlimited", rtol=1e-8, atol=1e-12,
                   return_states=False, substeps=4):
    """Simulate a model's output from sampled inputs, accurately.

    Parameters
    ----------
    model : Model
        The model (from :func:`algid.models.parse_equation`).
    parameters : mapping
        Parameter name -> value, for every unknown parameter of the model.
    time : array_like
        Sample times, strictly increasing (uniform or not).
    inputs : mapping
        Signal name -> samples at ``time``, for every signal of the model other than the
        output (extra entries are ignored).
    initial_state : array_like, optional
        The output and its derivatives up to order ``n - 1`` at ``time[0]``; default
        zeros.  :func:`fit_initial_state` fits it to a measured output.
    output : str, optional
        The signal to simulate; default ``model.output``.
    method : str, optional
        The :func:`scipy.integrate.solve_ivp` method: ``"DOP853"`` (default), or
        ``"Radau"``/``"BDF"``/``"LSODA"`` for a stiff model; or ``"RK4"``, the classical
        Runge-Kutta method with ``substeps`` fixed steps per sampling interval (faster,
        for loops such as an output-error fit).
    interpolation : {"bandlimited", "cubic"}, optional
        How the inputs are interpolated between samples (see the user guide, "How
        identify works"); ``"bandlimited"`` falls back to ``"cubic"`` on a non-uniform
        grid.
    rtol, atol : float, optional
        Tolerances of the integrator.  The default ``rtol = 1e-8`` keeps the
        integration error far below a model's own error.
    return_states : bool, optional
        If true, return the whole state (``n`` x samples) instead of the output alone.
    substeps : int, optional
        Steps per sampling interval of ``method="RK4"`` (default 4).

    Returns
    -------
    numpy.ndarray
        The simulated output at ``time`` (or the states); NaN from where the
        integration failed (a diverging model).

    Raises
    ------
    InputDataError
        Bad time axis, missing or non-finite inputs, a bad initial state.
    ModelError
        A missing parameter, an output that is not differentiated, or the output's
        highest derivative inside a nonlinear factor.

    Examples
    --------
    >>> import numpy as np
    >>> from algid.models import parse_equation
    >>> from algid.simulation import simulate_model
    >>> model = parse_equation("x' + a*x = u", "a")
    >>> t = np.linspace(0.0, 1.0, 101)
    >>> x = simulate_model(model, {"a": 2.0}, t, {"u": np.ones_like(t)})
    >>> round(float(x[-1]), 6)              # (1 - exp(-2)) / 2
    0.432332
    """
    equation, t = _prepare(model, parameters, time, inputs, output, interpolation)
    states = integrate(equation, t, initial_state, method, rtol, atol, substeps)
    return states if return_states else states[0]


def fit_initial_state(model, parameters, time, inputs, measured_output, n_samples=50, *,
                      output=None, method="DOP853", interpolation="bandlimited",
                      rtol=1e-8, atol=1e-12, substeps=4):
    """The initial state that best fits the first samples of a measured output.

    Least squares, over the initial state, of the simulated minus the measured output on
    the first ``n_samples`` samples, started from a local polynomial fit.  The inputs are
    interpolated on the whole record (so the band-limited interpolant is the same as in
    the full simulation).

    Parameters
    ----------
    model, parameters, time, inputs, output, method, interpolation, rtol, atol, substeps
        As in :func:`simulate_model`.
    measured_output : array_like
        The measured output at ``time``.
    n_samples : int, optional
        Number of leading samples fitted (default 50).

    Returns
    -------
    numpy.ndarray
        The output and its derivatives up to order ``n - 1`` at ``time[0]``.

    Examples
    --------
    >>> import numpy as np
    >>> from algid.models import parse_equation
    >>> from algid.simulation import fit_initial_state, simulate_model
    >>> model, values = parse_equation("x'' + B*x' + K*x = f", "B K"), {"B": 2.0, "K": 3.0}
    >>> t = np.linspace(0.0, 1.0, 101)
    >>> force = {"f": np.ones_like(t)}
    >>> x = simulate_model(model, values, t, force, initial_state=[0.5, -1.0])
    >>> np.round(fit_initial_state(model, values, t, force, x), 6)
    array([ 0.5, -1. ])
    """
    equation, t = _prepare(model, parameters, time, inputs, output, interpolation)
    y = np.asarray(measured_output, dtype=float)
    if y.shape != t.shape:
        raise InputDataError(f"measured_output has shape {y.shape}, time has {t.shape}")
    m = int(n_samples)
    if not equation.order + 1 <= m <= len(t):
        raise InputDataError(f"n_samples must be in {equation.order + 1}..{len(t)}, "
                             f"got {n_samples!r}")
    if not np.all(np.isfinite(y[:m])):
        raise InputDataError("measured_output has NaN or infinite values in the fitted part")
    head = t[:m]
    degree = min(equation.order + 2, m - 1)
    start = np.polynomial.polynomial.polyfit(head - head[0], y[:m], degree)
    guess = np.array([start[k] * math.factorial(k) for k in range(equation.order)])
    scale = np.std(y[:m]) + np.max(np.abs(y[:m])) + 1e-300

    def residual(state):
        simulated = integrate(equation, head, state, method, rtol, atol, substeps)[0]
        return np.where(np.isfinite(simulated), simulated - y[:m], 1e6 * scale)

    from scipy.optimize import least_squares

    return least_squares(residual, guess, x_scale="jac").x
