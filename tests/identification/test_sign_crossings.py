"""Crossings of the velocity inside sign(): refined by local fits of the position, the
steps placed at them, and the friction loop's bias that the refinement removes."""

import sys

import numpy as np
import pytest
from conftest import ROOT

import algid
from algid.identification._sign_crossings import crossing_jumps, crossing_motion, refine_crossings
from algid.identification._window_kernels import sign_samples, step_window_integrals, term_kernel
from algid.models._expression import Call, Signal
from algid.models._grammar import parse_equation
from algid.signals._differentiation import algebraic_derivative

if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks.synthetic_records import (  # noqa: E402
    FRICTION_EQUATION,
    FrictionLoop,
    friction_loop,
)


@pytest.mark.parametrize("jump", [-1.0, -2.7])
def test_a_kinked_stationary_point_is_found_where_the_differentiator_is_late(jump):
    """q = (a/2) s^2 before the crossing and ((a + J)/2) s^2 after it: the average of
    the kinked velocity over the differentiator's window is not zero at the crossing,
    the fit of q with the known jump J is (also near sticking, J close to -a, where the
    estimate is several samples late)."""
    dt, n = 1e-3, 800
    t = np.arange(n) * dt
    # upwards, then downwards; each at least 30 ms from the peak (a kink of its own)
    q, crossings = _exact_position(t, 0.1003, 3.0, jump, 0.4004)
    estimate = algebraic_derivative(q, dt)
    z = np.sign(estimate)
    i = np.flatnonzero(z[:-1] * z[1:] < 0)
    late = t[i] + estimate[i] / (estimate[i] - estimate[i + 1]) * dt
    refined = refine_crossings(q, t, estimate, jump)
    assert len(late) == len(refined) == 2
    assert np.all(late - crossings > 1e-4), late - crossings
    if jump < -2:
        assert np.max(late - crossings) > 3e-3     # beyond three samples
    assert np.all(np.abs(refined - crossings) < 2e-6), refined - crossings


def _exact_position(t, c0, a, jump, peak):
    """Position whose velocity rises through zero at ``c0`` (acceleration ``a`` before,
    ``a + J`` after), peaks at ``peak`` and falls back through zero with the acceleration
    ``-a`` before and ``-(a + J)`` after that second crossing (a downwards one: the
    curvature rises by ``-J``).  Returns the position and the two crossing times."""
    slope = a + jump
    v_peak = slope * (peak - c0)
    c1 = peak + v_peak / a
    q = np.empty_like(t)
    before = t < c0
    q[before] = 0.5 * a * (t[before] - c0) ** 2
    rising = (t >= c0) & (t < peak)
    q[rising] = 0.5 * slope * (t[rising] - c0) ** 2
    q_peak = 0.5 * slope * (peak - c0) ** 2
    falling = (t >= peak) & (t < c1)
    q[falling] = q_peak + v_peak * (t[falling] - peak) - 0.5 * a * (t[falling] - peak) ** 2
    q_c1 = q_peak + v_peak * (c1 - peak) - 0.5 * a * (c1 - peak) ** 2
    after = t >= c1
    q[after] = q_c1 - 0.5 * slope * (t[after] - c1) ** 2
    return q, np.array([c0, c1])


def test_crossings_near_the_ends_or_each_other_keep_the_interpolated_zero():
    dt = 1e-3
    t = np.arange(100) * dt
    v = np.sin(2 * np.pi * 45 * t)              # crossings every 11 samples
    zeros = refine_crossings(np.zeros_like(t), t, v, -1.0)
    z = np.sign(v)
    i = np.flatnonzero(z[:-1] * z[1:] < 0)
    assert np.array_equal(zeros, t[i] + v[i] / (v[i] - v[i + 1]) * dt)


@pytest.mark.parametrize("step_at", [0.0123, 0.0147, 0.0091])
def test_sign_samples_integrate_a_step_at_the_given_time(step_at):
    """The trapezoid sum of the samples is the integral of a sign that steps at the
    given time, also when it lies in another interval than the samples' change of sign."""
    t = np.arange(30) * 1e-3
    v = t - 0.0112                               # samples change sign after t = 11 ms
    z = sign_samples(v, t, [step_at])
    trapezoid = float(np.sum((z[1:] + z[:-1]) / 2 * np.diff(t)))
    exact = -(step_at - t[0]) + (t[-1] - step_at)
    assert trapezoid == pytest.approx(exact, abs=1e-15)
    assert np.allclose(sign_samples(v, t), sign_samples(v, t, [0.0112]), atol=1e-12)
    with pytest.raises(ValueError, match="crossing times"):
        sign_samples(v, t, [0.01, 0.02])


def test_crossing_jumps_come_from_the_model():
    model = parse_equation(*FRICTION_EQUATION)
    jumps = crossing_jumps(model, {"M": 2.0, "Fv": 5.0, "Fc": 1.0, "off": -0.2})
    assert jumps == {Call("sign", (Signal("q", 1),)): pytest.approx(-1.0)}
    # no sign of the output's derivative, or a second discontinuous factor: none
    assert crossing_jumps(parse_equation("M*q'' + Fv*q' = F", "M Fv"),
                          {"M": 1.0, "Fv": 1.0}) == {}
    assert crossing_jumps(parse_equation("M*q'' + Fc*sign(q') + Fs*sign(q) = F",
                                         "M Fc Fs"), {"M": 1, "Fc": 1, "Fs": 1}) == {}
    # third order in q: q'' does not jump
    assert crossing_jumps(parse_equation("q''' + M*q'' + Fc*sign(q') = F", "M Fc"),
                          {"M": 1.0, "Fc": 1.0}) == {}


def test_noise_free_friction_loop_without_the_crossing_bias():
    """The estimate of q' is late at every crossing (0.37 ms on average): without the
    refinement M was biased by 4.9e-4 and the offset by 1e-3 on the noise-free record;
    with crossings fitted by the kinked polynomial, 2e-5 and 2e-5; fitted by the
    model's motion, with exact window integrals of the steps, 6e-7 and 2e-6 (Fv and
    Fc 4e-7 and 3e-7, from 3e-5 and 7e-5 with the trapezoid sum at the steps)."""
    record, truth = friction_loop(noise=0.0)
    r = algid.identify(record, *FRICTION_EQUATION)
    errors = {p: abs(r.values[p] / truth[p] - 1) for p in truth}
    assert errors["M"] < 2e-6 and errors["off"] < 1e-5, errors
    assert errors["Fv"] < 2e-6 and errors["Fc"] < 2e-6, errors


def _loop_and_motion(noise=0.0, seed=0, n=3000):
    loop = FrictionLoop()
    record, truth = friction_loop(seed, n=n, noise=noise)
    loop.sample(record["t"])
    model = parse_equation(*FRICTION_EQUATION)
    motion = crossing_motion(model, truth, record, record["t"])
    velocity = algebraic_derivative(record["q"], record["t"][1] - record["t"][0])
    jump = crossing_jumps(model, truth)[Call("sign", (Signal("q", 1),))]
    return record, np.array(loop.events), motion, velocity, jump


def test_the_model_motion_places_the_crossings_of_the_friction_loop():
    """Fitted by the model's motion (the measured force through the parameters), the
    crossings of the exact friction loop are found to a fraction of a microsecond;
    the kinked polynomial, which leaves out how the loop reacts to the step of the
    friction (the third derivative jumps too), puts them about 12 us early."""
    record, events, (forcing, damping), velocity, jump = _loop_and_motion()
    t, q = record["t"], record["q"]
    motion = refine_crossings(q, t, velocity, jump, forcing=forcing, damping=damping)
    polynomial = refine_crossings(q, t, velocity, jump)

    def errors(times):
        nearest = events[np.argmin(np.abs(events[None, :] - times[:, None]), axis=1)]
        return (times - nearest)[np.abs(times - nearest) < 1e-4]   # the refined ones

    assert len(errors(motion)) >= 10
    assert np.max(np.abs(errors(motion))) < 1e-6, errors(motion)
    assert np.mean(errors(polynomial)) < -5e-6, errors(polynomial)


def test_crossing_time_sensitivity_is_the_derivative_of_the_refined_time():
    """The reported derivative of each refined time with respect to the fitted position
    samples is that of the refinement itself (central differences on a noisy record;
    the search interpolates its minimum by a parabola, hence the tolerance)."""
    record, _, (forcing, damping), velocity, jump = _loop_and_motion(noise=1e-6, n=1500)
    t, q = record["t"], record["q"]
    times, moves = refine_crossings(q, t, velocity, jump, forcing=forcing,
                                    damping=damping, sensitivity=True)
    j = next(k for k, move in enumerate(moves) if move is not None)
    first, weights = moves[j]
    h = 1e-8
    numeric = []
    for n in range(first, first + len(weights)):
        up, down = q.copy(), q.copy()
        up[n] += h
        down[n] -= h
        numeric.append((refine_crossings(up, t, velocity, jump, forcing=forcing,
                                         damping=damping)[j]
                        - refine_crossings(down, t, velocity, jump, forcing=forcing,
                                           damping=damping)[j]) / (2 * h))
    numeric = np.array(numeric)
    assert np.linalg.norm(weights - numeric) < 0.05 * np.linalg.norm(numeric)


@pytest.mark.parametrize("derivative", [0, 1])
def test_step_window_integrals_are_exact(derivative):
    """Window integrals of a piecewise-constant signal against the term kernel, on a
    jittered grid, equal Gauss-Legendre quadrature piece by piece (to round-off)."""
    nodes, weights = np.polynomial.legendre.leggauss(40)
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.8e-3, 1.2e-3, 200))
    times, steps = np.array([0.031, 0.0705, 0.1102]), np.array([2.0, -2.0, 2.0])
    length, stride, a = 40, 3, 8
    got = step_window_integrals(t, -1.0, times, steps, length, a, derivative, stride)
    for w, value in enumerate(got):
        lo, hi = t[w * stride], t[w * stride + length - 1]
        edges = np.r_[lo, times[(times > lo) & (times < hi)], hi]
        exact = 0.0
        for left, right in zip(edges[:-1], edges[1:]):
            level = -1.0 + steps[times <= 0.5 * (left + right)].sum()
            x = left + 0.5 * (right - left) * (nodes + 1)
            exact += level * 0.5 * (right - left) * np.sum(
                weights * term_kernel(a, derivative, (x - lo) / (hi - lo)))
        exact /= (hi - lo) ** (derivative + 1)
        assert value == pytest.approx(exact, abs=1e-12 * max(1.0, abs(exact)))
