"""identify() on the real benchmark records: Silverbox and EMPS, automatic window.

The records are those shipped with the package (:mod:`algid.datasets`).
"""

import numpy as np
import pytest

import algid
from algid import datasets
from algid.models._grammar import parse_equation

SILVERBOX_RATE = 610.35
SILVERBOX_EQUATION = "V2'' + B*V2' + K*V2 + K3*V2**3 = G*V1 + d"
EMPS_EQUATION = datasets.EMPS_EQUATION
EMPS_PUBLISHED = datasets.EMPS_PUBLISHED


@pytest.fixture(scope="module")
def silverbox():
    record = datasets.silverbox()
    return {"V1": np.asarray(record["V1"]), "V2": np.asarray(record["V2"])}


def emps_record(run, pulses=False):
    """The force on the mass is ``gtau * vir`` on both runs: on the validation run the
    pulses are already in the drive command (``pulses=True`` counts them twice)."""
    record = datasets.emps(run)
    force = record.gtau * np.asarray(record["vir"])
    if pulses:
        force = force + np.asarray(record["pulses_N"])
    return {"t": np.asarray(record["t"]), "qm": np.asarray(record["qm"]), "F": force}


@pytest.fixture(scope="module")
def emps():
    return emps_record("estimation")


@pytest.fixture(scope="module")
def emps_validation():
    return emps_record("validation")


def rows(record, start, stop):
    return {k: v[start:stop] for k, v in record.items()}


def test_silverbox_cubic_model_simulates_the_arrow_part_within_half_a_millivolt(silverbox):
    r = algid.identify(rows(silverbox, 40650, 105712), SILVERBOX_EQUATION, "B K K3 G d",
                       rate=SILVERBOX_RATE)
    # measured: 0.480 mV (band-limited input, RK4 with 4 steps per sample: within 9 uV
    # rms of the default DOP853, which gives 0.482 mV but takes minutes; initial state
    # fitted on the first 50 samples, error over the rest)
    v = r.simulate(rows(silverbox, 100, 40575), fit_samples=50, method="RK4")
    assert v.rmse <= 0.5e-3
    natural_frequency = np.sqrt(r.K) / (2 * np.pi)
    assert 67.5 < natural_frequency < 69.0
    assert r.K3 > 0                      # a hardening spring


def test_emps_estimation_run_matches_the_published_values(emps):
    r = algid.identify(emps, EMPS_EQUATION, "M Fv Fc off")
    limits = {"M": 0.01, "Fv": 0.02, "Fc": 0.03, "off": 0.05}
    errors = {p: abs(r.values[p] / EMPS_PUBLISHED[p] - 1) for p in limits}
    assert all(errors[p] <= limits[p] for p in limits), errors
    # relative error of the predicted force: measured 4.52 % (published 4.08 % with its
    # own filtering; the published values give 4.50 % with this measure)
    assert r.equation_error(emps) < 0.05


def test_emps_record_reads_with_the_published_equation_as_it_is(emps):
    r = algid.identify(datasets.emps(), EMPS_EQUATION, list(EMPS_PUBLISHED))
    assert r.values == algid.identify(emps, EMPS_EQUATION, "M Fv Fc off").values


def test_emps_published_values_are_keyed_by_the_equations_parameters():
    model = parse_equation(EMPS_EQUATION, "M Fv Fc off")
    assert list(EMPS_PUBLISHED) == list(model.parameters)
    assert set(datasets.EMPS_PUBLISHED_RELATIVE_STD) == set(EMPS_PUBLISHED)


def test_emps_validation_run_identified_anew(emps_validation):
    r = algid.identify(emps_validation, EMPS_EQUATION, "M Fv Fc off")
    # measured: M -1.41 %, Fv +3.52 %, Fc +2.20 %, off +1.95 %
    limits = {"M": 0.03, "Fv": 0.05, "Fc": 0.05, "off": 0.05}
    errors = {p: abs(r.values[p] / EMPS_PUBLISHED[p] - 1) for p in limits}
    assert all(errors[p] <= limits[p] for p in limits), errors
    # predicted force on this run: measured 12.80 %, not worse than the published
    # parameters under the same measure (12.84 %; published with its filtering: 5.98 %)
    published = r.with_parameters(EMPS_PUBLISHED)
    assert r.equation_error(emps_validation) <= published.equation_error(emps_validation)


def test_emps_pulses_added_to_the_force_count_them_twice():
    """With ``gtau*vir + pulses_N`` as the force the pulses (0 or 5, mean 2.5) become a
    force the motion does not show: the offset absorbs their mean and lands far from
    the published value (measured -78 %; 2 % with ``F = gtau*vir``)."""
    r = algid.identify(emps_record("validation", pulses=True), EMPS_EQUATION, "M Fv Fc off")
    assert abs(r.values["off"] / EMPS_PUBLISHED["off"] - 1) > 0.5


def test_emps_validation_run_simulates_with_the_default_integrator(emps, emps_validation):
    """sign(q') of the simulated velocity: integrated from switch to switch, held at
    standstill while the force is below the friction, instead of crawling."""
    r = algid.identify(emps, EMPS_EQUATION, "M Fv Fc off")
    v = r.simulate(emps_validation)
    # open loop over 24.8 s of a mass without spring, from the measured force alone:
    # measured fit 89.95 % (RMSE 8.3 mm), within 1 um of DOP853 at rtol 1e-10
    assert v.fit_percent > 85
