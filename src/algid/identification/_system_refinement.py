"""Output-error refinement of a system of equations: every measured output simulated,
the shared parameters fitted to all of them at once.

The algebraic estimate of :mod:`algid.identification._system_identify` starts a
Levenberg–Marquardt iteration (:func:`scipy.optimize.least_squares`) on the residuals
``(y_j - y_j_sim) / sigma_j`` of every output of every segment.  The simulation is the
exact one of :mod:`algid.simulation._system`; the initial state of each segment enters
the outputs linearly and is solved for at every step (variable projection), so that
the iteration runs over the parameters only and their Jacobian has the initial states
projected out.  ``sigma_j`` is each output's residual rms (the algebraic estimate's
first, then the refined one's, once more).  The covariance is the sandwich of
:func:`algid.identification._refinement.sandwich_covariance` (the Cramér–Rao bound
under white output noise; honest under coloured residuals).

``refine="auto"`` reports the refined estimate where the system is linear, both
estimates simulate stably and the weighted simulation error drops (as for a single
linear equation; the simulation is exact, so no precision margin is asked of it: the
algebraic standard errors, from the residuals' own covariance, vary by a factor of two
between noise realisations); else the algebraic estimate, with the reason in
``result.refinement``.

A system nonlinear in its signals is simulated by the compiled fixed-step integrator
(:class:`algid.simulation._fast_simulation.FastSystemSimulation`) and fitted by
:func:`~algid.identification._output_error_nonlinear.refine_nonlinear`, its initial
states iterated with the parameters (:func:`_refine_nonlinear`); ``"auto"`` reports it
under the rules of one nonlinear equation.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from algid.errors import ModelError
from algid.identification._refinement import Refinement, sandwich_covariance
from algid.identification._residual_tests import system_residual_test
from algid.identification._system_result import WEAK_RELATIVE_ERROR
from algid.simulation._system import free_responses, simulate_space, state_space

__all__ = ["refine_system", "SimulationResiduals", "central_jacobian"]

#: Reweighting passes (``sigma_j`` from the residuals of the previous fit).
PASSES = 2

#: Runge-Kutta steps per sample of the second simulation of a nonlinear system, whose
#: optimum's distance is the refined estimate's numerical error.
OTHER_SUBSTEPS = 8


class SimulationResiduals:
    """Weighted simulation residuals of every output on every segment, the initial
    states projected out."""

    def __init__(self, system, segments, sigma, observed=None):
        self.system = system
        self.observed = list(system.outputs if observed is None else observed)
        self.segments = segments
        self.sigma = sigma
        self.evaluations = 0
        self.states = []   # per segment, the fitted initial state (of the last call)
        self.bases = []    # per segment, the weighted free responses (rows x states)

    def __call__(self, theta):
        self.evaluations += 1
        values = dict(zip(self.system.parameters, theta))
        try:
            space = state_space(self.system, values)
        except ModelError:
            return None
        try:
            return self._residuals(space)
        except (np.linalg.LinAlgError, ValueError):   # overflowing modes
            return None

    def _residuals(self, space):
        blocks, states, bases = [], [], []
        outputs = self.observed
        rows = [space.outputs.index(y) for y in outputs]
        with np.errstate(over="ignore", invalid="ignore"):
            for seg in self.segments:
                inputs = {u: seg.values[u] for u in self.system.inputs}
                forced = simulate_space(space, seg.t, inputs)[rows]
                free = free_responses(space, seg.t)[:, rows]   # (states, outputs, samples)
                w = np.array([1.0 / self.sigma[y] for y in outputs])
                target = np.array([seg.values[y] for y in outputs]) - forced
                basis = (free * w[None, :, None]).reshape(len(free), -1).T
                rhs = (target * w[:, None]).ravel()
                if not (np.all(np.isfinite(basis)) and np.all(np.isfinite(rhs))):
                    return None
                x0 = np.linalg.lstsq(basis, rhs, rcond=None)[0]
                states.append(x0)
                bases.append(basis)
                blocks.append(rhs - basis @ x0)
        self.states, self.bases = states, bases
        r = np.concatenate(blocks)
        return r if np.all(np.isfinite(r)) else None

    def bounds(self):
        """Rows of each (segment, output) run in the residual vector."""
        bounds, start = [], 0
        for seg in self.segments:
            for _ in self.observed:
                bounds.append((start, start + len(seg)))
                start += len(seg)
        return bounds

    def per_output_rms(self, r):
        """Output name -> rms of its residuals, in its own units."""
        sums = {y: 0.0 for y in self.observed}
        counts = dict.fromkeys(sums, 0)
        for (a, b), (_, y) in zip(self.bounds(), [(s, y) for s in self.segments
                                                  for y in self.observed]):
            sums[y] += float(r[a:b] @ r[a:b]) * self.sigma[y] ** 2
            counts[y] += b - a
        return {y: float(np.sqrt(sums[y] / counts[y])) for y in sums}


def central_jacobian(residuals, theta, scale):
    """Central-difference Jacobian of the residuals in the scaled parameters."""
    columns = []
    for k in range(len(theta)):
        h = 1e-3 * scale[k]
        up, down = theta.copy(), theta.copy()
        up[k] += h
        down[k] -= h
        r_up, r_down = residuals(up), residuals(down)
        if r_up is None or r_down is None:
            return None
        columns.append((r_up - r_down) / (2 * h))
    residuals(theta)   # leave the states of theta
    return np.column_stack(columns)


def _fit(residuals, start, scale):
    """Levenberg–Marquardt from ``start`` in the parameters over ``scale``: the
    estimate and whether it converged, or None where ``start`` does not simulate."""
    from scipy.optimize import least_squares

    first = residuals(start)
    if first is None:
        return None
    failed = np.full(len(first), 1e150)   # a parameter set that does not simulate

    def scaled(z):
        r = residuals(start + scale * z)
        return failed if r is None else r

    solution = least_squares(scaled, np.zeros(len(start)), method="lm", x_scale=1.0,
                             diff_step=1e-6, xtol=1e-10, ftol=1e-12, gtol=1e-12,
                             max_nfev=200 * (len(start) + 1))
    return start + scale * solution.x, bool(solution.success)


def refine_system(result, segments, refine):
    """The output-error refinement of an algebraic :class:`SystemResult` (``refine``:
    True, False or ``"auto"``) on its measured outputs (the hidden ones simulated)."""
    system = result.system
    observed = [y for y in system.outputs if y not in result.hidden]
    algebraic = {"values": dict(result.values), "covariance": result.covariance,
                 "numerical_error": dict(result.numerical_error),
                 "warnings": list(result.warnings)}
    result = replace(result, algebraic=algebraic)
    if refine is False:
        return replace(result, refinement=Refinement(False, "refine=False"))
    start = np.array([result.values[p] for p in system.parameters])
    se = np.sqrt(np.maximum(np.diag(result.covariance), 0.0))
    weak = [p for p, v, s in zip(system.parameters, start, se)
            if not s <= WEAK_RELATIVE_ERROR * abs(v)]
    if weak and refine == "auto" and not result.hidden:
        # (a start that leaves parameters undetermined, such as an equation without a
        # known term fallen to its trivial solution, can end at a confident wrong one;
        # with hidden signals the mapped coefficients are a rough start by design, and
        # the fit on the full system is what determines the parameters)
        return _not_refined(result, refine, f"the algebraic estimate leaves "
                                            f"{', '.join(weak)} poorly determined: no fit "
                                            f"is started from it (refine=True refines "
                                            f"anyway)")
    scale = np.where(se > 0, se, np.maximum(np.abs(start), 1.0) * 1e-6)
    if not system.is_linear:
        return _refine_nonlinear(result, segments, refine, start, scale)
    sigma = {y: 1.0 for y in observed}
    residuals = SimulationResiduals(system, segments, sigma, observed)
    r0 = residuals(start)
    if r0 is None:
        return _not_refined(result, refine, "the algebraic estimate does not simulate "
                                            "stably on these records")
    sigma.update(residuals.per_output_rms(r0))
    theta, converged = start, False
    for _ in range(PASSES):
        fitted = _fit(residuals, theta, scale)
        if fitted is None:
            return _not_refined(result, refine, "the refinement diverged")
        theta, converged = fitted
        r = residuals(theta)
        if r is None:
            return _not_refined(result, refine, "the refined estimate does not simulate "
                                                "stably")
        sigma.update(residuals.per_output_rms(r))
    before = float(np.sum(residuals(start) ** 2))   # with the final weights
    r = residuals(theta)
    after = float(r @ r)
    J = central_jacobian(residuals, theta, scale)
    if J is None:
        return _not_refined(result, refine, "the refined estimate's neighbourhood does "
                                            "not simulate stably")
    n_states = len(residuals.states[0]) * len(segments)
    dof = len(r) - len(theta) - n_states
    covariance, ar = sandwich_covariance(J, r, residuals.bounds(), dof)
    test = system_residual_test(residuals, theta, r, J, ar, dof)
    rms = residuals.per_output_rms(r)
    refinement = Refinement(True, "refined by output error", converged=converged,
                            evaluations=residuals.evaluations,
                            rms_before=float(np.sqrt(before / len(r))),
                            rms_after=float(np.sqrt(after / len(r))), noise_ar=tuple(ar),
                            initial_states=list(residuals.states), residual_test=test)
    if refine == "auto" and not after < before:
        return replace(result, refinement=replace(
            refinement, applied=False,
            reason="the refinement did not lower the simulation error"))
    return replace(result, values=dict(zip(system.parameters, theta.tolist())),
                   covariance=covariance, estimate="refined", refinement=refinement,
                   noise_rms=rms, numerical_error={})


def _refine_nonlinear(result, segments, refine, start, scale):
    """:func:`refine_system` of a system nonlinear in its signals (every output measured:
    a hidden signal is eliminated only from a linear system): the output-error fit of
    :func:`~algid.identification._output_error_nonlinear.refine_nonlinear`, its initial
    states iterated with the parameters, reported by ``"auto"`` under the rules of one
    nonlinear equation."""
    from algid.identification._output_error import PRECISION_MARGIN
    from algid.identification._output_error_nonlinear import (
        fit_initial_states,
        prepare_nonlinear_system,
        refine_nonlinear,
    )
    from algid.identification._records import UNIFORM_TOLERANCE
    from algid.simulation._fast_simulation import fast_simulation_unavailable
    from algid.simulation._system_equations import SystemStructure

    system = result.system
    unavailable = fast_simulation_unavailable(None)
    if unavailable is not None:
        return _not_refined(result, refine, f"{unavailable}: not refined")
    try:
        SystemStructure(system)
    except ModelError as error:   # (a sign() of an output, a derivative of an input)
        return _not_refined(result, refine, f"{error}: not refined")
    if not np.all(np.isfinite(start)):
        return _not_refined(result, refine, "the algebraic estimate is not finite")
    if any(seg.step is None for seg in segments):
        return _not_refined(result, refine, "the output-error refinement needs uniformly "
                                            "sampled records")
    step = segments[0].step
    if any(abs(seg.step - step) > UNIFORM_TOLERANCE * step for seg in segments):
        return _not_refined(result, refine, "the output-error refinement needs records of "
                                            "one sampling step")
    sigma = {y: 1.0 for y in system.outputs}
    theta, covariance, info, states = start, None, None, None
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        for _ in range(PASSES):   # (each output weighted by its residuals' rms)
            data = prepare_nonlinear_system(system, segments, sigma)
            if info is None:   # (the initial states fitted to the algebraic estimate)
                states = start_states = fit_initial_states(data, theta)
                first = _output_rms(data, theta, states)
                if first is None:
                    return _not_refined(result, refine, "the algebraic estimate does not "
                                                        "simulate stably on these records")
                sigma = first
                data = prepare_nonlinear_system(system, segments, sigma)
            data.start = states
            # (the numerical error: the optimum with the inputs interpolated otherwise
            # and twice the steps, which sees a jump of sign(u) within a step too)
            theta, covariance, info = refine_nonlinear(
                data, theta, scale, prepare_nonlinear_system(system, segments, sigma,
                                                             "cubic", OTHER_SUBSTEPS))
            if not np.all(np.isfinite(theta)):
                return _not_refined(result, refine, "the refinement diverged")
            states = info.initial_states
            sigma = _output_rms(data, theta, states)
            if sigma is None:
                return _not_refined(result, refine, "the refined estimate does not "
                                                    "simulate stably")
    # (the last pass starts where the first ended: against the algebraic start, in the
    # last pass's weights)
    before = np.concatenate([y - simulation.run(start, x0) for simulation, y, x0
                             in zip(data.simulations, data.outputs, start_states)])
    info = replace(info, rms_before=float(np.sqrt(np.mean(before ** 2))))
    algebraic_se = np.sqrt(np.maximum(np.diag(result.covariance), 0.0))
    refined_se = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    numerical = np.asarray(info.numerical_error, dtype=float)
    why = None
    if not (np.all(np.isfinite(covariance))
            and info.rms_after < info.rms_before * (1 - 1e-9)):
        why = "the refinement did not lower the simulation error"
    elif refine == "auto" and np.any(numerical > refined_se):
        worst = int(np.argmax(numerical / np.maximum(refined_se, 1e-300)))
        why = (f"the simulation's own error (its interpolation of the inputs) exceeds the "
               f"noise's: {system.parameters[worst]} moves by {numerical[worst]:.2g} with "
               f"another interpolation, over its standard error (refine=True refines "
               f"anyway)")
    elif refine == "auto" and np.any(refined_se > PRECISION_MARGIN * algebraic_se):
        worst = int(np.argmax(refined_se / np.maximum(algebraic_se, 1e-300)))
        why = (f"the output-error fit is much less precise than the algebraic estimate "
               f"({system.parameters[worst]}: standard error {refined_se[worst]:.2g} "
               f"against {algebraic_se[worst]:.2g}): its residuals are mostly the "
               f"system's error, not noise (refine=True refines anyway)")
    if why is not None:
        if refine is True and why.startswith("the refinement did not"):
            raise ModelError(f"refine=True: {why}")
        warnings = list(result.warnings)
        if "mostly the system's error" in why:   # (what the fit's residuals name, or that)
            warnings = [f"not refined, the system misses the records: {w}"
                        for w in info.residual_test.warnings()] \
                or [f"not refined: {why}"]
            warnings += result.warnings
        return replace(result, refinement=replace(info, applied=False, reason=why),
                       warnings=warnings)
    refinement = replace(info, applied=True, reason="refined by output error")
    return replace(result, values=dict(zip(system.parameters, theta.tolist())),
                   covariance=covariance, estimate="refined", refinement=refinement,
                   noise_rms=sigma,
                   numerical_error=dict(zip(system.parameters, numerical.tolist())))


def _output_rms(data, theta, states):
    """Output name -> rms of its simulation residuals (in its own units), or None where
    a segment does not simulate."""
    outputs = data.model.outputs
    sums, counts = dict.fromkeys(outputs, 0.0), dict.fromkeys(outputs, 0)
    for simulation, measured, x0 in zip(data.simulations, data.outputs, states):
        r = (measured - simulation.run(theta, x0)).reshape(len(outputs), -1)
        if not np.all(np.isfinite(r)):
            return None
        for y, row, w in zip(outputs, r, simulation.weights):
            sums[y] += float(row @ row) / w ** 2
            counts[y] += len(row)
    return {y: float(np.sqrt(sums[y] / counts[y])) for y in outputs}


def _not_refined(result, refine, reason):
    if refine is True:
        raise ModelError(f"refine=True: {reason}")
    return replace(result, refinement=Refinement(False, reason))
