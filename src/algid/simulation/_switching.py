"""Simulation across the switches of ``sign()`` of the simulated state (Filippov).

In ``M*q'' + Fv*q' + Fc*sign(q') + off = F`` the right-hand side jumps by ``2 Fc / M``
where the velocity crosses zero.  An adaptive integrator that meets the jump shrinks its
step to rounding at every crossing; and where the jump points the state back towards
``q' = 0`` from both sides (the mass held by Coulomb friction, ``|F - off| < Fc``) the
sign flips at every step and the integrator crawls.

Here every ``sign(a)`` whose argument ``a`` reads the simulated state is a *mode*, +1
or -1, held constant between switches, so that each piece is smooth and is integrated
by the chosen :func:`scipy.integrate.solve_ivp` method, and the switches are located as
events (where ``a`` crosses zero).  At a switch the next mode is decided from the rate
``da/dt`` under either mode:

- both positive (negative): the state crosses to the positive (negative) side;
- ``da/dt <= 0`` under +1 and ``>= 0`` under -1, both flows towards the surface: the
  state slides on ``a = 0`` with Filippov's convex combination of the two right-hand
  sides that keeps ``da/dt = 0`` (for ``sign(q')``: the mass sticks, ``q'' = 0``).
  The sliding ends where one of the two rates changes sign (the force overcomes the
  friction), and the state leaves to that side.

Only one switch slides at a time; a second one that would slide at once takes the side
of the sum of its rates, and if that chatters the caller's bound on the right-hand
side's evaluations stops the integration.  ``da/dt`` is exact when ``a`` is a
derivative of the output (``sign(q')``); otherwise a central difference along the flow.
"""

from __future__ import annotations

import numpy as np

__all__ = ["integrate_switched"]

#: Step of the central difference of ``da/dt``, as a fraction of the sampling step.
RATE_STEP = 1e-3


class _Pieces:
    """The right-hand side and the events of each smooth piece of a switched model.

    ``equation`` provides ``order``, ``plain_switches`` (for each switch the order of
    the output derivative that is its argument, or None), ``top(time, state, modes)``
    (the highest derivative with the switches held at ``modes``) and
    ``switch_argument(j, time, state)``.
    """

    def __init__(self, equation, step, tick):
        self.equation = equation
        self.order = equation.order
        self.h = RATE_STEP * step
        self.tick = tick  # called with the time at each right-hand-side evaluation

    def top(self, time, state, modes, sliding):
        """The highest derivative; on the surface of switch ``sliding`` the Filippov
        combination that keeps its argument's rate at zero."""
        if sliding is None:
            return self.equation.top(time, state, modes)
        up_modes, down_modes = _with(modes, sliding, 1.0), _with(modes, sliding, -1.0)
        up = self.rate(sliding, time, state, up_modes, None)
        down = self.rate(sliding, time, state, down_modes, None)
        weight = 0.5 if down == up else min(max(down / (down - up), 0.0), 1.0)
        return (weight * self.equation.top(time, state, up_modes)
                + (1.0 - weight) * self.equation.top(time, state, down_modes))

    def rate(self, j, time, state, modes, sliding):
        """``da/dt`` of switch ``j``'s argument along the flow of the given modes."""
        k = self.equation.plain_switches[j]
        if k is not None:
            return state[k + 1] if k + 1 < self.order else self.top(time, state, modes, sliding)
        state = np.asarray(state, dtype=float)
        flow = np.append(state[1:], self.top(time, state, modes, sliding))
        h, argument = self.h, self.equation.switch_argument
        return (argument(j, time + h, state + h * flow)
                - argument(j, time - h, state - h * flow)) / (2.0 * h)

    def piece(self, modes, sliding):
        """``(rhs, events, owners)`` of the piece with the given modes and sliding."""
        def rhs(time, state):
            self.tick(time)
            derivative = np.empty(self.order)
            derivative[:-1] = state[1:]
            derivative[-1] = self.top(time, state, modes, sliding)
            return derivative

        events, owners = [], []
        for j, mode in enumerate(modes):
            if j == sliding:
                for side in (1.0, -1.0):  # leaves when the rate under `side` turns outwards
                    events.append(self._event(lambda time, state, j=j, side=side: self.rate(
                        j, time, state, _with(modes, j, side), None), side))
                    owners.append(("leave", j, side))
            else:
                events.append(self._event(lambda time, state, j=j:
                                          self.equation.switch_argument(j, time, state), -mode))
                owners.append(("cross", j, mode))
        return rhs, events, owners

    @staticmethod
    def _event(function, direction):
        function.terminal = True
        function.direction = direction
        return function

    def decide(self, j, time, state, modes, sliding, previous):
        """The modes and sliding switch after switch ``j``'s argument reached zero."""
        up = self.rate(j, time, state, _with(modes, j, 1.0), sliding)
        down = self.rate(j, time, state, _with(modes, j, -1.0), sliding)
        if up > 0 and down > 0:
            return _with(modes, j, 1.0), sliding
        if up < 0 and down < 0:
            return _with(modes, j, -1.0), sliding
        if sliding is None and up <= 0 <= down and up < down:
            return modes, j
        # tangent, repelling or a second sliding switch: cross on
        side = -previous if previous else (1.0 if up + down >= 0 else -1.0)
        return _with(modes, j, side), sliding

    def start(self, time, state):
        """Modes (and sliding switch) at the first sample."""
        values = [self.equation.switch_argument(j, time, state)
                  for j in range(len(self.equation.plain_switches))]
        modes = [1.0 if v >= 0 else -1.0 for v in values]
        sliding = None
        for j, value in enumerate(values):
            if value == 0:
                modes, sliding = self.decide(j, time, state, modes, sliding, None)
        return modes, sliding


def _with(modes, j, value):
    changed = list(modes)
    changed[j] = value
    return changed


def integrate_switched(equation, t, state, method, rtol, atol, tick):
    """Integrate piecewise between the switches; the states at the sample times.

    Parameters
    ----------
    equation : object
        The model solved for its highest derivative, with the switch interface of
        ``_Pieces``.
    t : numpy.ndarray
        Sample times.
    state : numpy.ndarray
        The state at ``t[0]``.
    method : str
        The :func:`scipy.integrate.solve_ivp` method of each piece.
    rtol, atol : float
        Its tolerances.
    tick : callable
        Called with the time at each right-hand-side evaluation (the caller's bound on
        the work).

    Returns
    -------
    numpy.ndarray
        ``order`` x ``len(t)``; NaN from where the integration failed.
    """
    pieces = _Pieces(equation, (t[-1] - t[0]) / (len(t) - 1), tick)
    out = np.full((equation.order, len(t)), np.nan)
    out[:, 0] = state
    now, filled = float(t[0]), 1
    modes, sliding = pieces.start(now, state)
    while filled < len(t):
        rhs, events, owners = pieces.piece(modes, sliding)
        from scipy.integrate import solve_ivp

        solution = solve_ivp(rhs, (now, t[-1]), state, method=method, t_eval=t[filled:],
                             events=events or None, rtol=rtol, atol=atol)
        # an event before the first sample time leaves no sample: SciPy then gives a list
        y = np.asarray(solution.y, dtype=float).reshape(equation.order, -1)
        reached = y.shape[1]
        out[:, filled:filled + reached] = y
        filled += reached
        if solution.status != 1 or not np.isfinite(y[:, -1:]).all():
            break  # done, or failed (a diverging model): NaN from there on
        which = next(i for i, times in enumerate(solution.t_events) if times.size)
        now = float(solution.t_events[which][0])
        state = np.array(solution.y_events[which][0], dtype=float)
        kind, j, side = owners[which]
        if kind == "leave":
            modes, sliding = _with(modes, j, side), None
        else:
            modes, sliding = pieces.decide(j, now, state, modes, sliding, side)
    return out
