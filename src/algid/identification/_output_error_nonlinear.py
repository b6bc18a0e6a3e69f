"""Output-error refinement of models nonlinear in their signals (Duffing, friction).

The same fit as :mod:`algid.identification._output_error`,

    min over theta and x0_s of  sum over segments s and samples k of
        (y_k - yhat_k(theta, x0_s))**2,

with the output simulated by :class:`algid.simulation._fast_simulation.FastSimulation`
(``sign()`` switching located within the step, Coulomb sticking as sliding), so that
``yhat`` is a continuous, piecewise smooth function of the parameters and of the initial
state.  The initial state enters nonlinearly: it is iterated with the parameters
(Levenberg–Marquardt on both, each scaled by its uncertainty: the parameters by the
algebraic standard errors, the initial state by those of a polynomial fit of the first
samples), then polished by Gauss–Newton steps with central differences.  The covariance
is the same sandwich form on the Jacobian of the parameters with the initial states
projected out (the parameters' block of the inverse Fisher information, the initial
states as nuisance).

A system of equations nonlinear in its signals is fitted the same way
(:func:`prepare_nonlinear_system`): every output simulated at once
(:class:`algid.simulation._fast_simulation.FastSystemSimulation`), each weighted by the
inverse of its noise level, so that one segment's rows are its outputs one after the
other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from algid.identification._refinement import Refinement, sandwich_covariance
from algid.identification._residual_tests import (
    nonlinear_residual_test,
    nonlinear_system_residual_test,
)

__all__ = ["NonlinearData", "prepare_nonlinear", "prepare_nonlinear_system",
           "fit_initial_states", "refine_nonlinear"]

#: Finite-difference step of the Jacobian, in units of each variable's scale.
_JACOBIAN_STEP = 1e-3

#: Gauss–Newton steps after the Levenberg–Marquardt iteration, at most.
_POLISH_STEPS = 3

#: Samples of the polynomial fit that starts each segment's initial state.
_START_SAMPLES = 40


@dataclass
class NonlinearData:
    """The records as the nonlinear refinement simulates them (:func:`prepare_nonlinear`).

    Attributes
    ----------
    model : algid.models._model.Model
    simulations : list of FastSimulation
        One per segment.
    outputs : list of numpy.ndarray
        Per segment, the measured output.
    start : list of numpy.ndarray
        Per segment, the first guess of the initial state.
    start_scale : list of numpy.ndarray
        Per segment, its uncertainty (the scale of its steps).
    segments : list of Segment
        The segments simulated.
    interpolation : str
        The inputs between samples.
    runs : int
        Outputs per segment (a system's: each segment's rows are ``runs`` equal runs,
        one per output, weighted by the inverse of its noise level).
    """

    model: object
    simulations: list
    outputs: list
    start: list
    start_scale: list
    segments: list
    interpolation: str
    runs: int = 1

    @property
    def order(self):
        """The number of states of each segment."""
        return self.simulations[0].order


def _initial_guess(t, y, order):
    """The output and its derivatives at ``t[0]`` from a polynomial fit of the first
    samples, and their standard errors."""
    m = int(min(len(y), max(_START_SAMPLES, 4 * (order + 2))))
    degree = int(min(order + 2, m - 1))
    s = t[:m] - t[0]
    span = s[-1] if s[-1] > 0 else 1.0
    V = np.vander(s / span, degree + 1, increasing=True)
    coefficients, *_ = np.linalg.lstsq(V, y[:m], rcond=None)
    residual = y[:m] - V @ coefficients
    variance = float(residual @ residual) / max(m - degree - 1, 1)
    errors = np.sqrt(np.maximum(np.diag(np.linalg.pinv(V.T @ V)) * variance, 0.0))
    factorial = np.cumprod(np.r_[1.0, np.arange(1, order)])
    value = coefficients[:order] * factorial / span ** np.arange(order)
    error = errors[:order] * factorial / span ** np.arange(order)
    typical = np.abs(value) + np.sqrt(np.mean(y ** 2)) / span ** np.arange(order)
    return value, np.maximum(error, 1e-6 * typical)


def prepare_nonlinear(model, segments, interpolation="bandlimited"):
    """:class:`NonlinearData` of uniformly sampled segments.

    Parameters
    ----------
    model : algid.models._model.Model
    segments : list of Segment
    interpolation : {"bandlimited", "cubic"}
        The inputs between samples.

    Returns
    -------
    NonlinearData
    """
    from algid.simulation._fast_simulation import FastSimulation

    simulations, outputs, start, scale = [], [], [], []
    for seg in segments:
        t = np.asarray(seg.t, dtype=float)
        columns = {name: np.asarray(seg.values[name], dtype=float) for name in model.inputs}
        simulations.append(FastSimulation(model, t, columns, interpolation))
        y = np.asarray(seg.values[model.output], dtype=float)
        outputs.append(y)
        x0, error = _initial_guess(t, y, simulations[-1].order)
        start.append(x0)
        scale.append(error)
    return NonlinearData(model, simulations, outputs, start, scale, list(segments),
                         interpolation)


def prepare_nonlinear_system(system, segments, sigma, interpolation="bandlimited",
                             substeps=None):
    """:class:`NonlinearData` of a system of equations on uniformly sampled segments.

    Parameters
    ----------
    system : algid.models.SystemModel
        Every output measured.
    segments : list of Segment
    sigma : mapping
        Output name -> its noise level (each output's residuals are divided by it).
    interpolation : {"bandlimited", "cubic"}
        The inputs between samples.
    substeps : int, optional
        Runge-Kutta steps per sample (default that of
        :class:`~algid.simulation._fast_simulation.FastSystemSimulation`).

    Returns
    -------
    NonlinearData
    """
    from algid.simulation._fast_simulation import FastSystemSimulation, WeightedRows

    weights = np.array([1.0 / sigma[y] for y in system.outputs])
    simulations, outputs, start, scale = [], [], [], []
    for seg in segments:
        t = np.asarray(seg.t, dtype=float)
        columns = {name: np.asarray(seg.values[name], dtype=float) for name in system.inputs}
        simulation = FastSystemSimulation(system, t, columns, interpolation=interpolation,
                                          **({} if substeps is None else
                                             {"substeps": substeps}))
        simulations.append(WeightedRows(simulation, weights))
        measured = [np.asarray(seg.values[y], dtype=float) for y in system.outputs]
        outputs.append(np.concatenate([y * w for y, w in zip(measured, weights)]))
        guesses = [_initial_guess(t, y, sum(1 for name, _ in simulation.states if name == o))
                   for o, y in zip(system.outputs, measured)]
        start.append(np.concatenate([value for value, _ in guesses]))
        scale.append(np.concatenate([error for _, error in guesses]))
    return NonlinearData(system, simulations, outputs, start, scale, list(segments),
                         interpolation, runs=len(system.outputs))


def fit_initial_states(data, theta):
    """Each segment's initial state fitted alone, the parameters held at ``theta``, from
    :attr:`NonlinearData.start`: a start near the optimum for :func:`refine_nonlinear`
    (whose polynomial guess of a velocity on noisy samples can be far off, and from
    there the joint iteration can wander to a wrong minimum).

    Parameters
    ----------
    data : NonlinearData
    theta : numpy.ndarray

    Returns
    -------
    list of numpy.ndarray
        Per segment, the fitted state (the guess where a simulation diverges).
    """
    from scipy.optimize import least_squares

    states = []
    for simulation, y, start, scale in zip(data.simulations, data.outputs, data.start,
                                           data.start_scale):
        def residual(z, simulation=simulation, y=y, start=start, scale=scale):
            r = y - simulation.run(theta, start + z * scale)
            return np.where(np.isfinite(r), r, 1e150)

        fit = least_squares(residual, np.zeros(len(start)), method="lm",
                            diff_step=_JACOBIAN_STEP, max_nfev=50 * (len(start) + 1))
        good = np.all(np.isfinite(simulation.run(theta, start + fit.x * scale)))
        states.append(start + fit.x * scale if good else start)
    return states


def _residual(data, theta, states):
    """The residuals of all segments, stacked (NaN where a simulation diverged)."""
    return np.concatenate([y - sim.run(theta, x0) for sim, y, x0
                           in zip(data.simulations, data.outputs, states)])


class _Variables:
    """The parameters and every segment's initial state as one scaled vector ``z``."""

    def __init__(self, data, theta, scale, states=None):
        self.p = len(theta)
        self.n = data.order
        self.origin = np.concatenate([np.asarray(theta, float)]
                                     + list(data.start if states is None else states))
        self.scale = np.concatenate([np.asarray(scale, float)] + list(data.start_scale))

    def split(self, z):
        v = self.origin + z * self.scale
        theta = v[:self.p]
        states = [v[self.p + s * self.n:self.p + (s + 1) * self.n]
                  for s in range((len(v) - self.p) // self.n)]
        return theta, states


def _central_jacobian(data, variables, z):
    """Central differences of the residuals in every scaled variable."""
    columns = []
    for i in range(len(z)):
        up, down = z.copy(), z.copy()
        up[i] += _JACOBIAN_STEP
        down[i] -= _JACOBIAN_STEP
        columns.append((_residual(data, *variables.split(up))
                        - _residual(data, *variables.split(down))) / (2 * _JACOBIAN_STEP))
    return np.array(columns).T


def _projected(J, data, p):
    """The parameters' columns of ``J`` with each segment's initial-state columns
    projected out of its rows; the segments' rows."""
    Jp = J[:, :p].copy()
    bounds, at, n = [], 0, data.order
    for s, y in enumerate(data.outputs):
        b = at + len(y)
        F = J[at:b, p + s * n:p + (s + 1) * n]
        Jp[at:b] -= F @ np.linalg.lstsq(F, Jp[at:b], rcond=None)[0]
        bounds.append((at, b))
        at = b
    return Jp, bounds


def refine_nonlinear(data, theta, scale, other=None):
    """The output-error estimate of a nonlinear model started from ``theta``.

    Parameters
    ----------
    data : NonlinearData
    theta : numpy.ndarray
        The starting estimate (identify's), in ``model.parameters`` order.
    scale : numpy.ndarray
        Per parameter, a positive typical uncertainty (the algebraic standard errors).
    other : NonlinearData, optional
        The same records with the inputs interpolated otherwise: one Gauss–Newton step
        to its optimum is the estimate's numerical error.

    Returns
    -------
    theta : numpy.ndarray
    covariance : numpy.ndarray
    refinement : Refinement
    """
    from scipy.optimize import least_squares

    count = [0]
    start = _Variables(data, theta, scale)
    p = start.p

    def residual(z):
        count[0] += 1
        r = _residual(data, *start.split(z))
        return np.where(np.isfinite(r), r, 1e150)

    z0 = np.zeros(len(start.origin))
    r0 = residual(z0)
    rms_before = float(np.sqrt(np.mean(r0 ** 2)))
    fit = least_squares(residual, z0, method="lm", x_scale=1.0, diff_step=_JACOBIAN_STEP,
                        xtol=1e-13, ftol=1e-15, gtol=1e-15, max_nfev=100 * (len(z0) + 1))
    z, r = fit.x, residual(fit.x)
    J = _central_jacobian(data, start, z)
    count[0] += 2 * len(z)
    if not (np.all(np.isfinite(J)) and np.all(r < 1e150)):   # diverged: nothing to report
        nan = np.full(p, np.nan)
        return nan, np.full((p, p), np.nan), Refinement(
            applied=False, reason="", converged=False, evaluations=count[0],
            rms_before=rms_before, rms_after=float("nan"), numerical_error=nan)
    for _ in range(_POLISH_STEPS):   # to round-off (as the linear refinement)
        step = np.linalg.lstsq(J, r, rcond=None)[0]
        trial = residual(z - step)
        if not trial @ trial <= r @ r:
            break
        trial_J = _central_jacobian(data, start, z - step)
        count[0] += 2 * len(z)
        if not np.all(np.isfinite(trial_J)):
            break
        z, r, J = z - step, trial, trial_J
        if np.max(np.abs(step)) < 1e-10:
            break
    theta_hat, states = start.split(z)
    Jp, bounds = _projected(J, data, p)
    dof = len(r) - len(z)
    runs = [(a + k * (b - a) // data.runs, a + (k + 1) * (b - a) // data.runs)
            for a, b in bounds for k in range(data.runs)]   # (one noise run per output)
    covariance, ar = sandwich_covariance(Jp, r, runs, dof)
    n = data.order
    free = [J[a:b, p + s * n:p + (s + 1) * n] for s, (a, b) in enumerate(bounds)]
    if data.runs == 1:
        test = nonlinear_residual_test(data, theta_hat, states, r, free, Jp, bounds, ar, dof)
    else:
        test = nonlinear_system_residual_test(data, theta_hat, states, r, free, Jp, bounds,
                                              runs, ar, dof)
    covariance = covariance * np.outer(scale, scale)
    numerical = np.full(p, np.nan)
    if other is not None:
        moved = _residual(other, theta_hat, states)
        if np.all(np.isfinite(moved)):
            step = np.linalg.lstsq(J, moved, rcond=None)[0]
            numerical = np.abs(step[:p]) * np.asarray(scale, float)
        count[0] += 1
    return theta_hat, covariance, Refinement(
        applied=True, reason="", converged=bool(fit.success), evaluations=count[0],
        rms_before=rms_before, rms_after=float(np.sqrt(np.mean(r ** 2))),
        noise_ar=tuple(float(a) for a in ar), initial_states=[np.array(x) for x in states],
        residual_test=test, numerical_error=numerical)
