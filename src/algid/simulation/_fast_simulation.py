"""A fast fixed-step simulator of any model algid can simulate, for fits that simulate
it hundreds of times.

:func:`algid.simulate_model` integrates in Python (its right-hand side is a tree of
closures), a few seconds per record: an output-error fit of a nonlinear model needs
hundreds of simulations.  Here the model solved for the highest derivative of its
output,

    y^(n) = -(forcing(t) + sum_t w_t g_t(y, y', ..., u(t), t)) / w_top,

is integrated by the classical Runge-Kutta method with ``substeps`` steps per sampling
interval, in one compiled loop (numba, :mod:`algid.simulation._rk4_kernel`) shared by
every model:

- the *forcing* (every term that does not read the output, weighted) and the inputs the
  state terms read are sampled once, at every step and half step, from the simulator's
  own interpolants (band-limited by default, as :func:`algid.simulate_model`);
- each state term ``g_t`` is a short program for a stack machine (:func:`program`), so
  that a new model needs no compilation;
- a ``sign()`` of a derivative of the output is a *mode* held between switches (as in
  :mod:`algid.simulation._switching`): where its argument changes sign within a step,
  the crossing is located on the step's cubic Hermite interpolant, the step integrated
  to it and on from it under the new mode; where both flows point to the surface of a
  ``sign()`` of the highest state derivative (a mass held by Coulomb friction) the state
  slides on it, ``y^(n-1) = 0``, until the force overcomes the friction.  The simulated
  output is then a continuous function of the parameters, as a fit's finite
  differences need.

Within a step, the forcing and inputs between the sampled points (at a crossing) are the
quadratic through the step's three points.  A second crossing within the same step is
handled at the next one.
"""

from __future__ import annotations

import numpy as np

from algid.errors import ModelError
from algid.models._expression import Call, Constant, Power, Product, Signal, Sum, Time

__all__ = ["Program", "program", "FastSimulation", "FastSystemSimulation", "WeightedRows",
           "fast_simulation_unavailable",
           "FUNCTION_CODES", "SUBSTEPS"]

#: Runge-Kutta steps per sampling step.
SUBSTEPS = 4

# the stack machine's operations
_CONST, _STATE, _INPUT, _TIME, _MODE, _ADD, _MUL, _POW, _FUNC = range(9)

#: Codes of the functions of the stack machine.
FUNCTION_CODES = {name: i for i, name in enumerate(
    ("sign", "abs", "tanh", "sin", "cos", "tan", "exp", "log", "sqrt", "sinh", "cosh",
     "arctan"))}


class Program:
    """The state terms of a model as stack-machine code.

    Attributes
    ----------
    ops : numpy.ndarray of int64
        Operation codes, the terms one after the other.
    args : numpy.ndarray of float64
        Each operation's argument (a constant, an index, an exponent, a function code).
    starts : numpy.ndarray of int64
        Where each term's code starts in ``ops`` (and, last, the end).
    inputs : list of tuple
        ``(name, k)`` of each input (or its ``k``-th derivative) the terms read, in the
        order of the ``INPUT`` indices.
    switches : list of int
        For each ``sign()`` of the output, the order of the derivative it reads.
    depth : int
        The deepest stack the code needs.
    """

    def __init__(self):
        self.ops, self.args, self.starts = [], [], [0]
        self.inputs, self.switches, self.depth = [], [], 1


def program(factors, output, order, states=None):
    """Stack-machine code of the factors that read the output.

    Parameters
    ----------
    factors : sequence of Expr
        The factors of the state terms.
    output : str or None
        The simulated signal (None for a system).
    order : int
        The highest derivative of the output (the state holds the lower ones).
    states : mapping, optional
        For a system: ``(output, k)`` -> the index of its state (the structure refused
        already what cannot be simulated).

    Returns
    -------
    Program

    Raises
    ------
    ModelError
        A factor reads a derivative of the output of ``order`` or more, or a ``sign()``
        whose argument reads the output but is not one of its derivatives.
    """
    code = Program()

    def emit(expr, depth):
        code.depth = max(code.depth, depth)
        if isinstance(expr, Constant):
            _op(code, _CONST, float(expr.value))
        elif isinstance(expr, Time):
            _op(code, _TIME, 0.0)
        elif isinstance(expr, Signal):
            if states is not None and (expr.name, expr.derivative) in states:
                _op(code, _STATE, float(states[(expr.name, expr.derivative)]))
            elif expr.name == output:
                if expr.derivative >= order:
                    raise ModelError(f"cannot simulate: {expr} appears inside a nonlinear "
                                     f"factor")
                _op(code, _STATE, float(expr.derivative))
            else:
                key = (expr.name, expr.derivative)
                if key not in code.inputs:
                    code.inputs.append(key)
                _op(code, _INPUT, float(code.inputs.index(key)))
        elif isinstance(expr, Call) and expr.function == "sign" \
                and output in expr.args[0].signals():
            argument = expr.args[0]
            if not (isinstance(argument, Signal) and argument.name == output):
                raise ModelError(f"cannot simulate {expr} fast: only a sign() of a "
                                 f"derivative of the output switches exactly")
            if argument.derivative not in code.switches:
                code.switches.append(argument.derivative)
            _op(code, _MODE, float(code.switches.index(argument.derivative)))
        elif isinstance(expr, Call):
            emit(expr.args[0], depth)
            _op(code, _FUNC, float(FUNCTION_CODES[expr.function]))
        elif isinstance(expr, (Sum, Product)):
            parts = expr.terms if isinstance(expr, Sum) else expr.factors
            emit(parts[0], depth)
            for part in parts[1:]:
                emit(part, depth + 1)
                _op(code, _ADD if isinstance(expr, Sum) else _MUL, 0.0)
        elif isinstance(expr, Power):
            emit(expr.base, depth)
            _op(code, _POW, float(expr.exponent))
        else:
            raise ModelError(f"cannot simulate the factor {expr}")

    for factor in factors:
        emit(factor, 1)
        code.starts.append(len(code.ops))
    code.ops = np.array(code.ops, dtype=np.int64)
    code.args = np.array(code.args, dtype=float)
    code.starts = np.array(code.starts, dtype=np.int64)
    return code


def _op(code, op, arg):
    code.ops.append(op)
    code.args.append(arg)


def fast_simulation_unavailable(model):
    """Why :class:`FastSimulation` cannot simulate a model (None if it can).

    Parameters
    ----------
    model : algid.models._model.Model or None
        None: only whether the fast simulators can run at all (numba).

    Returns
    -------
    str or None
        One line, or None.
    """
    try:
        import numba  # noqa: F401
    except ImportError:
        return "the fast simulator needs numba (pip install 'algid[fast]')"
    if model is None:
        return None
    try:
        _Structure(model)
    except ModelError as error:
        return str(error)
    return None


class _Structure:
    """A model solved for the highest derivative of its output: its top, state and
    known terms, and the state terms' code."""

    def __init__(self, model):
        output = model.output
        plain = [t for t in model.terms if t.factor == Signal(output) and t.derivative > 0]
        if not plain:
            raise ModelError(f"cannot simulate {model.equation!r}: the output {output!r} "
                             f"is not differentiated in a plain term")
        self.order = max(t.derivative for t in plain)
        self.top = [t for t in plain if t.derivative == self.order]
        self.state, self.known = [], []
        for term in model.terms:
            if term in self.top:
                continue
            if output in term.factor.signals():
                self.state.append(term)
            else:
                self.known.append(term)
        factors = [Signal(output, t.derivative) if t.derivative else t.factor
                   for t in self.state]
        self.code = program(factors, output, self.order)


class FastSimulation:
    """The output of a model simulated on one uniformly sampled run of its inputs.

    Parameters
    ----------
    model : algid.models._model.Model
    t : numpy.ndarray
        The sample times (uniform).
    columns : mapping
        Each input signal of the model -> its samples.
    interpolation : {"bandlimited", "cubic"}
        The inputs between samples, as :func:`algid.simulate_model`.
    substeps : int
        Runge-Kutta steps per sampling step.

    Raises
    ------
    ModelError
        The model cannot be simulated fast (:func:`fast_simulation_unavailable`).
    """

    def __init__(self, model, t, columns, interpolation="bandlimited", substeps=SUBSTEPS):
        from algid.simulation._model import differentiate, known_term_values
        from algid.simulation._rk4_kernel import simulate_output

        structure = _Structure(model)
        self.order = structure.order
        grid = _FineGrid(t, columns, interpolation, substeps)
        self.t, self.step, self.substeps = grid.t, grid.step, grid.substeps
        self._kernel = simulate_output
        on_fine, fine = grid.on_fine, grid.points
        splines = grid.splines
        known = []
        for term in structure.known:
            values = known_term_values(term, columns, splines, self.t)
            known.append(on_fine(np.asarray(values, dtype=float)))
        self.known = np.array(known).reshape(len(known), len(fine))
        code = structure.code
        self.inputs = np.array([
            on_fine(np.asarray(columns[name], dtype=float) if k == 0 else
                    differentiate(np.asarray(columns[name], dtype=float), self.t, k))
            for name, k in code.inputs]).reshape(len(code.inputs), len(fine))
        self.code = code
        self.switches = np.array(code.switches, dtype=np.int64)
        names = model.parameters
        self._known_map = _weights_map(structure.known, names)
        self._state_map = _weights_map(structure.state, names)
        self._top_map = _weights_map(structure.top, names)

    def run(self, theta, x0):
        """The simulated output at the samples (NaN from where it diverges).

        Parameters
        ----------
        theta : numpy.ndarray
            The parameters, in ``model.parameters`` order.
        x0 : numpy.ndarray
            The initial state ``(y, y', ..., y^(n-1))``.

        Returns
        -------
        numpy.ndarray
        """
        theta = np.asarray(theta, dtype=float)
        top = float(np.sum(_weights(self._top_map, theta)))
        forcing = _weights(self._known_map, theta) @ self.known
        out = np.empty(len(self.t))
        with np.errstate(all="ignore"):
            self._kernel(self.code.ops, self.code.args, self.code.starts,
                         _weights(self._state_map, theta), top,
                         np.ascontiguousarray(forcing), self.inputs, self.switches,
                         self.code.depth, np.asarray(x0, dtype=float).copy(),
                         float(self.t[0]), self.step, self.substeps, len(self.t), out)
        return out


class _FineGrid:
    """The points a fixed-step simulation reads its inputs at (every Runge-Kutta step and
    half step), and the inputs there."""

    def __init__(self, t, columns, interpolation, substeps):
        from algid.simulation._interpolation import UPSAMPLING, Interpolant, bandlimited_samples

        self.t = np.asarray(t, dtype=float)
        self.step = (self.t[-1] - self.t[0]) / (len(self.t) - 1)
        self.substeps = int(substeps)
        if UPSAMPLING % (2 * self.substeps):
            raise ModelError(f"substeps must divide {UPSAMPLING // 2}, got {substeps}")
        count = (len(self.t) - 1) * 2 * self.substeps + 1
        self.points = self.t[0] + np.arange(count) * (self.step / (2 * self.substeps))
        self.points[-1] = self.t[-1]
        self._interpolation = interpolation
        self._bandlimited = bandlimited_samples
        self._decimation = UPSAMPLING // (2 * self.substeps)
        grid = self

        class Splines(dict):   # made where a known term differentiates an input
            def __missing__(splines, name):
                splines[name] = Interpolant(grid.t, np.asarray(columns[name], dtype=float),
                                            interpolation, scalar=False)
                return splines[name]

        self.splines = Splines()

    def on_fine(self, values):
        """Samples at :attr:`t` -> values at :attr:`points`."""
        # (the band-limited points are a subset of its upsampled ones: no spline)
        if self._interpolation == "bandlimited":
            return self._bandlimited(values)[::self._decimation]
        from algid.simulation._interpolation import Interpolant

        return Interpolant(self.t, values, self._interpolation, scalar=False).spline(
            self.points)


class FastSystemSimulation:
    """The outputs of a system of equations simulated on one uniformly sampled run of its
    inputs, as :class:`FastSimulation` simulates one equation.

    The system is solved for its top derivatives (:class:`SystemStructure`); its state
    terms run as one stack-machine program, its other terms are sampled once on the
    fine grid.  A ``sign()`` of an output is refused (as by :class:`SystemEquations`).

    Parameters
    ----------
    system : algid.models.SystemModel
    t : numpy.ndarray
        The sample times (uniform).
    columns : mapping
        Each input of the system -> its samples.
    outputs : sequence of str, optional
        The outputs :meth:`run` returns (default: all).
    interpolation : {"bandlimited", "cubic"}
        The inputs between samples.
    substeps : int
        Runge-Kutta steps per sampling step.

    Attributes
    ----------
    order : int
        The number of states.
    states : list of (str, int)
        Per state, the output and its derivative order.

    Raises
    ------
    ModelError
        A system that cannot be simulated (:class:`SystemStructure`).
    """

    def __init__(self, system, t, columns, outputs=None, interpolation="bandlimited",
                 substeps=SUBSTEPS):
        from algid.simulation._rk4_kernel import simulate_system_outputs
        from algid.simulation._system_equations import SystemStructure

        structure = SystemStructure(system)
        self._outputs = tuple(structure.outputs)
        self.states, self.order = structure.states, len(structure.states)
        grid = _FineGrid(t, columns, interpolation, substeps)
        self.t, self.step, self.substeps = grid.t, grid.step, grid.substeps
        self._kernel = simulate_system_outputs
        read = set(self._outputs)
        state_terms = [term for term in structure.other_terms
                       if read & set(term[3].signals())]
        known_terms = [term for term in structure.other_terms
                       if not read & set(term[3].signals())]
        where = {s: i for i, s in enumerate(self.states)}
        self.code = program([factor for *_, factor in state_terms], None, 0, states=where)
        # (the inputs interpolated, then every factor of them evaluated on the fine grid,
        # as the system's integrator does: a sign(u) interpolated from its samples would
        # ring where it jumps)
        fine = {name: grid.on_fine(np.asarray(columns[name], dtype=float))
                for name in structure.inputs}
        with np.errstate(all="ignore"):
            self.known = np.array([np.broadcast_to(np.asarray(
                factor.evaluate(fine, time=grid.points), dtype=float), grid.points.shape)
                for *_, factor in known_terms]).reshape(len(known_terms), len(grid.points))
        self.inputs = np.array([fine[name] for name, _ in self.code.inputs]
                               ).reshape(len(self.code.inputs), len(grid.points))
        names = system.parameters
        self._top_map = (np.array([[i, j] for i, j, *_ in structure.top_terms], dtype=np.int64),
                         _weights_map([_Weight(c, p) for *_, c, p in structure.top_terms],
                                      names))
        self._state_map = (np.array([i for i, *_ in state_terms], dtype=np.int64),
                           _weights_map([_Weight(c, p) for _, c, p, _ in state_terms], names))
        self._known_map = (np.array([i for i, *_ in known_terms], dtype=np.int64),
                           _weights_map([_Weight(c, p) for _, c, p, _ in known_terms], names))
        self._tops = np.array(structure.tops, dtype=np.int64)
        self._chains = np.array(structure.chains, dtype=np.int64).reshape(-1, 2)
        chosen = self._outputs if outputs is None else tuple(outputs)
        self._read = np.array([where[(y, 0)] for y in chosen], dtype=np.int64)

    def run(self, theta, x0):
        """The simulated outputs at the samples (NaN from where they diverge, all NaN
        where the parameters do not determine the top derivatives).

        Parameters
        ----------
        theta : numpy.ndarray
            The parameters, in ``system.parameters`` order.
        x0 : numpy.ndarray
            The initial state, as :attr:`states`.

        Returns
        -------
        numpy.ndarray, shape (outputs, samples)
        """
        from algid.simulation._system_equations import solve_tops

        theta = np.asarray(theta, dtype=float)
        m = len(self._outputs)
        out = np.full((len(self._read), len(self.t)), np.nan)
        top = np.zeros((m, m))
        rows, weights = self._top_map
        np.add.at(top, (rows[:, 0], rows[:, 1]), _weights(weights, theta))
        try:
            solve = solve_tops(top, self._outputs)
        except ModelError:
            return out
        gain = np.zeros((m, len(self._state_map[0])))
        gain[self._state_map[0], np.arange(gain.shape[1])] = _weights(self._state_map[1], theta)
        known = np.zeros((m, len(self._known_map[0])))
        known[self._known_map[0], np.arange(known.shape[1])] = _weights(self._known_map[1],
                                                                         theta)
        with np.errstate(all="ignore"):
            self._kernel(self.code.ops, self.code.args, self.code.starts,
                         np.ascontiguousarray(solve @ gain),
                         np.ascontiguousarray(solve @ (known @ self.known)), self.inputs,
                         self._tops, self._chains, self._read, self.code.depth,
                         np.asarray(x0, dtype=float).copy(), float(self.t[0]), self.step,
                         self.substeps, len(self.t), out)
        return out


class WeightedRows:
    """A system's simulation as one run of rows, as an output-error fit stacks them: its
    outputs one after the other, each times its weight.

    Parameters
    ----------
    simulation : FastSystemSimulation
    weights : numpy.ndarray
        One per output :meth:`FastSystemSimulation.run` returns.

    Attributes
    ----------
    order : int
        The number of states.
    step : float
        The sampling step.
    """

    def __init__(self, simulation, weights):
        self.simulation, self.weights = simulation, np.asarray(weights, dtype=float)
        self.order, self.step = simulation.order, simulation.step

    def run(self, theta, x0):
        """The weighted outputs, one after the other (NaN where they diverge).

        Parameters
        ----------
        theta, x0 : numpy.ndarray
            As :meth:`FastSystemSimulation.run`.

        Returns
        -------
        numpy.ndarray
        """
        return (self.simulation.run(theta, x0) * self.weights[:, None]).ravel()


class _Weight:
    """A term's coefficient and parameter, as :func:`_weights_map` reads them."""

    def __init__(self, coefficient, parameter):
        self.coefficient, self.parameter = coefficient, parameter


def _weights_map(terms, names):
    """``(coefficients, parameter indices, -1 for known)`` of terms."""
    return (np.array([float(t.coefficient) for t in terms]),
            np.array([-1 if t.parameter is None else names.index(t.parameter)
                      for t in terms], dtype=np.int64))


def _weights(mapping, theta):
    coefficients, index = mapping
    return coefficients * np.where(index >= 0, theta[np.maximum(index, 0)], 1.0) \
        if len(index) else coefficients
