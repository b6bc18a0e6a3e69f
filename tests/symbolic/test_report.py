"""The step-by-step derivation report: contents, formats, and that the LaTeX renders."""

import pytest
from matplotlib.mathtext import MathTextParser

from algid.cli import main
from algid.errors import ModelError
from algid.symbolic import LinearODEModel
from algid.symbolic._report import derivation_report, display_equations

USER_MODEL = LinearODEModel.from_equation("y'' + a*y' + b*y = u' + u", parameters="a b",
                                          input="u", output="y", name="user")


@pytest.mark.parametrize("model", ["msd", "msd_mass", USER_MODEL])
def test_every_display_equation_renders_with_mathtext(model):
    parser = MathTextParser("path")
    equations = display_equations(model)
    assert len(equations) > 10
    for latex in equations:
        parser.parse(f"${latex}$")  # raises ValueError on invalid TeX


@pytest.mark.parametrize("fmt", ["text", "latex", "markdown"])
def test_report_has_every_step(fmt):
    report = derivation_report("msd", fmt)
    for title in ("Model", "Laplace transform", "Derivative 1", "Derivative 2",
                  "Multiplication by s", "time domain", "More equations", "Linear system",
                  "Solution"):
        assert title in report
    if fmt == "latex":
        assert report.startswith(r"\documentclass") and report.rstrip().endswith(r"\end{document}")
        assert report.count(r"\begin{multline*}") == report.count(r"\end{multline*}")
    if fmt == "markdown":
        assert report.count("$$") % 2 == 0


def test_text_report_states_initial_condition_removal():
    """Snapshot of the report's wording; the derivation itself is tested on its own."""
    report = derivation_report("msd", "text")
    assert "Still present: x(0)" in report
    assert "The initial conditions are gone" in report
    assert "B*p_0_0 + K*p_0_1 = q_0" in report


def test_unknown_format():
    with pytest.raises(ModelError, match="unknown format"):
        derivation_report("msd", "html")


def test_cli_derive_user_model(capsys):
    code = main(["derive", "--equation", "y'' + a*y' + b*y = u", "--parameters", "a b",
                 "--signals", "u", "y", "--format", "markdown"])
    out = capsys.readouterr().out
    assert code == 0 and "# Algebraic estimator of model `custom`" in out


def test_cli_derive_bad_equation(capsys):
    code = main(["derive", "--equation", "y'' = u", "--parameters", "a"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "parameter a does not appear" in err
    code = main(["derive", "--equation", "y'' + a*y = u", "--parameters", "a",
                 "--signals", "f", "x"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "not the output" in err


def test_cli_derive_equation_in_several_signals(capsys):
    """Without --signals, an equation that is not linear in f and x is derived in every
    signal it reads (nonlinear factors too)."""
    code = main(["derive", "--equation", "y'' + a*y' + b*y**3 = u + c*w", "--parameters",
                 "a b c", "--format", "markdown"])
    out = capsys.readouterr().out
    assert code == 0 and "the signals y, u, w are measured (z1 stands for y\\*\\*3)" in out
