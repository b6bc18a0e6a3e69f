"""Identify the parameters of a user model on whole measured records.

The algebraic method's equations hold on every window ``[t0, t0 + T]``, whatever the
state at ``t0``: each window turns every term ``D^k z`` into the integral of ``z``
against a modulating kernel (:mod:`algid.identification._window_kernels`) and gives one
linear equation in the parameters.  Windows of one length slide over every record
(``length // 8`` samples apart, never across a gap) and the stacked equations are
solved for one parameter set.  Two kernel multiplicities work as an embedded pair: the
higher one (``a = 12``) gives the estimate, the lower one (``a = 8``) its numerical
error.

Solvers (``method``): ``"bc"`` (default), least squares with the bias of output noise
removed (Koopmans' estimator; no simulation, so closed loops and integrating plants
are fine); ``"ls"``, plain least squares; ``"iv"``, instrumental variables from the
output simulated by the current estimate (open-loop stable plants); ``"gls"``,
Koopmans' estimator on the equations weighted by the inverse covariance of their noise
(:mod:`algid.identification._window_weighting`).

The time and every column are scaled by powers of two and the equations solved in an
orthonormal basis of their regressors (:mod:`algid.identification._window_basis`), so
that any units give the same window and estimates.  Standard errors come from a
sandwich over the window index: the covariance that white output noise puts into the
equations where the residuals' own (HAC) covariance agrees with it, else the smallest
at least both (:mod:`algid.identification._window_covariance`).  Without ``window`` the length is
chosen on a grid by the worst parameter's error (:func:`window_criterion`).  The
crossings of a ``sign(q')`` are placed by fits of ``q`` with the motion the model gives
it (:mod:`algid.identification._sign_crossings`), and the equations solved again.
What the records cannot determine is refused, naming the parameters.

The user guide, "How identify works", gives the equations, the solvers, the
covariance, the window rule and the crossings in full.
"""

from __future__ import annotations

import types
from typing import NamedTuple

import numpy as np

from algid._memory import check_fits
from algid.errors import InputDataError, ModelError
from algid.identification._adequacy import (
    misfit_limit,
    misfit_ratio,
    missing_terms,
    model_adequacy,
)
from algid.identification._arguments import check_arguments, check_memory, check_model_columns
from algid.identification._bias_compensation import solve_equilibrated
from algid.identification._methods import METHODS
from algid.identification._model_velocity import has_velocity, settle_crossings
from algid.identification._record_source import is_streamed_input, record_source
from algid.identification._records import (
    Segment,
    check_factors,
    estimate_derivative,
    prepare_records,
)
from algid.identification._sign_crossings import crossing_jumps
from algid.identification._streamed_problem import (
    CHUNK_SAMPLES,
    STREAM_SAMPLES,
    StreamedProblem,
    scan_record,
    stream_refusal,
)
from algid.identification._window_basis import (
    WindowBasis,
    check_excited,
    check_finite,
    separability,
)
from algid.identification._window_covariance import hac_meat, sandwich
from algid.identification._window_problem import (
    DERIVATIVE_SAMPLES,
    MULTIPLICITIES,
    WindowProblem,
    add_derivatives,
    derivative_estimate,
    is_sign_factor,
    window_stride,
)
from algid.identification._window_rule import (
    WindowFit,
    check_multiplicities,
    choose_window,
    grid_lengths,
    min_length,
    window_advice,
    window_criterion,
    window_grid,
    window_length,
)
from algid.identification._window_weighting import whitened_equations
from algid.models._argument import estimator_module
from algid.models._compiled import model_of
from algid.models._grammar import parse_equation
from algid.models._model import Model
from algid.models._system import is_system

__all__ = ["identify", "check_chunk", "METHODS", "MULTIPLICITIES", "AGREEMENT", "CROSSING_PASSES",
           "CROSSINGS",
           "STREAM_SAMPLES", "CHUNK_SAMPLES", "EXCERPT_SAMPLES", "EXCERPTS",
           "window_criterion", "window_grid", "WEIGHTING_Z", "WEIGHTING_FLOOR"]

#: Weighted and unweighted estimates further apart than this many standard deviations
#: of their difference (in any parameter) reject the weighting (``method="gls"``).
WEIGHTING_Z = 4.0

#: The variance of that difference is at least this share of the unweighted one's.
WEIGHTING_FLOOR = 0.1


#: The covariance of output noise through the kernels replaces the residuals' own (HAC)
#: where the latter's variances are at most this many times the former's.
AGREEMENT = 4.0

#: Solves with the crossings of ``sign(q')`` placed by the model's motion (the second
#: with the first's parameters: noise-free friction loop, M 1.3e-6 -> 5.8e-7).
CROSSING_PASSES = 2

#: How :func:`identify` may place the steps of a ``sign(q')`` (its ``crossings``).
CROSSINGS = ("auto", "velocity", "local")

#: Round-off standard error of the solution, per sample of a window, relative to the
#: known side (in the orthonormal basis of :mod:`algid.identification._window_basis`).
ROUNDOFF = 4 * np.finfo(float).eps


#: The automatic window of a record read in chunks is chosen on this many samples of it,
#: in :data:`EXCERPTS` excerpts spread over the record (standard errors scaled to the
#: whole record's samples).
EXCERPT_SAMPLES = 2**18

#: Excerpts of the window rule on a record read in chunks.
EXCERPTS = 8

#: Why a record read in chunks is not refined.
STREAMED_UNREFINED = ("a record read in chunks is not refined (the output-error fit "
                      "simulates it whole): load it and call result.refine(record)")

#: Memory per window of each length and multiplicity of a streamed fit (bytes per row
#: entry; the rows, their orthonormal basis, the scores and the solver's copies).
ROW_BYTES = 8 * 8


class _Solution(NamedTuple):
    """The solve of one multiplicity's window equations (:func:`_solve_multiplicity`),
    in the orthonormal basis of :class:`WindowBasis`."""

    phi: np.ndarray            # the solution in the basis
    basis: WindowBasis
    ids: np.ndarray            # the segment of each window
    scores: np.ndarray         # the estimating equations per window
    jacobian: np.ndarray       # their derivative
    variance: float | None     # the noise variance of a correction (None: none)
    weights: np.ndarray        # the regressors or instruments of the scores
    separation: object         # the separability check (highest multiplicity), or None
    grams: np.ndarray | None   # per-window noise covariances of [A | b] in the basis
    misfit: float              # the squared misfit of the solved (whitened) equations
    trace: float               # what unit output noise makes of it before the fit
    projection: bool           # whether the residuals are a projection (not instruments)


def _solve_multiplicity(problem, length, a, top, instruments=None, method="ls"):
    """The window equations of multiplicity ``a`` solved by ``method`` (a name of
    :data:`METHODS`), or by instrumental variables (``instruments``: the rows of the
    simulated output); ``top``, the highest multiplicity, is checked for separability."""
    A, b, ids = problem.rows(length, a)
    check_finite(problem, A, b)
    if not problem.cache.excited:  # once: a vanishing term does so at any window
        check_excited(problem, length, a, A, b)
        problem.cache.excited = True
    basis = WindowBasis(A, b)
    grams = basis.grams(problem.noise_grams(length, a))
    separation = None
    if a == top:
        separation = separability(basis, problem.exact_columns, grams.sum(axis=0))
        if separation.proportional:
            raise ModelError(separation.message(problem.parameters))
    variance = None
    weights = basis.A
    if instruments is not None:
        Z = weights = basis.instruments(instruments)
        phi = solve_equilibrated(Z.T @ basis.A, Z.T @ basis.b)
        scores, jacobian = Z * (basis.b - basis.A @ phi)[:, None], Z.T @ basis.A
    else:
        phi, scores, jacobian, variance = METHODS[method].solve(
            basis.A, basis.b, grams, problem.noise_bound())
        if METHODS[method].weighted:
            whitened = whitened_equations(problem, length, a,
                                          np.append(basis.theta(phi), -1.0), basis, ids,
                                          window_stride(length))
            if whitened is not None:
                phi, scores, jacobian, variance, weights = whitened.solve(
                    problem.noise_bound())
                return _Solution(phi, basis, ids, scores, jacobian, variance, weights,
                                 separation, grams,
                                 *_misfit(whitened.A, whitened.b, phi, whitened.noise),
                                 projection=True)
    return _Solution(phi, basis, ids, scores, jacobian, variance, weights, separation,
                     grams, *_misfit(basis.A, basis.b, phi, grams.sum(axis=0)),
                     projection=instruments is None)


def _misfit(A, b, phi, noise):
    """The squared misfit ``|b - A phi|^2`` of solved window equations and
    ``theta_bar^T Q theta_bar``, what white output noise of unit variance makes of it in
    expectation at ``theta_bar = (phi, -1)`` (``Q``: the sum of the windows' noise
    covariances of ``[A | b]``)."""
    r = b - A @ phi
    theta_bar = np.append(phi, -1.0)
    return float(r @ r), float(theta_bar @ noise @ theta_bar)


def _covariance_noise(problem, solution, variance, bread, meat):
    """The output noise variance of the covariance's noise model, and the factor the
    residuals' HAC sum is inflated by.

    Where the samples' differences show the output noise (their orders agree:
    :meth:`WindowProblem.output_noise_variance`), its variance is theirs, the noise
    bound: the correction's variance, the equations' misfit capped by that bound, was
    4 % low on average on white noise (the cap cuts the upper half of its spread, and
    the fit absorbs a share of the misfit).  Elsewhere (a noise-free record, a signal
    with few samples per period) the misfit's, unbiased for the share the fit absorbs:
    to first order the residuals are ``r = (I - A J^-1 W^T) e``, so ``E[r^T r] =
    sigma^2 (tr S - tr(J^-1 W^T S W))``, ``tr S`` the solution's ``trace`` and ``W^T S
    W`` the noise ``meat`` per unit variance; capped by the bound as before.  The HAC
    sum of the residuals takes the same factor.  Instruments (their residuals are not a
    projection) keep ``variance`` and the HAC sum.
    """
    bound = problem.noise_bound()
    if not solution.projection or not solution.trace > 0:
        return variance, 1.0
    fitted = float(np.trace(bread @ meat)) / solution.trace
    inflation = 1.0 / (1.0 - fitted) if 0.0 <= fitted < 1.0 else 1.0
    if problem.output_noise_variance() > 0 and 0 < bound < np.inf:
        return bound, inflation
    return min(solution.misfit / solution.trace * inflation, max(variance, bound)), \
        inflation


def _solve(problem, length, multiplicities, instruments=None, method="ls"):
    """Estimates of every multiplicity on windows of ``length`` samples; the result is
    that of the highest multiplicity (the most accurate quadrature), the others serve
    as its error check."""
    top = max(multiplicities)
    separate = {}
    for a in multiplicities:
        current = _solve_multiplicity(problem, length, a, top,
                                      None if instruments is None else instruments[a][0],
                                      method)
        separate[a] = current.basis.theta(current.phi)
        if a == top:
            solution = current
    del current
    phi, basis, ids = solution.phi, solution.basis, solution.ids
    variance = solution.variance
    r = basis.b - basis.A @ phi
    bread = np.linalg.pinv(solution.jacobian)
    theta_s = basis.theta(phi)
    theta_bar = np.append(theta_s, -1.0)   # in the units of the rows (noise_meat)
    stride = window_stride(length)
    noise = None
    if variance is None:  # least squares: misfit per unit noise variance
        variance = solution.misfit / solution.trace if solution.trace > 0 else np.inf
        if not variance <= problem.noise_bound():
            variance = problem.noise_bound()
    # the per-window noise matrices: their memory for noise_meat's
    solution = solution._replace(grams=None)
    hac = hac_meat(solution.scores, ids, int(np.ceil(length / stride)))
    if variance is not None and np.isfinite(variance) and variance > 0:
        beta = np.ldexp(1.0, -basis.b_shift)
        meat = beta ** 2 * problem.noise_meat(length, top, theta_bar, solution.weights,
                                              stride)
        variance, inflation = _covariance_noise(problem, solution, variance, bread, meat)
        noise, hac = variance * meat, inflation * hac
    covariance, middle = sandwich(
        bread, hac, noise, AGREEMENT, floor=ROUNDOFF * length * np.linalg.norm(basis.b),
        middle=True)
    columns, known, _ = problem.exponents()
    shift = known - columns
    with np.errstate(over="ignore", under="ignore"):
        theta = np.ldexp(theta_s, shift)
        covariance = np.ldexp(basis.covariance(covariance), shift[:, None] + shift[None, :])
    lost = ~np.isfinite(theta) | ((theta == 0) & (theta_s != 0)) \
        | ~(np.diag(covariance) > 0) | ~np.isfinite(np.diag(covariance))
    if np.any(lost):
        name = problem.parameters[int(np.flatnonzero(lost)[0])]
        raise InputDataError(f"the estimate of {name} or its variance is outside the "
                             f"floating-point range in the units of these records (a "
                             f"factor 2**{int(shift[np.flatnonzero(lost)[0]])} from the "
                             f"signals'); express the time or the signals in other units")
    A = basis.A @ basis.R[:-1, :-1]
    scale = np.ldexp(np.sqrt(np.mean(A ** 2, axis=0)) / max(float(np.sqrt(np.mean(
        basis.b ** 2))), 1e-300), basis.shifts - basis.b_shift - shift)
    return WindowFit(theta, covariance,
                {a: np.ldexp(v, shift) for a, v in separate.items()},
                scale, r, len(ids), solution.separation, noise_model=middle == "noise")


def _simulated_values(problem, theta, model):
    """Noise-free output of the current estimate on every segment (instruments)."""
    from algid.simulation._model import fit_initial_state, simulate_model

    parameters = dict(zip(model.parameters, theta))
    # fixed-step RK4 on cubic splines: instruments need only be noise-free and correlated
    options = {"method": "RK4", "substeps": 4, "interpolation": "cubic"}
    for seg in problem.user_segments:
        inputs = {name: seg.values[name] for name in model.inputs}
        x0 = fit_initial_state(model, parameters, seg.t, inputs, seg.values[model.output],
                               min(50, len(seg)), **options)
        y = simulate_model(model, parameters, seg.t, inputs, initial_state=x0, **options)
        if not np.all(np.isfinite(y)):
            return False
        values = dict(seg.values)
        values[model.output] = y
        for name, k in model.needs_derivatives:
            if name == model.output:
                values[(name, k)] = estimate_derivative(y, seg.t, k, seg.step)
        seg.simulated = values
    problem.cache.forget_simulated()
    return True


def _idle_records(data, segments, length, step):
    """Warnings for the records of several that hold no window (a record in other time
    units than the rest, say, whose estimates it then does not inform)."""
    if hasattr(data, "keys"):  # one record (as _records reads the data)
        return []
    window = (length - 1) * step
    used = {seg.record for seg in segments if seg.t[-1] - seg.t[0] >= window * (1 - 1e-9)}
    return [f"record {i} has no run as long as the window ({window:.4g} s): it does not "
            f"inform the estimates (its time in other units?)"
            for i in range(len(data)) if i not in used]


#: The most rows a chunk may be given.
MAX_CHUNK = 2**40


def check_chunk(chunk):
    """Refuse a ``chunk=`` that is not a number of rows (None passes)."""
    if chunk is not None and (isinstance(chunk, bool) or not isinstance(
            chunk, (int, np.integer)) or not 1 <= chunk <= MAX_CHUNK):
        raise InputDataError(f"chunk must be a number of rows from 1 to 2**40, got "
                             f"{chunk!r}")


def _streamed_source(data, model, *, method, refine, chunk):
    """The chunked source of ``data`` when it is read in chunks, else None.

    Files, Dask DataFrames and ``chunk=`` ask for it (refused where it cannot be);
    otherwise a single record longer than :data:`STREAM_SAMPLES` is read in chunks where
    nothing needs it whole (the model, ``method="iv"``, ``refine=True``)."""
    check_chunk(chunk)
    if not (is_streamed_input(data) or chunk is not None):
        if refine is True or METHODS[method].instrumental or METHODS[method].weighted \
                or stream_refusal(model) \
                or isinstance(data, (list, tuple)):
            return None
        try:   # (counted before any conversion of the record)
            rows = len(data) if hasattr(data, "columns") else len(data[model.output])
        except (KeyError, TypeError, IndexError, ValueError):
            return None   # (not a record with that column: refused in memory)
        return record_source(data) if rows > STREAM_SAMPLES else None
    if isinstance(data, (list, tuple)):
        raise InputDataError("chunk: a record is read in chunks one at a time; identify a "
                             "list of records in memory (without chunk=), or each alone")
    why = stream_refusal(model)
    if why is not None:
        raise ModelError(f"{why}: a record read in chunks takes models without sign() "
                         f"or derivatives inside nonlinear factors (load the record and "
                         f"pass it in memory)")
    if METHODS[method].instrumental:
        raise ModelError(f"method={method!r} simulates the whole record: a record read in "
                         f"chunks takes method 'bc' or 'ls'")
    if METHODS[method].weighted:
        raise ModelError(f"method={method!r} weighs the windows of the whole record "
                         f"together: a record read in chunks takes method 'bc' or 'ls'")
    if refine is True:
        raise ModelError(f"refine: {STREAMED_UNREFINED}")
    return record_source(data)


def _identify_streamed(source, model, *, time, rate, window, method, multiplicities, refine,
                       chunk):
    """:func:`identify` on a record read in chunks (the module notes of
    :mod:`algid.identification._streamed_problem`)."""
    chunk = CHUNK_SAMPLES if chunk is None else int(chunk)
    shortest = min_length(multiplicities)
    scan = scan_record(source, model, time=time, rate=rate, chunk=chunk, min_length=shortest)
    problem = StreamedProblem(model, source, scan, time=time, rate=rate, chunk=chunk)
    length = window_length(window, scan.step, problem, multiplicities)
    scores, separations = None, {}
    if length is None:
        length, scores = _excerpt_window(problem, multiplicities, method, separations)
    # a pass per window length (the fit's, then the adequacy test's twice and half as
    # long), the rows of one length in memory at a time: the half windows' the most
    windows = sum(problem.windows(max(shortest, (length + 1) // 2))) * len(multiplicities)
    check_fits(windows, ROW_BYTES * (len(model.parameters) + 1),
               what=f"identify on windows of {(length - 1) * scan.step:.4g} s (a longer "
                    f"window= needs fewer)", unit="windows")
    problem.multiplicities = multiplicities
    fit = _solve(problem, length, multiplicities, method=method)
    def missing(equation, parameters):   # another equation, on the same passes' terms
        other = parse_equation(equation, parameters, output=model.output)
        other_scan = scan_record(source, other, time=time, rate=rate, chunk=chunk,
                                 min_length=shortest)
        refit = StreamedProblem(other, source, other_scan, time=time, rate=rate, chunk=chunk)
        refit.multiplicities = multiplicities
        return _misfit_of(refit, length, multiplicities)

    return _result(problem, fit, length, method=method, multiplicities=multiplicities,
                   scores=scores, separations=separations, n_samples=scan.n_samples,
                   time=time, rate=rate, refine=refine, unrefined=STREAMED_UNREFINED,
                   missing=missing,
                   grid=lambda found: _excerpt_window(problem, multiplicities, method,
                                                      found)[1])


def _excerpt_window(problem, multiplicities, method, separations):
    """The window rule on :data:`EXCERPTS` excerpts of a record read in chunks, the
    standard errors scaled to the record's samples (their ``share`` of it; the whole
    record when it has at most :data:`EXCERPT_SAMPLES`)."""
    excerpt = problem.excerpts(EXCERPT_SAMPLES, EXCERPTS, min_length(multiplicities))
    return choose_window(excerpt, multiplicities, _solve, method=method,
                         separations=separations)


def _local_crossings(problem, fit, solve):
    """The fit with the steps of ``sign(q')`` at crossings placed by local fits of the
    position (:mod:`algid.identification._sign_crossings`), :data:`CROSSING_PASSES`
    times with the previous estimate (same window: re-chosen, it varied with the noise
    and so did its quadrature bias)."""
    model = problem.model
    problem.velocity_crossings = False
    for _ in range(CROSSING_PASSES):
        problem.first_values = dict(zip(model.parameters, fit.theta))
        problem.sign_jumps = crossing_jumps(model, problem.first_values)
        if not problem.sign_jumps:
            break
        problem.cache.forget_factors(problem.sign_jumps)
        fit = solve()
    return fit


def _place_crossings(problem, fit, length, solve, final=True, restart=None,
                     crossings="auto"):
    """The fit with the steps of a ``sign(q')`` placed by the model: by local fits of
    the position where they leave a misfit of the window equations within what output
    noise allows (and an estimate with a dissipative velocity), else by the model's own
    velocity at the fixed point (:func:`settle_crossings`) unless its misfit exceeds
    both the local fits' and that limit.  A noisy position scatters the local fits (and
    its derivative's signs), which the velocity does not read; a model that misses some
    of the records' dynamics moves its velocity's crossings, which the local fits do
    not; the misfit sees either.  On a precise position the local fits are exact where
    the velocity, driven by a force linear between samples, places a step of a closed
    loop's kinked force a few microseconds off.  The problem is left with the placement
    of the fit returned (``final``: as :func:`settle_crossings`; ``restart()``: where
    the fixed point does not settle from ``fit``, one settled roughly elsewhere, its
    steps in place, or None; ``crossings``: ``"local"`` or ``"velocity"`` keeps that placement, the
    second where it settles).  Returns the fit and, for the velocity's placement, the
    Jacobian of its fixed point (else None)."""
    if not crossing_jumps(problem.model, dict(zip(problem.parameters, fit.theta))):
        return fit, None
    top = max(fit.separate)
    if crossings == "local":
        return _local_crossings(problem, fit, solve), None
    if crossings == "auto":
        local = _local_crossings(problem, fit, solve)
        local_values = problem.first_values
        local_misfit = misfit_ratio(problem, length, top, problem.to_rows(local.theta))
        limit = misfit_limit(local.n_windows, length, len(local.theta),
                             window_stride(length))
        if local_misfit <= limit and has_velocity(problem, local.theta):
            return local, None   # (a precise position: its crossings are exact)
        # (where both are within what noise allows, as on short windows, the velocity's,
        # which the noise does not scatter)
        allowed = max(local_misfit, limit)
    settled = settle_crossings(problem, fit, solve, final=final)
    if settled is None and restart is not None:
        settled = restart()   # (the window is chosen again: a start is enough)
    if settled is not None and (crossings == "velocity" or misfit_ratio(
            problem, length, top, problem.to_rows(settled.fit.theta)) <= allowed):
        return settled.fit, settled.contraction
    if crossings == "velocity":
        return _local_crossings(problem, fit, solve), None
    problem.velocity_crossings = False
    problem.first_values = local_values
    problem.sign_jumps = crossing_jumps(problem.model, local_values)
    problem.cache.forget_factors(problem.sign_jumps)
    return local, None


def _longest_window_start(problem, multiplicities, method):
    """A first estimate for the fixed point of :func:`settle_crossings` from the
    longest window the rule allows: on a noisy position the rule's first window, chosen
    with the signs of a noisy derivative, can be so short that its estimate has no
    velocity at all (a mass near zero, a negative damping).  The fixed point settled
    roughly there (:class:`SettledFit`, its steps in place), or None."""
    longest = max(grid_lengths(problem, multiplicities), default=None)
    if longest is None:
        return None
    problem.velocity_crossings, problem.sign_jumps = False, {}
    problem.cache.forget_factors({term.factor for term in problem.model.terms})
    try:
        first = _solve(problem, longest, multiplicities, method=method)
    except (InputDataError, ModelError, np.linalg.LinAlgError):
        return None
    return settle_crossings(problem, first, lambda: _solve(
        problem, longest, multiplicities, method=method), final=False)


def _window_again(problem, multiplicities, method, length, scores, separations, fit,
                  chord=None):
    """The automatic window chosen again on ``problem`` with its steps held, and the
    fit settled there (:func:`settle_crossings`); where it does not settle, on the
    window given (its scores and checks); where neither does, the local fits' placement
    on the window given.  ``chord``: the Jacobian of the first window's fixed point."""
    checks = {}
    again, again_scores = choose_window(problem, multiplicities, _solve, method=method,
                                        separations=checks)
    tries = [(again, again_scores, checks)] + ([] if again == length else
                                               [(length, scores, separations)])
    for size, size_scores, size_checks in tries:
        settled = settle_crossings(problem, fit, lambda size=size: _solve(
            problem, size, multiplicities, method=method), chord=chord)
        if settled is not None:
            return size, size_scores, size_checks, settled.fit
    return length, scores, separations, _local_crossings(
        problem, fit, lambda: _solve(problem, length, multiplicities, method=method))


def _least_squares_misfit(segments, step, equation, parameters, output, length, multiplicities):
    """Misfit of another equation on the same signals, fitted by least squares."""
    problem = WindowProblem(parse_equation(equation, parameters, output=output), segments, step)
    return _misfit_of(problem, length, multiplicities)


def _misfit_of(problem, length, multiplicities):
    """The misfit of a problem's equation fitted by least squares on ``length``."""
    fit = _solve(problem, length, multiplicities, method="ls")
    return misfit_ratio(problem, length, max(fit.separate), problem.to_rows(fit.theta))


def identify(data, equation, parameters=None, *, time=None, rate=None, output=None,
             window=None, method="bc", multiplicities=MULTIPLICITIES, name="custom",
             iterations=3, refine="auto", hidden=None, chunk=None, crossings="auto"):
    """Identify the parameters of a model equation on measured records.

    Parameters
    ----------
    data : record, list of records, path or Dask DataFrame
        A record: a mapping of column name -> samples, a pandas ``DataFrame`` (time as
        a column or as its index), an xarray ``Dataset`` or a python-control
        ``TimeResponseData``; a list of records is identified together.  Rows may be
        missing from a record with a time column (gaps), and NaN (or masked) samples
        are dropped (an infinite one is refused).  A path to a Parquet or CSV file, or
        a Dask ``DataFrame``, is one record read in chunks, never whole (as is a
        record of more than :data:`STREAM_SAMPLES` samples): see the user guide,
        "Fleets and long records".
    equation : str, Model, module or list of str
        The model, e.g. ``"M*q'' + Fv*q' + Fc*sign(q') + off = F"``, or a compiled
        model (:func:`algid.compile_equation`): the same model argument as
        :func:`algid.estimate` and :class:`algid.OnlineEstimator`.  A list of
        equations (or a :class:`algid.models.SystemModel`) is a system sharing
        ``parameters``, one measured output per equation: see the user guide,
        "Systems of equations"; the result is then a
        :class:`~algid.identification.SystemResult` (``method`` "bc" or "ls").
    parameters : sequence of str or str
        The unknown parameters (not needed when ``equation`` is a Model).
    time : str, optional
        Name of the time column; by default a column ``t`` or ``time``.
    rate : float, optional
        Sampling rate (Hz) of records without a time column (with one, it must agree
        with it: :data:`algid._record_input.RATE_TOLERANCE`).
    output : str, optional
        Output signal; by default the signal of highest derivative order.
    window : float, optional
        Window length (s); chosen from the data when omitted (see the user guide,
        "How identify works").
    method : {"bc", "ls", "iv", "gls"}
        Bias-compensated least squares (the default: it removes the bias that white
        output noise causes and needs no simulation, so it also works in closed loop
        and on integrating plants), plain least squares, instrumental variables from
        the output simulated by the current estimate (open-loop stable plants only;
        slower: it simulates the model at every iteration), or bias-compensated
        generalised least squares: the windows weighed by the inverse covariance of
        the noise in their equations (near the Cramér–Rao bound where the misfit is
        white output noise; 1 to 4 times the cost of "bc" at a given window, the record
        in memory, no ``sign()`` or derivative inside a nonlinear factor).  Where its
        estimate and that of "bc" differ by more than output noise allows, the result
        is that of "bc", with a warning.  See the user guide, "How identify works".
    multiplicities : tuple of int
        Kernel multiplicities stacked (each at least the model order).
    name : str
        Label of the model.
    iterations : int
        Instrumental-variable iterations.
    refine : {"auto", True, False}
        Refine the algebraic estimate by output error
        (:meth:`IdentificationResult.refine`: the efficient estimate under white
        output noise, with standard errors at the Cramér–Rao bound).  ``"auto"``
        (default): where it is safe (a linear model whose algebraic and refined models
        are stable, a nonlinear one whose fit is not much less precise than the
        algebraic estimate, and the simulation error drops); True: always (refused for
        a model it cannot simulate); False: the algebraic estimate.
    hidden : sequence of str, optional
        For a system of equations: outputs of its equations that are not measured
        (eliminated from a linear system; see the user guide, "Systems of equations").
    chunk : int, optional
        Read the record in chunks of this many rows (by default a file, a Dask
        ``DataFrame`` or a record of more than :data:`STREAM_SAMPLES` samples is read in
        chunks of :data:`CHUNK_SAMPLES`).  A record read in chunks takes models whose
        factors hold no ``sign`` and no derivative, ``method`` "bc" or "ls", uniformly
        sampled runs,
        and is not refined; it is never held whole in memory.  Its automatic window is
        chosen on excerpts of the record (:data:`EXCERPT_SAMPLES` samples in all).
    crossings : {"auto", "velocity", "local"}
        How the steps of a ``sign(q')`` (friction) are placed: by the model's own
        velocity, driven by the measured signals (unbiased on a noisy position, where
        the model holds), or by local fits of the position (exact on a precise one,
        and unmoved by dynamics the model leaves out); ``"auto"`` (default): the local
        fits where their window equations leave a misfit within what output noise
        allows, else the velocity unless its misfit is larger still (the user guide,
        "How identify works").  Ignored by models without ``sign(q')``.

    Returns
    -------
    IdentificationResult or SystemResult
        With ``warnings`` when the model does not explain the data within the noise
        (:mod:`algid.identification._adequacy`); ``estimate`` says whether ``values``
        are the refined or the algebraic estimate, ``algebraic`` keeps the latter.

    Raises
    ------
    ModelError, InputDataError
        One-line messages for a bad equation, an argument of the wrong type, unusable
        data, or records too large for the memory available.

    Examples
    --------
    >>> from algid.identification import identify
    >>> from algid.simulation import simulate
    >>> sim = simulate("sine", frequency=3.0, duration=10.0, rate=100.0, noise_std=1e-4, seed=0)
    >>> record = {"t": sim.t, "f": sim.f, "x": sim.x}
    >>> result = identify(record, "x'' + B*x' + K*x = f", "B K")
    >>> round(result.B, 3), round(result.K, 2), result.warnings
    (2.0, 3.0, [])
    """
    from algid.identification._output_error import check_refine

    if isinstance(equation, types.ModuleType):  # a compiled model: its own equation(s)
        equation = model_of(estimator_module(equation, parameters))
    if is_system(equation):   # several equations sharing parameters
        from algid.identification._system_identify import identify_system

        check_chunk(chunk)
        if chunk is not None or is_streamed_input(data):
            raise InputDataError("a system of equations is identified on records in "
                                 "memory: a file, a Dask DataFrame or chunk= is for one "
                                 "equation (load the record)")
        if output is not None:
            raise ModelError("output: a system of equations takes outputs=[...] through "
                             "algid.models.parse_system, one per equation")
        return identify_system(data, equation, parameters, time=time, rate=rate,
                               window=window, method=method, multiplicities=multiplicities,
                               name=name, refine=refine, hidden=hidden)
    if hidden is not None:
        raise ModelError("hidden: a single equation's signals are all measured; hidden "
                         "signals belong to a system of equations (a list)")
    refine = check_refine(refine)
    if not (isinstance(crossings, str) and crossings in CROSSINGS):
        raise ModelError(f"crossings must be one of {', '.join(map(repr, CROSSINGS))}, "
                         f"not {crossings!r}")
    multiplicities = check_arguments(
        equation, parameters, time=time, rate=rate, output=output, window=window,
        method=method, methods=METHODS, multiplicities=multiplicities, name=name,
        iterations=iterations)
    model = equation if isinstance(equation, Model) else parse_equation(
        equation, parameters, output=output, name=name)
    check_model_columns(model, time)
    multiplicities = check_multiplicities(model, multiplicities)
    if METHODS[method].weighted and stream_refusal(model) is not None:
        # (the models a record read in chunks refuses: sign() and derivatives inside
        # nonlinear factors, whose errors are their placement's and differentiator's)
        raise ModelError(f"method={method!r} weighs the windows by their output noise, "
                         f"and this model's equations carry other errors (a sign() or a "
                         f"derivative inside a nonlinear factor): use method='bc'")
    source = _streamed_source(data, model, method=method, refine=refine, chunk=chunk)
    if source is not None:   # read in chunks: a file, a Dask DataFrame or a long record
        return _identify_streamed(source, model, time=time, rate=rate, window=window,
                                  method=method, multiplicities=multiplicities,
                                  refine=refine, chunk=chunk)
    check_memory(data, model)
    shortest = min_length(multiplicities)
    if model.needs_derivatives:   # (segments too short for the differentiator: dropped)
        shortest = max(shortest, DERIVATIVE_SAMPLES)
    segments, step, n_samples = prepare_records(data, model.signals, time=time, rate=rate,
                                                min_length=shortest)
    add_derivatives(model, segments, derivative_estimate)
    check_factors(model, segments)
    problem = WindowProblem(model, segments, step)
    length = window_length(window, step, problem, multiplicities)
    scores, separations = None, {}
    if length is None:
        length, scores = choose_window(problem, multiplicities, _solve, method=method,
                                       separations=separations)
    fit, chord = _place_crossings(
        problem, _solve(problem, length, multiplicities, method=method), length,
        lambda: _solve(problem, length, multiplicities, method=method), final=scores is None,
        restart=None if scores is None else lambda: _longest_window_start(
            problem, multiplicities, method), crossings=crossings)
    notes = []
    if crossings == "velocity" and not problem.velocity_crossings \
            and problem.sign_jumps:
        notes = ["crossings='velocity': the model's velocity did not settle on these "
                 "records (no estimate on the way had a stable, dissipative one): the "
                 "steps of sign() are placed by local fits of the position"]
    if scores is not None and problem.velocity_crossings:
        # the window chosen again with the steps the model places (the first rule saw
        # the signs of a noisy derivative), and the fixed point settled on it
        length, scores, separations, fit = _window_again(
            problem, multiplicities, method, length, scores, separations, fit, chord)
    if METHODS[method].weighted:
        rejected = _weighting_rejected(problem, fit, length, multiplicities, method)
        if rejected:   # what method="bc" gives, said so
            plain = identify(data, equation, parameters, time=time, rate=rate,
                             output=output, window=window, method="bc",
                             multiplicities=multiplicities, name=name,
                             iterations=iterations, refine=refine, chunk=chunk,
                             crossings=crossings)
            plain.warnings.append(rejected)
            return plain
    fit.differentiator_error = _differentiator_error(problem, fit, length, multiplicities,
                                                     method)
    if METHODS[method].instrumental:
        for _ in range(iterations):
            if not _simulated_values(problem, fit.theta, model):
                raise InputDataError("instrumental variables: the simulated output of the "
                                     "first estimate diverges; use method='bc'")
            instruments = {a: problem.rows(length, a, "simulated") for a in multiplicities}
            fit = _solve(problem, length, multiplicities, instruments)
    return _result(problem, fit, length, method=method, multiplicities=multiplicities,
                   scores=scores, separations=separations, n_samples=n_samples, time=time,
                   rate=rate, refine=refine, missing=lambda eq, names: _least_squares_misfit(
                       segments, step, eq, names, model.output, length, multiplicities),
                   idle=_idle_records(data, segments, length, step) + notes,
                   segments=segments)


def _differentiator_error(problem, fit, length, multiplicities, method):
    """Per parameter, how far the estimate moves when the derivatives inside nonlinear
    factors are estimated on a differentiator window twice as long (zero where the
    model has none, or has a ``sign()``, whose steps the crossings place).

    The differentiator attenuates what it differentiates (as the square of its window,
    centred), and both kernel multiplicities read the same estimate, so their difference
    does not see it: on a noise-free record of ``y'' + B*abs(y')*y' + K*y = G*u`` the
    damping was 7 standard errors off with a numerical error of a tenth of one.
    The difference is that of the longer window's error, about three times the default
    one's: a bound, as the multiplicities' difference is.
    """
    model = problem.model
    if any(is_sign_factor(term.factor) for term in model.terms) \
            or not model.needs_derivatives:
        return 0.0
    segments = []
    for seg in problem.user_segments:
        values = dict(seg.values)
        for name, k in model.needs_derivatives:
            try:
                values[(name, k)] = derivative_estimate(seg.values[name], seg.t, k,
                                                        seg.step, widen=2)
            except InputDataError:   # (a segment shorter than the wider window: as is)
                pass
        segments.append(Segment(seg.record, seg.rows, seg.t, values, seg.step))
    wider = WindowProblem(model, segments, problem.step)
    wider.cache.noise_bound = problem.noise_bound()
    wider.cache.noise_variance = problem.cache.noise_variance   # (the same samples')
    wider.derivative_widen = 2
    if METHODS[method].instrumental:   # (both by the first, bias-compensated, solve)
        fit = _solve(problem, length, multiplicities, method="bc")
        method = "bc"
    try:
        other = _solve(wider, length, multiplicities, method=method)
    except (InputDataError, ModelError, np.linalg.LinAlgError):
        return 0.0
    return np.abs(other.theta - fit.theta)


def _weighting_rejected(problem, fit, length, multiplicities, method):
    """Why the weighted fit is not kept, or "" where it is: where it differs from the
    unweighted ("bc") one at its window by more than output noise allows (a Hausman
    test), the misfit is not only noise, the windows cannot be weighed by it, and the
    weighting moves the estimate instead.

    Under output noise both are consistent and the weighted one efficient, so their
    difference has the variance ``Var(bc) - Var(gls)`` (floored at
    :data:`WEIGHTING_FLOOR` of ``Var(bc)``; its standard deviation plus both numerical
    errors); a parameter more than :data:`WEIGHTING_Z` of these off rejects the
    weighting.

    Returns
    -------
    str
        The warning to give with the estimate of method "bc" (its own window), or "".
    """
    plain = _solve(problem, length, multiplicities, method="bc")
    variance = np.diag(plain.covariance)
    # and the quadrature's share: each estimate's numerical error (the difference of
    # its multiplicities), which a noise-free record's tiny misfit would not cover
    numerical = sum(np.ptp(list(f.separate.values()), axis=0) for f in (fit, plain))
    spread = np.sqrt(np.maximum(variance - np.diag(fit.covariance),
                                WEIGHTING_FLOOR * variance)) + numerical
    z = np.abs(fit.theta - plain.theta) / spread
    worst = int(np.argmax(z))
    if not z[worst] > WEIGHTING_Z:
        return ""
    return (f"method={method!r}: the weighted estimate of {problem.parameters[worst]} is "
            f"{z[worst]:.1f} standard deviations from the unweighted one, more than "
            f"output noise explains (a misfit that is not white output noise: a wrong "
            f"model, coloured noise?), so the windows are not weighed by it: this is "
            f"the estimate of method='bc'")


def _result(problem, fit, length, *, method, multiplicities, scores, separations, n_samples,
            time, rate, refine, missing=None, idle=(), segments=(), unrefined=None,
            grid=None):
    """The result of a fit on ``length``-sample windows: its adequacy, what the records
    separate (refused, or warned with advice on the window), then the refinement.

    ``missing`` refits another equation (the adequacy test's missing terms; None: not
    looked for); ``separations`` holds the window rule's checks of its grid, or is
    empty (then, for advice, ``grid(separations)`` fills it and returns the grid's
    scores; by default the rule on ``problem``); ``unrefined`` says why the records
    cannot be refined (None: they can)."""
    from algid.identification._output_error import refine_result, simulates_stably
    from algid.identification._result import IdentificationResult

    model = problem.model
    adequacy = model_adequacy(problem, length, fit, _solve, method, min_length(multiplicities),
                              window_stride(length))
    # where the misfit is output noise, a combination no better determined than the
    # noise or the misfit is free; where it is more, the model's error may be the cause
    noise_like = adequacy.misfit <= adequacy.misfit_limit
    if not noise_like and missing is not None:   # would a term the model lacks explain it?
        adequacy = missing_terms(adequacy, model, missing)

    grid_scores = scores

    def advice():
        # which windows would separate the parameters, or how much less noise: for an
        # explicit window the grid of the automatic rule is solved now (only when refused
        # or warned, so a clean fixed-window call costs no more than before)
        nonlocal grid_scores
        if not separations:
            try:
                grid_scores = grid(separations) if grid else choose_window(
                    problem, multiplicities, _solve, method=method,
                    separations=separations)[1]
            except (InputDataError, ModelError, np.linalg.LinAlgError):
                return ""
        return window_advice(separations, problem.step, grid_scores)

    if noise_like and (fit.separation.free or fit.separation.misfit_free):
        raise ModelError(f"{fit.separation.message(model.parameters)}; {advice()}".rstrip("; "))
    weak = fit.separation.poorly_separated(adequacy.adequate)
    separation = fit.separation.warnings(model.parameters, adequacy.adequate,
                                         advice() if weak else "")
    idle = list(idle)
    unstable = []
    if METHODS[method].instrumental and model.is_linear and not simulates_stably(
            model, dict(zip(model.parameters, fit.theta.tolist()))):
        # its instruments came from simulations of a stable start; the end is not
        unstable = ["the instrumental-variable estimate's model is not stable: its "
                    "simulation on these records diverges, and so would its instruments "
                    "(use method='bc')"]
    result = IdentificationResult(
        model=model, values=dict(zip(model.parameters, fit.theta.tolist())),
        covariance=fit.covariance, window=(length - 1) * problem.step, n_samples=n_samples,
        n_windows=fit.n_windows, method=method, multiplicities=multiplicities,
        time=time, rate=rate, window_scores=scores,
        separate={a: dict(zip(model.parameters, v.tolist())) for a, v in fit.separate.items()},
        numerical_error=dict(zip(model.parameters, fit.numerical_error.tolist())),
        adequacy=adequacy,
        warnings=adequacy.warnings() + separation + idle + unstable)
    # (what the records can determine holds for a refined estimate too; whether the
    # model explains them is asked of its simulation residuals instead)
    return refine_result(result, segments, problem.step, refine, separation + idle + unstable,
                         unavailable=unrefined)
