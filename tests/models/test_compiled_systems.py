"""compile_equation on a system of equations that share parameters: one generated
estimator for the stacked rows of every equation, solved at every instant through the
normal equations, run by estimate and OnlineEstimator like one equation's."""

import numpy as np
import pytest

import algid
from algid.errors import InputDataError, ModelError
from algid.estimation._online import OnlineEstimator
from algid.models._compiled import compile_equation
from algid.simulation import simulate_system

TWO_MASS = ["m1*x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u",
            "m2*x2'' + c2*x2' + k2*(x2 - x1) = 0"]
TWO_MASS_TRUE = {"m1": 1.0, "c1": 0.5, "k1": 20.0, "k2": 15.0, "m2": 0.8, "c2": 0.3}
MOTOR = ["L*i' + R*i + K*w = u", "J*w' + b*w = K*i"]
MOTOR_TRUE = {"L": 0.5, "R": 2.0, "K": 0.8, "J": 0.2, "b": 0.1}
RATE = 512.0
FINER = 8


def _record(equations, values, duration, initial_state=None):
    """The system simulated (algid.simulate_system, exact for an input linear between
    samples) on a grid FINER times finer than RATE, then sampled at RATE: the input's
    kinks between samples, which the estimator's quadrature does not follow, are
    FINER**2 times smaller than on the grid itself."""
    fine = np.arange(int(duration * RATE * FINER) + 1) / (RATE * FINER)
    u = np.sin(2.1 * fine) + 0.5 * np.cos(5.3 * fine) + 0.3 * np.sin(11.7 * fine)
    out = simulate_system(equations, values, fine, {"u": u}, initial_state=initial_state)
    return {"t": fine[::FINER], "u": u[::FINER],
            **{name: samples[::FINER] for name, samples in out.items()}}


@pytest.fixture(scope="module")
def two_mass():
    return (compile_equation(TWO_MASS, list(TWO_MASS_TRUE)),
            _record(TWO_MASS, TWO_MASS_TRUE, 12.0, initial_state=[0.01, 0.0, -0.02, 0.0]))


@pytest.fixture(scope="module")
def motor():
    return compile_equation(MOTOR, "L R K J b"), _record(MOTOR, MOTOR_TRUE, 10.0)


def _worst(result, true, at=-1):
    return max(abs(getattr(result, p)[at] / v - 1) for p, v in true.items())


def test_two_masses_module_stacks_both_equations(two_mass):
    module, _ = two_mass
    assert module.PARAMETERS == tuple(TWO_MASS_TRUE)
    assert module.EQUATIONS == tuple(TWO_MASS) and module.OUTPUTS == ("x1", "x2")
    assert module.CHANNELS == ("x1", "x2", "u") and module.FACTORS == {}
    # 4 rows of the first equation (4 parameters), 3 of the second: 7 rows, 6 unknowns
    assert module.N_EQUATIONS == 7 and module.ROWS == (1, 1, 1, 1, 2, 2, 2)
    assert "normal equations" in module.cramer.__doc__


def test_two_masses_converge_to_the_six_parameters(two_mass):
    """Noise-free: the joint estimate reaches 5e-8 (measured; 3.5e-6 on the coarse grid
    itself, 4e-11 on a smooth input solved by DOP853: the quadrature of the samples is
    the limit, not the normal equations)."""
    module, record = two_mass
    r = algid.estimate(record["t"], signals={k: record[k] for k in ("u", "x1", "x2")},
                       model=module)
    assert _worst(r, TWO_MASS_TRUE) < 3e-7
    # the estimate settles within a second or two, as one equation's does
    assert _worst(r, TWO_MASS_TRUE, at=int(4 * RATE)) < 1e-5
    assert r.numerical_error[-1] < 3e-7


def test_dc_motor_shares_its_constant_between_the_equations(motor):
    module, record = motor
    assert module.N_EQUATIONS == 6 and len(module.PARAMETERS) == 5
    r = algid.estimate(record, module)
    assert _worst(r, MOTOR_TRUE) < 3e-7
    # the speed equation alone has no known term: the shared K is what fixes its scale
    with pytest.raises(ModelError, match="no known term"):
        compile_equation(MOTOR[1], "K J b")


def test_every_way_of_giving_a_system_estimates_the_same(motor):
    module, record = motor
    signals = {k: record[k] for k in ("u", "i", "w")}
    reference = algid.estimate(record["t"], signals=signals, model=module)
    again = algid.estimate(record, MOTOR, "L R K J b")   # the equations, compiled there
    stream = OnlineEstimator(model=module, rate=RATE, engine="numpy")
    chunks = [stream.update(record["t"][a:a + 700],
                            signals={k: v[a:a + 700] for k, v in signals.items()})
              for a in range(0, record["t"].size, 700)]
    for p in MOTOR_TRUE:
        np.testing.assert_array_equal(getattr(again, p), getattr(reference, p))
        np.testing.assert_array_equal(np.concatenate([getattr(c, p) for c in chunks]),
                                      getattr(reference, p))


def test_identify_and_tracker_take_a_compiled_system(motor):
    module, record = motor
    result = algid.identify(record, module, refine=False)
    assert all(abs(result.values[p] / v - 1) < 1e-4 for p, v in MOTOR_TRUE.items())
    assert type(algid.Tracker(module, rate=RATE)).__name__ == "SystemTracker"
    with pytest.raises(ModelError, match="identify_many takes one equation"):
        algid.identify_many({0: record}, module)


def test_a_one_equation_list_estimates_as_the_equation(motor):
    _, record = motor
    single = compile_equation(MOTOR[0], "L R K")
    listed = compile_equation(MOTOR[:1], "L R K")
    assert not hasattr(single, "EQUATIONS") and listed.EQUATIONS == (MOTOR[0],)
    a = algid.estimate(record, single)
    b = algid.estimate(record, listed)
    for p in ("L", "R", "K"):
        np.testing.assert_array_equal(getattr(a, p), getattr(b, p))


def test_an_equation_without_parameters_is_left_out():
    module = compile_equation(["x2' + x2 = x1", "x1' + a*x1 = u"], "a")
    assert module.EQUATIONS == ("x1' + a*x1 = u",) and module.CHANNELS == ("x1", "u")
    assert "Left out (no parameter): x2' + x2 = x1." in module.__doc__


def test_a_factor_has_one_channel_in_the_whole_system():
    equations = ["y'' + B*y' + K*y + K3*y**3 = G*u", "z' + a*z = c*y**3 + d*tanh(z)"]
    true = {"B": 0.8, "K": 9.0, "K3": 2.0, "G": 1.5, "a": 2.0, "c": 0.7, "d": 0.4}
    module = compile_equation(equations, list(true))
    assert module.FACTORS == {"z1": "y**3", "z2": "tanh(z)"}
    assert module.CHANNELS == ("y", "z1", "u", "z", "z2")
    t = np.arange(int(6 * RATE) + 1) / RATE
    u = np.sin(2.1 * t) + 0.5 * np.cos(5.3 * t)
    out = simulate_system(equations, true, t, {"u": u}, initial_state=[0.2, -0.1, 0.1])
    r = algid.estimate({"t": t, "u": u, **out}, module)
    # the nonlinear simulation's own tolerance (DOP853 at 1e-8) is the limit
    assert _worst(r, true) < 1e-4


@pytest.mark.parametrize("equations, parameters, error, match", [
    ([], "a", ModelError, "at least one equation"),
    (["y' + a*y + b*y = u", "z' + c*z = y"], "a b c", ModelError,
     "no data can separate a, b: only a combination"),
    (["a*y' + a*y + b*y' + b*y = u", "z' + c*z = y"], "a b c", ModelError,
     "no data can separate a, b"),
    (["y' + a*y = u", "z' + b*z = 0"], "a b c", ModelError, "parameter c appears in no"),
    (["y' + a*y = u", "z' + b*z = y"], "a b", ModelError, None),
    ([f"y{i}' + a{i}*y{i} + b{i}*y{i + 1} = u" for i in range(7)] + ["y7' = u"],
     " ".join(f"a{i} b{i}" for i in range(7)), ModelError,
     "a system of 14 parameters: its generated estimator solves at most 12"),
])
def test_a_bad_system_is_one_line(equations, parameters, error, match):
    if match is None:   # a good system, for contrast
        assert compile_equation(equations, parameters).PARAMETERS == ("a", "b")
        return
    with pytest.raises(error, match=match) as caught:
        compile_equation(equations, parameters)
    assert "\n" not in str(caught.value) and issubclass(error, ValueError)


def test_missing_signals_and_the_pair_form_are_refused(two_mass):
    module, record = two_mass
    with pytest.raises(InputDataError, match="needs the signal 'x2'"):
        algid.estimate(record["t"], signals={"u": record["u"], "x1": record["x1"]},
                       model=module)
    with pytest.raises(InputDataError, match="reads the signals x1, x2, u"):
        algid.estimate(record["t"], record["u"], record["x1"], model=module)
    with pytest.raises(InputDataError, match="'x2'"):
        algid.estimate({k: record[k] for k in ("t", "u", "x1")}, module)
