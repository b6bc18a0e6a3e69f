"""The adequacy test of identify()'s algebraic estimate (of its window equations): it flags
wrong models and stays silent on right ones.  (A refined estimate's test, of its
simulation residuals, is in test_output_error.py.)

The rates of hits and false alarms over 100 noise realisations per case are measured
by ``python -m benchmarks.adequacy``; these tests run a few realisations of each.
"""

import functools
import json
import sys

import numpy as np
import pytest
from conftest import ROOT

import algid
from algid.cli import main
from algid.identification._adequacy import MISFIT_LIMIT, SHIFT_LIMIT, Adequacy, misfit_limit

#: identify's algebraic estimate, whose adequacy test this is
identify = functools.partial(algid.identify, refine=False)

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.adequacy import SECOND_ORDER, delayed, second_order  # noqa: E402
from benchmarks.synthetic_records import (  # noqa: E402
    CUBIC_EQUATION,
    FRICTION_EQUATION,
    LINEAR_EQUATION,
    cubic_spring,
    friction_loop,
    linear_offsets,
)

WRONG_DERIVATIVE = ("y'' + B*y' + K*y = G*u'", "B K G")


@pytest.fixture(scope="module")
def cubic_records():
    return [cubic_spring(seed)[0] for seed in range(2)]


@pytest.mark.parametrize("make, equation", [
    (lambda s: linear_offsets(s)[0], LINEAR_EQUATION),
    (lambda s: friction_loop(s)[0], FRICTION_EQUATION),
    (second_order, SECOND_ORDER),
])
def test_right_models_are_not_flagged(make, equation):
    for seed in range(3):
        r = identify(make(seed), *equation)
        assert r.warnings == [] and r.adequacy.adequate, (seed, r.adequacy)
        # white output noise: the misfit is at most about the noise bound
        assert r.adequacy.misfit < MISFIT_LIMIT


def test_right_cubic_model_is_not_flagged_and_a_linear_one_is(cubic_records):
    for record in cubic_records:
        right = identify(record, *CUBIC_EQUATION)
        assert right.warnings == [], right.adequacy
        wrong = identify(record, *LINEAR_EQUATION)
        # one line for the term that explains the misfit, one for the shift
        assert len(wrong.warnings) == 2, wrong.adequacy
        assert wrong.adequacy.misfit > MISFIT_LIMIT and wrong.adequacy.shift > SHIFT_LIMIT


def multisine_cubic(coefficient, seed, noise=0.01):
    """60 s at 100 Hz of ``y'' + 2y' + 3y + coefficient*y**3 = u`` (six-tone input)."""
    from scipy.integrate import solve_ivp

    rng = np.random.default_rng(seed)
    t = np.arange(0, 60, 0.01)
    u = sum(np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
            for f in (0.05, 0.13, 0.31, 0.7, 1.3, 2.9))
    s = solve_ivp(lambda tt, x: [x[1], np.interp(tt, t, u) - 2 * x[1] - 3 * x[0]
                                 - coefficient * x[0] ** 3],
                  (0, 60), [0, 0], t_eval=t, max_step=0.005, rtol=1e-9, atol=1e-12)
    return {"t": t, "u": u, "y": s.y[0] + noise * s.y[0].std() * rng.standard_normal(len(t))}


@pytest.mark.parametrize("coefficient, seed", [(2, 1), (5, 2), (10, 3)])
def test_a_missing_term_that_explains_the_misfit_is_named(coefficient, seed):
    record = multisine_cubic(coefficient, seed)
    # the estimates hardly move between window lengths: only the missing term tells
    linear = identify(record, "y'' + B*y' + K*y = u", "B K")
    assert linear.adequacy.missing == ("y**3",), linear.adequacy
    assert linear.adequacy.explained < 0.5 and not linear.adequacy.adequate
    assert any("a term in y**3 would explain most of it" in w for w in linear.warnings)
    # without the spring the output itself explains the misfit
    no_spring = identify(record, "y'' + B*y' = u", "B")
    assert no_spring.adequacy.missing == ("y",), no_spring.adequacy
    right = identify(record, "y'' + B*y' + K*y + K3*y**3 = u", "B K K3")
    assert right.warnings == [] and right.adequacy.missing == (), right.adequacy


def test_missing_term_names_do_not_clash_with_the_models():
    record = multisine_cubic(5, 2)
    r = identify({"t": record["t"], "u": record["u"], "_c1": record["y"]},
                       "_c1'' + _c2*_c1' + _c3*_c1 = u", "_c2 _c3")
    assert r.adequacy.missing == ("_c1**3",), r.adequacy


def test_published_emps_model_is_not_flagged():
    for run in ("estimation", "validation"):
        r = identify(algid.datasets.emps(run), algid.datasets.EMPS_EQUATION,
                           list(algid.datasets.EMPS_PUBLISHED))
        # force disturbances, not output noise: a large misfit no power of q explains
        assert r.adequacy.misfit > r.adequacy.misfit_limit, run
        assert r.warnings == [] and r.adequacy.missing == (), (run, r.adequacy)


@pytest.mark.parametrize("wrong", ["derivative", "delay"])
def test_wrong_derivative_order_and_delayed_output_are_flagged(wrong):
    for seed in range(2):
        record = second_order(seed)
        if wrong == "delay":
            r = identify(delayed(record, 5, "y"), *SECOND_ORDER)
        else:
            r = identify(record, *WRONG_DERIVATIVE)
        assert len(r.warnings) == 1 and not r.adequacy.adequate, r.adequacy
        text = r.warnings[0]
        assert "\n" not in text and "does not explain the data within the noise" in text
        assert r.adequacy.parameter in text
        assert "warning: " + text in repr(r)
        # made for the identified values: not carried over to other ones
        other = r.with_parameters(r.values)
        assert other.warnings == [] and other.adequacy is None


def test_misfit_of_a_wrong_model_falls_with_the_noise_as_one_plus_bias_over_noise():
    """The misfit is the residual energy over that of output noise: about 1 for a
    right model at any noise level, ``1 + b / sigma^2`` for a systematic misfit ``b``."""
    clean, late = {}, {}
    for noise in (0.01, 0.05):
        record = second_order(0, noise=noise)
        clean[noise] = identify(record, *SECOND_ORDER).adequacy.misfit
        late[noise] = identify(delayed(record, 5, "y"), *SECOND_ORDER).adequacy.misfit
    assert all(0.5 < m < 1.6 for m in clean.values()), clean
    predicted = 1 + (late[0.01] - 1) / 25
    assert abs(late[0.05] / predicted - 1) < 0.3, (late, predicted)


def test_other_methods_carry_the_test():
    record = second_order(1)
    for method in ("ls", "iv"):
        r = identify(record, *SECOND_ORDER, method=method)
        assert isinstance(r.adequacy, Adequacy) and r.warnings == [], (method, r.adequacy)
        assert np.isfinite(r.adequacy.shift)
    r = identify(record, *WRONG_DERIVATIVE, method="ls")
    assert len(r.warnings) == 1


def test_a_user_window_too_long_to_double_is_compared_with_half_of_it():
    record = second_order(0)
    # twelve records of 5 s: a 3 s window leaves one in each (the 11 non-overlapping
    # windows that three parameters need), and none holds a window twice as long
    parts = [{k: v[i:i + 500] for k, v in record.items()} for i in range(0, 6000, 500)]
    r = identify(parts, *SECOND_ORDER, window=3.0)
    assert r.adequacy.other_window == pytest.approx(1.5, abs=0.011)
    assert r.warnings == []


def test_misfit_limit_rises_on_few_windows():
    # chi-square with few degrees of freedom exceeds 2 often: the limit follows it
    assert misfit_limit(2000, 16, 4, 2) == MISFIT_LIMIT
    few = misfit_limit(40, 16, 4, 2)
    assert few > misfit_limit(100, 16, 4, 2) > MISFIT_LIMIT
    assert few > 5


def test_cli_prints_one_stderr_line_per_warning_and_json_carries_them(tmp_path, capsys):
    record = second_order(0)
    path = tmp_path / "late.csv"
    late = delayed(record, 5, "y")
    np.savetxt(path, np.column_stack([late["t"], late["u"], late["y"]]), delimiter=",",
               header="t,u,y", comments="")
    argv = [str(path), "--equation", SECOND_ORDER[0], "--parameters", SECOND_ORDER[1]]
    assert main(["identify", *argv, "--no-refine"]) == 0
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"warning: {path}: the model does not")
    assert "parameter" in out
    # refined (the default): the residual test names the shift (``delayed`` takes the
    # output's samples 5 rows later: the output is ahead of the model)
    assert main(["identify", *argv]) == 0
    out, err = capsys.readouterr()
    lines = err.splitlines()
    assert len(lines) == 1 and "output advanced by about 4.8 samples" in lines[0], lines
    assert main(["identify", *argv, "--json"]) == 0
    out, err = capsys.readouterr()
    payload = json.loads(out)
    assert len(payload["warnings"]) == 1 and payload["warnings"][0] in err
    # a right model: no warning, an empty list
    path = tmp_path / "right.csv"
    np.savetxt(path, np.column_stack([record["t"], record["u"], record["y"]]), delimiter=",",
               header="t,u,y", comments="")
    assert main(["identify", str(path), *argv[1:], "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["warnings"] == [] and err == ""
