"""Tests of algid.simulation against closed-form solutions of the mass-spring-damper.

Reference plant: x'' + 2 x' + 3 x = F (m=1, c=2, k=3); the characteristic roots are
-1 +- i sqrt(2), so every homogeneous solution is
exp(-(t - t0)) (a cos(sqrt(2)(t - t0)) + b sin(sqrt(2)(t - t0))).

Tolerances: the step and sine paths evaluate matrix exponentials of A (t - t0) with
||A (t - t0)|| <= ~20, whose round-off is a small multiple of eps * 20 ~ 4e-15 on
responses of size ~1; 1e-13 leaves a margin of 25.  The callable path is an adaptive
integration with rtol 1e-13, whose global error over 5 time constants stays well
below 1e-11.
"""

from __future__ import annotations

import csv

import control
import numpy as np
import pytest
import sympy as sp

from algid.errors import InputDataError
from algid.simulation import SimulationResult, plant, simulate
from algid.simulation._plant import INPUT_NAMES

SQ2 = np.sqrt(2.0)
EXACT = 1e-13  # absolute tolerance for the round-off-exact paths (responses are O(1))


# --------------------------------------------------------------------------------------
# closed-form references for x'' + 2x' + 3x = F, state (x0, v0) at time t0
# --------------------------------------------------------------------------------------


def _homogeneous(t, t0, a, b):
    s = t - t0
    e = np.exp(-s)
    x = e * (a * np.cos(SQ2 * s) + b * np.sin(SQ2 * s))
    v = e * ((-a + SQ2 * b) * np.cos(SQ2 * s) + (-b - SQ2 * a) * np.sin(SQ2 * s))
    return x, v


def step_exact(t, x0=0.0, v0=0.0, t0=0.0, amp=1.0):
    """F = amp: particular solution amp/3."""
    a = x0 - amp / 3.0
    b = (v0 + a) / SQ2
    xh, vh = _homogeneous(t, t0, a, b)
    return amp / 3.0 + xh, vh


def sine_exact(t, x0=0.0, v0=0.0, t0=0.0):
    """F = sin t: particular solution (sin t - cos t) / 4."""
    a = x0 - (np.sin(t0) - np.cos(t0)) / 4.0
    b = (v0 - (np.cos(t0) + np.sin(t0)) / 4.0 + a) / SQ2
    xh, vh = _homogeneous(t, t0, a, b)
    return (np.sin(t) - np.cos(t)) / 4.0 + xh, (np.cos(t) + np.sin(t)) / 4.0 + vh


def ramp_exact(t, x0=0.0, v0=0.0, t0=0.0):
    """F = t: particular solution t/3 - 2/9."""
    a = x0 - (t0 / 3.0 - 2.0 / 9.0)
    b = (v0 - 1.0 / 3.0 + a) / SQ2
    xh, vh = _homogeneous(t, t0, a, b)
    return t / 3.0 - 2.0 / 9.0 + xh, 1.0 / 3.0 + vh


def test_closed_forms_solve_the_ode():
    """The hand-derived references satisfy the ODE and the initial conditions."""
    t, t0, x0, v0 = sp.symbols("t t0 x0 v0", real=True)
    s2 = sp.sqrt(2)
    for forcing, xp in [
        (sp.Integer(1), sp.Rational(1, 3)),
        (sp.sin(t), (sp.sin(t) - sp.cos(t)) / 4),
        (t, t / 3 - sp.Rational(2, 9)),
    ]:
        xp0 = xp.subs(t, t0)
        vp0 = sp.diff(xp, t).subs(t, t0)
        a = x0 - xp0
        b = (v0 - vp0 + a) / s2
        x = xp + sp.exp(-(t - t0)) * (a * sp.cos(s2 * (t - t0)) + b * sp.sin(s2 * (t - t0)))
        assert sp.expand(sp.diff(x, t, 2) + 2 * sp.diff(x, t) + 3 * x - forcing) == 0
        assert sp.expand(x.subs(t, t0) - x0) == 0
        assert sp.expand(sp.diff(x, t).subs(t, t0) - v0) == 0


# --------------------------------------------------------------------------------------
# plant
# --------------------------------------------------------------------------------------


def test_plant_matrices():
    sys = plant(m=2.0, c=4.0, k=6.0)
    assert isinstance(sys, control.StateSpace)
    np.testing.assert_array_equal(sys.A, [[0.0, 1.0], [-3.0, -2.0]])
    np.testing.assert_array_equal(sys.B, [[0.0], [0.5]])
    np.testing.assert_array_equal(sys.C, [[1.0, 0.0]])
    np.testing.assert_array_equal(sys.D, [[0.0]])
    assert sys.isctime()
    # DC gain of 1/(m s^2 + c s + k) is 1/k
    assert control.dcgain(sys) == pytest.approx(1.0 / 6.0, rel=1e-14)


def test_plant_defaults_and_validation():
    np.testing.assert_array_equal(plant().A, [[0.0, 1.0], [-3.0, -2.0]])
    with pytest.raises(InputDataError, match="m"):
        plant(m=0.0)


# --------------------------------------------------------------------------------------
# time grid
# --------------------------------------------------------------------------------------


def test_default_grid():
    res = simulate()
    assert res.t.shape == (5001,)
    assert res.t[0] == 0.0 and res.t[-1] == 5.0
    np.testing.assert_allclose(np.diff(res.t), 1e-3, rtol=1e-12)
    for name in ("t", "f", "x", "x_true", "v_true"):
        arr = getattr(res, name)
        assert arr.dtype == np.float64 and arr.shape == (5001,)


def test_grid_from_duration_and_rate():
    res = simulate(duration=0.5, rate=20.0)
    np.testing.assert_array_equal(res.t, np.arange(11) / 20.0)


# --------------------------------------------------------------------------------------
# step
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("ic", [(0.0, 0.0), (0.5, -1.0)])
def test_step_matches_closed_form(ic):
    res = simulate("step", initial_state=ic)
    x, v = step_exact(res.t, *ic)
    np.testing.assert_array_equal(res.f, np.ones(5001))
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=EXACT)
    np.testing.assert_allclose(res.v_true, v, rtol=0, atol=EXACT)
    np.testing.assert_array_equal(res.x, res.x_true)
    # constant from the first sample: x''(0) = F - 2 v0 - 3 x0 (no ramp start)
    x_dd0 = (res.v_true[1] - res.v_true[0]) / 1e-3
    assert x_dd0 == pytest.approx(1.0 - 2 * ic[1] - 3 * ic[0], abs=5e-3)


def test_step_amplitude_scales_response():
    res = simulate("step", amplitude=-2.5, duration=2.0)
    x, _ = step_exact(res.t, amp=-2.5)
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=2.5 * EXACT)
    assert np.all(res.f == -2.5)


def test_step_long_record_does_not_accumulate_error():
    # 100 001 samples: a step-by-step recursion would accumulate ~n*eps; the
    # anchored matrix exponentials keep the error at round-off.
    res = simulate("step", duration=5.0, rate=20000.0, initial_state=(0.5, -1.0))
    x, v = step_exact(res.t, 0.5, -1.0)
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=EXACT)
    np.testing.assert_allclose(res.v_true, v, rtol=0, atol=EXACT)


# --------------------------------------------------------------------------------------
# sine
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("ic", [(0.0, 0.0), (0.5, -1.0)])
def test_sine_matches_closed_form(ic):
    res = simulate("sine", initial_state=ic)
    x, v = sine_exact(res.t, *ic)
    np.testing.assert_allclose(res.f, np.sin(res.t), rtol=0, atol=1e-15)
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=EXACT)
    np.testing.assert_allclose(res.v_true, v, rtol=0, atol=EXACT)


def test_sine_at_resonance():
    # x'' + x = sin t from rest (c=0, k=1, w=1): x = (sin t - t cos t) / 2 grows
    # linearly; the exponential of the augmented system is still exact.
    res = simulate("sine", m=1.0, c=0.0, k=1.0, frequency=1.0, duration=10.0, rate=500.0)
    t = res.t
    np.testing.assert_allclose(res.x_true, (np.sin(t) - t * np.cos(t)) / 2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.v_true, t * np.sin(t) / 2, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------------------
# other damping regimes, long records and resonance
# --------------------------------------------------------------------------------------


def test_step_overdamped_and_critically_damped():
    # x'' + 3x' + 2x = 1 (roots -1, -2): x = 1/2 - exp(-t) + exp(-2t)/2
    res = simulate("step", m=1.0, c=3.0, k=2.0)
    t = res.t
    x = 0.5 - np.exp(-t) + np.exp(-2 * t) / 2
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=EXACT)
    np.testing.assert_allclose(res.v_true, np.exp(-t) - np.exp(-2 * t), rtol=0, atol=EXACT)
    # x'' + 2x' + x = 1 (double root -1): x = 1 - (1 + t) exp(-t)
    res = simulate("step", m=1.0, c=2.0, k=1.0)
    np.testing.assert_allclose(res.x_true, 1 - (1 + t) * np.exp(-t), rtol=0, atol=EXACT)
    np.testing.assert_allclose(res.v_true, t * np.exp(-t), rtol=0, atol=EXACT)


def test_step_without_spring():
    # x'' + 2x' = 1 from rest (k = 0, the step is resonant with the pole at 0):
    # x = t/2 - (1 - exp(-2t))/4.
    res = simulate("step", c=2.0, k=0.0)
    t = res.t
    np.testing.assert_allclose(res.x_true, t / 2 - (1 - np.exp(-2 * t)) / 4, rtol=0, atol=EXACT)
    np.testing.assert_allclose(res.v_true, (1 - np.exp(-2 * t)) / 2, rtol=0, atol=EXACT)


def test_undamped_long_record_keeps_phase():
    # x'' + 100 x = 1, x(0) = 1: x = 1/100 + (99/100) cos(10 t); 10 t reaches 2000 rad,
    # where a scaling-and-squaring exponential of A t would lose ~1e-11.
    res = simulate(
        "step", c=0.0, k=100.0, duration=200.0, rate=100.0, initial_state=(1.0, 0.0)
    )
    t = res.t
    np.testing.assert_allclose(res.x_true, 0.01 + 0.99 * np.cos(10 * t), rtol=0, atol=1e-13)
    np.testing.assert_allclose(res.v_true, -9.9 * np.sin(10 * t), rtol=0, atol=1e-12)


def test_long_sine_keeps_phase():
    # x'' + 2x' + 3x = A sin(w t) from rest; after the transient exp(-t) has died out
    # (t > 40: exp(-40) ~ 4e-18) only the steady state A Im(G(iw) exp(iwt)) remains.
    amp, w = 2.0, 3.0
    res = simulate("sine", amplitude=amp, frequency=w, duration=45.0, rate=200.0)
    g = 1.0 / (3.0 - w**2 + 2j * w)
    late = res.t > 40.0
    expected = amp * np.imag(g * np.exp(1j * w * res.t[late]))
    np.testing.assert_allclose(res.x_true[late], expected, rtol=0, atol=EXACT)
    np.testing.assert_allclose(res.f, amp * np.sin(w * res.t), rtol=0, atol=0)


@pytest.mark.parametrize("duration", [5.0, 300.0])
def test_sine_near_resonance(duration):
    # x'' + x = sin(w t) from rest, w = 1.01: x = (sin(w t) - w sin t) / (1 - w^2).
    # The short record is resonant on its time scale (gap * duration < 1), the long one
    # is not; both are exact.  Amplitudes reach ~1/(1 - w^2) ~ 50.
    w = 1.01
    res = simulate("sine", c=0.0, k=1.0, frequency=w, duration=duration, rate=100.0)
    t = res.t
    x = (np.sin(w * t) - w * np.sin(t)) / (1 - w**2)
    scale = np.max(np.abs(x))
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=scale * 1e-13)


@pytest.mark.parametrize(
    ("B", "K"),
    [(2.0, 3.0), (0.0, 3.0), (2.0, 1.0), (2.0, 1.0 + 1e-9), (3.0, 2.0), (1000.0, 1.0),
     (5.0, 0.0), (0.0, 0.0), (0.1, 1e4)],
)
def test_transition_matrix_against_high_precision(B, K):
    from mpmath import mp

    from algid.simulation._responses import transition_matrices

    mp.dps = 40
    A = np.array([[0.0, 1.0], [-K, -B]])
    tau = np.linspace(0.0, 3.0, 13)
    phi = transition_matrices(A, tau)
    for i, ti in enumerate(tau):
        ref = np.array(mp.expm(mp.matrix(A.tolist()) * mp.mpf(ti)).tolist(), dtype=float)
        scale = np.max(np.abs(ref))
        # The phase sqrt(K - B^2/4) tau inherits the rounding of that square root
        # (~eps * 300 rad for K = 1e4); elsewhere the error is a few eps.
        tol = scale * (1e-15 + 2e-16 * np.sqrt(K) * ti)
        np.testing.assert_allclose(phi[i], ref, rtol=0, atol=tol)


# --------------------------------------------------------------------------------------
# callable and array inputs
# --------------------------------------------------------------------------------------


def test_callable_agrees_with_sine_path():
    ic = (0.5, -1.0)
    exact = simulate("sine", initial_state=ic)
    res = simulate(np.sin, initial_state=ic)
    np.testing.assert_array_equal(res.f, np.sin(res.t))
    np.testing.assert_allclose(res.x_true, exact.x_true, rtol=0, atol=1e-11)
    np.testing.assert_allclose(res.v_true, exact.v_true, rtol=0, atol=1e-11)
    x, _ = sine_exact(res.t, *ic)
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=1e-11)


def test_callable_accuracy_is_relative_to_scale():
    # A force of 1e-6 N gives a response of ~1e-7 m; the tolerance scales with it.
    res = simulate(lambda t: 1e-6 * np.sin(t), duration=3.0)
    x, _ = sine_exact(res.t)
    np.testing.assert_allclose(res.x_true, 1e-6 * x, rtol=0, atol=1e-17)


def test_array_input_equals_control_forced_response():
    t = np.arange(3001) / 1000.0
    u = np.cos(3 * t) + 0.1 * t
    res = simulate(u, timepts=t, initial_state=(0.2, 0.1))
    ref = control.forced_response(
        plant(), timepts=t, inputs=u, initial_state=[0.2, 0.1], return_states=True
    )
    np.testing.assert_array_equal(res.f, u)
    np.testing.assert_array_equal(res.x_true, np.asarray(ref.states)[0])
    np.testing.assert_array_equal(res.v_true, np.asarray(ref.states)[1])
    np.testing.assert_allclose(res.x_true, np.asarray(ref.outputs), rtol=0, atol=0)


def test_constant_array_equals_step_path():
    ic = (0.5, -1.0)
    res = simulate(np.ones(5001), initial_state=ic)
    step = simulate("step", initial_state=ic)
    # control.forced_response steps sample by sample; its round-off stays ~1e-14 here.
    np.testing.assert_allclose(res.x_true, step.x_true, rtol=0, atol=EXACT)
    np.testing.assert_allclose(res.v_true, step.v_true, rtol=0, atol=EXACT)


def test_ramp_array_is_exact():
    # Linear interpolation of F = t is exact, so the array path reproduces the ramp.
    res = simulate(np.arange(5001) / 1000.0, initial_state=(0.5, -1.0))
    x, v = ramp_exact(res.t, 0.5, -1.0)
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=EXACT)
    np.testing.assert_allclose(res.v_true, v, rtol=0, atol=EXACT)


def test_sampled_sine_array_has_interpolation_error():
    # Linear interpolation of sin t with step h has mean error (h^2/12) sin t, which the
    # plant passes with gain |G(i)| = 1/|2 + 2i| = 1/sqrt(8): ~2.9e-8 at h = 1e-3.
    res = simulate(np.sin(np.arange(5001) / 1000.0))
    x, _ = sine_exact(res.t)
    err = np.max(np.abs(res.x_true - x))
    predicted = (1e-3**2 / 12) / np.sqrt(8.0)
    assert 0.5 * predicted < err < 1.2 * predicted


# --------------------------------------------------------------------------------------
# non-uniform and shifted time grids
# --------------------------------------------------------------------------------------


@pytest.fixture
def jittered_grid():
    rng = np.random.default_rng(7)
    return 0.3 + np.cumsum(rng.uniform(0.5e-3, 2e-3, size=2000))


def test_step_and_sine_on_nonuniform_grid(jittered_grid):
    t = jittered_grid
    ic = (0.5, -1.0)
    res = simulate("step", timepts=t, initial_state=ic)
    np.testing.assert_array_equal(res.t, t)
    x, v = step_exact(t, *ic, t0=t[0])
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=EXACT)
    np.testing.assert_allclose(res.v_true, v, rtol=0, atol=EXACT)
    res = simulate("sine", timepts=t, initial_state=ic)
    x, v = sine_exact(t, *ic, t0=t[0])
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=EXACT)
    np.testing.assert_allclose(res.v_true, v, rtol=0, atol=EXACT)


def test_array_and_callable_on_nonuniform_grid(jittered_grid):
    t = jittered_grid
    ic = (0.5, -1.0)
    res = simulate(t.copy(), timepts=t, initial_state=ic)  # ramp F = t, exact under FOH
    x, v = ramp_exact(t, *ic, t0=t[0])
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=EXACT)
    np.testing.assert_allclose(res.v_true, v, rtol=0, atol=EXACT)
    res = simulate(np.sin, timepts=t, initial_state=ic)
    x, _ = sine_exact(t, *ic, t0=t[0])
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=1e-11)


def test_shifted_uniform_grid():
    t = 10.0 + np.arange(2001) / 400.0
    res = simulate("sine", timepts=t, initial_state=(0.1, 0.2))
    x, _ = sine_exact(t, 0.1, 0.2, t0=10.0)
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=EXACT)


# --------------------------------------------------------------------------------------
# mass scaling
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("inputs", ["step", "sine", np.cos, "array"])
def test_doubling_all_parameters_halves_the_response(inputs):
    # 2x'' + 4x' + 6x = F has the transfer function 1/(2(s^2 + 2s + 3)).
    if isinstance(inputs, str) and inputs == "array":
        inputs = np.cos(np.arange(5001) / 1000.0)
    one = simulate(inputs, m=1.0, c=2.0, k=3.0)
    two = simulate(inputs, m=2.0, c=4.0, k=6.0)
    np.testing.assert_allclose(two.x_true, 0.5 * one.x_true, rtol=0, atol=1e-14)
    np.testing.assert_allclose(two.v_true, 0.5 * one.v_true, rtol=0, atol=1e-14)
    assert (two.m, two.c, two.k) == (2.0, 4.0, 6.0)
    assert (two.B, two.K) == (2.0, 3.0)


def test_mass_closed_form():
    # 2x'' + 4x' + 6x = 2 is x'' + 2x' + 3x = 1.
    res = simulate("step", m=2.0, c=4.0, k=6.0, amplitude=2.0, initial_state=(0.5, -1.0))
    x, _ = step_exact(res.t, 0.5, -1.0)
    np.testing.assert_allclose(res.x_true, x, rtol=0, atol=EXACT)


# --------------------------------------------------------------------------------------
# noise
# --------------------------------------------------------------------------------------


def test_noise_is_seeded_and_reproducible():
    # the legacy global state is read on purpose: simulate must leave it alone
    state = np.random.get_state()[1].copy()  # noqa: NPY002
    a = simulate("sine", noise_std=1e-3, seed=42)
    b = simulate("sine", noise_std=1e-3, seed=42)
    c = simulate("sine", noise_std=1e-3, seed=43)
    np.testing.assert_array_equal(np.random.get_state()[1], state)  # noqa: NPY002
    np.testing.assert_array_equal(a.x, b.x)
    assert not np.array_equal(a.x, c.x)
    clean = simulate("sine")
    np.testing.assert_array_equal(a.x_true, clean.x_true)
    np.testing.assert_array_equal(a.v_true, clean.v_true)
    np.testing.assert_array_equal(a.f, clean.f)
    assert a.noise_std == 1e-3 and a.seed == 42
    expected = clean.x_true + np.random.default_rng(42).normal(0.0, 1e-3, size=5001)
    np.testing.assert_array_equal(a.x, expected)


def test_noise_statistics():
    sigma, n = 2e-3, 5001
    res = simulate("step", noise_std=sigma, seed=2024)
    e = res.x - res.x_true
    # For Gaussian samples the sample std has relative standard error 1/sqrt(2(n-1))
    # = 0.01 and the mean has standard error sigma/sqrt(n); allow 5 standard errors.
    assert abs(np.std(e, ddof=1) / sigma - 1.0) < 5 / np.sqrt(2 * (n - 1))
    assert abs(np.mean(e)) < 5 * sigma / np.sqrt(n)


def test_no_noise_copy():
    res = simulate()
    np.testing.assert_array_equal(res.x, res.x_true)
    assert res.x is not res.x_true
    assert res.noise_std == 0.0 and res.seed is None


# --------------------------------------------------------------------------------------
# result object
# --------------------------------------------------------------------------------------


def test_unpacking_and_properties():
    res = simulate("sine", m=2.0, c=1.0, k=8.0, duration=1.0, rate=100.0)
    assert isinstance(res, SimulationResult)
    t, f, x = res
    assert t is res.t and f is res.f and x is res.x
    assert res.B == 0.5 and res.K == 4.0


def test_to_csv_round_trip(tmp_path):
    res = simulate("sine", noise_std=1e-4, seed=1, duration=1.0, rate=1000.0,
                   initial_state=(1 / 3, np.pi))
    path = res.to_csv(tmp_path / "run.csv")
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == ["t", "f", "x"]
    assert len(rows) == 1 + res.t.size
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    np.testing.assert_array_equal(data[:, 0], res.t)
    np.testing.assert_array_equal(data[:, 1], res.f)
    np.testing.assert_array_equal(data[:, 2], res.x)


def test_to_timeresponse():
    res = simulate("sine", noise_std=1e-3, seed=3, duration=1.0, rate=100.0)
    tr = res.to_timeresponse()
    assert isinstance(tr, control.TimeResponseData)
    np.testing.assert_array_equal(tr.time, res.t)
    np.testing.assert_array_equal(np.squeeze(tr.outputs), res.x)
    np.testing.assert_array_equal(np.squeeze(tr.inputs), res.f)
    # the noise-free states and the parameters travel with the response
    np.testing.assert_array_equal(tr.states[0], res.x_true)
    np.testing.assert_array_equal(tr.states[1], res.v_true)
    assert tr.params == {"m": 1.0, "c": 2.0, "k": 3.0}
    assert (tr.input_labels, tr.output_labels, tr.state_labels) == (["F"], ["x"], ["x", "v"])


def test_result_is_read_only_and_plots_through_python_control():
    import matplotlib

    matplotlib.use("Agg")
    res = simulate("step", duration=0.5, rate=100.0)
    with pytest.raises(AttributeError, match="read-only"):
        res.x = np.zeros(51)
    plot = res.plot()
    lines = plot.lines[0, 0]  # the output x against time
    np.testing.assert_array_equal(lines[0].get_xdata(), res.t)
    np.testing.assert_array_equal(lines[0].get_ydata(), res.x)


# --------------------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"m": 0.0}, "m"),
        ({"m": -1.0}, "m"),
        ({"m": np.nan}, "m"),
        ({"c": -0.1}, "c"),
        ({"k": -3.0}, "k"),
        ({"k": np.inf}, "k"),
        ({"c": "soft"}, "c"),
        ({"duration": 0.0}, "duration"),
        ({"duration": -1.0}, "duration"),
        ({"rate": 0.0}, "rate"),
        ({"rate": -5.0}, "rate"),
        ({"duration": 1e-4, "rate": 1000.0}, "duration"),
        ({"timepts": [0.0]}, "timepts"),
        ({"timepts": [0.0, 0.1, 0.1, 0.3]}, "timepts does not increase at row 2"),
        ({"timepts": [0.0, 0.2, 0.1]}, "timepts does not increase at row 2"),
        ({"timepts": [0.0, np.nan, 0.1]}, "timepts has NaN at row 1"),
        ({"timepts": np.zeros((2, 3))}, "timepts"),
        ({"noise_std": -1e-3}, "noise_std"),
        ({"noise_std": np.nan}, "noise_std"),
        ({"initial_state": (0.0, 0.0, 0.0)}, "initial_state"),
        ({"initial_state": (0.0, np.inf)}, "initial_state"),
        ({"amplitude": np.nan}, "amplitude"),
        ({"inputs": "sine", "frequency": np.inf}, "frequency"),
    ],
)
def test_validation_errors(kwargs, name):
    kwargs = dict(kwargs)
    inputs = kwargs.pop("inputs", "step")
    with pytest.raises(InputDataError) as info:
        simulate(inputs, **kwargs)
    msg = str(info.value)
    assert name in msg
    assert "\n" not in msg
    assert isinstance(info.value, ValueError)


def test_unknown_input_name_lists_valid_names():
    with pytest.raises(InputDataError, match="inputs") as info:
        simulate("ramp")
    msg = str(info.value)
    assert "'ramp'" in msg
    for valid in INPUT_NAMES:
        assert repr(valid) in msg


@pytest.mark.parametrize(
    "func",
    [
        lambda t: 1.0,  # not vectorised
        lambda t: np.ones((2, t.size)),
        lambda t: np.where(t > 0.5, np.nan, 0.0),
        lambda t: np.full(t.shape, np.inf),
    ],
)
def test_bad_callable(func):
    with pytest.raises(InputDataError, match="inputs"):
        simulate(func, duration=1.0, rate=100.0)


@pytest.mark.parametrize(
    "values",
    [np.ones(10), np.ones((2, 101)), np.r_[np.ones(50), np.nan, np.ones(50)], ["a"] * 101],
)
def test_bad_array(values):
    with pytest.raises(InputDataError, match="inputs"):
        simulate(values, duration=1.0, rate=100.0)


def test_nan_sample_is_located():
    values = np.ones(101)
    values[17] = np.nan
    with pytest.raises(InputDataError, match="inputs has NaN at row 17"):
        simulate(values, duration=1.0, rate=100.0)


def test_a_callable_pulse_after_a_quiet_start_is_not_stepped_over():
    """The adaptive integrator, started on a zero input, stepped over a 3 ms pulse at
    3 s (x identically 0); the first-order hold on the samples sees it, and so must the
    integration (the same response as the pulse at 1 s, and as the sampled pulse)."""
    def pulse(at):
        return lambda t: 100.0 * np.exp(-((t - at) / 0.003) ** 2)

    late = simulate(pulse(3.0), rate=1000, duration=6)
    early = simulate(pulse(1.0), rate=1000, duration=6)
    peak = np.max(np.abs(early.x))
    assert peak > 0.1
    # from rest, the same response 2 s later (up to the integration's tolerance)
    np.testing.assert_allclose(late.x[2000:], early.x[:-2000], rtol=0, atol=1e-9 * peak)
    assert np.all(late.x[:2900] == 0.0)
    # the first-order hold on 6 samples of the pulse: to a few per cent of it
    sampled = simulate(pulse(3.0)(late.t), rate=1000, duration=6)
    np.testing.assert_allclose(late.x, sampled.x, rtol=0, atol=1e-2 * peak)
