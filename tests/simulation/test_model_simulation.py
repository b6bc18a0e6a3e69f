"""Accurate simulation of user models (algid.simulation._model)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from algid.errors import InputDataError, ModelError
from algid.models._grammar import parse_equation
from algid.simulation._model import fit_initial_state, simulate_model

LINEAR = parse_equation("x'' + B*x' + K*x = f", ["B", "K"])


def exact_response(kind, *, B, K, duration, rate, omega, x0=0.0, v0=0.0):
    """Closed form of x'' + B x' + K x = sin(omega t): forced part plus free modes."""
    assert kind == "sine"
    t = np.arange(int(round(duration * rate)) + 1) / rate
    gain = 1.0 / (K - omega ** 2 + 1j * B * omega)
    roots = np.roots([1.0, B, K]).astype(complex)
    rest = np.array([x0 - gain.imag, v0 - omega * gain.real], dtype=complex)
    c = np.linalg.solve(np.array([[1.0, 1.0], roots]), rest)
    x = np.imag(gain * np.exp(1j * omega * t)) + np.real(c @ np.exp(np.outer(roots, t)))
    return t, np.sin(omega * t), x


def test_linear_plant_matches_the_closed_form():
    """Exact response (matrix exponential of plant + sine generator) to ~1e-10."""
    t, f, x = exact_response("sine", B=2.0, K=3.0, duration=5.0, rate=1000.0, x0=0.5,
                             v0=-0.2, omega=7.0)
    simulated = simulate_model(LINEAR, {"B": 2.0, "K": 3.0}, t, {"f": f},
                               initial_state=[0.5, -0.2], interpolation="cubic", rtol=1e-10)
    # cubic-spline error (7e-3)**4/384 ~ 6e-12 of the input; integrator at rtol 1e-10
    assert np.max(np.abs(simulated - x)) < 1e-9 * np.max(np.abs(x))


def test_linear_plant_against_python_control():
    ct = pytest.importorskip("control", reason="needs the 'simulate' extra")
    t = np.linspace(0.0, 2.0, 2001)
    f = np.sin(3.0 * t) + 0.5 * np.cos(11.0 * t)
    plant = ct.ss([[0, 1], [-3.0, -2.0]], [[0], [1]], [[1, 0]], [[0]])
    # python-control holds the input linear between samples: give it a fine grid
    fine = np.linspace(0.0, 2.0, 32001)
    reference = ct.forced_response(plant, fine, np.sin(3.0 * fine) + 0.5 * np.cos(11.0 * fine),
                                   X0=[0.1, 0.0]).outputs[::16]
    simulated = simulate_model(LINEAR, {"B": 2.0, "K": 3.0}, t, {"f": f},
                               initial_state=[0.1, 0.0], interpolation="cubic", rtol=1e-10)
    # linear interpolation at 1/16000 s: error ~ (11/16000)**2/8 ~ 6e-8 of the input
    assert np.max(np.abs(simulated - reference)) < 1e-7


def test_bandlimited_interpolation_at_few_samples_per_period():
    """A sine at 0.3 of the sampling rate: band-limited interpolation keeps the response
    exact to ~1e-5 away from the record's first samples; a cubic spline does not."""
    rate, omega = 100.0, 2 * np.pi * 30.0
    B, K = 20.0, (2 * np.pi * 25.0) ** 2
    t, f, x = exact_response("sine", B=B, K=K, duration=4.0, rate=rate, omega=omega)
    errors = {}
    for interpolation in ("bandlimited", "cubic"):
        simulated = simulate_model(LINEAR, {"B": B, "K": K}, t, {"f": f},
                                   interpolation=interpolation)
        late = slice(150, len(t) - 80)  # the filter's edge effects have decayed (B = 20/s)
        errors[interpolation] = np.max(np.abs(simulated - x)[late]) / np.max(np.abs(x))
    assert errors["bandlimited"] < 1e-4
    assert errors["cubic"] > 30 * errors["bandlimited"]


def _analytic_reference(rhs, t, state, rtol=1e-12):
    solution = solve_ivp(rhs, (t[0], t[-1]), state, method="DOP853", t_eval=t, rtol=rtol,
                         atol=1e-14)
    return solution.y[0]


def test_cubic_oscillator_against_a_finer_solution():
    model = parse_equation("x'' + B*x' + K*x + K3*x**3 = G*u + d", ["B", "K", "K3", "G", "d"])
    p = {"B": 0.5, "K": 4.0, "K3": 2.0, "G": 3.0, "d": 0.2}
    t = np.linspace(0.0, 10.0, 2001)

    def u_of(time):
        return np.sin(1.3 * time) + 0.4 * np.sin(3.1 * time)

    def rhs(time, s):
        return [s[1], -p["B"] * s[1] - p["K"] * s[0] - p["K3"] * s[0] ** 3
                + p["G"] * u_of(time) + p["d"]]

    reference = _analytic_reference(rhs, t, [0.3, 0.0])
    simulated = simulate_model(model, p, t, {"u": u_of(t)}, initial_state=[0.3, 0.0],
                               interpolation="cubic", rtol=1e-10)
    assert np.max(np.abs(simulated - reference)) < 1e-8 * np.max(np.abs(reference))


def test_friction_model_with_sign_of_the_simulated_velocity():
    model = parse_equation("M*q'' + Fv*q' + Fc*sign(q') + off = F", ["M", "Fv", "Fc", "off"])
    p = {"M": 2.0, "Fv": 3.0, "Fc": 0.5, "off": -0.1}
    t = np.linspace(0.0, 6.0, 6001)
    force = 4.0 * np.sin(2.0 * t)

    def rhs(time, s):
        return [s[1], (4.0 * np.sin(2.0 * time) - p["Fv"] * s[1] - p["Fc"] * np.sign(s[1])
                       - p["off"]) / p["M"]]

    reference = _analytic_reference(rhs, t, [0.0, 0.5], rtol=1e-10)
    simulated = simulate_model(model, p, t, {"F": force}, initial_state=[0.0, 0.5],
                               interpolation="cubic")
    # the velocity changes sign without sticking: both integrators resolve each switch
    assert np.max(np.abs(simulated - reference)) < 1e-6 * np.max(np.abs(reference))


def test_input_derivative_inside_a_factor_uses_the_differentiator():
    model = parse_equation("x'' + B*x' + K*x = G*tanh(u'/0.5)", ["B", "K", "G"])
    p = {"B": 1.0, "K": 4.0, "G": 2.0}
    t = np.linspace(0.0, 8.0, 8001)
    u = np.sin(1.5 * t)

    def rhs(time, s):
        return [s[1], -s[1] - 4.0 * s[0] + 2.0 * np.tanh(1.5 * np.cos(1.5 * time) / 0.5)]

    reference = _analytic_reference(rhs, t, [0.0, 0.0])
    simulated = simulate_model(model, p, t, {"u": u}, interpolation="cubic")
    # the differentiator's error on u' (20-sample window, f T = 0.005): ~1e-5 relative
    assert np.max(np.abs(simulated - reference)) < 1e-4 * np.max(np.abs(reference))


def test_fit_initial_state_recovers_the_state():
    t, f, x = exact_response("sine", B=2.0, K=3.0, duration=2.0, rate=1000.0, x0=0.5,
                             v0=-0.2, omega=7.0)
    state = fit_initial_state(LINEAR, {"B": 2.0, "K": 3.0}, t, {"f": f}, x, 50,
                              interpolation="cubic")
    np.testing.assert_allclose(state, [0.5, -0.2], atol=1e-7)


def test_states_and_output_option():
    t, f, x = exact_response("sine", B=2.0, K=3.0, duration=1.0, rate=1000.0, x0=0.5,
                             v0=-0.2, omega=7.0)
    states = simulate_model(LINEAR, {"B": 2.0, "K": 3.0}, t, {"f": f}, initial_state=[0.5, -0.2],
                            output="x", return_states=True, interpolation="cubic")
    assert states.shape == (2, len(t))
    np.testing.assert_allclose(states[1], np.gradient(x, t), atol=2e-3)


@pytest.mark.parametrize("call,error,match", [
    (lambda t, f: simulate_model(LINEAR, {"B": 1.0}, t, {"f": f}), ModelError, "'K'"),
    (lambda t, f: simulate_model(LINEAR, {"B": 1.0, "K": 1.0}, t, {}), InputDataError, "'f'"),
    (lambda t, f: simulate_model(LINEAR, {"B": 1.0, "K": 1.0}, t, {"f": f[:-1]}),
     InputDataError, r"different lengths \(time: 101, f: 100\)"),
    (lambda t, f: simulate_model(LINEAR, {"B": 1.0, "K": 1.0}, t, {"f": f},
                                 initial_state=[0.0]), InputDataError, "initial_state"),
    (lambda t, f: simulate_model(LINEAR, {"B": 1.0, "K": 1.0}, t, {"f": f}, output="f"),
     ModelError, "not differentiated"),
    (lambda t, f: simulate_model(LINEAR, {"B": 1.0, "K": 1.0}, t[::-1], {"f": f}),
     InputDataError, "time does not increase at row 1"),
    (lambda t, f: simulate_model(LINEAR, {"B": 1.0, "K": 1.0}, t,
                                 {"f": np.ma.masked_array(f, mask=t > 0.5)}),
     InputDataError, "input 'f' has a masked sample at row 51"),
    (lambda t, f: simulate_model(LINEAR, {"B": 1.0, "K": 1.0}, t, {"f": f + 1j}),
     InputDataError, "input 'f' is complex"),
    (lambda t, f: simulate_model("x'' + B*x' + K*x = f", {"B": 1.0, "K": 1.0}, t, {"f": f}),
     ModelError, "model must be a Model"),
    (lambda t, f: simulate_model(LINEAR, {"B": 1.0, "K": 1.0}, t, {"f": f},
                                 interpolation="linear"), InputDataError, "interpolation"),
])
def test_bad_input_is_a_clear_error(call, error, match):
    t = np.linspace(0.0, 1.0, 101)
    with pytest.raises(error, match=match):
        call(t, np.sin(t))


def test_non_uniform_time_falls_back_to_the_cubic_spline():
    rng = np.random.default_rng(3)
    t = np.sort(np.r_[0.0, rng.uniform(0.0, 3.0, 2998), 3.0])
    B, K, omega = 2.0, 3.0, 5.0
    gain = 1.0 / (K - omega ** 2 + 1j * B * omega)
    roots = np.roots([1.0, B, K]).astype(complex)
    c = np.linalg.solve(np.array([[1.0, 1.0], roots]),
                        np.array([0.2 - gain.imag, 0.1 - omega * gain.real], dtype=complex))
    exact = np.imag(gain * np.exp(1j * omega * t)) + np.real(c @ np.exp(np.outer(roots, t)))
    simulated = simulate_model(LINEAR, {"B": B, "K": K}, t, {"f": np.sin(omega * t)},
                               initial_state=[0.2, 0.1], rtol=1e-10)
    assert np.max(np.abs(simulated - exact)) < 1e-8 * np.max(np.abs(exact))


def test_a_diverging_model_gives_nan_after_the_integration_stops():
    model = parse_equation("x'' + K*x**3 = f", ["K"])
    t = np.linspace(0.0, 3.0, 301)
    # x'' = x**3 from x = 2 blows up near t = 0.5
    simulated = simulate_model(model, {"K": -1.0}, t, {"f": np.zeros_like(t)},
                               initial_state=[2.0, 0.0], interpolation="cubic")
    assert np.all(np.isfinite(simulated[:20])) and np.all(np.isnan(simulated[-100:]))
    # outside a function's domain: sqrt of a negative output stops the integration too
    model = parse_equation("x'' + K*sqrt(x) = f", ["K"])
    simulated = simulate_model(model, {"K": 1.0}, t, {"f": np.zeros_like(t)},
                               initial_state=[0.5, 0.0], interpolation="cubic")
    assert np.isfinite(simulated[0]) and np.isnan(simulated[-1])


def test_fixed_step_rk4_option():
    """method="RK4": 4 steps per sample on the same interpolant, close to DOP853."""
    t, f, x = exact_response("sine", B=2.0, K=3.0, duration=5.0, rate=200.0, x0=0.5,
                             v0=-0.2, omega=7.0)
    options = {"initial_state": [0.5, -0.2], "interpolation": "cubic"}
    rk4 = simulate_model(LINEAR, {"B": 2.0, "K": 3.0}, t, {"f": f}, method="RK4", **options)
    # RK4 global error ~ (h w)^4 / 120 with h = 1/800 s, w = 7: ~1e-10; spline ~1e-8
    assert np.max(np.abs(rk4 - x)) < 1e-7
    with pytest.raises(InputDataError, match="substeps"):
        simulate_model(LINEAR, {"B": 2.0, "K": 3.0}, t, {"f": f}, method="RK4", substeps=0)

