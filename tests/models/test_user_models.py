"""User equations through derivation, generated estimator and estimation."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import algid
from algid.errors import InputDataError, ModelError
from algid.models._compiled import compile_equation

TRUE = {"B": 0.8, "K": 9.0, "K3": 2.0, "G": 1.5, "d": 0.3}


def _cubic_record(rate=1000.0, duration=4.0):
    """y'' + B y' + K y + K3 y**3 = G u + d, from y(0) = 0.2, y'(0) = -0.1 (tight
    solve_ivp), u a sum of two sines known in closed form."""
    def u(t):
        return np.sin(2.1 * t) + 0.5 * np.cos(5.3 * t)

    def rhs(t, z):
        y, v = z
        return [v, TRUE["G"] * u(t) + TRUE["d"] - TRUE["B"] * v - TRUE["K"] * y
                - TRUE["K3"] * y**3]

    t = np.arange(int(duration * rate) + 1) / rate
    sol = solve_ivp(rhs, (0, t[-1]), [0.2, -0.1], t_eval=t, method="DOP853", rtol=1e-12,
                    atol=1e-14)
    return t, u(t), sol.y[0]


def test_cubic_spring_with_offset_is_estimated_exactly_up_to_quadrature():
    module = compile_equation("y'' + B*y' + K*y + K3*y**3 = G*u + d", "B K K3 G d")
    assert module.CHANNELS == ("y", "z1", "u", "one")
    t, u, y = _cubic_record()
    r = algid.estimate(t, signals={"u": u, "y": y}, model=module, filter_order=0)
    final = r.final()
    for name, value in TRUE.items():
        # noise-free, smooth: the 6-point rule at 1 kHz is accurate to about 1e-11 here
        assert final[name] == pytest.approx(value, rel=1e-9), name


def test_missing_signal_and_mixed_arguments_are_refused():
    module = compile_equation("y'' + B*y' + K*y + K3*y**3 = G*u + d", "B K K3 G d")
    t, u, y = _cubic_record(duration=0.1)
    with pytest.raises(InputDataError, match="needs the signal 'u'"):
        algid.estimate(t, signals={"y": y}, model=module)
    with pytest.raises(InputDataError, match="signals="):
        algid.estimate(t, u, signals={"u": u, "y": y}, model=module)


def test_bad_equation_is_a_model_error():
    with pytest.raises(ModelError):
        compile_equation("M*y'' + K*y = G*u", "M K G")


def test_a_zero_signal_is_accepted_and_lengths_are_checked():
    """One identically zero signal is data, not a lack of excitation; here it leaves H
    undetermined, and the error says so (not a number that looks right); a short
    signal is refused."""
    module = compile_equation("y'' + B*y' + K*y = G*u + H*w", "B K G H")
    t, u, y = _cubic_record(duration=0.1)
    with pytest.raises(InputDataError, match="cannot determine H "):
        algid.estimate(t, signals={"u": u, "y": y, "w": np.zeros_like(t)}, model=module)
    with pytest.raises(InputDataError,
                       match=r"different lengths \(t: 101, u: 101, y: 101, w: 50\)"):
        algid.estimate(t, signals={"u": u, "y": y, "w": u[:50]}, model=module)
    with pytest.raises(InputDataError, match="no excitation"):
        algid.estimate(t, signals={"u": 0 * u, "y": 0 * y, "w": 0 * u}, model=module)
