"""Systems of equations nonlinear in their signals: simulated, fitted, exported."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

import algid
from algid.errors import InputDataError, ModelError
from algid.simulation import simulate_system

#: Two masses, a hardening spring on the first.
CUBIC_TWO_MASS = ["m1*x1'' + c1*x1' + k1*x1 + k3*x1**3 + k2*(x1 - x2) = u",
                  "m2*x2'' + c2*x2' + k2*(x2 - x1) = 0"]
CUBIC_TRUE = {"m1": 1.0, "c1": 0.5, "k1": 20.0, "k3": 200.0, "k2": 15.0, "m2": 0.8,
              "c2": 0.3}
START = [0.01, 0.0, -0.02, 0.0]


def _force(t):
    freqs = np.array([0.2, 0.45, 0.7, 0.95, 1.3, 1.7, 2.2, 3.0])
    phases = np.random.default_rng(12345).uniform(0, 2 * np.pi, len(freqs))
    return 3 * np.sum(np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None]), axis=0)


def cubic_record(noise_db=None, seed=1, duration=12.0, rate=500.0, offset=0.0):
    """Both positions by SciPy's DOP853 at 1e-11 (not algid's simulator), the force
    interpolated by a cubic spline (plus ``offset`` on the first mass, which the
    equations lack); ``noise_db`` of white noise on each position."""
    p = CUBIC_TRUE
    t = np.arange(0, duration, 1 / rate)
    u = _force(t)
    spline = CubicSpline(t, u)

    def rhs(time, x):
        x1, v1, x2, v2 = x
        return [v1, (spline(time) + offset - p["c1"] * v1 - p["k1"] * x1 - p["k3"] * x1 ** 3
                     - p["k2"] * (x1 - x2)) / p["m1"],
                v2, (-p["c2"] * v2 - p["k2"] * (x2 - x1)) / p["m2"]]

    x = solve_ivp(rhs, (t[0], t[-1]), START, t_eval=t, method="DOP853", rtol=1e-11,
                  atol=1e-13).y
    record = {"t": t, "u": u, "x1": x[0], "x2": x[2]}
    if noise_db is not None:
        rng = np.random.default_rng(seed)
        for name in ("x1", "x2"):
            v = record[name]
            record[name] = v + 10 ** (-noise_db / 20) * np.std(v) * rng.standard_normal(len(v))
    return record


def test_a_nonlinear_system_is_simulated_as_an_independent_integrator_does():
    record = cubic_record(duration=6.0)
    simulated = simulate_system(CUBIC_TWO_MASS, CUBIC_TRUE, record["t"], record,
                                initial_state=START)
    for y in ("x1", "x2"):   # the spread of x1 is about 1: the cubic term is 3x the linear
        assert np.max(np.abs(simulated[y] - record[y])) < 1e-6 * np.ptp(record[y])


def test_the_fast_simulation_of_a_system_agrees_with_dop853():
    """The compiled fixed-step simulator (four Runge-Kutta steps per sample) that the
    refinement runs gives the outputs of the tight DOP853 integration."""
    pytest.importorskip("numba")
    from algid.models import parse_system
    from algid.simulation._fast_simulation import FastSystemSimulation

    record = cubic_record(duration=6.0)
    system = parse_system(CUBIC_TWO_MASS, list(CUBIC_TRUE))
    fast = FastSystemSimulation(system, record["t"], record, outputs=["x2", "x1"])
    theta = [CUBIC_TRUE[p] for p in system.parameters]
    x2, x1 = fast.run(theta, START)
    for name, simulated in (("x1", x1), ("x2", x2)):
        assert np.max(np.abs(simulated - record[name])) < 1e-6 * np.ptp(record[name])
    singular = dict(CUBIC_TRUE, m1=0.0)
    assert np.all(np.isnan(fast.run([singular[p] for p in system.parameters], START)))


@pytest.fixture(scope="module")
def cubic_fit():
    record = cubic_record(noise_db=40.0)
    return record, algid.identify(record, CUBIC_TWO_MASS, list(CUBIC_TRUE))


def test_a_nonlinear_system_fit_is_simulated_on_its_record(cubic_fit):
    record, fit = cubic_fit
    for p, v in CUBIC_TRUE.items():
        assert abs(fit.values[p] - v) < 4 * fit.stderr[p], p
    validation = fit.simulate(record)
    # 40 dB of white noise caps the fit at 99 %
    assert all(98.5 < f < 99.2 for f in validation.fit_percent.values()), \
        validation.fit_percent


def test_a_nonlinear_system_is_refined_by_output_error(cubic_fit):
    """Every output simulated, the initial states iterated with the parameters: the
    refined estimate is reported where it is the more precise, the algebraic one kept."""
    pytest.importorskip("numba")
    record, fit = cubic_fit
    assert fit.estimate == "refined", fit.refinement.reason
    algebraic = fit.algebraic
    for i, (p, v) in enumerate(CUBIC_TRUE.items()):
        # (at 40 dB the algebraic standard errors are 3-15 times the refined ones)
        assert fit.stderr[p] < 0.6 * np.sqrt(algebraic["covariance"][i, i]), p
        assert abs(fit.values[p] - v) < 4 * fit.stderr[p], p
        assert abs(algebraic["values"][p] - v) < 4 * np.sqrt(algebraic["covariance"][i, i])
        assert fit.numerical_error[p] < fit.stderr[p]
    assert set(fit.noise_rms) == {"x1", "x2"}
    for y in ("x1", "x2"):   # the noise drawn: 1 % of each output's spread
        assert 0.9 < fit.noise_rms[y] / (0.01 * np.std(cubic_record()[y])) < 1.1
    assert not fit.warnings   # (its residual test: nothing missing)
    assert len(fit.refinement.initial_states) == 1
    assert fit.refinement.initial_states[0] == pytest.approx(START, abs=0.01)
    plain = algid.identify(record, CUBIC_TWO_MASS, list(CUBIC_TRUE), refine=False)
    assert plain.estimate == "algebraic" and plain.values == algebraic["values"]


def test_a_nonlinear_system_exports_to_nlsys_not_to_control(cubic_fit):
    ct = pytest.importorskip("control")
    record, fit = cubic_fit
    system = fit.to_nlsys()
    assert (system.ninputs, system.noutputs, system.nstates) == (1, 2, 4)
    t = record["t"][:600]
    response = ct.input_output_response(system, t, record["u"][:600], X0=START,
                                        solve_ivp_method="DOP853",
                                        solve_ivp_kwargs={"rtol": 1e-10, "atol": 1e-12})
    ours = simulate_system(CUBIC_TWO_MASS, fit.values, t,
                           {"u": record["u"][:600]}, initial_state=START)
    # python-control holds the input linear between samples, algid interpolates it
    # band-limited: they differ by that interpolation, far below the noise
    assert np.max(np.abs(response.outputs[0] - ours["x1"])) < 1e-4 * np.ptp(ours["x1"])
    with pytest.raises(ModelError, match="to_nlsys"):
        fit.to_control()


@pytest.mark.parametrize("equations, message", [
    (["x1'' + a*x1'*x2'' + x1 = u", "x2'' + x2 = x1"], "x2'' appears inside a nonlinear"),
    (["x1'' + a*x1**3 = u'", "x2' + x2 = x1"], "derivative of an input"),
    (["a*x1'' + x1**3 = u", "x2' + x2 = x1"], "do not determine the highest"),
    (["x1'' + a*sign(x1') + x1 - x2 = u", "x2'' + x2 = x1"], "sign\\(\\) of the output x1"),
])
def test_nonlinear_systems_that_cannot_be_simulated_are_refused(equations, message):
    t = np.linspace(0, 1, 101)
    a = 0.0 if "a*x1''" in equations[0] else 1.0
    with pytest.raises((ModelError, InputDataError), match=message):
        simulate_system(equations, {"a": a}, t, {"u": np.sin(t)})


def test_a_function_outside_its_domain_stops_the_simulation_not_its_sign():
    """``u**0.5`` of a negative input is no real number: the outputs are NaN from there,
    not the real part of a complex root."""
    t = np.linspace(0, 5, 501)
    out = simulate_system(["x1' + a*x1 = b*u**0.5", "x2' + x2 = x1"], {"a": 1.0, "b": 1.0},
                          t, {"u": np.sin(t)})
    negative = t[np.argmax(np.sin(t) < 0)]   # pi
    assert np.all(np.isfinite(out["x1"][t < negative - 0.05]))
    assert not np.any(np.isfinite(out["x1"][t > negative + 0.05]))


def test_nonlinear_system_initial_states_read_as_numbers():
    t = np.linspace(0, 1, 101)
    equations = ["x1' + a*x1**3 = sign(u)", "x2' + x2 = x1"]
    column = simulate_system(equations, {"a": 1.0}, t, {"u": np.sin(t - 0.5)},
                             initial_state=[[0.5], [0.1]])
    flat = simulate_system(equations, {"a": 1.0}, t, {"u": np.sin(t - 0.5)},
                           initial_state=[0.5, 0.1])
    assert np.array_equal(column["x1"], flat["x1"]) and np.isfinite(flat["x2"]).all()
    with pytest.raises(InputDataError, match="initial_state must be numbers"):
        simulate_system(equations, {"a": 1.0}, t, {"u": np.sin(t)}, initial_state={"x1": 1})


def test_a_single_equation_s_right_hand_side_is_nan_outside_a_function_s_domain():
    """``to_nlsys``'s right-hand side of one equation: NaN (which stops an integrator)
    where ``u**0.5`` has a negative input, not a complex number or a raw error."""
    from algid.models import parse_equation
    from algid.simulation._output_equation import OutputEquation

    equation = OutputEquation(parse_equation("x' + a*x = u**0.5", "a"), {"a": 1.0})
    assert equation.derivative(0.0, [0.0], [4.0]) == [2.0]
    assert np.isnan(equation.derivative(0.0, [0.0], [-1.0])[0])


def test_a_system_equation_that_lacks_a_power_of_its_output_is_named():
    """The hardening spring written on the wrong mass: the first equation's misfit is
    hundreds of times the noise's while its estimates hardly shift between windows; as
    for one equation, a power of its output fitted beside it names what it lacks."""
    record = cubic_record(noise_db=40.0)
    wrong = ["m1*x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u",
             "m2*x2'' + c2*x2' + k3*x2**3 + k2*(x2 - x1) = 0"]
    fit = algid.identify(record, wrong, list(CUBIC_TRUE), refine=False)
    named = [w for w in fit.warnings if w.endswith("a missing term?")]
    assert len(named) == 1 and "x1**3" in named[0] and named[0].startswith(
        "the equation m1*x1''"), fit.warnings
    right = algid.identify(record, CUBIC_TWO_MASS, list(CUBIC_TRUE), refine=False)
    assert not right.warnings


def test_a_system_with_friction_keeps_its_algebraic_estimate_and_says_why():
    """A sign() of an output cannot be simulated in a system (its sticking needs the
    switching integrator of one equation): identify reports the algebraic estimate with
    the reason, and refine=True refuses in one line."""
    from algid.models import parse_equation
    from algid.simulation import simulate_model

    t = np.arange(0, 10, 1e-3)
    u = 3 * np.sin(2 * np.pi * 0.5 * t) + np.sin(2 * np.pi * 1.3 * t)
    x1 = simulate_model(parse_equation("x1'' + c*x1' + f*sign(x1') + k*x1 = u", "c f k"),
                        {"c": 1.0, "f": 0.5, "k": 5.0}, t, {"u": u})
    x2 = simulate_model(parse_equation("x2' + a*x2 = a*x1", "a"), {"a": 3.0}, t, {"x1": x1})
    rng = np.random.default_rng(0)
    record = {"t": t, "u": u, "x1": x1 + 1e-3 * rng.standard_normal(len(t)),
              "x2": x2 + 1e-3 * rng.standard_normal(len(t))}
    equations = ["x1'' + c*x1' + f*sign(x1') + k*x1 = u", "x2' + a*x2 = a*x1"]
    fit = algid.identify(record, equations, "c f k a")
    assert fit.estimate == "algebraic" and "sign() of the output x1" in fit.refinement.reason
    assert abs(fit.values["f"] - 0.5) < 4 * fit.stderr["f"]
    with pytest.raises(ModelError, match="refine=True: cannot simulate: sign\\(\\) of the "
                                         "output x1"):
        algid.identify(record, equations, "c f k a", refine=True)


def test_a_refined_nonlinear_system_s_residuals_name_what_it_lacks():
    """The records have a constant force on the first mass that the equations lack: the
    refined fit's residuals name an offset in equation 1."""
    record = cubic_record(noise_db=40.0, offset=0.5)
    fit = algid.identify(record, CUBIC_TWO_MASS, list(CUBIC_TRUE))
    assert fit.warnings and "an offset missing?" in fit.warnings[0] \
        and "in equation 1" in fit.warnings[0], fit.warnings
