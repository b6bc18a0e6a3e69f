"""The Model representation: channels, order, output, linearity."""

import pytest

from algid.models._expression import ONE, Call, Constant, Power, Product, Signal, Sum, Time
from algid.models._grammar import parse_equation


def test_model_properties_of_the_msd():
    m = parse_equation("x'' + B*x' + K*x = f", "B K")
    assert m.order == 2 and m.output == "x" and m.inputs == ("f",)
    assert m.channels == (Signal("x"), Signal("f"))
    assert m.is_linear and m.needs_derivatives == ()
    assert [t.parameter for t in m.parameter_terms("B")] == ["B"]
    assert str(m) == "custom: x'' + B*x' + K*x = f"
    assert [str(t) for t in m.terms] == ["x''", "B*x'", "K*x", "-f"]


def test_expressions_are_hashable_and_equal_by_value():
    a = Call("sign", (Signal("q", 1),))
    b = Call("sign", (Signal("q", 1),))
    assert a == b and hash(a) == hash(b) and len({a, b, ONE, Time()}) == 3
    assert str(Sum((Signal("y"), Constant(-1.0)))) == "y - 1"
    assert str(Product((Constant(2.0), Power(Sum((Signal("y"), ONE)), 2.0)))) == "2*(y + 1)**2"
    assert Product((Signal("u"), Signal("y", 2))).derivatives() == (("y", 2),)
    assert Product((Signal("u"), Signal("y", 2))).signals() == ("u", "y")


def test_unknown_function_node_is_refused():
    with pytest.raises(ValueError):
        Call("eval", (Signal("y"),))


def test_models_are_immutable():
    m = parse_equation("x'' + B*x' + K*x = f", "B K")
    with pytest.raises(AttributeError):
        m.output = "f"


def test_builtin_models_convert_to_a_model():
    from algid.symbolic._builtin_models import builtin_model

    m = builtin_model("msd_mass").to_model()
    assert m.parameters == ("m", "c", "k") and m.output == "x" and m.inputs == ("F",)
    assert m.is_linear and m.order == 2 and len(m.known_terms) == 1
    assert builtin_model("msd").to_model().equation == "x'' + B*x' + K*x = f"
