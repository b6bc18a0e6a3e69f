"""The derivation engine, checked symbolically: independence of the initial
conditions and exactness on closed-form trajectories of the ODE."""

import pytest
import sympy as sp

from algid.errors import ModelError
from algid.symbolic import TIME as t
from algid.symbolic import IteratedIntegral, LinearODEModel, derive, evaluate_kernel
from algid.symbolic._builtin_models import builtin_model


def _exact_trajectory(model, values, forcing, ics):
    """Closed-form solution of ``model`` with ``values`` substituted, by dsolve."""
    ode = model.ode().subs(values)
    u = model.input_function
    ode = ode.subs(u, forcing).doit()
    y = model.output_function
    sol = sp.dsolve(ode, y, ics={y.subs(t, 0): ics[0], y.diff(t).subs(t, 0): ics[1]})
    return sp.simplify(sol.rhs)


def _residual(derivation, signals, values):
    subs = {k.expression(): evaluate_kernel(k, signals) for k in derivation.kernels}
    theta = sp.Matrix([values[p] for p in derivation.parameters])
    residual = derivation.P.xreplace(subs) * theta - derivation.Q.xreplace(subs)
    return residual.applyfunc(sp.simplify)


@pytest.mark.parametrize("name", ["msd", "msd_mass"])
def test_initial_conditions_are_annihilated(name):
    d = derive(builtin_model(name))
    ics = set(d.initial_conditions)
    assert ics, "the Laplace transform must carry symbolic initial conditions"
    assert d.laplace.free_symbols & ics == ics
    # after n differentiations with respect to s none is left, and none reaches P or Q
    assert not (d.differentiated[-1].free_symbols & ics)
    # and fewer differentiations would not do
    assert d.differentiated[-2].free_symbols & ics
    assert not ((d.P.free_symbols | d.Q.free_symbols) & ics)


@pytest.mark.parametrize("name", ["msd", "msd_mass"])
def test_only_integrals_remain(name):
    d = derive(builtin_model(name))
    s = sp.Symbol("s")
    for term in sp.Add.make_args(d.multiplied):
        _, power = term.as_coeff_exponent(s)
        assert power <= 0
    assert d.s_power == d.model.order
    # the kernel orders are non-negative and the system is square
    assert all(k.order >= 0 for k in d.kernels)
    assert d.P.shape == (len(d.parameters), len(d.parameters))


def test_msd_first_equation_by_hand():
    """B(-2 int^2 tx + int t^2 x) + K int^2 t^2 x = int^2 t^2 f - 2 int^2 x + 4 int tx - t^2 x."""
    d = derive(builtin_model("msd"))
    x, f = sp.Function("x")(t), sp.Function("f")(t)
    I = IteratedIntegral  # noqa: E741 - the integral operator, as in the paper
    assert sp.expand(d.P[0, 0] - (-2 * I(t * x, 2) + I(t**2 * x, 1))) == 0
    assert sp.expand(d.P[0, 1] - I(t**2 * x, 2)) == 0
    q1 = I(t**2 * f, 2) - 2 * I(x, 2) + 4 * I(t * x, 1) - I(t**2 * x, 0)
    assert sp.expand(d.Q[0] - q1) == 0
    # the second equation is the first one integrated once more
    assert sp.expand(d.P[1, 1] - I(t**2 * x, 3)) == 0


@pytest.mark.parametrize("ics", [(sp.Rational(1, 2), -1), (-2, sp.Rational(3, 4))])
def test_msd_exact_on_closed_form_trajectory(ics):
    model = builtin_model("msd")
    B, K = model.parameters
    values = {B: 3, K: 2}  # poles -1 and -2: closed-form integrals stay simple
    forcing = sp.exp(-3 * t) + 1
    x = _exact_trajectory(model, values, forcing, ics)
    assert x.subs(t, 0) == ics[0]
    residual = _residual(derive(model), {"x": x, "f": forcing}, values)
    assert residual == sp.zeros(2, 1)


def test_msd_mass_exact_on_closed_form_trajectory():
    model = builtin_model("msd_mass")
    m, c, k = model.parameters
    values = {m: 2, c: 6, k: 4}
    forcing = 1 + t
    x = _exact_trajectory(model, values, forcing, (1, -1))
    residual = _residual(derive(model), {"x": x, "F": forcing}, values)
    assert residual == sp.zeros(3, 1)


def test_symbolic_initial_conditions_trajectory():
    """With x(0), x'(0) left as symbols the residual still vanishes identically."""
    model = builtin_model("msd")
    B, K = model.parameters
    a, b = sp.symbols("a b")
    values = {B: 3, K: 2}
    x = _exact_trajectory(model, values, sp.Integer(1), (a, b))
    assert {a, b} <= x.free_symbols
    residual = _residual(derive(model), {"x": x, "f": sp.Integer(1)}, values)
    assert residual == sp.zeros(2, 1)


def test_wrong_parameters_leave_a_residual():
    """The check above can fail: a trajectory of other parameters does not satisfy P theta = Q."""
    model = builtin_model("msd")
    B, K = model.parameters
    x = _exact_trajectory(model, {B: 3, K: 2}, sp.Integer(1), (0, 0))
    residual = _residual(derive(model), {"x": x, "f": sp.Integer(1)}, {B: 3, K: 3})
    assert residual != sp.zeros(2, 1)


def test_cramer_solution_solves_the_system():
    d = derive(builtin_model("msd_mass"))
    nums, den = d.cramer()
    Ps, Qs = d.entry_symbols()
    theta = sp.Matrix([n / den for n in nums])
    assert (Ps * theta - Qs).applyfunc(sp.simplify) == sp.zeros(3, 1)


def test_extra_equations_give_tall_system():
    d = derive(builtin_model("msd"), extra_equations=2)
    assert d.P.shape == (4, 2)


def test_from_equation_matches_builtin():
    parsed = LinearODEModel.from_equation("x'' + B*x' + K*x = f", parameters="B K", name="msd")
    builtin = builtin_model("msd")
    assert derive(parsed).P == derive(builtin).P
    assert derive(parsed).Q == derive(builtin).Q


def test_third_order_model_with_input_derivative():
    """A model outside the built-ins, of order 3 with an input derivative."""
    model = LinearODEModel.from_equation("x''' + a*x'' + b*x' + x = g' + g",
                                         parameters="a b", input="g", name="third")
    d = derive(model)
    assert d.n_derivatives == 3
    assert d.P.shape == (2, 2)
    assert not ((d.P.free_symbols | d.Q.free_symbols) & set(d.initial_conditions))
    a, b = model.parameters
    values = {a: 3, b: 3}  # characteristic polynomial (s + 1)**3: quick closed form
    g = sp.exp(-2 * t)
    ode = model.ode().subs(values).subs(model.input_function, g).doit()
    y = model.output_function
    sol = sp.dsolve(ode, y, ics={y.subs(t, 0): 1, y.diff(t).subs(t, 0): -1,
                                 y.diff(t, 2).subs(t, 0): 2})
    residual = _residual(d, {"x": sol.rhs, "g": g}, values)
    assert residual == sp.zeros(2, 1)


@pytest.mark.parametrize("kwargs, match", [
    (dict(output_coefficients=(1, "B*K", 1), input_coefficients=(1,), parameters=("B", "K")),
     "not affine"),
    (dict(output_coefficients=(1, "B", 1), input_coefficients=(1,), parameters=("B", "K")),
     "do not appear"),
    (dict(output_coefficients=("m", "c", "k"), input_coefficients=("m",),
          parameters=("m", "c", "k")),
     "homogeneous"),
    (dict(output_coefficients=(1, "B", "Z"), input_coefficients=(1,), parameters=("B",)),
     "not parameters"),
    (dict(output_coefficients=(0, 1), input_coefficients=(1,), parameters=("B",)),
     "leading"),
])
def test_model_errors(kwargs, match):
    with pytest.raises(ModelError, match=match):
        LinearODEModel(name="bad", **kwargs)


@pytest.mark.parametrize("equation, match", [
    ("x'' + B*x' = f = 1", "exactly one"),
    ("x'' + B*x'*x = f", "not linear"),
    ("x'' + B*x' + y' = f", "not the output"),
    ("x'' + B*x' + 1 = f", "not proportional"),
    ("x'' + B*x' + Q*x = f", "unknown names"),
])
def test_from_equation_errors(equation, match):
    with pytest.raises(ModelError, match=match):
        LinearODEModel.from_equation(equation, parameters="B")


def test_the_input_and_the_output_must_differ():
    # (it named the equation's input as an unknown name)
    with pytest.raises(ModelError, match="the input and the output are the same signal 'x'"):
        LinearODEModel.from_equation("x'' + B*x' = f", parameters="B", input="x", output="x")


def test_unknown_builtin():
    with pytest.raises(ModelError, match="known: msd"):
        builtin_model("nope")
