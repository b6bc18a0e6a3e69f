"""The output-error refinement of identify's estimate (identify(refine=...),
IdentificationResult.refine): its simulator, its estimate and its covariance."""

import numpy as np
import pytest

import algid
from algid.errors import InputDataError, ModelError
from algid.identification._linear_simulation import LinearSimulation, channel_samples
from algid.identification._output_error import (
    refine_result,
    refinement_unavailable,
    stabilised,
)
from algid.identification._records import Segment
from algid.models import parse_equation

LINEAR = ("y'' + B*y' + K*y = G*u + d", "B K G d")
TRUTH = {"B": 0.6, "K": 40.0, "G": 40.0, "d": 0.5}


def _segment(t, **values):
    return Segment(0, np.arange(len(t)), t, values, float(t[1] - t[0]))


@pytest.mark.parametrize("equation, parameters, values", [
    ("y'' + B*y' + K*y = G*u + d + e*t", "B K G d e",
     {"B": 0.6, "K": 40.0, "G": 40.0, "d": 0.5, "e": -0.2}),
    ("M*y' + a*y = b*u' + 1.5*u + d", "M a b d",
     {"M": 2.0, "a": 3.0, "b": 0.5, "d": 0.25}),
    ("y''' + a2*y'' + a1*y' + a0*y = g*u'' + u", "a2 a1 a0 g",
     {"a2": 3.0, "a1": 12.0, "a0": 10.0, "g": 0.3}),
])
def test_simulation_is_exact_for_an_input_linear_between_samples(equation, parameters,
                                                                 values):
    """Inputs linear in time are exact under the first-order hold; the adaptive
    simulator (DOP853 at 1e-12) agrees to its own accuracy, from any initial state."""
    model = parse_equation(equation, parameters, output="y")
    t = np.arange(0.0, 4.0, 0.01)
    u = 0.3 + 0.7 * t
    order = model.order
    x0 = np.linspace(0.4, -0.3, order)
    reference = algid.simulate_model(model, values, t, {"u": u}, initial_state=x0,
                                     interpolation="cubic", rtol=1e-12, atol=1e-14)
    sim = LinearSimulation(model, values, 0.01)
    forced, free = sim.run(channel_samples(sim.channels, _segment(t, u=u)))
    assert free.shape == (len(t), order)
    fitted = np.linalg.lstsq(free, reference - forced, rcond=None)[0]
    assert np.max(np.abs(forced + free @ fitted - reference)) < 1e-9 * np.max(np.abs(reference))


def test_simulation_at_a_high_rate_keeps_its_digits():
    """A lightly damped mode sampled 10,000 times per period: the Schur recursion keeps
    the free responses accurate (a transfer function in z would lose them)."""
    model = parse_equation(*LINEAR)
    t = np.arange(0, 2.0, 1e-4)
    sim = LinearSimulation(model, TRUTH, 1e-4)
    _, free = sim.run(channel_samples(sim.channels, _segment(t, u=np.zeros_like(t))))
    # the free response from y = 1, y' = 0 (observable form in the time unit of a step
    # h: x = (y, h (y' + B y)))
    omega = np.sqrt(TRUTH["K"] - TRUTH["B"] ** 2 / 4)
    sigma = TRUTH["B"] / 2
    exact = np.exp(-sigma * t) * (np.cos(omega * t) + sigma / omega * np.sin(omega * t))
    response = free @ np.array([1.0, TRUTH["B"] * 1e-4])
    assert np.max(np.abs(response - exact)) < 1e-10


@pytest.fixture(scope="module")
def linear_record():
    """10 s at 1 kHz of the linear model from a nonzero state, 3 % output noise."""
    model = parse_equation(*LINEAR)
    t = np.arange(0, 10, 1e-3)
    u = np.sin(2 * np.pi * 0.7 * t) + np.sin(2 * np.pi * 2.3 * t + 1)
    y = algid.simulate_model(model, TRUTH, t, {"u": u}, initial_state=[0.1, 0.0],
                             rtol=1e-10, atol=1e-14)
    rng = np.random.default_rng(0)
    return {"t": t, "u": u, "y": y + 0.03 * np.std(y) * rng.standard_normal(len(t))}


def test_identify_refines_a_linear_model_by_default(linear_record):
    refined = algid.identify(linear_record, *LINEAR)
    algebraic = algid.identify(linear_record, *LINEAR, refine=False)
    assert refined.estimate == "refined" and algebraic.estimate == "algebraic"
    assert refined.refinement.applied and refined.refinement.converged
    assert refined.refinement.rms_after <= refined.refinement.rms_before
    assert refined.algebraic["values"] == algebraic.values   # the algebraic one is kept
    # its numerical error: the change with a cubic-spline interpolation of the inputs,
    # negligible at 1 kHz for inputs below 3 Hz
    assert all(0 <= refined.numerical_error[p] < 0.01 * refined.stderr[p] for p in TRUTH)
    for p, truth in TRUTH.items():
        assert abs(refined.values[p] - truth) < 4 * refined.stderr[p]
    # most of the gain where the algebraic windows weight the data least evenly
    assert refined.stderr["B"] < 0.5 * algebraic.stderr["B"]
    assert all(refined.stderr[p] < algebraic.stderr[p] for p in TRUTH)
    assert "refined by output error" in repr(refined)


def test_refine_method_and_its_round_trip(linear_record):
    algebraic = algid.identify(linear_record, *LINEAR, refine=False)
    refined = algebraic.refine(linear_record)
    again = refined.refine(linear_record)   # starts from the algebraic estimate again
    assert refined.estimate == again.estimate == "refined"
    assert refined.values == again.values
    direct = algid.identify(linear_record, *LINEAR)
    assert refined.values == direct.values


def test_records_with_gaps_have_an_initial_state_per_run(linear_record):
    record = {k: v.copy() for k, v in linear_record.items()}
    keep = np.ones(len(record["t"]), bool)
    keep[3000:3400] = False      # rows missing: two runs
    gapped = {k: v[keep] for k, v in record.items()}
    result = algid.identify(gapped, *LINEAR)
    assert result.estimate == "refined"
    assert len(result.refinement.initial_states) == 2
    for p, truth in TRUTH.items():
        assert abs(result.values[p] - truth) < 4 * result.stderr[p]


def test_a_model_the_fast_simulator_cannot_run_keeps_the_algebraic_estimate(linear_record):
    """A sign() of an expression of the output (not one of its derivatives) has no exact
    switching in the fast simulator: not refined, said in the reason, refused with
    refine=True."""
    equation = ("y'' + B*y' + K*y + c*sign(y' + y) = G*u + d", "B K c G d")
    assert refinement_unavailable(parse_equation(*equation)) is not None
    result = algid.identify(linear_record, *equation)
    assert result.estimate == "algebraic" and not result.refinement.applied
    assert "sign(" in result.refinement.reason
    with pytest.raises(ModelError, match="refine: cannot simulate"):
        algid.identify(linear_record, *equation, refine=True)


def test_an_unstable_algebraic_model_starts_the_fit_reflected(linear_record):
    """A wrong model's algebraic estimate is often unstable: by default its fit starts
    from the same model with the unstable poles reflected, and must end stable; a
    pole on the imaginary axis cannot be reflected (not refined, said in the reason)."""
    result = algid.identify(linear_record, *LINEAR, refine=False)
    t = linear_record["t"]
    segments = [_segment(t, u=linear_record["u"], y=linear_record["y"])]
    unstable = result.with_parameters({"B": -0.5, "K": 40.0, "G": 40.0, "d": 0.5})
    assert stabilised(unstable.model, unstable.values)["B"] == pytest.approx(0.5)
    refined = refine_result(unstable, segments, 1e-3, "auto")
    assert refined.estimate == "refined" and "reflected" in refined.refinement.reason
    assert abs(refined.B - TRUTH["B"]) < 4 * refined.stderr["B"]
    integrating = result.with_parameters({"B": 0.6, "K": 0.0, "G": 40.0, "d": 0.5})
    kept = refine_result(integrating, segments, 1e-3, "auto")
    assert kept.estimate == "algebraic" and "not stable" in kept.refinement.reason
    assert kept.warnings == []      # said in the reason: the default is not an error
    tried = refine_result(integrating, segments, 1e-3, True)   # asked for: tried as is
    assert tried.estimate == "refined"
    assert abs(tried.K - TRUTH["K"]) < 4 * tried.stderr["K"]


@pytest.mark.parametrize("bad", ["yes", 1, None, 2.0])
def test_refine_argument_is_checked(linear_record, bad):
    with pytest.raises(InputDataError, match="refine must be True, False or 'auto'"):
        algid.identify(linear_record, *LINEAR, refine=bad)


def test_coloured_noise_raises_the_standard_errors(linear_record):
    """AR(1) noise of pole 0.9 (same variance): the covariance sees the colour (its AR
    model is not white) and its standard errors grow, as the estimates' spread does."""
    from scipy.signal import lfilter

    rng = np.random.default_rng(1)
    white = linear_record
    y_clean = white["y"] - (white["y"] - algid.simulate_model(
        parse_equation(*LINEAR), TRUTH, white["t"], {"u": white["u"]},
        initial_state=[0.1, 0.0], rtol=1e-10, atol=1e-14))
    e = lfilter([1.0], [1.0, -0.9], rng.standard_normal(len(y_clean)))
    e *= 0.03 * np.std(y_clean) / np.std(e)
    coloured = {"t": white["t"], "u": white["u"], "y": y_clean + e}
    r_white = algid.identify(white, *LINEAR)
    r_col = algid.identify(coloured, *LINEAR)
    assert len(r_white.refinement.noise_ar) <= 3
    assert len(r_col.refinement.noise_ar) >= 2 and r_col.refinement.noise_ar[1] < -0.5
    assert r_col.stderr["K"] > 2 * r_white.stderr["K"]


def _record(truth_equation, values, *, seconds=15.0, shift=0, drift=0.0, seed=3):
    """A multisine through ``truth_equation`` at 1 kHz, 30 dB of white output noise."""
    model = parse_equation(*truth_equation)
    t = np.arange(0, seconds, 1e-3)
    rng = np.random.default_rng(2024)
    u = sum(np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
            for f in np.geomspace(0.1, 5.0, 12))
    y = algid.simulate_model(model, values, t, {"u": u}, initial_state=[0.05, -0.2],
                             rtol=1e-10, atol=1e-14)
    if shift:
        y = np.concatenate([np.full(shift, y[0]), y[:-shift]])
    y = y + drift * t
    noise = np.random.default_rng(seed).standard_normal(len(t))
    return {"t": t, "u": u, "y": y + np.sqrt(np.mean(y ** 2)) / 31.6 * noise}


@pytest.mark.parametrize("case, truth, model, options, cause", [
    ("offset", LINEAR, ("y'' + B*y' + K*y = G*u", "B K G"), {}, "an offset missing"),
    ("late", LINEAR, LINEAR, {"shift": 3}, "delayed by about 3"),
    ("drift", LINEAR, LINEAR, {"drift": 0.002}, "a drift"),
    ("derivative", ("y'' + B*y' + K*y = G*u' + d", "B K G d"), LINEAR, {},
     "a term in u' missing"),
    ("gain", LINEAR, ("y'' + B*y' + K*y = 30*u + d", "B K d"), {}, "gain of u"),
])
def test_the_residual_test_names_the_cause_of_a_wrong_model(case, truth, model, options,
                                                             cause):
    result = algid.identify(_record(truth, TRUTH, **options), *model)
    assert result.estimate == "refined"
    assert not result.refinement.residual_test.adequate
    found = [w for w in result.warnings if w.startswith("the simulation residuals")]
    assert cause in found[0], result.warnings   # the likeliest first


def test_the_residual_test_is_silent_on_a_right_model():
    result = algid.identify(_record(LINEAR, TRUTH), *LINEAR)
    test = result.refinement.residual_test
    assert test.adequate and result.warnings == []
    # a term the model has scores nothing: its direction is fitted
    assert "offset" not in test.scores and "gain:u" not in test.scores
    # the algebraic estimate's own warnings stay with it
    assert isinstance(result.algebraic["warnings"], list)


def test_an_unstable_instrumental_variable_estimate_is_said(linear_record, monkeypatch):
    """method='iv' ending on a model whose simulation diverges says so (its instruments
    would too), in the algebraic result and in one the refinement does not replace."""
    from algid.identification import _output_error

    monkeypatch.setattr(_output_error, "simulates_stably", lambda model, values: False)
    result = algid.identify(linear_record, *LINEAR, method="iv")
    assert result.estimate == "algebraic"
    assert any("instrumental-variable estimate's model is not stable" in w
               for w in result.warnings)
    bc = algid.identify(linear_record, *LINEAR, refine=False)
    assert not any("instrumental" in w for w in bc.warnings)


def test_given_values_refined_on_a_record_report_their_errors(linear_record):
    """A result of values of one's choosing, refined: its repr gives the standard errors
    and says where it started."""
    start = algid.IdentificationResult.from_values(
        LINEAR[0], {"B": 0.5, "K": 41.0, "G": 39.0, "d": 0.4})
    refined = start.refine(linear_record)
    assert refined.estimate == "refined" and refined.n_samples == len(linear_record["t"])
    assert "±" in repr(refined) and "refined by output error from given values" in repr(
        refined)
    for p, truth in TRUTH.items():
        assert abs(refined.values[p] - truth) < 4 * refined.stderr[p]


def test_refined_residuals_far_above_the_noise_are_named():
    """A model without the record's offset: its refined fit leaves residuals five times
    the output noise.  Their AR model absorbed the constant part, and the test named
    nothing; the correlation under the alternative (the candidate's part removed) names
    the offset.  The right model is silent."""
    from benchmarks.synthetic_records import linear_offsets

    record, _ = linear_offsets(0)
    fit = algid.identify(record, "y'' + B*y' + K*y = G*u", "B K G")
    assert fit.estimate == "refined"
    assert fit.warnings[0].startswith("the simulation residuals keep a constant part: an "
                                      "offset missing?"), fit.warnings
    right = algid.identify(record, "y'' + B*y' + K*y = G*u + d", "B K G d", refine=True)
    assert right.estimate == "refined" and right.warnings == [], right.warnings


def test_a_right_model_under_coloured_noise_is_not_warned():
    """AR(1) output noise of pole 0.9 on the right model: its simulation residuals are
    about four times the white noise the samples' differences show, and a warning said
    so on every record ("the model does not explain the records ... or their noise is
    not white"); coloured noise is no model error, and the covariance counts it."""
    from benchmarks.residual_adequacy import CASES, clean_output, record

    truth, values, model, options, _ = CASES["right_ar1"]
    full = record(clean_output(truth, values, options), 0, colour=True)
    result = algid.identify({k: v[:15000] for k, v in full.items()}, *model)
    assert result.estimate == "refined" and result.warnings == [], result.warnings
