"""The compiled loops of :class:`algid.simulation._fast_simulation.FastSimulation` and
:class:`~algid.simulation._fast_simulation.FastSystemSimulation`.

Classical Runge-Kutta steps of a model solved for the highest derivative of its output,
its state terms run as stack-machine code (:func:`algid.simulation._fast_simulation.program`),
``sign()`` switches located within the step and Coulomb sticking as sliding; the
mathematics is described there.  Imported only when numba is.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from algid._compile_notice import watch

watch()   # a line on stderr while numba compiles these for more than a second

__all__ = ["simulate_output", "simulate_system_outputs"]

_jit = numba.njit(cache=True, nogil=True, error_model="numpy")
_inline = numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")


@_jit
def _function(code, v):
    if code == 0:
        return 1.0 if v > 0 else (-1.0 if v < 0 else 0.0)
    if code == 1:
        return abs(v)
    if code == 2:
        return math.tanh(v)
    if code == 3:
        return math.sin(v)
    if code == 4:
        return math.cos(v)
    if code == 5:
        return math.tan(v)
    if code == 6:
        return math.exp(v) if v < 709.0 else math.inf
    if code == 7:
        return math.log(v) if v > 0 else (-math.inf if v == 0 else math.nan)
    if code == 8:
        return math.sqrt(v) if v >= 0 else math.nan
    if code == 9:
        return math.sinh(v) if abs(v) < 709.0 else math.copysign(math.inf, v)
    if code == 10:
        return math.cosh(v) if abs(v) < 709.0 else math.inf
    return math.atan(v)


@_jit
def _power(base, exponent):
    if exponent == math.floor(exponent) and abs(exponent) < 64:
        n = int(abs(exponent))
        result = 1.0
        for _ in range(n):
            result *= base
        return result if exponent >= 0 else 1.0 / result
    if base < 0:
        return math.nan
    return base ** exponent


@_inline
def _term(ops, args, start, end, x, u, time, modes, stack):
    sp = 0
    for q in range(start, end):
        op = ops[q]
        if op == 0:
            stack[sp] = args[q]
            sp += 1
        elif op == 1:
            stack[sp] = x[int(args[q])]
            sp += 1
        elif op == 2:
            stack[sp] = u[int(args[q])]
            sp += 1
        elif op == 3:
            stack[sp] = time
            sp += 1
        elif op == 4:
            stack[sp] = modes[int(args[q])]
            sp += 1
        elif op == 5:
            sp -= 1
            stack[sp - 1] += stack[sp]
        elif op == 6:
            sp -= 1
            stack[sp - 1] *= stack[sp]
        elif op == 7:
            stack[sp - 1] = _power(stack[sp - 1], args[q])
        else:
            stack[sp - 1] = _function(int(args[q]), stack[sp - 1])
    return stack[0]


@_inline
def _top(ops, args, starts, weights, top_weight, x, force, u, time, modes, stack):
    total = force
    for j in range(len(weights)):
        total += weights[j] * _term(ops, args, starts[j], starts[j + 1], x, u, time, modes,
                                    stack)
    return -total / top_weight


@_inline
def _at(forcing, inputs, p, tau, u):
    """The forcing at fraction ``tau`` of the step whose points start at ``p`` (the
    quadratic through its start, middle and end), and the inputs into ``u``."""
    l0 = 2.0 * (tau - 0.5) * (tau - 1.0)
    l1 = -4.0 * tau * (tau - 1.0)
    l2 = 2.0 * tau * (tau - 0.5)
    for j in range(inputs.shape[0]):
        u[j] = l0 * inputs[j, p] + l1 * inputs[j, p + 1] + l2 * inputs[j, p + 2]
    return l0 * forcing[p] + l1 * forcing[p + 1] + l2 * forcing[p + 2]


@_inline
def _flow(ops, args, starts, weights, top_weight, x, force, u, time, modes, stack, dx):
    n = x.shape[0]
    for i in range(n - 1):
        dx[i] = x[i + 1]
    dx[n - 1] = _top(ops, args, starts, weights, top_weight, x, force, u, time, modes,
                     stack)


def _rk4_step(ops, args, starts, weights, top_weight, forcing, inputs, p, t0, h, tau0, tau1,
         x, modes, stack, u, k1, k2, k3, k4, tmp):
    """One Runge-Kutta step from fraction ``tau0`` to ``tau1`` of the step at ``p``
    (of length ``h``, starting at ``t0``); ``x`` is advanced in place."""
    n = x.shape[0]
    dt = (tau1 - tau0) * h
    f = _at(forcing, inputs, p, tau0, u)
    _flow(ops, args, starts, weights, top_weight, x, f, u, t0 + tau0 * h, modes, stack, k1)
    for i in range(n):
        tmp[i] = x[i] + 0.5 * dt * k1[i]
    tm = 0.5 * (tau0 + tau1)
    f = _at(forcing, inputs, p, tm, u)
    _flow(ops, args, starts, weights, top_weight, tmp, f, u, t0 + tm * h, modes,
          stack, k2)
    for i in range(n):
        tmp[i] = x[i] + 0.5 * dt * k2[i]
    _flow(ops, args, starts, weights, top_weight, tmp, f, u, t0 + tm * h, modes,
          stack, k3)
    for i in range(n):
        tmp[i] = x[i] + dt * k3[i]
    f = _at(forcing, inputs, p, tau1, u)
    _flow(ops, args, starts, weights, top_weight, tmp, f, u, t0 + tau1 * h, modes,
          stack, k4)
    for i in range(n):
        x[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


def _rate_at(ops, args, starts, weights, top_weight, forcing, inputs, p, t0, h, tau, x,
          modes, j, side, switches, stack, u):
    """``d/dt`` of switch ``j``'s argument at ``x`` with its mode set to ``side``."""
    k = switches[j]
    if k + 1 < x.shape[0]:
        return x[k + 1]
    held = modes[j]
    modes[j] = side
    f = _at(forcing, inputs, p, tau, u)
    value = _top(ops, args, starts, weights, top_weight, x, f, u, t0 + tau * h, modes,
                 stack)
    modes[j] = held
    return value


_rk4 = _jit(_rk4_step)
_rate = _jit(_rate_at)


@_jit
def _slide(x, dt):
    """``dt`` along the surface ``y^(n-1) = 0`` (the lower derivatives a polynomial)."""
    n = x.shape[0]
    x[n - 1] = 0.0
    for i in range(n - 1):       # ascending: each uses the higher ones not yet moved
        term, factor = 0.0, 1.0
        for m in range(1, n - i):
            factor *= dt / m
            term += x[i + m] * factor
        x[i] += term


@_jit
def _hermite_root(a0, a1, d0, d1):
    """The fraction in (0, 1] where the cubic Hermite interpolant of values ``a0, a1``
    and slopes ``d0, d1`` (per unit fraction) first reaches zero (bisection)."""
    lo, hi = 0.0, 1.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        s = mid
        h00 = (1 + 2 * s) * (1 - s) ** 2
        h10 = s * (1 - s) ** 2
        h01 = s * s * (3 - 2 * s)
        h11 = s * s * (s - 1)
        value = h00 * a0 + h10 * d0 + h01 * a1 + h11 * d1
        if (value > 0) == (a0 > 0) and value != 0:
            lo = mid
        else:
            hi = mid
    return hi


@_jit
def _quadratic_root(r0, rm, r1):
    """The first fraction in (0, 1] where the quadratic through ``r0, rm, r1`` (at 0,
    1/2, 1) changes sign from that of ``r0`` (bisection)."""
    lo, hi = 0.0, 1.0
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        value = (2.0 * (mid - 0.5) * (mid - 1.0) * r0 - 4.0 * mid * (mid - 1.0) * rm
                 + 2.0 * mid * (mid - 0.5) * r1)
        if (value > 0) == (r0 > 0) and value != 0:
            lo = mid
        else:
            hi = mid
    return hi


@_jit
def _decide(ops, args, starts, weights, top_weight, forcing, inputs, p, t0, h, tau, x,
            modes, j, previous, switches, stack, u):
    """The mode of switch ``j`` once its argument reached zero, or 2.0: slide."""
    up = _rate(ops, args, starts, weights, top_weight, forcing, inputs, p, t0, h, tau, x,
               modes, j, 1.0, switches, stack, u)
    down = _rate(ops, args, starts, weights, top_weight, forcing, inputs, p, t0, h, tau,
                 x, modes, j, -1.0, switches, stack, u)
    if up > 0 and down > 0:
        return 1.0
    if up < 0 and down < 0:
        return -1.0
    if switches[j] == x.shape[0] - 1 and up <= 0 <= down and up < down:
        return 2.0
    return -previous


@_jit
def _steps(ops, args, starts, weights, top_weight, forcing, inputs, switches, x, modes,
           sliding, stack, u, k1, k2, k3, k4, tmp, start, t0, h, substeps, first, total,
           out):
    """Runge-Kutta steps ``first, first + 1, ...`` until one meets a switch (``x`` back
    at its start; its index returned) or ``total`` (returned); the output written at
    every sample reached.  ``-1 - i`` where the state diverged at sample ``i``."""
    n = x.shape[0]
    for g in range(first, total):
        p = 2 * g
        ts = t0 + g * h
        for q in range(n):
            start[q] = x[q]
        event = False
        if sliding >= 0:
            _slide(x, h)
            up = _rate(ops, args, starts, weights, top_weight, forcing, inputs, p,
                       ts, h, 1.0, x, modes, sliding, 1.0, switches, stack, u)
            down = _rate(ops, args, starts, weights, top_weight, forcing, inputs, p,
                         ts, h, 1.0, x, modes, sliding, -1.0, switches, stack, u)
            event = up > 0 or down < 0
        else:
            _rk4(ops, args, starts, weights, top_weight, forcing, inputs, p, ts, h, 0.0, 1.0,
                 x, modes, stack, u, k1, k2, k3, k4, tmp)
            for j in range(switches.shape[0]):
                if x[switches[j]] * modes[j] < 0:
                    event = True
        if event:
            for q in range(n):
                x[q] = start[q]
            return g
        if (g + 1) % substeps == 0:
            for q in range(n):
                if not abs(x[q]) < 1e150:
                    return -1 - (g + 1) // substeps
            out[(g + 1) // substeps] = x[0]
    return total


@_jit
def _leave(ops, args, starts, weights, top_weight, forcing, inputs, switches, x, modes,
           sliding, stack, u, k1, k2, k3, k4, tmp, start, p, ts, h):
    """The step at ``p`` in which the state leaves sliding on switch ``sliding``: to the
    time the force overcomes the friction, then on in the mode it turns to."""
    n = x.shape[0]
    j = sliding
    for q in range(n):
        start[q] = x[q]
    _slide(x, h)
    up1 = _rate(ops, args, starts, weights, top_weight, forcing, inputs, p, ts, h, 1.0, x,
                modes, j, 1.0, switches, stack, u)
    side = 1.0 if up1 > 0 else -1.0
    r1 = up1 if side > 0 else _rate(ops, args, starts, weights, top_weight, forcing,
                                    inputs, p, ts, h, 1.0, x, modes, j, -1.0, switches,
                                    stack, u)
    r0 = _rate(ops, args, starts, weights, top_weight, forcing, inputs, p, ts, h, 0.0,
               start, modes, j, side, switches, stack, u)
    for q in range(n):
        tmp[q] = 0.5 * (start[q] + x[q])
    rm = _rate(ops, args, starts, weights, top_weight, forcing, inputs, p, ts, h, 0.5, tmp,
               modes, j, side, switches, stack, u)
    tau = 0.0 if (r0 > 0) == (side > 0) and r0 != 0 else _quadratic_root(r0, rm, r1)
    for q in range(n):
        x[q] = start[q]
    _slide(x, tau * h)
    modes[j] = side
    _rk4(ops, args, starts, weights, top_weight, forcing, inputs, p, ts, h, tau, 1.0, x,
         modes, stack, u, k1, k2, k3, k4, tmp)


@_jit
def _cross(ops, args, starts, weights, top_weight, forcing, inputs, switches, x, modes,
           stack, u, k1, k2, k3, k4, tmp, start, p, ts, h):
    """The step at ``p`` in which the argument of a switch reaches zero: to the first
    crossing (on the step's cubic Hermite interpolant), then on in the new mode or
    sliding.  Returns the switch that slides, or -1."""
    n = x.shape[0]
    for q in range(n):
        start[q] = x[q]
    _rk4(ops, args, starts, weights, top_weight, forcing, inputs, p, ts, h, 0.0, 1.0, x,
         modes, stack, u, k1, k2, k3, k4, tmp)
    first, first_tau = -1, 2.0
    for j in range(switches.shape[0]):
        k = switches[j]
        if x[k] * modes[j] < 0:
            a0 = start[k]
            if a0 * modes[j] <= 0:
                tau = 0.0
            else:
                d0 = _rate(ops, args, starts, weights, top_weight, forcing, inputs, p, ts,
                           h, 0.0, start, modes, j, modes[j], switches, stack, u) * h
                d1 = _rate(ops, args, starts, weights, top_weight, forcing, inputs, p, ts,
                           h, 1.0, x, modes, j, modes[j], switches, stack, u) * h
                tau = _hermite_root(a0, x[k], d0, d1)
            if tau < first_tau:
                first, first_tau = j, tau
    j, tau = first, first_tau
    for q in range(n):
        x[q] = start[q]
    _rk4(ops, args, starts, weights, top_weight, forcing, inputs, p, ts, h, 0.0, tau, x,
         modes, stack, u, k1, k2, k3, k4, tmp)
    x[switches[j]] = 0.0
    sliding = -1
    mode = _decide(ops, args, starts, weights, top_weight, forcing, inputs, p, ts, h, tau,
                   x, modes, j, modes[j], switches, stack, u)
    if mode == 2.0:
        sliding = j
        _slide(x, (1.0 - tau) * h)
    else:
        modes[j] = mode
        _rk4(ops, args, starts, weights, top_weight, forcing, inputs, p, ts, h, tau, 1.0,
             x, modes, stack, u, k1, k2, k3, k4, tmp)
    return sliding


@_jit
def simulate_output(ops, args, starts, weights, top_weight, forcing, inputs, switches,
                    depth, x0, t0, step, substeps, n_samples, out):
    """Simulate, writing the output at the samples into ``out``; NaN once it diverges.

    Parameters
    ----------
    ops, args, starts : numpy.ndarray
        The state terms' stack-machine code
        (:class:`~algid.simulation._fast_simulation.Program`).
    weights : numpy.ndarray
        Each state term's weight.
    top_weight : float
        The weight of the highest derivative of the output.
    forcing : numpy.ndarray, shape ((n_samples - 1) * 2 * substeps + 1,)
        The weighted sum of the terms that do not read the output, at every step and
        half step.
    inputs : numpy.ndarray, shape (m, same)
        The inputs the state terms read, at the same points.
    switches : numpy.ndarray of int64
        Per switch, the derivative of the output it reads.
    depth : int
        Stack depth.
    x0 : numpy.ndarray
        The initial state ``(y, y', ..., y^(n-1))``.
    t0, step : float
        The first sample's time, the sampling step.
    substeps : int
        Runge-Kutta steps per sampling step.
    n_samples : int
    out : numpy.ndarray, shape (n_samples,)

    Returns
    -------
    int
        The number of samples simulated (``n_samples`` unless it diverged).
    """
    n = x0.shape[0]
    x = x0.copy()
    stack = np.zeros(depth + 1)
    u = np.zeros(inputs.shape[0])
    k1, k2, k3, k4 = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    tmp, start = np.zeros(n), np.zeros(n)
    modes = np.ones(switches.shape[0])
    sliding = -1
    h = step / substeps
    for j in range(switches.shape[0]):
        modes[j] = 1.0 if x[switches[j]] >= 0 else -1.0
    for j in range(switches.shape[0]):
        if x[switches[j]] == 0 and sliding < 0:
            mode = _decide(ops, args, starts, weights, top_weight, forcing, inputs, 0, t0,
                           h, 0.0, x, modes, j, 1.0, switches, stack, u)
            if mode == 2.0:
                sliding = j
            else:
                modes[j] = mode
    out[0] = x[0]
    total = (n_samples - 1) * substeps
    g = 0
    while g < total:
        g = _steps(ops, args, starts, weights, top_weight, forcing, inputs, switches, x,
                   modes, sliding, stack, u, k1, k2, k3, k4, tmp, start, t0, h, substeps, g,
                   total, out)
        if g < 0:                       # diverged at sample -1 - g
            for q in range(-1 - g, n_samples):
                out[q] = math.nan
            return -1 - g
        if g == total:
            break
        if sliding >= 0:
            _leave(ops, args, starts, weights, top_weight, forcing, inputs, switches, x,
                   modes, sliding, stack, u, k1, k2, k3, k4, tmp, start, 2 * g, t0 + g * h,
                   h)
            sliding = -1
        else:
            sliding = _cross(ops, args, starts, weights, top_weight, forcing, inputs,
                             switches, x, modes, stack, u, k1, k2, k3, k4, tmp, start,
                             2 * g, t0 + g * h, h)
        g += 1
        if g % substeps == 0:
            for q in range(n):
                if not abs(x[q]) < 1e150:
                    for r in range(g // substeps, n_samples):
                        out[r] = math.nan
                    return g // substeps
            out[g // substeps] = x[0]
    return n_samples


@_inline
def _system_flow(ops, args, starts, gain, forcing, inputs, point, tops, chains, x, time,
                 modes, stack, u, g, dx):
    """The derivative of a system's state at fine point ``point`` into ``dx``."""
    for j in range(inputs.shape[0]):
        u[j] = inputs[j, point]
    for j in range(g.shape[0]):
        g[j] = _term(ops, args, starts[j], starts[j + 1], x, u, time, modes, stack)
    for c in range(chains.shape[0]):
        dx[chains[c, 0]] = x[chains[c, 1]]
    for o in range(tops.shape[0]):
        total = forcing[o, point]
        for j in range(g.shape[0]):
            total += gain[o, j] * g[j]
        dx[tops[o]] = total


@_jit
def simulate_system_outputs(ops, args, starts, gain, forcing, inputs, tops, chains, outputs,
                            depth, x0, t0, step, substeps, n_samples, out):
    """Simulate a system solved for its top derivatives, writing its outputs at the
    samples into ``out``; NaN once it diverges.

    Parameters
    ----------
    ops, args, starts : numpy.ndarray
        The state terms' stack-machine code
        (:class:`~algid.simulation._fast_simulation.Program`).
    gain : numpy.ndarray, shape (outputs, terms)
        Each state term's weight in each top derivative (the equations solved).
    forcing : numpy.ndarray, shape (outputs, (n_samples - 1) * 2 * substeps + 1)
        The terms that do not read an output, solved likewise, at every step and half
        step.
    inputs : numpy.ndarray, shape (m, same)
        The inputs the state terms read, at the same points.
    tops : numpy.ndarray of int64
        Per output, the state that its top derivative is the derivative of.
    chains : numpy.ndarray of int64, shape (c, 2)
        ``(i, j)``: state ``i``'s derivative is state ``j``.
    outputs : numpy.ndarray of int64
        The states written into ``out``.
    depth : int
        Stack depth.
    x0 : numpy.ndarray
        The initial state.
    t0, step : float
        The first sample's time, the sampling step.
    substeps : int
        Runge-Kutta steps per sampling step.
    n_samples : int
    out : numpy.ndarray, shape (len(outputs), n_samples)

    Returns
    -------
    int
        The number of samples simulated (``n_samples`` unless it diverged).
    """
    n = x0.shape[0]
    x = x0.copy()
    stack = np.zeros(depth + 1)
    u = np.zeros(inputs.shape[0])
    g = np.zeros(starts.shape[0] - 1)
    modes = np.zeros(0)
    k1, k2, k3, k4, tmp = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    h = step / substeps
    for o in range(outputs.shape[0]):
        out[o, 0] = x[outputs[o]]
    for k in range(1, n_samples):
        for j in range(substeps):
            p = 2 * ((k - 1) * substeps + j)
            time = t0 + ((k - 1) * substeps + j) * h
            _system_flow(ops, args, starts, gain, forcing, inputs, p, tops, chains, x, time,
                         modes, stack, u, g, k1)
            for i in range(n):
                tmp[i] = x[i] + 0.5 * h * k1[i]
            _system_flow(ops, args, starts, gain, forcing, inputs, p + 1, tops, chains, tmp,
                         time + 0.5 * h, modes, stack, u, g, k2)
            for i in range(n):
                tmp[i] = x[i] + 0.5 * h * k2[i]
            _system_flow(ops, args, starts, gain, forcing, inputs, p + 1, tops, chains, tmp,
                         time + 0.5 * h, modes, stack, u, g, k3)
            for i in range(n):
                tmp[i] = x[i] + h * k3[i]
            _system_flow(ops, args, starts, gain, forcing, inputs, p + 2, tops, chains, tmp,
                         time + h, modes, stack, u, g, k4)
            for i in range(n):
                x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        for i in range(n):
            if not abs(x[i]) < 1e150:
                for q in range(k, n_samples):
                    for o in range(outputs.shape[0]):
                        out[o, q] = math.nan
                return k
        for o in range(outputs.shape[0]):
            out[o, k] = x[outputs[o]]
    return n_samples
