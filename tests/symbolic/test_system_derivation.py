"""The derivation of a system of equations: each equation's, stacked in the system's
unknowns, exact on closed-form signals; its report and the command line."""

import pytest
import sympy as sp
from matplotlib.mathtext import MathTextParser

from algid.cli import main
from algid.models import parse_system
from algid.symbolic import TIME, derive, evaluate_kernel
from algid.symbolic._report import derivation_report, display_equations

MOTOR = (["L*i' + R*i + K*w = u", "J*w' + b*w = K*i"], "L R K J b")
MOTOR_VALUES = {"L": sp.Rational(1, 20), "R": sp.Rational(6, 5), "K": sp.Rational(3, 10),
                "J": sp.Rational(1, 100), "b": sp.Rational(1, 50)}
TWO_MASSES = (["m1*x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u",
               "m2*x2'' + c2*x2' + k2*(x2 - x1) = 0"], "m1 c1 k1 k2 m2 c2")


def _motor_signals():
    """Closed-form signals of the motor: a speed, the current it needs, the voltage."""
    v = MOTOR_VALUES
    w = sp.sin(TIME) + TIME ** 2 / 3 + 1
    i = (v["J"] * w.diff(TIME) + v["b"] * w) / v["K"]
    u = v["L"] * i.diff(TIME) + v["R"] * i + v["K"] * w
    return {"w": w, "i": i, "u": u}


def test_rows_are_each_equations_in_the_systems_columns():
    d = derive(parse_system(*TWO_MASSES))
    names = [str(p) for p in d.parameters]
    assert names == TWO_MASSES[1].split() and d.P.shape == (7, 6) and not d.square
    for e, equation in enumerate(d.equations):
        rows = [r for r, (k, _) in enumerate(d.rows) if k == e]
        columns = [names.index(str(p)) for p in equation.model.parameters]
        block = d.P.extract(rows, list(range(6)))
        assert block.extract(list(range(len(rows))), columns) == equation.P
        others = [j for j in range(6) if j not in columns]
        assert block.extract(list(range(len(rows))), others).is_zero_matrix
        assert d.Q.extract(rows, [0]) == equation.Q
    # the second mass's equation has no known term: its rows' Q are zero
    assert all(q == 0 for q in d.equations[1].Q) and any(q != 0 for q in d.equations[0].Q)


def test_stacked_system_exact_on_closed_form_signals():
    """Every row of the stacked system holds at the true parameters, at any t, whatever
    the initial conditions of the signals (not zero here)."""
    d = derive(parse_system(*MOTOR))
    signals = _motor_signals()
    subs = {k.expression(): evaluate_kernel(k, signals) for k in d.kernels}
    theta = sp.Matrix([MOTOR_VALUES[str(p)] for p in d.parameters])
    residual = (d.P.xreplace(subs) * theta - d.Q.xreplace(subs)).applyfunc(sp.simplify)
    assert residual.is_zero_matrix
    wrong = dict(MOTOR_VALUES, K=MOTOR_VALUES["K"] * 2)
    theta = sp.Matrix([wrong[str(p)] for p in d.parameters])
    off = (d.P.xreplace(subs) * theta - d.Q.xreplace(subs)).subs(TIME, 1)
    assert all(abs(float(x)) > 1e-6 for x in off)


def test_equation_without_parameters_left_out():
    system = parse_system(["x2' + x2 = x1", "x1' + a*x1 = u"], "a")
    d = derive(system)
    assert len(d.equations) == 1 and d.skipped == ("x2' + x2 = x1",) and d.P.shape == (1, 1)
    report = derivation_report(system)
    assert "Without unknowns, and left out: x2' + x2 = x1" in report
    # numbered as in the system, counted in the singular
    assert "Equation 2 of 2: x1' + a*x1 = u" in report and "2.1. Model" in report
    assert "a*p2_0_0 = q2_0" in report and "1 equation in 1 unknown" in report


@pytest.mark.parametrize("fmt", ["text", "latex", "markdown"])
def test_system_report(fmt):
    report = derivation_report(parse_system(*MOTOR), fmt)
    for part in ("Equation 1 of 2", "Equation 2 of 2", "No known term", "The system",
                 "Stacked linear system", "6 equations in 5 unknowns", "K appears in several"):
        assert part in report, part
    if fmt == "latex":
        assert report.startswith(r"\documentclass") and report.rstrip().endswith(r"\end{document}")
        assert report.count(r"\begin{multline*}") == report.count(r"\end{multline*}")


def test_system_display_equations_render_with_mathtext():
    parser = MathTextParser("path")
    equations = display_equations(parse_system(*TWO_MASSES))
    assert len(equations) > 40
    for latex in equations:
        parser.parse(f"${latex}$")


def test_markdown_and_latex_texts_are_not_markup():
    markdown = derivation_report(parse_system(*TWO_MASSES), "markdown")
    assert "## Equation 1 of 2: `m1*x1'' + c1*x1' + k1*x1 + k2*(x1 - x2) = u`" in markdown
    assert "<" not in markdown.replace("$$", "")
    latex = derivation_report(parse_system(*TWO_MASSES), "latex")
    assert "t \\textgreater{} 0" in derivation_report("msd", "latex")
    assert "<" not in latex and ">" not in latex


@pytest.mark.parametrize("thing", [["y' + a*y = u"], None, 3])
def test_not_a_model_is_one_line(thing):
    from algid.errors import ModelError

    for call in (derive, derivation_report):
        with pytest.raises(ModelError, match="parse_system"):
            call(thing)


def test_cli_derive_system_with_outputs(capsys):
    argv = ["derive", "--equation", "y' + a*y = u", "--equation", "z' + b*z = c*y'",
            "--parameters", "a b c"]
    assert main(argv) == 2 and "ambiguous" in capsys.readouterr().err
    assert main(argv + ["--output", "y", "--output", "z"]) == 0
    assert "Equation 2 of 2" in capsys.readouterr().out


def test_cli_derive_system(capsys):
    code = main(["derive", "--equation", MOTOR[0][0], "--equation", MOTOR[0][1],
                 "--parameters", MOTOR[1]])
    out = capsys.readouterr().out
    assert code == 0 and out.startswith("Algebraic estimator of the system 'custom'")
    assert "S.1. Stacked linear system P theta = Q" in out


@pytest.mark.parametrize("argv, message", [
    (["derive", "--equation", MOTOR[0][0], "--equation", MOTOR[0][1], "--parameters",
      MOTOR[1], "--signals", "u", "i"], "--signals names the input and output of one"),
    (["derive", "--equation", MOTOR[0][0], "--equation", MOTOR[0][1], "--parameters",
      "L R K J b c"], "parameter c appears in no equation"),
    (["codegen", "--lang", "c", "--out", "never-written", "--equation", "x' + a*x = f",
      "--equation", "y' = f", "--parameters", "a"], "one equation; --equation was given 2"),
])
def test_cli_system_refusals(capsys, argv, message):
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err


def test_initial_conditions_of_signals_with_underscores_are_named_right():
    from algid.models import parse_equation

    report = derivation_report(parse_equation("x_d'' + a*x_d' = u", "a"))
    assert "unknown symbols (x_d(0), x_d'(0))" in report


def test_normal_equations_program_gives_the_parameters_on_closed_form_signals():
    """The program of the generated cramer() (normal equations of the 6 by 5 stacked
    system, structural zeros left out) returns the motor's parameters from the exact
    kernels of closed-form signals."""
    d = derive(parse_system(*MOTOR))
    steps, numerators, denominator = d.cramer_program()
    assert str(steps[0][0]) == "n_0_0" and not d.square
    Ps, Qs = d.entry_symbols()
    assert Ps[0, 3] == 0 and Qs[4] == 0   # J is not in the first equation; no known term
    signals = _motor_signals()
    kernels = {k.expression(): evaluate_kernel(k, signals).subs(TIME, sp.Rational(3, 2))
               for k in d.kernels}
    values = {}
    for i in range(Ps.shape[0]):
        values[Qs[i]] = d.Q[i].xreplace(kernels)
        for j in range(Ps.shape[1]):
            values[Ps[i, j]] = d.P[i, j].xreplace(kernels)
    for symbol, expression in steps:
        values[symbol] = expression.xreplace(values)
    den = denominator.xreplace(values)
    for p, numerator in zip(d.parameters, numerators):
        assert float(sp.N(numerator.xreplace(values) / den, 30)) == \
            pytest.approx(float(MOTOR_VALUES[str(p)]), rel=1e-12), p


def test_inseparable_parameters_are_named():
    assert derive(parse_system(*MOTOR)).inseparable() == ()
    d = derive(parse_system(["y' + a*y + b*y = u", "z' + c*z = y"], "a b c"))
    assert d.inseparable() == ("a", "b")
