"""The errata report: every verdict is computed, and the realisation of the filters
agrees with the integral form of P and Q."""

import dataclasses
import json
import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import quad

from algid.cli import main
from algid.symbolic import TIME as t
from algid.symbolic import IteratedIntegral as I
from algid.symbolic import _errata as errata
from algid.symbolic import derive
from algid.symbolic._builtin_models import builtin_model
from algid.symbolic._realization import (
    entries,
    integrate_from_zero,
    kernel_terms,
    realize,
    solve_state_equations,
)

s = sp.Symbol("s")
B, K, m, c, k = sp.symbols("B K m c k")
x, f = sp.Function("x")(t), sp.Function("f")(t)
X, F = sp.Function("X")(s), sp.Function("F")(s)
p11, p12, p21, p22, q1, q2 = sp.symbols("p11 p12 p21 p22 q1 q2")
WRONG = {"11", "14", "15", "22", "26", "27", "28", "29", "30", "31"}


@pytest.fixture(scope="module")
def report():
    return errata.errata_report()


def entry(number):
    return next(e for e in errata.PRINTED if e.number == number)


def verdict(number, printed):
    """Verdict of entry ``number`` with its printed form replaced."""
    return errata.check_equation(dataclasses.replace(entry(number), printed=printed))


def outcome(number, printed=None):
    e = entry(number)
    return (e if printed is None else dataclasses.replace(e, printed=printed)).evaluate()


# ------------------------------------------------------------------ the report


def test_every_numbered_equation_is_judged_in_order(report):
    numbers = [v.number for v in report]
    assert numbers == [str(n) for n in range(1, 34)] + ["footnote 1"]
    assert all(v.explanation for v in report)


def test_the_wrong_equations(report):
    assert {v.number for v in report if not v.correct} == WRONG
    for v in report:
        assert (v.corrected is None) == v.correct


def test_explanations_name_the_difference(report):
    """Partly a snapshot: the wording of the explanations is compared with today's text.

    The corrected (14) and (15) are the forms derived by hand from the model.
    """
    by = {v.number: v for v in report}
    assert "B*d^2/ds^2[s*X(s)]" in by["11"].explanation
    # (14): the right side must keep the x(s) terms
    assert by["14"].corrected.endswith("= -X''(s) - 4*X'(s)/s - 2*X(s)/s**2 + F''(s)/s**2")
    assert by["15"].corrected == "B*p11 + K*p12 = q1"
    assert "sign of the K term flipped" in by["15"].explanation
    assert "labelled p12 but it defines p22" in by["22"].explanation
    for n in ("26", "27", "28", "29", "30", "31"):
        assert "theta_m(t), V(t)" in by[n].explanation
    assert "where psi2 = q11' does not hold" in by["31"].explanation
    assert "no equation for z3" in by["28"].explanation


def test_corrected_forms_pass_their_own_check():
    for number in ("11", "14", "15", "22"):
        ok, corrected, _ = outcome(number)
        assert not ok
        assert outcome(number, corrected)[0], number


def test_monkeypatched_table_changes_the_report(monkeypatch):
    fixed = dataclasses.replace(entry("15"), printed=((B * p11 + K * p12, q1),))
    table = tuple(fixed if e.number == "15" else e for e in errata.PRINTED)
    monkeypatch.setattr(errata.transcription, "PRINTED", table)
    verdicts = errata.errata_report()
    assert {v.number for v in verdicts if not v.correct} == WRONG - {"15"}


@pytest.mark.parametrize("number, printed", [
    # the printed form, corrected by hand from first principles
    ("11", ((sp.Derivative(s**2 * X, (s, 2)) + B * sp.Derivative(s * X, (s, 2)),
             sp.Derivative(F - K * X, (s, 2))),)),
    ("14", ((B * (2 * X.diff(s) / s**2 + X.diff(s, 2) / s) + K * X.diff(s, 2) / s**2,
             F.diff(s, 2) / s**2 - 2 * X / s**2 - 4 * X.diff(s) / s - X.diff(s, 2)),)),
    ("15", ((-B * p11 - K * p12, -q1),)),  # both sides negated is the same equation
    ("22", ((p22, I(p12, 1)), (p22, I(t**2 * x, 3)))),
])
def test_wrong_becomes_right_when_corrected(number, printed):
    assert verdict(number, printed).correct


@pytest.mark.parametrize("number, printed", [
    ("1", ((sp.Symbol("F_s"), k * x),)),
    ("3", ((sp.Symbol("sum_F"), m * sp.Symbol("a"), m * x.diff(t)),)),
    ("5", ((x.diff(t, 2) + c / m * x.diff(t) + k * x, sp.Function("F")(t) / m),)),
    ("6", ((x.diff(t, 2) + B * x.diff(t) - K * x, f),)),
    ("7", ((sp.Symbol("G"), X / F, 1 / (s**2 + K * s + B)),)),
    ("8", ((k, K / m),)),
    ("10", ((s**2 * X - s * sp.Symbol("x0") + B * (s * X - sp.Symbol("x0")) + K * X, F),)),
    ("12", ((sp.Derivative(s**2 * X, (s, 2)), 2 * X + 2 * s * X.diff(s) + s**2 * X.diff(s, 2)),)),
    ("16", ((p11, -2 * I(t * x, 2) + I(t**2 * x, 2)),)),
    ("18", ((q1, I(t**2 * f + 2 * x, 2) + 4 * I(t * x, 1) - t**2 * x),)),
    ("20", ((sp.MatMul(sp.ImmutableMatrix([[p11, p12], [p21, p22]]), sp.ImmutableMatrix([B, K])),
             sp.ImmutableMatrix([q2, q1])),)),
    ("24", ((K, (-p11 * q1 + p21 * q2) / (p11 * p22 - p12 * p21)),)),
    ("32", ((K, errata.LowPass(-p21 * q1 + p11 * q2) / (p11 * p22 - p12 * p21)),)),
])
def test_right_becomes_wrong_when_perturbed(number, printed):
    assert errata.check_equation(entry(number)).correct
    assert not verdict(number, printed).correct


def test_swapped_cramer_formulas_are_reported_as_mislabelled():
    den = p11 * p22 - p12 * p21
    v = verdict("24", ((K, (p22 * q1 - p12 * q2) / den),))
    assert not v.correct
    assert "solution for B" in v.explanation


def test_footnote_with_wrong_limits_is_wrong():
    phi = sp.Function("phi")
    s1, s2 = sp.symbols("sigma1 sigma2")
    wrong = sp.Integral(sp.Integral(phi(s2), (s2, 0, t)), (s1, 0, t))  # inner limit t, not sigma1
    assert not verdict("footnote 1", ((I(phi(t), 2), wrong),)).correct


def test_format(report):
    text = errata.format_errata(report)
    lines = text.splitlines()
    assert f"{len(WRONG)} of {len(report)}" in lines[0]
    assert sum(1 for line in lines if " WRONG " in line) == len(WRONG)
    assert "Corrected forms" in text
    data = json.loads(errata.format_errata(report, "json"))
    assert [d["number"] for d in data] == [v.number for v in report]
    with pytest.raises(ValueError):
        errata.format_errata(report, "xml")


# ------------------------------------------------------------------ the CLI


def test_cli_json(capsys):
    assert main(["errata", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert {d["number"] for d in data if not d["correct"]} == WRONG
    assert all({"number", "correct", "printed", "corrected", "explanation"} <= set(d) for d in data)


def test_cli_text(capsys):
    assert main(["errata"]) == 0
    out = capsys.readouterr().out
    assert "(15)" in out and "B*p11 + K*p12 = q1" in out


def test_cli_without_sympy(capsys, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "sympy", None)
    assert main(["errata"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("algid: error:") and "SymPy" in err and len(err.splitlines()) == 1


# ------------------------------------------------------------ the realisation


@pytest.fixture(scope="module")
def msd():
    return derive(builtin_model("msd"))


@pytest.mark.parametrize("layout", ["entries", "chains"])
def test_realization_reproduces_the_integral_form(msd, layout):
    real = realize(msd, layout=layout)
    assert real.check()
    # A is nilpotent (chains of integrators), C constant, B(t) and D(t) polynomial in t
    n = len(real.states)
    assert real.A ** n == sp.zeros(n, n)
    assert not real.C.free_symbols and real.B.free_symbols <= {t} and real.D.free_symbols <= {t}


@pytest.fixture(scope="module")
def closed_form():
    """An exact trajectory of x'' + 2x' + 3x = f with x(0) = 3, x'(0) = -3."""
    xt = 1 + 2 * sp.exp(-t) - t * sp.exp(-2 * t)
    return {"x": xt, "f": sp.expand(xt.diff(t, 2) + 2 * xt.diff(t) + 3 * xt)}


def _kernel_by_quadrature(signals, kern, at):
    """Cauchy's formula int^(k) g(t) = int_0^t (t - tau)^(k-1) g(tau) dtau / (k-1)!, by quad."""
    g = sp.lambdify(t, t**kern.power * signals[kern.signal])
    if kern.order == 0:
        return g(at)
    weight = math.factorial(kern.order - 1)
    return quad(lambda tau: (at - tau) ** (kern.order - 1) * g(tau), 0, at,
                epsabs=1e-14, epsrel=1e-13)[0] / weight


@pytest.mark.parametrize("layout", ["entries", "chains"])
def test_realization_response_on_a_closed_form_trajectory(msd, closed_form, layout):
    """Integrating the state equations symbolically gives P and Q as numerical
    quadrature of the kernels does."""
    response = realize(msd, layout=layout).response(closed_form)
    for at in (0.4, 1.7):
        values = {kern.expression(): sp.Float(_kernel_by_quadrature(closed_form, kern, at))
                  for kern in msd.kernels}
        for name, expr in entries(msd).items():
            want = float(expr.xreplace(values))
            got = float(response[name].subs(t, at))
            assert got == pytest.approx(want, rel=1e-9, abs=1e-12), (name, at)


def test_chains_agree_with_the_generated_module(msd, closed_form):
    from algid._generated import msd as generated

    real = realize(msd, layout="chains")
    assert real.chains == generated.CHAINS
    # the generated regressors, fed with kernel values, equal the filter outputs
    signals = closed_form
    response = real.response(signals)
    times = np.array([0.3, 1.0, 2.5])
    kernels = {}
    for sig, power, order in generated.KERNELS:
        g = t**power * signals[sig]
        for _ in range(order):
            g = integrate_from_zero(g)
        kernels[generated.kernel_name(sig, power, order)] = sp.lambdify(t, g)(times) + 0 * times
    (P, Q) = generated.regressors(kernels)
    got = {"p11": P[0][0], "p12": P[0][1], "p21": P[1][0], "p22": P[1][1], "q1": Q[0], "q2": Q[1]}
    for name, value in got.items():
        want = sp.lambdify(t, response[name])(times)
        np.testing.assert_allclose(value, want, rtol=1e-12, atol=1e-14)


def test_paper_style_realization_text(msd):
    """Snapshot of the printed realisation (state names and printing as of today).

    The equations themselves are checked by the tests of the realisation above.
    """
    text = realize(msd).format()
    assert "p11_z1' = p11_z2 + t**2*x(t)" in text
    assert "where p21_z2 = p11" in text and "where p22_z2 = p12" in text


def test_integrate_from_zero_matches_sympy():
    tau = sp.Symbol("tau")
    for g in (t**3 * sp.exp(-2 * t), 3 + t**2, t * sp.exp(t) - 5 * sp.exp(-t / 2)):
        assert sp.simplify(integrate_from_zero(g) - sp.integrate(g.subs(t, tau), (tau, 0, t))) == 0


def test_kernel_algebra_and_state_equations_reject_what_they_cannot_realise():
    assert kernel_terms(I(t**2 * f - 2 * x, 2)) == {("f", 2, 2): 1, ("x", 0, 2): -2}
    assert kernel_terms(I(I(t * x, 1), 2)) == {("x", 1, 3): 1}
    for bad in (t * I(x, 1), x * f, t**2):
        with pytest.raises(ValueError):
            kernel_terms(bad)
    z1, z2 = sp.symbols("z1 z2")
    with pytest.raises(ValueError, match="cycle"):
        solve_state_equations({z1: z2, z2: z1 + x}, {"y": z1})
    with pytest.raises(ValueError, match="no state equation for z2"):
        solve_state_equations({z1: z2 + x}, {"y": z1})
    form = solve_state_equations({z1: t * x + z2, z2: x}, {"y": z1 - t**2 * x})
    assert sp.expand(form["y"] - (I(t * x, 1) + I(x, 2) - t**2 * x)) == 0
    with pytest.raises(ValueError):
        realize(derive(builtin_model("msd")), layout="diagonal")
