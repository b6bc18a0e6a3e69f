"""Simulation across the switches of sign() of the simulated state (algid.simulation._switching):
stick-slip against its closed form, and the bound on the integrator's work."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from algid.errors import ModelError
from algid.models._grammar import parse_equation
from algid.simulation import _model as model_simulation
from algid.simulation._model import simulate_model

FRICTION = parse_equation("M*q'' + Fv*q' + Fc*sign(q') + off = F", "M Fv Fc off")


def stick_slip(t, *, mass, coulomb, amplitude, omega):
    """Exact ``q(t)`` of ``M q'' + Fc sign(q') = A sin(w t)`` from rest at ``q = 0``.

    Stuck while ``|A sin(w t)| <= Fc``; then moving in the direction of the force, with
    ``v(s) = A (cos(w s0) - cos(w s)) / (M w) - d Fc (s - s0) / M``, until ``v = 0``;
    the phases' ends are roots found by brentq on a fine grid.
    """
    def force(s):
        return amplitude * np.sin(omega * s)

    grid = np.linspace(0.0, t[-1], 200001)
    q = np.empty_like(t)
    now, position = 0.0, 0.0
    while True:
        ahead = grid[grid > now]
        slipping = np.abs(force(ahead)) > coulomb
        if not slipping.any():
            q[t >= now] = position
            return q
        k = int(np.argmax(slipping))
        start = now if k == 0 else brentq(lambda s: abs(force(s)) - coulomb, ahead[k - 1],
                                          ahead[k])
        q[(t >= now) & (t < start)] = position
        direction = np.sign(force(ahead[k]))
        c0, s0, q0 = np.cos(omega * start), np.sin(omega * start), position

        def velocity(s, c0=c0, start=start, direction=direction):
            return (amplitude * (c0 - np.cos(omega * s)) / (mass * omega)
                    - direction * coulomb * (s - start) / mass)

        def place(s, c0=c0, s0=s0, q0=q0, start=start, direction=direction):
            return (q0 + amplitude / (mass * omega) * ((s - start) * c0
                                                       - (np.sin(omega * s) - s0) / omega)
                    - direction * coulomb * (s - start) ** 2 / (2 * mass))

        moving = grid[grid > start + 1e-9]
        stops = np.flatnonzero(np.sign(velocity(moving)) != direction)
        stop = t[-1] if stops.size == 0 else brentq(velocity, moving[stops[0] - 1],
                                                    moving[stops[0]])
        inside = (t >= start) & (t <= stop)
        q[inside] = place(t[inside])
        if stops.size == 0:
            return q
        now, position = stop, place(stop)


@pytest.fixture(scope="module")
def sticking():
    t = np.arange(6001) * 1e-3
    q = stick_slip(t, mass=1.0, coulomb=1.0, amplitude=1.3, omega=np.pi)
    stuck = np.diff(q) == 0
    # the force stays below the friction at most stops: 7 stuck phases, 1950 samples
    assert np.sum(np.diff(stuck.astype(int)) == 1) + stuck[0] >= 5
    return t, 1.3 * np.sin(np.pi * t), q


def test_stick_slip_follows_the_closed_form(sticking):
    t, force, exact = sticking
    values = {"M": 1.0, "Fv": 0.0, "Fc": 1.0, "off": 0.0}
    simulated = simulate_model(FRICTION, values, t, {"F": force}, initial_state=[0.0, 0.0],
                               interpolation="cubic")
    # DOP853 at rtol 1e-8 on each smooth piece, the switches located to rounding:
    # measured 1.7e-8 of the largest position (fixed-step RK4 chatters: 4.7e-3)
    assert np.max(np.abs(simulated - exact)) < 1e-7 * np.max(np.abs(exact))


def test_sticking_to_a_moving_belt_uses_the_rate_along_the_flow(sticking):
    """sign(q' - vb): the switch is not a derivative of the output, its rate is a
    central difference; relative to the belt the motion is the one above."""
    t, force, exact = sticking
    belt = parse_equation("M*q'' + Fc*sign(q' - vb) = F", "M Fc")
    speed = 0.3
    simulated = simulate_model(belt, {"M": 1.0, "Fc": 1.0}, t,
                               {"F": force, "vb": np.full_like(t, speed)},
                               initial_state=[0.0, speed], interpolation="cubic")
    # the integrator's tolerance is relative to the state, here mostly the belt's travel
    # (1.8): measured 4.1e-9 of it
    assert np.max(np.abs(simulated - speed * t - exact)) < 1e-7 * np.max(np.abs(simulated))


def test_too_much_work_is_a_one_line_error_suggesting_rk4(monkeypatch):
    stiff = parse_equation("x'' + B*x' + K*x = f", "B K")
    t = np.arange(200) * 1e-3
    values, inputs = {"B": 2e4, "K": 1e8}, {"f": np.sin(30 * t)}
    # DOP853 is held to its stability limit here, about 70 evaluations per sample
    monkeypatch.setattr(model_simulation, "MAX_EVALUATIONS", 20)
    with pytest.raises(ModelError, match=r"stopped at t = .*20 per sample.*method='RK4'") as info:
        simulate_model(stiff, values, t, inputs, interpolation="cubic")
    assert "\n" not in str(info.value)
    monkeypatch.setattr(model_simulation, "MAX_EVALUATIONS", 200)
    assert np.all(np.isfinite(simulate_model(stiff, values, t, inputs, interpolation="cubic")))


def test_the_work_bound_stops_an_integration_that_does_not_advance(monkeypatch):
    monkeypatch.setattr(model_simulation, "MAX_STALLED_EVALUATIONS", 100)
    budget = model_simulation._Budget(np.arange(1000) * 1e-3)
    for i in range(1000):            # one evaluation per 0.1 step, a look far ahead
        budget.tick(50.0 if i % 10 == 0 else i * 1e-4)
    with pytest.raises(model_simulation._Exhausted, match="without advancing"):
        for _ in range(200):
            budget.tick(0.1 + 1e-9)


def test_a_switch_before_the_first_sample_time_is_crossed():
    # sliding at 1e-3 m/s against Coulomb friction: the mass stops at t = 1e-3 s, before
    # the second sample (the solver's first piece ends on an event without a sample)
    t = np.arange(50) * 0.01
    values = {"M": 1.0, "Fv": 0.0, "Fc": 1.0, "off": 0.0}
    simulated = simulate_model(FRICTION, values, t, {"F": np.zeros_like(t)},
                               initial_state=[0.0, 1e-3], interpolation="cubic")
    # q = v0 t - t**2 / 2 until v0, then at rest at v0**2 / 2
    np.testing.assert_allclose(simulated[1:], 0.5e-6, rtol=1e-9)
    assert simulated[0] == 0.0
