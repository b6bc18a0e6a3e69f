"""The identify benchmark's output-error baseline and Monte Carlo helper, on tiny runs."""

import sys

import numpy as np
from conftest import ROOT

import algid

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.identify_speed import monte_carlo, output_error_fit  # noqa: E402
from benchmarks.synthetic_records import LINEAR_EQUATION, linear_offsets  # noqa: E402


def test_output_error_fit_reaches_the_truth_from_a_perturbed_start():
    record, truth = linear_offsets(0, noise=0.0, n=400)
    r = algid.identify(record, *LINEAR_EQUATION, window=0.4)
    start = r.with_parameters({p: 1.02 * v for p, v in truth.items()})
    values = output_error_fit(start, record)
    for p in truth:
        # the cubic-spline input limits the simulation, hence the fit, to about 1e-3
        assert abs(values[p] / truth[p] - 1) < 3e-3, p


def test_monte_carlo_summary():
    out = monte_carlo(lambda seed: linear_offsets(seed, n=800), LINEAR_EQUATION, 3, 0)
    assert out["runs"] == 3 and out["parameters"] == ["B", "K", "G", "d"]
    assert np.all(np.isfinite(out["spread_over_stderr"])) and "oe_rmse" not in out
