"""Tests of algid.signals._filters and of the ``lowpass`` option of algid.estimate."""

import numpy as np
import pytest
import scipy.signal
from msd_reference import analytic_response

from algid.errors import InputDataError
from algid.estimation._batch import estimate
from algid.signals._filters import as_lowpass, lti_response
from algid.signals._quadrature import cumulative_integral

EPS = np.finfo(float).eps
H = 1e-3


def test_zero_matrix_reproduces_the_quadrature_rule():
    # With A = 0 the state is the integral of the interpolated input, i.e. the
    # quadrature rule itself: both sum the same n increments, so they agree to about
    # n * eps relative to the largest partial sum.
    t = np.arange(5001) * H
    y = np.sin(3 * t) + t**2
    for order in (2, 3, 6, 8):
        z = lti_response(np.zeros((1, 1)), [1.0], y, H, points=order)[:, 0]
        ref = cumulative_integral(y, H, points=order)
        assert np.max(np.abs(z - ref)) <= t.size * EPS * np.max(np.abs(ref))


def _first_order_sine(t, a, w):
    """Response of 1/(s + a) to sin(w t) from rest."""
    return (w * np.exp(-a * t) + a * np.sin(w * t) - w * np.cos(w * t)) / (a * a + w * w)


@pytest.mark.parametrize("order", [2, 3, 4])
def test_error_decreases_like_h_to_the_order(order):
    # The interpolation of q points makes the error O(h**q): halving h divides it by
    # 2**q.  Coarse steps keep the error far above round-off; the bound allows half an
    # order of slack for the higher-order term.
    a, w = 10.0, 3.0
    F = as_lowpass(([1.0], [1.0, a]))
    errors = []
    for h in (0.02, 0.01):
        t = np.arange(int(round(2.0 / h)) + 1) * h
        errors.append(np.max(np.abs(F.apply(np.sin(w * t), h, points=order)
                                    - _first_order_sine(t, a, w))))
    rate = np.log2(errors[0] / errors[1])
    assert order - 0.5 <= rate <= order + 0.5


def test_polynomial_input_of_low_degree_is_exact():
    # u = t**3 is reproduced by every interpolation of >= 4 points, so the response of
    # 1/(s + a) is exact up to round-off (values are O(1) here).
    a = 4.0
    t = np.arange(2001) * H
    exact = t**3 / a - 3 * t**2 / a**2 + 6 * t / a**3 - 6 / a**4 + 6 * np.exp(-a * t) / a**4
    for order in (4, 6, 8):
        y = as_lowpass(([1.0], [1.0, a])).apply(t**3, H, points=order)
        assert np.max(np.abs(y - exact)) <= 1e3 * EPS * np.max(np.abs(exact))


def test_initial_state_free_response():
    A = np.array([[0.0, 1.0], [-3.0, -2.0]])
    t = np.arange(1001) * H
    z = lti_response(A, [0.0, 1.0], np.zeros_like(t), H, initial_state=[1.0, 0.0])
    w = np.sqrt(2.0)
    exact = np.exp(-t) * (np.cos(w * t) + np.sin(w * t) / w)
    assert np.max(np.abs(z[:, 0] - exact)) <= 1e3 * EPS


def _specs():
    import control

    num, den = [100.0], [1.0, 20.0, 100.0]  # 100 / (s + 10)**2
    return {
        "tuple": (num, den),
        "scipy_tf": scipy.signal.lti(num, den),
        "scipy_zpk": scipy.signal.ZerosPolesGain([], [-10.0, -10.0], 100.0),
        "scipy_ss": scipy.signal.lti(num, den).to_ss(),
        "control_tf": control.tf(num, den),
        "control_ss": control.ss(control.tf(num, den)),
    }


@pytest.mark.parametrize("kind", ["tuple", "scipy_tf", "scipy_zpk", "scipy_ss",
                                  "control_tf", "control_ss"])
def test_specifications_give_the_same_filter(kind):
    t = np.arange(3001) * H
    y = np.cos(5 * t) + t
    ref = as_lowpass(_specs()["tuple"]).apply(y, H)
    out = as_lowpass(_specs()[kind]).apply(y, H)
    # different realisations of one transfer function: equal up to round-off
    assert np.max(np.abs(out - ref)) <= 1e-12 * np.max(np.abs(ref))
    assert as_lowpass(_specs()[kind]).dc_gain() == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize("kind", ["step", "sine"])
@pytest.mark.parametrize("filter_order,lowpass", [
    (0, ([100.0], [1.0, 20.0, 100.0])),
    (2, ([100.0], [1.0, 20.0, 100.0])),
    (1, ([1.0, 3.0], [1.0, 6.0, 25.0, 20.0])),  # zero at -3, poles -1.0, -2.5 +/- 3.97j
])
def test_noise_free_estimates_stay_exact(kind, filter_order, lowpass):
    # The same filter on numerators and denominator keeps n_i = theta_i d, so the noise-
    # free estimate is exact.  The data are exact to round-off and the quadrature error
    # is O(h**6) ~ 1e-18 relative, so what remains is round-off amplified by the
    # conditioning of det P, which is large only at the very start (the bound is the
    # round-off level the invariant filter alone has on the same data: its largest error
    # within 10 ms of the instant, a single sample's error being a matter of luck, with
    # a factor 10 slack).
    t, f, x = analytic_response(kind, duration=5.0)
    r = estimate(t, f, x, filter_order=filter_order, lowpass=lowpass)
    ref = estimate(t, f, x, filter_order=2)
    for time in (0.2, 1.0, 5.0):
        got = r.at(time)
        near = np.abs(t - time) <= 0.01
        for name, true in (("B", 2.0), ("K", 3.0)):
            base = np.max(np.abs(ref.estimates[name][near] - true))
            bound = 10 * max(base, 1e3 * EPS * true)
            assert abs(got[name] - true) <= bound, (time, name, got[name])


def test_noisy_estimate_with_lowpass_is_close():
    # A smoke check of the filter on noisy data: at 5 s the estimate with 1/s and a
    # second-order low-pass filter is within about ten times the Cramer-Rao bound
    # (0.0053 for B, 0.0016 for K at sigma = 0.01): more than 4 standard deviations
    # even for an estimator twice as noisy as an efficient one.
    t, f, x = analytic_response("step", duration=5.0)
    x = x + np.random.default_rng(7).normal(0.0, 0.01, t.size)
    r = estimate(t, f, x, filter_order=1, lowpass=([4.0], [1.0, 4.0, 4.0]))
    final = r.final()
    assert abs(final["B"] - 2.0) < 0.05 and abs(final["K"] - 3.0) < 0.02


@pytest.mark.parametrize("spec,fragment", [
    (([1.0], [1.0, -1.0]), "not stable"),
    (([1.0], [1.0, 0.0]), "not stable"),               # 1/s: marginal
    (([1.0], [1.0, 0.0, 4.0]), "not stable"),          # undamped oscillator
    (([1.0, 1.0], [1.0, 2.0]), "not strictly proper"),
    (([2.0], [3.0]), "no pole"),
    (([0.0], [1.0, 2.0]), "numerator is zero"),
    (([1.0], [1.0, np.nan]), "non-finite"),
    (([[1.0, 2.0], [3.0, 4.0]], [1.0, 2.0]), "1-D"),
    ("1/(s+1)", "must be (num, den)"),
    (scipy.signal.dlti([1.0], [1.0, -0.5]), "continuous-time"),
    (scipy.signal.StateSpace([[-1.0]], [[1.0]], [[1.0]], [[0.5]]), "strictly proper"),
])
def test_bad_filters_are_rejected(spec, fragment):
    with pytest.raises(InputDataError, match="lowpass") as info:
        as_lowpass(spec)
    assert fragment in str(info.value)
    assert "\n" not in str(info.value)


def test_bad_control_filters_are_rejected():
    import control

    with pytest.raises(InputDataError, match="continuous-time"):
        as_lowpass(control.tf([1.0], [1.0, -0.5], 0.1))
    mimo = control.ss(-np.eye(2), np.eye(2), np.eye(2), np.zeros((2, 2)))
    with pytest.raises(InputDataError, match="single-input single-output"):
        as_lowpass(mimo)
    with pytest.raises(InputDataError, match="not stable"):
        as_lowpass(control.ss([[1.0]], [[1.0]], [[1.0]], [[0.0]]))


def test_estimate_rejects_a_bad_lowpass():
    t, f, x = analytic_response("step", duration=0.5)
    with pytest.raises(InputDataError, match="lowpass is not stable"):
        estimate(t, f, x, lowpass=([1.0], [1.0, -2.0]))

