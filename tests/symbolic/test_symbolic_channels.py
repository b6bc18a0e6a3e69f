"""The derivation on user models with several channels: offsets, nonlinear factors.

For a nonlinear model the derivation treats every factor as a channel: the residual
``P theta - Q`` must vanish exactly on any trajectory that satisfies the equation,
whatever its initial conditions, and must not vanish for wrong parameters.
"""

import sympy as sp

from algid.models._grammar import parse_equation
from algid.symbolic import TIME as t
from algid.symbolic import derive, evaluate_kernel
from algid.symbolic._channels import ChannelModel, channel_names


def _residual(derivation, signals, values):
    subs = {k.expression(): evaluate_kernel(k, signals) for k in derivation.kernels}
    theta = sp.Matrix([values[p] for p in derivation.parameters])
    return (derivation.P.xreplace(subs) * theta - derivation.Q.xreplace(subs)).applyfunc(
        sp.expand)


def test_channel_names():
    model = parse_equation("V2'' + B*V2' + K*V2 + K3*V2**3 = G*V1 + d", "B K K3 G d")
    names = channel_names(model)
    assert sorted(names.values()) == ["V1", "V2", "one", "z1"]
    assert [str(f) for f, n in names.items() if n == "z1"] == ["V2**3"]


def test_cubic_spring_with_offset_is_exact_on_a_trajectory():
    """Silverbox's model: y'' + B y' + K y + K3 y**3 = G u + d, with y(0), y'(0) != 0."""
    model = ChannelModel(parse_equation("y'' + B*y' + K*y + K3*y**3 = G*u + d",
                                        "B K K3 G d"))
    d = derive(model)
    assert d.P.shape == (5, 5)
    assert not ((d.P.free_symbols | d.Q.free_symbols) & set(d.initial_conditions))
    truth = dict(zip(model.parameters, (sp.Rational(1, 2), 3, 2, sp.Rational(5, 4), -1)))
    B, K, K3, G, dd = model.parameters
    y = 2 - t + 3 * t**2  # y(0) = 2, y'(0) = -1
    u = sp.expand((y.diff(t, 2) + B * y.diff(t) + K * y + K3 * y**3 - dd).subs(truth) / truth[G])
    signals = {"y": y, "u": u, "z1": sp.expand(y**3), "one": sp.Integer(1)}
    assert _residual(d, signals, truth) == sp.zeros(5, 1)
    wrong = {**truth, K3: 1}
    assert _residual(d, signals, wrong) != sp.zeros(5, 1)


def test_friction_model_channels():
    """EMPS's model: M q'' + Fv q' + Fc sign(q') + off = F; sign(q') is one channel."""
    model = ChannelModel(parse_equation("M*q'' + Fv*q' + Fc*sign(q') + off = F",
                                        "M Fv Fc off"))
    assert model.channels == ("q", "z1", "one", "F")
    assert str(model.factors["z1"]) == "sign(q')"
    d = derive(model)
    # q is differentiated twice: its two initial values are annihilated; the other
    # channels are never differentiated and carry none
    assert {str(s) for s in d.initial_conditions} == {"q0", "q_d0"}
    assert d.P.shape == (4, 4)
