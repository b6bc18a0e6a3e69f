"""Output-error refinement of identify's estimate.

The algebraic estimate weights the data by its kernels and windows, so its variance
stays above the Cramér–Rao bound.  The output-error (prediction-error) fit

    min over theta and x0_s of  sum over segments s and samples k of
        (y_k - yhat_k(theta, x0_s))**2

where ``yhat`` is the model's output simulated from the measured inputs, is the
maximum-likelihood estimate under white Gaussian output noise, asymptotically
efficient.  The algebraic estimate, which needs no initial state, starts it.

For a model linear in its signals the simulation is
:mod:`algid.identification._linear_simulation` (exact for inputs interpolated as
band-limited signals); a nonlinear one (Duffing, friction) is fitted by
:mod:`algid.identification._output_error_nonlinear` on the fast simulator, with the
same covariance and a residual test whose directions come from the model simulated
with each candidate term; it is not reported where it is much less precise than the
algebraic estimate (:data:`PRECISION_MARGIN`: its residuals are then mostly the model's
error, which no candidate need name).

The initial state of each segment (each record, and each run between gaps) is a
nuisance parameter: the output is linear in it, so it is solved for by least squares
inside every evaluation (variable projection), and the parameters alone are iterated
(Levenberg–Marquardt, :func:`scipy.optimize.least_squares`, on parameters scaled by the
algebraic standard errors).  The covariance is the sandwich form of
:func:`algid.identification._refinement.sandwich_covariance`, honest under coloured
residuals.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from algid.errors import InputDataError, ModelError
from algid.identification._linear_simulation import (
    LinearSimulation,
    channel_samples,
    output_polynomials,
    simulates_stably,
    step_points,
)
from algid.identification._records import UNIFORM_TOLERANCE
from algid.identification._refinement import Refinement, sandwich_covariance
from algid.identification._residual_tests import residual_test, settles
from algid.models._expression import Signal

__all__ = ["OutputErrorData", "refinement_unavailable", "refine_linear",
           "refine_result", "check_refine", "stabilised", "jacobian",
           "projected_jacobian", "prepare", "REFINE_CHOICES", "PRECISION_MARGIN"]

#: Finite-difference step of the Jacobian, in algebraic standard errors.
_JACOBIAN_STEP = 1e-3

#: Gauss–Newton steps after the Levenberg–Marquardt iteration, at most.
_POLISH_STEPS = 3

#: A nonlinear model's refinement is not reported (``refine="auto"``) where a standard
#: error exceeds the algebraic one this many times (measured: 0.4-1.05 times on Duffing
#: and friction records at 30 dB; 2.3-11 times on EMPS, 75 times on a noise-free record).
PRECISION_MARGIN = 2.0


def refinement_unavailable(model):
    """Why a model cannot be refined (None if it can): by :func:`refine_linear`, or, for
    a model nonlinear in its signals, by
    :func:`~algid.identification._output_error_nonlinear.refine_nonlinear`.

    Parameters
    ----------
    model : algid.models._model.Model

    Returns
    -------
    str or None
        One line, or None.
    """
    if not model.is_linear:
        from algid.simulation._fast_simulation import fast_simulation_unavailable

        return fast_simulation_unavailable(model)
    output = model.output
    order = max((t.derivative for t in model.terms
                 if isinstance(t.factor, Signal) and t.factor.name == output), default=0)
    if order == 0:
        return f"the output {output!r} is not differentiated: nothing to simulate"
    for term in model.terms:
        if isinstance(term.factor, Signal) and term.factor.name != output \
                and term.derivative > order:
            return (f"the term {term} differentiates an input more often than the "
                    f"output ({order}): the model is not proper")
    return None


@dataclass
class OutputErrorData:
    """The records as the refinement simulates them (built once by :func:`prepare`).

    Attributes
    ----------
    model : algid.models._model.Model
    step : float
        Sampling step (s).
    upsampling : int
        Points per sampling step of the inputs.
    inputs : list of numpy.ndarray
        Per segment, the input channels (:func:`channel_samples`).
    points : list of numpy.ndarray
        Per segment, :func:`step_points` of its inputs.
    gains : numpy.ndarray
        Per channel, its scale over the output's (the inputs and the outputs above are
        divided by powers of two to unit size, so that any units fit alike).
    output_scale : float
        The power of two the outputs were divided by.
    channels : tuple of str
        The input channels, in the order of ``inputs``' rows.
    outputs : list of numpy.ndarray
        Per segment, the measured output.
    """

    model: object
    step: float
    upsampling: int
    inputs: list
    outputs: list
    points: list = field(default_factory=list)
    gains: np.ndarray | None = None
    output_scale: float = 1.0
    channels: tuple = ()


def prepare(model, segments, step, interpolation="bandlimited"):
    """:class:`OutputErrorData` of the segments.

    Parameters
    ----------
    model : algid.models._model.Model
    segments : list of Segment
        Uniformly sampled runs.
    step : float
        Sampling step (s).
    interpolation : {"bandlimited", "cubic", "linear"}
        The inputs between samples: as band-limited signals (as
        :func:`algid.simulate_model` does by default; the choice that does not bias
        the estimate at few samples per period), a cubic spline (the other choice whose
        difference gives the numerical error), or linear.

    Returns
    -------
    OutputErrorData
    """
    from algid.simulation._interpolation import UPSAMPLING

    upsampling = 1 if interpolation == "linear" else UPSAMPLING
    channels = LinearSimulation(model, dict.fromkeys(model.parameters, 1.0), step).channels
    inputs = [channel_samples(channels, seg, upsampling, interpolation) for seg in segments]
    outputs = [np.asarray(seg.values[model.output], dtype=float) for seg in segments]
    # every channel and the output divided by a power of two to unit size (exact)
    scales = np.array([_power_of_two(np.concatenate([u[j] for u in inputs]))
                       for j in range(len(channels))])
    output_scale = _power_of_two(np.concatenate(outputs))
    inputs = [u / scales[:, None] for u in inputs]
    return OutputErrorData(
        model, step, upsampling, inputs, [y / output_scale for y in outputs],
        [step_points(u, upsampling) for u in inputs], scales / output_scale, output_scale,
        channels)


def _power_of_two(values):
    """The power of two nearest the largest magnitude (1 for zeros)."""
    largest = float(np.max(np.abs(values))) if len(values) else 0.0
    return float(2.0 ** np.frexp(largest)[1]) if largest > 0 and np.isfinite(largest) \
        else 1.0


@dataclass
class _Evaluation:
    residual: np.ndarray                 # all segments, stacked
    free: list                           # per segment: (N_s, n)
    initial: list                        # per segment: the fitted initial state


def _evaluate(data, theta):
    model = data.model
    sim = LinearSimulation(model, dict(zip(model.parameters, theta)), data.step,
                           data.upsampling)
    residual, free, initial = [], [], []
    for inputs, y, points in zip(data.inputs, data.outputs, data.points):
        forced, F = sim.run(inputs, points, data.gains)
        if not (np.all(np.isfinite(forced)) and np.all(np.isfinite(F))):
            return _Evaluation(np.full(sum(len(y) for y in data.outputs), np.inf), [], [])
        x0 = np.linalg.lstsq(F, y - forced, rcond=None)[0] if F.shape[1] else np.zeros(0)
        residual.append(y - forced - F @ x0)
        free.append(F)
        initial.append(x0)
    return _Evaluation(np.concatenate(residual), free, initial)


def jacobian(data, theta, scale):
    """The residuals' Jacobian in the parameters, initial states projected out.

    Central differences of steps ``scale * 1e-3`` of the residuals, the initial states
    refitted at each (variable projection).

    Parameters
    ----------
    data : OutputErrorData
    theta : numpy.ndarray
        The parameters.
    scale : numpy.ndarray
        Per parameter, its typical uncertainty.

    Returns
    -------
    numpy.ndarray, shape (N, p)
    """
    columns = []
    for i in range(len(theta)):
        h = scale[i] * _JACOBIAN_STEP
        up, down = np.array(theta, float), np.array(theta, float)
        up[i] += h
        down[i] -= h
        columns.append((_evaluate(data, up).residual
                        - _evaluate(data, down).residual) / (2 * h))
    return np.array(columns).T


def projected_jacobian(data, theta, scale, free=None):
    """:func:`jacobian` with the free responses projected out, segment by segment.

    (The Jacobian of residuals with refitted initial states also has a part in the span
    of the free responses, of the order of the residuals: it is dropped, leaving the
    parameters' block of the Fisher information with the initial states as nuisance.)

    Parameters
    ----------
    data : OutputErrorData
    theta, scale : numpy.ndarray
        As :func:`jacobian`.
    free : list of numpy.ndarray, optional
        The free responses at ``theta`` (computed when not given).

    Returns
    -------
    J : numpy.ndarray, shape (N, p)
    bounds : list of (int, int)
        Each segment's rows.
    """
    J = jacobian(data, theta, scale)
    free = _evaluate(data, theta).free if free is None else free
    bounds, at = [], 0
    for F in free:
        b = at + F.shape[0]
        if F.shape[1]:
            J[at:b] -= F @ np.linalg.lstsq(F, J[at:b], rcond=None)[0]
        bounds.append((at, b))
        at = b
    return J, bounds


def refine_linear(data, theta, scale, other=None):
    """The output-error estimate started from ``theta``.

    Parameters
    ----------
    data : OutputErrorData
        The records (:func:`prepare`) of a model for which
        :func:`refinement_unavailable` is None.
    theta : numpy.ndarray
        The starting estimate (identify's), in ``model.parameters`` order.
    scale : numpy.ndarray
        Per parameter, a positive typical uncertainty (the algebraic standard errors).
    other : OutputErrorData, optional
        The same records with the inputs interpolated otherwise (a cubic spline): the
        estimate's change from one to the other (one Gauss–Newton step from it) is its
        numerical error, in :attr:`Refinement.numerical_error`.

    Returns
    -------
    theta : numpy.ndarray
    covariance : numpy.ndarray
    refinement : Refinement
    """
    from scipy.optimize import least_squares

    theta0 = np.asarray(theta, dtype=float)
    scale = np.asarray(scale, dtype=float)
    count = [0]

    def residual(z):
        count[0] += 1
        r = _evaluate(data, theta0 + z * scale).residual
        return np.where(np.isfinite(r), r, 1e150)

    start = _evaluate(data, theta0)
    rms_before = float(np.sqrt(np.mean(start.residual ** 2))) * data.output_scale
    fit = least_squares(residual, np.zeros(len(theta0)), method="lm", x_scale=1.0,
                        diff_step=_JACOBIAN_STEP, xtol=1e-13, ftol=1e-15, gtol=1e-15,
                        max_nfev=100 * (len(theta0) + 1))
    theta_hat = theta0 + fit.x * scale
    final = _evaluate(data, theta_hat)
    J, bounds = projected_jacobian(data, theta_hat, scale, final.free)
    count[0] += 2 * len(theta0)
    # Gauss-Newton steps with central-difference Jacobians: the optimum to round-off
    # (the iteration's forward differences stop it about 1e-6 standard errors away)
    for _ in range(_POLISH_STEPS):
        step_z = np.linalg.lstsq(J * scale, final.residual, rcond=None)[0]
        polished = theta_hat - step_z * scale
        trial = _evaluate(data, polished)
        count[0] += 1
        if not trial.residual @ trial.residual <= final.residual @ final.residual:
            break
        theta_hat, final = polished, trial
        J, bounds = projected_jacobian(data, theta_hat, scale, final.free)
        count[0] += 2 * len(theta0)
        if np.max(np.abs(step_z)) < 1e-10:
            break
    dof = len(final.residual) - len(theta0) - sum(F.shape[1] for F in final.free)
    # in the scaled parameters (columns of like size in any units: a pseudo-inverse
    # would otherwise drop the smaller ones), then back
    J = J * scale
    covariance, ar = sandwich_covariance(J, final.residual, bounds, dof)
    covariance = covariance * np.outer(scale, scale)
    rms_after = float(np.sqrt(np.mean(final.residual ** 2))) * data.output_scale
    numerical = np.full(len(theta0), np.nan)
    if other is not None:   # one Gauss-Newton step on the other interpolation's residuals
        step_to = np.linalg.lstsq(J, _evaluate(other, theta_hat).residual, rcond=None)[0]
        numerical = np.abs(step_to) * scale
        count[0] += 1
    test = None
    if np.all(np.isfinite(final.residual)) and np.all(np.isfinite(J)):
        test = residual_test(data, theta_hat, final.residual, final.free, J, bounds, ar, dof)
    return theta_hat, covariance, Refinement(
        applied=True, reason="", converged=bool(fit.success), evaluations=count[0],
        rms_before=rms_before, rms_after=rms_after, noise_ar=tuple(float(a) for a in ar),
        initial_states=[x0 * data.output_scale for x0 in final.initial],
        residual_test=test, numerical_error=numerical)


#: Values of ``refine`` that :func:`algid.identify` takes.
REFINE_CHOICES = ("auto", True, False)

def check_refine(refine):
    """``refine`` as one of :data:`REFINE_CHOICES`, else an InputDataError."""
    if isinstance(refine, (bool, np.bool_)):
        return bool(refine)
    if isinstance(refine, str) and refine == "auto":
        return refine
    raise InputDataError(f"refine must be True, False or 'auto', got {refine!r:.40}")


def stabilised(model, values):
    """The parameters with the unstable roots of the output's polynomial reflected into
    the left half-plane, the same leading coefficient (None where the parameters
    cannot set that polynomial, or a root stays on the imaginary axis).

    Parameters
    ----------
    model : algid.models._model.Model
    values : mapping
        Parameter name -> value.

    Returns
    -------
    dict or None
    """
    den, _ = output_polynomials(model, values)
    n = max(den)
    coefficients = np.array([den.get(k, 0.0) for k in range(n, -1, -1)])
    roots = np.roots(coefficients)
    if np.any(roots.real == 0):
        return None
    target = np.real(np.poly(np.where(roots.real > 0, -roots.conj(), roots)))
    target = target[::-1] * coefficients[0]                  # by derivative order
    names = [p for p in model.parameters
             if any(t.parameter == p and isinstance(t.factor, Signal)
                    and t.factor.name == model.output for t in model.terms)]
    A, known = np.zeros((n + 1, len(names))), np.zeros(n + 1)
    for term in model.terms:
        if isinstance(term.factor, Signal) and term.factor.name == model.output:
            if term.parameter is None:
                known[term.derivative] += term.coefficient
            else:
                A[term.derivative, names.index(term.parameter)] += term.coefficient
    solution = np.linalg.lstsq(A, target - known, rcond=None)[0]
    if not np.allclose(A @ solution + known, target, rtol=1e-9, atol=1e-12 * np.max(
            np.abs(target))):
        return None
    return dict(values, **dict(zip(names, solution.tolist())))


def _typical_uncertainty(result):
    """Per parameter, the scale of the refinement's steps: the algebraic standard error
    or numerical error, at least a millionth of the value (a noise-free record's
    errors are round-off, below a difference step's resolution)."""
    names = result.model.parameters
    theta = np.abs(np.array([result.values[p] for p in names], dtype=float))
    se = np.array([result.stderr[p] for p in names], dtype=float)
    numerical = np.array([result.numerical_error.get(p, 0.0) for p in names], dtype=float)
    spread = np.fmax(np.where(np.isfinite(se), se, 0.0),
                     np.where(np.isfinite(numerical), numerical, 0.0))
    return np.maximum(spread, np.maximum(1e-6 * theta, 1e-300))


def _not_refined(result, algebraic, why, refine):
    """The algebraic result, saying why it is not refined (an error where asked to)."""
    from dataclasses import replace

    if refine is True:
        raise ModelError(f"refine: {why}")
    return replace(result, algebraic=algebraic,
                   refinement=Refinement(applied=False, reason=why))


def refine_result(result, segments, step, refine, data_warnings=(), unavailable=None):
    """``result`` refined by output error (:func:`refine_linear`) where ``refine`` asks.

    Parameters
    ----------
    result : IdentificationResult
        The algebraic result.
    segments : list of Segment
        The records' runs of contiguous samples.
    step : float
        Sampling step (s).
    refine : {"auto", True, False}
        ``"auto"``: refine where it is safe (the algebraic model is stable and the
        refined one too, the simulation error drops, and the simulation's own error, its
        interpolation of the inputs, is below the noise's), else keep the algebraic
        estimate and say why in :attr:`Refinement.reason`; True: refine, refusing a
        model that cannot be, with a warning where the fit does not lower the
        simulation error; False: keep the algebraic estimate.
    data_warnings : sequence of str
        The result's warnings about the records and what they determine (not about the
        algebraic model's fit): kept in a refined result, whose other warnings are
        those of its residual test (all the algebraic ones stay in
        ``algebraic["warnings"]``).
    unavailable : str, optional
        Why these records cannot be refined (a record read in chunks): the algebraic
        estimate, with this reason (refused with ``refine=True``).

    Returns
    -------
    IdentificationResult
        With ``estimate`` ``"refined"`` or ``"algebraic"``, ``algebraic`` (the algebraic
        values and covariance) and ``refinement``.

    Raises
    ------
    ModelError
        ``refine=True`` on a model that cannot be simulated by the linear simulator.
    """
    from dataclasses import replace

    refine = check_refine(refine)
    algebraic = {"values": dict(result.values), "covariance": result.covariance.copy(),
                 "numerical_error": dict(result.numerical_error),
                 "warnings": list(result.warnings)}
    if refine is False:
        return replace(result, algebraic=algebraic, refinement=Refinement(
            applied=False, reason="not asked (refine=False)"))
    model = result.model
    nonlinear = not model.is_linear
    why = unavailable or refinement_unavailable(model)
    if why is None and any(seg.step is None for seg in segments):
        why = "the output-error refinement needs uniformly sampled records"
    elif why is None:   # the runs' own steps (exact from their ends), as one
        step = float(np.average([seg.step for seg in segments],
                                weights=[len(seg) for seg in segments]))
        if any(abs(seg.step - step) > UNIFORM_TOLERANCE * step for seg in segments):
            why = "the output-error refinement needs records of one sampling step"
    if why is not None:
        return _not_refined(result, algebraic, why, refine)
    theta0 = np.array([result.values[p] for p in model.parameters], dtype=float)
    started = ""
    if not np.all(np.isfinite(theta0)):
        why = "the algebraic estimate is not finite"
    elif refine == "auto" and not nonlinear and not simulates_stably(model, result.values):
        # (a wrong model's algebraic estimate often is: its fit then starts from the
        # same model with its unstable poles reflected, and must end stable)
        reflected = stabilised(model, result.values)
        if reflected is None:
            why = ("the algebraic estimate's model is not stable: an output-error fit "
                   "could diverge (refine=True tries it)")
        else:
            theta0 = np.array([reflected[p] for p in model.parameters])
            started = "; started from the algebraic model with its unstable poles reflected"
    if why is not None:
        return _not_refined(result, algebraic, why, refine)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        if nonlinear:   # (a nonlinear model's simulation is bounded or it diverges)
            from algid.identification._output_error_nonlinear import (
                prepare_nonlinear,
                refine_nonlinear,
            )

            theta, covariance, info = refine_nonlinear(
                prepare_nonlinear(model, segments), theta0, _typical_uncertainty(result),
                prepare_nonlinear(model, segments, "cubic"))
        else:
            data = prepare(model, segments, step)
            other = prepare(model, segments, step, "cubic")
            theta, covariance, info = refine_linear(data, theta0,
                                                    _typical_uncertainty(result), other)
    values = dict(zip(model.parameters, theta.tolist()))
    if not (np.all(np.isfinite(theta)) and np.all(np.isfinite(covariance))
            and info.rms_after < info.rms_before * (1 - 1e-9)):
        why = "the output-error fit did not lower the simulation error"
    elif refine == "auto" and not nonlinear and not simulates_stably(model, values):
        why = "the output-error fit gives a model that is not stable"
    elif refine == "auto" and np.any(info.numerical_error
                                     > np.sqrt(np.maximum(np.diag(covariance), 0.0))):
        # (few samples per period, or a noise-free record: the refined estimate would
        # carry an error its standard errors do not hold)
        worst = int(np.argmax(info.numerical_error
                              / np.sqrt(np.maximum(np.diag(covariance), 1e-300))))
        why = (f"the simulation's own error (its interpolation of the inputs) exceeds "
               f"the noise's: {model.parameters[worst]} moves by "
               f"{info.numerical_error[worst]:.2g} with another interpolation, over its "
               f"standard error (refine=True refines anyway)")
    misfit = False   # (the refused fit's residuals mostly the model's error)
    if why is None and refine == "auto" and nonlinear:
        # a nonlinear fit must not be the less precise: efficient under the noise,
        # its errors are at most the algebraic ones
        # (about equal for an offset, which both take from the mean) unless its
        # residuals are mostly the model's error (a simulation that drifts from the
        # records), as on a noise-free record or a simplified model of a machine
        refined_se = np.sqrt(np.maximum(np.diag(covariance), 0.0))
        algebraic_se = np.sqrt(np.maximum(np.diag(result.covariance), 0.0))
        worse = refined_se > PRECISION_MARGIN * algebraic_se
        misfit = bool(np.any(worse))
        if misfit:
            worst = int(np.argmax(np.where(worse, refined_se / np.maximum(
                algebraic_se, 1e-300), 0.0)))
            why = (f"the output-error fit is much less precise than the algebraic estimate "
                   f"({model.parameters[worst]}: standard error {refined_se[worst]:.2g} "
                   f"against {algebraic_se[worst]:.2g}): its residuals are mostly the "
                   f"model's error, not noise (refine=True refines anyway)")
    if why is not None:   # (a warning where asked for: "auto" says so in the reason)
        info.applied, info.reason = False, why
        notes = [f"not refined: {why}; the algebraic estimate is reported"] \
            if refine is True else []
        named = []
        if misfit and settles(model, values):
            # residuals mostly model error on a model that forgets its errors: what its
            # test names is the model's lack, not drift (an integrating model, such as a
            # mass with friction, drifts from a record under any small error, and there
            # the named terms would be false leads), and the algebraic estimate is off
            # by as much
            named = [f"not refined, the model misses the records: {w}"
                     for w in info.residual_test.warnings()]
        return replace(result, algebraic=algebraic, refinement=info,
                       warnings=named + result.warnings + notes)
    info.reason = (f"output error {info.rms_after:.3g} rms (algebraic "
                   f"{info.rms_before:.3g}){started}")
    # (a named model error first: it says what to change; what the records determine
    # follows)
    warnings = info.residual_test.warnings() \
        + [w for w in result.warnings if w in data_warnings]
    return replace(result, values=values, covariance=covariance, estimate="refined",
                   numerical_error=dict(zip(model.parameters,
                                            info.numerical_error.tolist())),
                   algebraic=algebraic, refinement=info, warnings=warnings)
