"""Systems of linear model equations: their state-space form, simulated exactly.

The equations ``sum_j P_ij(D) y_j + sum_c Q_ic(D) u_c = 0`` (one output ``y_i`` per
equation, ``n_j`` the highest derivative of ``y_j`` in any equation) take the state
``x = (y_1, ..., y_1^(n_1 - 1), y_2, ...)``.  The top derivatives satisfy
``M y_top = -(L x + E u)``, ``M`` the coefficients of every ``y_j^(n_j)`` in every
equation (invertible: each output's top derivative is determined), which gives
``x' = A x + B u``, ``y = C x``.  The input channels are the measured inputs, the
constant 1 (offsets) and time (drifts); their derivatives are refused (a state-space
model has no direct path from ``u'``).

The simulation holds each input linear between samples (first-order hold) and is exact
for such inputs: ``exp`` of the augmented matrix gives the one-step transition and the
two input matrices, and the recursion runs in the eigenvector basis of the transition
(one first-order recursion per mode, :func:`scipy.signal.lfilter`), or step by step
where that basis is ill-conditioned.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from algid.errors import InputDataError, ModelError
from algid.models._expression import Constant, Signal, Time

__all__ = ["StateSpace", "state_space", "simulate_system", "simulate_space",
           "free_responses", "fit_initial_state", "ONE", "TIME"]

#: Input channel names of the constant 1 and of time.
ONE, TIME = "__one__", "__time__"

#: Condition number of the eigenvector basis above which the recursion runs step by step.
MODAL_CONDITION = 1e8


class StateSpace(NamedTuple):
    """``x' = A x + B u``, ``y = C x`` of a linear system of equations.

    Attributes
    ----------
    A, B, C : numpy.ndarray
    states : list of (str, int)
        Per state, the output and its derivative order.
    channels : list of str
        Per column of ``B``: a measured input, :data:`ONE` or :data:`TIME`.
    outputs : tuple of str
        Per row of ``C``.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    states: list
    channels: list
    outputs: tuple


def state_space(system, values):
    """The state-space form of a linear system of equations at parameter values.

    Parameters
    ----------
    system : algid.models.SystemModel
        Linear in its signals.
    values : mapping
        Parameter name -> value.

    Returns
    -------
    StateSpace

    Raises
    ------
    ModelError
        A nonlinear equation, a derivative of an input, an output that appears
        undifferentiated only, or top derivatives that the equations do not determine.
    """
    if not system.is_linear:
        raise ModelError("this system is not linear in its signals: it has no "
                         "state-space form")
    outputs = system.outputs
    orders = {y: 0 for y in outputs}
    channels = []
    for model in system.equations:
        for term in model.terms:
            factor, k = term.factor, term.derivative
            if isinstance(factor, Signal) and factor.name in orders:
                orders[factor.name] = max(orders[factor.name], k)
            elif isinstance(factor, Signal):
                if k > 0:
                    raise ModelError(f"the term {term} holds a derivative of the input "
                                     f"{factor.name}: a system is simulated from its inputs "
                                     f"only")
                channels.append(factor.name)
            elif isinstance(factor, Constant) and k == 0:
                channels.append(ONE)
            elif isinstance(factor, Time) and k <= 1:
                channels.append(TIME if k == 0 else ONE)
    for y, n in orders.items():
        if n == 0:
            raise ModelError(f"the output {y} appears undifferentiated only: an algebraic "
                             f"equation has no state to simulate")
    channels = list(dict.fromkeys(channels))
    states = [(y, k) for y in outputs for k in range(orders[y])]
    where = {s: i for i, s in enumerate(states)}
    m, n, c = len(outputs), len(states), len(channels)
    top, lower, forcing = np.zeros((m, m)), np.zeros((m, n)), np.zeros((m, c))
    for i, model in enumerate(system.equations):
        for term in model.terms:
            value = term.coefficient * (1.0 if term.parameter is None
                                        else float(values[term.parameter]))
            factor, k = term.factor, term.derivative
            if isinstance(factor, Signal) and factor.name in orders:
                if k == orders[factor.name]:
                    top[i, outputs.index(factor.name)] += value
                else:
                    lower[i, where[(factor.name, k)]] += value
            elif isinstance(factor, Signal):
                forcing[i, channels.index(factor.name)] += value
            elif isinstance(factor, Constant) and k == 0:
                forcing[i, channels.index(ONE)] += value * factor.value
            elif isinstance(factor, Time) and k <= 1:
                forcing[i, channels.index(TIME if k == 0 else ONE)] += value
    if not np.all(np.isfinite(top)) or np.linalg.cond(top) > 1e12:
        raise ModelError("the equations do not determine the highest derivatives of "
                         f"{', '.join(outputs)} at these parameters (their coefficients "
                         f"form a singular matrix)")
    with np.errstate(over="ignore", invalid="ignore"):
        solved = 0.0 - np.linalg.solve(top, np.column_stack([lower, forcing]))
    if not np.all(np.isfinite(solved)):
        raise ModelError("the state-space form of these equations is not finite at these "
                         "parameters")
    A, B = np.zeros((n, n)), np.zeros((n, c))
    for (y, k), i in where.items():
        if k + 1 < orders[y]:
            A[i, where[(y, k + 1)]] = 1.0
        else:
            A[i] = solved[outputs.index(y), :n]
            B[i] = solved[outputs.index(y), n:]
    C = np.zeros((m, n))
    for j, y in enumerate(outputs):
        C[j, where[(y, 0)]] = 1.0
    return StateSpace(A, B, C, states, channels, outputs)


def _channel_values(channels, t, inputs):
    columns = []
    for name in channels:
        if name == ONE:
            columns.append(np.ones(len(t)))
        elif name == TIME:
            columns.append(np.asarray(t, dtype=float))
        else:
            columns.append(np.asarray(inputs[name], dtype=float))
    return np.array(columns).reshape(len(channels), len(t))


def _discretise(A, B, step):
    from scipy.linalg import expm

    n, c = B.shape
    block = np.zeros((n + 2 * c, n + 2 * c))
    block[:n, :n] = A * step
    block[:n, n:n + c] = B * step
    block[n:n + c, n + c:] = np.eye(c)
    E = expm(block)
    Ad, Bd1 = E[:n, :n], E[:n, n + c:]
    return Ad, E[:n, n:n + c] - Bd1, Bd1


def _uniform_step(t):
    steps = np.diff(t)
    if steps.size and np.all(np.abs(steps - steps[0]) <= 1e-9 * abs(steps[0])):
        return float(steps[0])
    return None


def _propagate(Ad, drive, x0):
    """``x_0 = x0``, ``x_{k+1} = Ad x_k + drive_k``: states (n, samples)."""
    n, count = drive.shape[0], drive.shape[1] + 1
    values, vectors = np.linalg.eig(Ad)
    if np.linalg.cond(vectors) <= MODAL_CONDITION:
        from scipy.signal import lfilter

        inverse = np.linalg.inv(vectors)
        w = np.empty((n, count), dtype=complex)
        w[:, 0] = inverse @ x0
        w[:, 1:] = inverse @ drive
        z = np.empty_like(w)
        for i, lam in enumerate(values):
            z[i] = lfilter([1.0], [1.0, -lam], w[i])
        x = vectors @ z
        return x.real
    x = np.empty((n, count))
    x[:, 0] = x0
    for k in range(count - 1):
        x[:, k + 1] = Ad @ x[:, k] + drive[:, k]
    return x


def simulate_system(equations, values, time, inputs, *, initial_state=None):
    """Simulate a system of model equations driven by sampled inputs.

    A linear system holds each input linear between samples (first-order hold), for
    which the simulation is exact (:mod:`algid.simulation._system`).  A system
    nonlinear in its signals (``x1**3``, ``sign(x2')``) is integrated by DOP853 with
    relative tolerance 1e-8, its inputs interpolated as band-limited signals (a cubic
    spline on a non-uniform grid), as :func:`algid.simulation.simulate_model` does
    (:mod:`algid.simulation._system_equations`).

    Parameters
    ----------
    equations : sequence of str, or algid.models.SystemModel
        The equations, one output each (as for :func:`algid.identify`).
    values : mapping
        Parameter name -> value, for every parameter of the equations.
    time : array_like
        Sample times (s), increasing.
    inputs : mapping
        Input name -> samples.
    initial_state : array_like, optional
        Each output and its derivatives below its order, output by output (zero by
        default).

    Returns
    -------
    dict
        Output name -> simulated samples; for a nonlinear system, NaN from where the
        integration failed (the system diverges, or leaves a function's domain).

    Raises
    ------
    ModelError, InputDataError
        A top derivative inside a nonlinear factor, a missing or non-finite input, bad
        times.

    Examples
    --------
    >>> import numpy as np
    >>> from algid.simulation import simulate_system
    >>> t = np.linspace(0.0, 5.0, 501)
    >>> y = simulate_system(["x1' + a*x1 = u", "x2' + x2 = x1"], {"a": 2.0}, t,
    ...                     {"u": np.ones_like(t)})
    >>> round(float(y["x1"][-1]), 4), round(float(y["x2"][-1]), 3)
    (0.5, 0.493)
    """
    from algid.models._system import parse_system
    from algid.simulation._model import as_floats, check_time_and_inputs

    if not hasattr(values, "keys"):
        raise InputDataError(f"values must be a mapping of parameter name -> value, got "
                             f"{type(values).__name__}")
    system = parse_system(equations, list(values))
    checked = {}
    for p, v in values.items():
        v = as_floats(v, f"parameter {p}")
        if v.shape != () or not np.isfinite(v):
            raise InputDataError(f"parameter {p} must be one finite number, got {v!r:.40}")
        checked[p] = float(v)
    values = checked
    t, inputs = check_time_and_inputs(time, inputs, system.inputs)
    if not system.is_linear:
        from algid.simulation._system_equations import (
            SystemEquations,
            simulate_nonlinear_system,
        )

        equations = SystemEquations(system, values)
        with np.errstate(over="ignore", invalid="ignore"):
            outputs = simulate_nonlinear_system(equations, t, inputs, initial_state)
        return dict(zip(equations.outputs, outputs))
    space = state_space(system, values)
    if initial_state is not None:
        initial_state = np.asarray(initial_state, dtype=float).ravel()
        if initial_state.shape != (len(space.states),) or \
                not np.all(np.isfinite(initial_state)):
            raise InputDataError(f"initial_state must hold {len(space.states)} finite "
                                 f"values ({', '.join(y + chr(39) * k for y, k in space.states)})")
    return dict(zip(space.outputs, simulate_space(space, t, inputs, initial_state)))


def simulate_space(space, t, inputs, initial_state=None):
    """Simulate a state-space system on sampled inputs (first-order hold, exact).

    Parameters
    ----------
    space : StateSpace
        From :func:`state_space`.
    t : numpy.ndarray
        Sample times (increasing).
    inputs : mapping
        Input name -> samples (the measured inputs of ``space.channels``).
    initial_state : numpy.ndarray, optional
        The state at ``t[0]`` (zero by default).

    Returns
    -------
    numpy.ndarray, shape (outputs, samples)
    """
    t = np.asarray(t, dtype=float)
    n = space.A.shape[0]
    x0 = np.zeros(n) if initial_state is None else np.asarray(initial_state, dtype=float)
    u = _channel_values(space.channels, t, inputs)
    step = _uniform_step(t)
    if step is not None:
        Ad, Bd0, Bd1 = _discretise(space.A, space.B, step)
        drive = Bd0 @ u[:, :-1] + Bd1 @ u[:, 1:]
        return space.C @ _propagate(Ad, drive, x0)
    x = np.empty((n, len(t)))
    x[:, 0] = x0
    cache = {}
    for k in range(len(t) - 1):
        h = float(t[k + 1] - t[k])
        if h not in cache:
            cache[h] = _discretise(space.A, space.B, h)
        Ad, Bd0, Bd1 = cache[h]
        x[:, k + 1] = Ad @ x[:, k] + Bd0 @ u[:, k] + Bd1 @ u[:, k + 1]
    return space.C @ x


def free_responses(space, t):
    """The outputs' response to each unit initial state without input.

    Parameters
    ----------
    space : StateSpace
    t : numpy.ndarray
        Sample times.

    Returns
    -------
    numpy.ndarray, shape (states, outputs, samples)
    """
    t = np.asarray(t, dtype=float)
    n = space.A.shape[0]
    values, vectors = np.linalg.eig(space.A)
    if np.linalg.cond(vectors) <= MODAL_CONDITION:
        # C exp(A t) = (C V) exp(Lambda t) V^-1: one exponential per mode
        modes = np.exp(np.outer(values, t - t[0]))            # (n, samples)
        left, right = space.C @ vectors, np.linalg.inv(vectors)
        return np.einsum("oi,is,ik->kos", left, modes, right).real
    zero = StateSpace(space.A, np.zeros((n, 0)), space.C, space.states, [], space.outputs)
    return np.array([simulate_space(zero, t, {}, np.eye(n)[i]) for i in range(n)])


def fit_initial_state(space, t, inputs, measured, fit_samples):
    """The initial state that best fits the measured outputs on the first samples.

    Least squares over the measured outputs (every output, or those of ``measured``
    where some are hidden), each weighted by the inverse of its spread.

    Parameters
    ----------
    space : StateSpace
    t : numpy.ndarray
    inputs : mapping
    measured : mapping
        Output name -> measured samples (of some or all outputs).
    fit_samples : int

    Returns
    -------
    initial_state : numpy.ndarray
    forced : numpy.ndarray
        The forced response (outputs, samples), to which the free response of
        ``initial_state`` adds.
    free : numpy.ndarray
        :func:`free_responses`.
    """
    forced = simulate_space(space, t, inputs)
    free = free_responses(space, t)
    rows, rhs = [], []
    for y in measured:
        j = space.outputs.index(y)
        v = np.asarray(measured[y], dtype=float)
        scale = float(np.std(v)) or 1.0
        rows.append(free[:, j, :fit_samples].T / scale)
        rhs.append((v[:fit_samples] - forced[j, :fit_samples]) / scale)
    x0 = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    if not np.all(np.isfinite(x0)):
        raise InputDataError("the initial state cannot be fitted on these samples")
    return x0, forced, free
