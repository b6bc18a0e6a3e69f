"""The restricted grammar of model equations: what it reads and what it refuses."""

import re

import numpy as np
import pytest

from algid.errors import ModelError
from algid.models._expression import ONE, Call, Constant, Power, Product, Signal, Time
from algid.models._grammar import parse_equation


def terms_of(model):
    return {(t.parameter, t.derivative, t.factor): t.coefficient for t in model.terms}


def test_silverbox_equation():
    m = parse_equation("V2'' + B*V2' + K*V2 + K3*V2**3 = G*V1 + d", "B K K3 G d")
    assert m.parameters == ("B", "K", "K3", "G", "d")
    assert terms_of(m) == {
        (None, 2, Signal("V2")): 1.0, ("B", 1, Signal("V2")): 1.0, ("K", 0, Signal("V2")): 1.0,
        ("K3", 0, Power(Signal("V2"), 3.0)): 1.0, ("G", 0, Signal("V1")): -1.0,
        ("d", 0, ONE): -1.0}
    assert m.output == "V2" and m.order == 2 and m.signals == ("V2", "V1")
    assert not m.is_linear and m.needs_derivatives == ()
    assert m.channels == (Signal("V2"), Power(Signal("V2"), 3.0), Signal("V1"), ONE)


def test_emps_equation_needs_the_velocity():
    m = parse_equation("M*q'' + Fv*q' + Fc*sign(q') + off = F", ["M", "Fv", "Fc", "off"])
    assert terms_of(m)[("Fc", 0, Call("sign", (Signal("q", 1),)))] == 1.0
    assert m.known_terms == (m.terms[-1],) and m.terms[-1].coefficient == -1.0
    assert m.needs_derivatives == (("q", 1),)
    assert m.output == "q" and m.inputs == ("F",)


def test_linear_msd_and_drift():
    m = parse_equation("x'' + B*x' + K*x = f + d0 + d1*t", "B K d0 d1")
    assert m.is_linear and m.order == 2
    assert terms_of(m)[("d1", 0, Time())] == -1.0


def test_products_abs_tanh_and_scaling():
    m = parse_equation("y'' + a*y*u + b*abs(y) + c*tanh(y/0.1) - 2*(e1*u)/4 = 3*u", "a b c e1")
    t = terms_of(m)
    assert t[("a", 0, Product((Signal("u"), Signal("y"))))] == 1.0
    assert t[("e1", 0, Signal("u"))] == -0.5
    assert t[(None, 0, Signal("u"))] == -3.0
    tanh = next(f for (p, _, f) in t if p == "c")
    assert str(tanh) == "tanh(10*y)"
    # u*y and y*u are one channel
    m2 = parse_equation("y'' + a*y*u + b*u*y = u", "a b")
    assert len(m2.channels) == 3


def test_factor_evaluates_with_numpy():
    m = parse_equation("y'' + a*y*u' + b*y**2 + c = u", "a b c")
    y, u, du = np.array([1.0, -2.0]), np.array([3.0, 4.0]), np.array([0.5, 0.25])
    values = {"y": y, "u": u, ("u", 1): du}
    factors = {t.parameter: t.factor for t in m.terms}
    np.testing.assert_allclose(factors["a"].evaluate(values), y * du)
    np.testing.assert_allclose(factors["b"].evaluate(values), y ** 2)
    np.testing.assert_allclose(factors["c"].evaluate(values), [1.0, 1.0])
    assert m.needs_derivatives == (("u", 1),)


def test_like_terms_combine_and_known_constants_are_allowed():
    m = parse_equation("y' + a*y + a*y = u + 2", "a")
    assert terms_of(m)[("a", 0, Signal("y"))] == 2.0
    assert terms_of(m)[(None, 0, ONE)] == -2.0


@pytest.mark.parametrize("equation, parameters, fragment", [
    ("y'' + B*K*y = u", "B K", "multiplied together"),
    ("y'' + sin(B*y) = u", "B", "inside sin()"),
    ("y'' + y**B = u", "B", "exponent"),
    ("y'' + B*y = u/K", "B K", "denominator"),
    ("B*y'' + K*y = 0", "B K", "no known term"),
    ("(y**3)' + B*y = u", "B", "parenthesised"),
    ("y'' + B'*y = u", "B", "cannot be differentiated"),
    ("t' + B*y = u", "B", "only a measured signal"),
    ("y'' + B*y = u", "B C", "C does not appear"),
    ("y'' + B*y", "B", "exactly one '='"),
    ("y'' + B*y = u == v", "B", "exactly one '='"),
    ("y'' + B*y = foo(u)", "B", "unknown function foo"),
    ("y'' + B*y = __import__(u)", "B", "name __import__ is reserved"),
    # the internal name of a derivative, typed: its order was not bounded (400: minutes)
    ("y'' + B*y' = __d400__u", "B", "name __d400__u is reserved"),
    ("__d0__y' + B*y = u", "B", "name __d0__y is reserved"),
    ("y'' + B*y = u.real", "B", "not allowed"),
    ("y'' + B*y = u[0]", "B", "not allowed"),
    ("y'' + B*y = 'u'", "B", "prime must follow"),
    ("y'' + B*y = u + 1j", "B", "not a real number"),
    ("y'' + B*y = import os", "B", "cannot read"),
    ("y'' + B*y = u", "", "no unknown parameters"),
    ("y'' + B*y = u", "B B", "listed twice"),
    ("y'' + t*y = u", "t", "reserved"),
    ("y'' + B*y = sign", "B", "must be called"),
    ("B = 1", "B", "no measured signal"),
    ("y'' + u'' + B*y = 0", "B", "ambiguous"),
    ("y'' + B*y = u", "B 2x", "not an identifier"),
    ("", "B", "empty"),
])
def test_bad_equations_are_one_line_model_errors(equation, parameters, fragment):
    with pytest.raises(ModelError) as info:
        parse_equation(equation, parameters)
    message = str(info.value)
    assert fragment in message and "\n" not in message


def test_unknown_signal_when_signals_are_given():
    with pytest.raises(ModelError, match="unknown name z"):
        parse_equation("y'' + B*y = z", "B", signals=["y", "u"])
    with pytest.raises(ModelError, match="both a signal and a parameter"):
        parse_equation("y'' + B*y = u", "B", signals=["y", "u", "B"])


def test_output_can_be_named():
    m = parse_equation("y'' + u'' + B*y = 0", "B", output="u")
    assert m.output == "u"
    with pytest.raises(ModelError, match="output w"):
        parse_equation("y'' + B*y = u", "B", output="w")


def test_printing_round_trips():
    text = "y'' + a*y*u' + b*abs(y - 1) + c*tanh(y/0.1) + d*y**(-2) + e*sqrt(y) = u"
    m = parse_equation(text, "a b c d e")
    nonlinear = [t.factor for t in m.terms if t.parameter is not None]
    again = parse_equation("y'' + " + " + ".join(f"p{i}*({f})" for i, f in enumerate(nonlinear))
                           + " = u", [f"p{i}" for i in range(len(nonlinear))])
    assert [t.factor for t in again.terms if t.parameter is not None] == nonlinear
    assert Constant(2.5).__str__() == "2.5"


@pytest.mark.parametrize("equation, fragment", [
    (["y' + a*y = u", "x' = y"], "one text, got a list of 2: a system of equations goes to"),
    (("y' + a*y = u",), "got a tuple of 1"),
    (None, "got NoneType"),
    (3.0, "got float"),
    ("   ", "the equation is empty"),
])
def test_not_a_text_named_for_what_it_is(equation, fragment):
    """parse_equation takes one text; a list is a system, which compile_equation takes."""
    from algid.models import compile_equation

    with pytest.raises(ModelError, match=re.escape(fragment)):
        parse_equation(equation, "a")
    if isinstance(equation, (list, tuple)):
        assert compile_equation(equation, "a").EQUATIONS == ("y' + a*y = u",)
        return
    with pytest.raises(ModelError, match=re.escape(fragment)):
        compile_equation(equation, "a")
