"""Identify a system of equations that share parameters, on whole measured records.

Every equation gives its window equations as in :func:`algid.identify`
(:class:`algid.identification._window_problem.WindowProblem`: the same windows slide over the same
segments for every equation), each in its own units.  Mapped onto the parameters of the
system, they are stacked, each equation weighted by the inverse rms of its residuals
(a first solve with each equation's rows of unit norm gives them), and solved for one
parameter set:

- *bias compensation* (``method="bc"``): every measured output is noisy, with its own
  variance.  Noise on output ``y_j`` puts into the rows of equation ``i`` a known
  covariance per window ``G_ij`` (through every term that reads ``y_j``: the window
  kernels and the terms' sensitivities), so the expected normal matrix exceeds the
  noise-free one by ``sum_i w_i^2 sum_j sigma_j^2 G_ij``.  The ``sigma_j^2`` are taken
  in the proportions of their bounds from the samples' differences (``rho_j``,
  :meth:`WindowProblem.noise_bound`) and scaled by one common factor, the smallest
  eigenvalue of the pencil (Koopmans' estimator, capped at 1: the bounds);
- *covariance*: a sandwich over the window index, the estimating equations of all the
  equations summed per window, so that the correlation between equations that share a
  noisy signal (the noise of ``x2`` enters both equations of two coupled masses) is in
  the HAC middle;
- *window*: on the grid of the single-equation rule, the window whose worst parameter's
  error (standard error or the difference of the two multiplicities) is least relative
  to its best on the grid;
- *what the records cannot determine*: the stacked regressors with unit columns are
  rank-deficient (a homogeneous equation whose scale no other equation fixes, two
  parameters whose terms are proportional in every equation): refused, naming the
  parameters of the null direction;
- *adequacy per equation*: each equation's residual energy over what its outputs'
  noise puts there, and the shift of the estimates between windows half and twice as
  long; an equation whose misfit exceeds the limit of
  :func:`algid.identification._adequacy.misfit_limit` while the estimates shift by more
  than :data:`algid.identification._adequacy.SHIFT_LIMIT` standard errors is named in a
  warning.
"""

from __future__ import annotations

import numpy as np

from algid.errors import InputDataError, ModelError
from algid.identification._adequacy import SHIFT_LIMIT, misfit_limit
from algid.identification._arguments import check_arguments, check_memory
from algid.identification._bias_compensation import koopmans
from algid.identification._homogeneous import divisions, row_map, to_physical
from algid.identification._methods import METHODS
from algid.identification._records import check_factors, prepare_records
from algid.identification._system_result import WEAK_RELATIVE_ERROR
from algid.identification._window_basis import NAMED_WEIGHT, ROUNDOFF_SEPARABILITY
from algid.identification._window_covariance import hac_meat, sandwich
from algid.identification._window_problem import (
    DERIVATIVE_SAMPLES,
    MULTIPLICITIES,
    WindowProblem,
    add_derivatives,
    derivative_estimate,
    difference_noise_bound,
    window_stride,
)
from algid.identification._window_rule import (
    HAC_WINDOWS,
    WindowFit,
    check_multiplicities,
    coarse_to_fine,
    independent_windows,
    longest_window,
    min_length,
    needed_windows,
    window_criterion,
    window_grid,
    window_length,
)
from algid.models._system import SystemModel, parse_system

__all__ = ["identify_system", "solve_normal", "equation_weight", "column_units",
           "SYSTEM_METHODS", "EXACT_RESIDUAL"]

#: An equation's residual below this fraction of its largest term is exact (round-off
#: and the quadrature's error, not noise): its weight is that of this residual.  Without
#: the floor, a noise-free record gave equations without a known term weights 1e6 to 1e8
#: times the others', whose squares the normal equations could not hold: a chain of
#: three masses fell to the trivial solution of its second and third equations.  (At
#: 40 dB the residual is 3e-3 of the largest term or more; noise-free, the quadrature's
#: error is up to 5e-5 of it and round-off 1e-13.)
EXACT_RESIDUAL = 1e-6

#: Output noise below this fraction of an output's spread is none, for the question of
#: the term an equation lacks (:func:`_noise_free`).
NOISE_FREE = 1e-6

#: Methods offered for systems (instrumental variables need a simulation of every
#: output: not for systems).
SYSTEM_METHODS = ("bc", "ls")

#: Standard errors (of the difference) beyond which, and half the value, a window's
#: estimate counts as a degenerate solve in the window rule.
DEGENERATE_DISTANCE = 10.0



class _Rows:
    """The stacked window equations of every equation at one length and multiplicity, in
    the parameters of the system scaled by powers of two (``phi = theta * 2**g``)."""

    def __init__(self, problems, system, noisy, bounds, length, multiplicity, maps=None):
        P = len(system.parameters)
        maps = maps or {}
        self.blocks, self.grams = [], []
        self.raw_blocks = []    # (before any equation is divided by its pivot)
        self.g, knowns = column_units(problems, system.parameters)
        shifts = [problem.exponents()[0] - known for problem, known in zip(problems, knowns)]
        self.ids = None
        for i, problem in enumerate(problems):
            A, b, ids = problem.rows(length, multiplicity)
            if self.ids is None:
                self.ids = ids
            where = _columns(system, problem)
            scale = np.ldexp(1.0, shifts[i] - self.g[where])
            phi = np.zeros((len(b), P + 1))
            phi[:, where] = A * scale
            phi[:, P] = b
            with np.errstate(over="ignore", invalid="ignore"):
                finite = np.all(np.isfinite(np.sum(phi ** 2, axis=0)))
            if not finite:
                raise InputDataError(f"the window equations of equation {i + 1} overflow "
                                     f"floating point in these units: rescale the signals")
            self.blocks.append(phi)
            full = np.append(scale, 1.0)
            index = [*where, P]
            total = np.zeros((len(b), P + 1, P + 1))
            for signal in noisy:
                if signal not in problem.model.signals:
                    continue
                local = problem.noise_grams(length, multiplicity, signal)
                local = local * full[None, :, None] * full[None, None, :]
                total[np.ix_(np.arange(len(b)), index, index)] += bounds[signal] * local
            self.raw_blocks.append(phi)
            M = maps.get(i)
            if M is not None:   # in the ratios to its pivot (module _homogeneous)
                phi = phi @ M.T
                total = M @ total @ M.T
            self.blocks[-1] = phi
            self.grams.append(total)

    def residuals(self, theta_bar):
        return [phi @ theta_bar for phi in self.blocks]


def column_units(problems, parameters):
    """The powers of two in which the stacked rows are solved.

    Every equation's residual is in the power of two of its known term, and every
    parameter in the largest of the powers that put its column there (``phi = theta *
    2**g``).  An equation without a known term takes the power that puts a parameter it
    shares with an equation that has one at that parameter's power (its own largest
    column would leave its rows 2**-500 apart from the others' on signals of 1e-150).

    Parameters
    ----------
    problems : sequence of WindowProblem
        One per equation with parameters.
    parameters : sequence of str
        The system's parameters.

    Returns
    -------
    g : numpy.ndarray
        Per parameter (int).
    knowns : list of int
        Per equation, the power of two of its residual.
    """
    g = np.full(len(parameters), -np.inf)
    knowns = [0] * len(problems)
    for i in sorted(range(len(problems)), key=lambda i: not problems[i].model.known_terms):
        columns, known, _ = problems[i].exponents()
        where = [parameters.index(p) for p in problems[i].model.parameters]
        if not problems[i].model.known_terms:
            shared = [c - g[p] for c, p in zip(columns, where) if np.isfinite(g[p])]
            known = int(max(shared) if shared else max(columns))
        knowns[i] = known
        for c, p in zip(columns, where):
            g[p] = max(g[p], c - known)
    return g.astype(int), knowns


def _solve_rows(rows, weights, method):
    """Koopmans' (or least-squares) solve of weighted stacked rows: ``phi``, the scores
    per window, the Jacobian, the variance factor and the residuals per equation."""
    P = rows.blocks[0].shape[1] - 1
    normal = sum(w ** 2 * (phi.T @ phi) for w, phi in zip(weights, rows.blocks))
    noise = sum(w ** 2 * g.sum(axis=0) for w, g in zip(weights, rows.grams)) \
        if rows.grams else np.zeros_like(normal)
    theta_bar, variance = solve_normal(normal, noise, method)
    residuals = rows.residuals(theta_bar)
    scores = sum(w ** 2 * (-phi[:, :P] * r[:, None]) for w, phi, r in
                 zip(weights, rows.blocks, residuals))
    if rows.grams and variance:
        scores = scores + variance * sum(w ** 2 * (g @ theta_bar)[:, :P]
                                         for w, g in zip(weights, rows.grams))
    jacobian = normal[:P, :P] - variance * noise[:P, :P]
    return theta_bar, scores, jacobian, variance, residuals


def solve_normal(normal, noise, method):
    """``theta_bar = (theta, -1)`` and the noise variance factor of the correction from
    the sums ``normal = Phi^T Phi`` and ``noise`` of weighted stacked rows: Koopmans'
    estimator (``method="bc"``, the factor at most 1: the noise bounds are in
    ``noise``), or least squares (factor 0) where it makes no correction or for
    ``"ls"``."""
    P = normal.shape[0] - 1
    if method == "bc":
        theta_bar, variance = koopmans(normal, noise, 1.0)
        if theta_bar is not None:
            return theta_bar, variance
    d = np.sqrt(np.diag(normal)[:P])
    d[d == 0] = 1.0
    H = normal[:P, :P] / d[:, None] / d[None, :]
    x = np.linalg.lstsq(H, normal[:P, P] / d, rcond=None)[0] / d
    return np.append(x, -1.0), 0.0


def _weights(rows, method):
    """Per equation, the inverse rms of its residuals at a first solve in which every
    equation's rows have unit norm."""
    first = [1.0 / max(np.linalg.norm(phi), 1e-300) for phi in rows.blocks]
    theta_bar, _, _, _, residuals = _solve_rows(rows, first, method)
    return [equation_weight(r, phi, theta_bar) for r, phi in zip(residuals, rows.blocks)]


def equation_weight(residuals, phi, theta_bar):
    """An equation's weight in the stacked solve: the inverse rms of its residuals at a
    first solve, that rms at least :data:`EXACT_RESIDUAL` of its largest term's.

    Parameters
    ----------
    residuals : numpy.ndarray
        Its residuals at the first solve, one per row.
    phi : numpy.ndarray, shape (rows, p + 1)
        The equation's rows, in the system's columns.
    theta_bar : numpy.ndarray
        The first solve, ``(theta, -1)``.

    Returns
    -------
    float
    """
    rms = float(np.sqrt(np.mean(residuals ** 2)))
    # (each column times its parameter: the terms whose sum the residual is)
    largest = float(np.max(np.sqrt(np.mean((phi * theta_bar) ** 2, axis=0))))
    return 1.0 / max(rms, EXACT_RESIDUAL * largest, 1e-300)


def _columns(system, problem):
    """Positions, in the system's parameters, of one equation's parameters."""
    return [system.parameters.index(p) for p in problem.model.parameters]


class _SystemFit(WindowFit):
    """A :class:`WindowFit` of a system, with its per-equation diagnostics."""

    def __init__(self, *args, misfits=None, null=None, **kwargs):
        super().__init__(*args, **kwargs)
        self.misfits = misfits
        self.null = null


def _solve(problems, system, noisy, bounds, length, multiplicities, method):
    top = max(multiplicities)
    stride = window_stride(length)
    separate, weights, fit = {}, None, None
    P = len(system.parameters)
    divided = divisions([p.model for p in problems], system.parameters)
    maps = {d.equation: row_map(P + 1, d) for d in divided}
    for a in sorted(multiplicities, reverse=True):
        rows = _Rows(problems, system, noisy, bounds, length, a, maps)
        if weights is None:
            weights = _weights(rows, method)
        theta_bar, scores, jacobian, variance, residuals = _solve_rows(rows, weights, method)
        scaled = to_physical(theta_bar[:P], divided)[0]
        theta = np.ldexp(scaled, -rows.g)
        separate[a] = theta
        if a != top:
            continue
        d = np.sqrt(np.abs(np.diag(jacobian)))
        d[d == 0] = 1.0
        bread = np.linalg.pinv(jacobian / d[:, None] / d[None, :]) / d[:, None] / d[None, :]
        meat = hac_meat(scores, rows.ids, int(np.ceil(length / stride)))
        covariance = to_physical(theta_bar[:P], divided, sandwich(bread, meat))[1]
        scale = np.ldexp(1.0, -rows.g)
        covariance = covariance * scale[:, None] * scale[None, :]
        # (a divided equation's weight, on its rows before division: over its pivot)
        raw = list(weights)
        for d in divided:
            raw[d.equation] = weights[d.equation] / max(abs(theta_bar[d.pivot]), 1e-300)
        stacked = np.vstack([w * phi for w, phi in zip(raw, rows.raw_blocks)])
        null = _null_direction(stacked[:, :P])
        misfits = []
        for g, r in zip(rows.grams, residuals):
            weight = float(theta_bar @ g.sum(axis=0) @ theta_bar)
            energy = float(r @ r)
            misfits.append(0.0 if energy == 0 else (energy / weight if weight > 0
                                                    else np.inf))
        b = stacked[:, P]
        rms_b = max(float(np.sqrt(np.mean(b ** 2))), 1e-300)
        effect = np.ldexp(np.sqrt(np.mean(stacked[:, :P] ** 2, axis=0)) / rms_b, rows.g)
        fit = _SystemFit(theta, covariance, None, effect, np.concatenate(residuals),
                         len(rows.ids), misfits=misfits, null=null)
    fit.separate = separate
    return fit


def _null_direction(A):
    """The unit-column regressors' weakest direction, where it is at round-off level."""
    norms = np.linalg.norm(A, axis=0)
    if np.any(norms == 0):
        v = (norms == 0).astype(float)
        return v / np.linalg.norm(v)
    s, vt = np.linalg.svd(A / norms, full_matrices=False)[1:]
    if s[-1] <= ROUNDOFF_SEPARABILITY * s[0]:
        return vt[-1]
    return None


def _refuse_null(system, null):
    weight = np.abs(null)
    named = [p for p, v in zip(system.parameters, weight) if v >= NAMED_WEIGHT * weight.max()]
    if len(named) == 1:
        raise ModelError(f"the records cannot determine {named[0]}: its terms vanish on "
                         f"them")
    raise ModelError(f"the records cannot separate {', '.join(named)}: only a combination "
                     f"of them is determined (fix one, or add an equation or a known term "
                     f"that sets their scale)")


class _Grid:
    """The segments and parameters the window rule's limits need."""

    def __init__(self, segments, parameters):
        self.segments, self.parameters = segments, parameters


def _choose_window(problems, system, noisy, bounds, multiplicities, method):
    n_min = min_length(multiplicities)
    grid_problem = _Grid(problems[0].segments, system.parameters)
    longest = longest_window(grid_problem, n_min) + 1
    grid = [n for n in window_grid(n_min, max(n_min, longest))
            if independent_windows(grid_problem, n) >= needed_windows(grid_problem)]
    if not grid:
        raise InputDataError(f"the records are too short: windows of at least {n_min} "
                             f"samples must leave {needed_windows(grid_problem)} "
                             f"non-overlapping ones")
    fits = {}   # length -> fit (None: not solvable, or a null direction)

    def solve_at(lengths):
        for n in lengths:
            if n in fits:
                continue
            # (each equation's rows summed the window rule's cheaper way)
            views = [problem.for_window_rule(n, every_window=True) for problem in problems]
            try:
                fit = _solve(views, system, noisy, bounds, n, multiplicities, method)
            except (np.linalg.LinAlgError, InputDataError):
                fit = None
            fits[n] = fit if fit is not None and fit.null is None else None

    def scores():
        solved = {n: f for n, f in fits.items() if f is not None}
        if not solved:
            return {}
        # the trivial solution of an equation without a known term (all its parameters
        # zero, with zero scores) attracts the solves on windows so short that the
        # noise dominates: such a fit, far from the longest window's by half a value and
        # many standard errors, is left out (it would also make every other window look
        # poor)
        reference = solved[max(solved)]
        solved = {n: f for n, f in solved.items() if _consistent(f, reference)}
        trusted = {n: f for n, f in solved.items()
                   if independent_windows(grid_problem, n) >= HAC_WINDOWS} or solved
        return window_criterion(trusted)

    def best():
        criterion = scores()
        return min(criterion, key=criterion.get) if criterion else None

    coarse_to_fine(grid, solve_at, best)
    criterion = scores()
    if not criterion:
        return grid[len(grid) // 2], {}
    return min(criterion, key=criterion.get), criterion


def _consistent(fit, reference):
    """Whether no parameter of ``fit`` is both half its value and
    :data:`DEGENERATE_DISTANCE` standard errors from ``reference``'s."""
    distance = np.abs(fit.theta - reference.theta)
    spread = np.sqrt(np.diag(fit.covariance) + np.diag(reference.covariance))
    far = (distance > 0.5 * np.abs(reference.theta)) & (distance > DEGENERATE_DISTANCE * spread)
    return not np.any(far)


def _shift(problems, system, noisy, bounds, length, multiplicities, method, fit):
    """Largest shift, in standard errors, of the estimates on windows half and twice as
    long (within the rule's limits), or None where neither fits."""
    grid_problem = _Grid(problems[0].segments, system.parameters)
    shifts = []
    for other in (length // 2, 2 * length):
        if other < min_length(multiplicities) or \
                independent_windows(grid_problem, other) < needed_windows(grid_problem):
            continue
        try:
            alt = _solve(problems, system, noisy, bounds, other, multiplicities, method)
        except (np.linalg.LinAlgError, InputDataError):
            continue
        spread = np.sqrt(np.diag(fit.covariance) + np.diag(alt.covariance))
        shifts.append(float(np.max(np.abs(alt.theta - fit.theta) / spread)))
    return max(shifts) if shifts else None


def identify_system(data, equations, parameters=None, *, time=None, rate=None,
                    outputs=None, window=None, method="bc", multiplicities=MULTIPLICITIES,
                    name="custom", refine="auto", hidden=None):
    """Identify the shared parameters of a system of equations (:func:`algid.identify`
    with a list of equations; ``hidden``: outputs that are not measured)."""
    from algid.identification._output_error import check_refine
    from algid.identification._system_refinement import refine_system
    from algid.identification._system_result import SystemResult

    refine = check_refine(refine)

    if method not in SYSTEM_METHODS:
        raise InputDataError(f"method {method!r} is not offered for systems of equations "
                             f"(choose from {', '.join(SYSTEM_METHODS)})")
    system = parse_system(equations, parameters, outputs=outputs, name=name) \
        if not isinstance(equations, SystemModel) else equations
    hidden = _check_hidden(hidden)
    if hidden:
        return _identify_hidden(data, system, hidden, time=time, rate=rate, window=window,
                                method=method, multiplicities=multiplicities, refine=refine)
    multiplicities = check_arguments(
        system.equations[0], system.parameters, time=time, rate=rate, output=None,
        window=window, method=method, methods=METHODS, multiplicities=multiplicities,
        name=name, iterations=1)
    if time is not None and time in system.signals:
        raise InputDataError(f"time column {time!r} is also a signal of the equations; "
                             f"give the column of the sample times")
    for model in system.equations:
        check_memory(data, model)
        multiplicities = check_multiplicities(model, multiplicities)
    shortest = min_length(multiplicities)
    if any(model.needs_derivatives for model in system.equations):
        shortest = max(shortest, DERIVATIVE_SAMPLES)   # (as one equation's identify)
    segments, step, n_samples = prepare_records(data, system.signals, time=time, rate=rate,
                                                min_length=shortest)
    problems = []   # the equations with parameters (a fully known one informs none)
    for model in system.equations:
        add_derivatives(model, segments, derivative_estimate)
        check_factors(model, segments)
        if model.parameters:
            problems.append(WindowProblem(model, segments, step))
    noisy = tuple(y for y in system.outputs if any(y in p.model.signals for p in problems))
    bounds = {}
    for y in noisy:
        problem = next(p for p in problems if y in p.model.signals)
        bounds[y] = problem.noise_bound(y)
    scores = None
    if window is None:
        length, scores = _choose_window(problems, system, noisy, bounds, multiplicities,
                                        method)
    else:
        length = window_length(window, step, _Grid(problems[0].segments, system.parameters),
                               multiplicities)
    try:
        fit = _solve(problems, system, noisy, bounds, length, multiplicities, method)
    except (np.linalg.LinAlgError, ValueError):
        raise InputDataError(f"the window equations on windows of {(length - 1) * step:.4g} "
                             f"s cannot be solved (not finite, or singular): use a longer "
                             f"window, or the automatic one") from None
    if fit.null is not None:
        _refuse_null(system, fit.null)
    degenerate = [p for p, s in zip(system.parameters, fit.stderr) if not s > 0]
    if degenerate:   # the trivial solution of an equation without a known term
        raise InputDataError(f"the estimate of {', '.join(degenerate)} is degenerate on "
                             f"windows of {(length - 1) * step:.4g} s (zero standard error: "
                             f"an equation without a known term solved by zeros): the "
                             f"records do not excite the system, or the window is too short")
    warnings = []
    stride = window_stride(length)
    shift = None
    for model, misfit in zip([p.model for p in problems], fit.misfits):
        limit = misfit_limit(fit.n_windows, length, len(system.parameters), stride)
        if misfit > limit:
            if shift is None:
                shift = _shift(problems, system, noisy, bounds, length, multiplicities,
                               method, fit) or 0.0
            if shift > SHIFT_LIMIT:
                warnings.append(f"the equation {model.equation} does not explain the "
                                f"records within the noise: its misfit is {misfit:.3g} "
                                f"times the noise's and the estimates shift by {shift:.3g} "
                                f"standard errors between windows")
            # (as for one equation: would a power of its output explain it?)
            warnings += _missing_term(system, problems, model, misfit, limit, shift, noisy,
                                      bounds, length, multiplicities)
    values = dict(zip(system.parameters, fit.theta.tolist()))
    result = SystemResult(
        system=system, values=values, covariance=fit.covariance,
        window=(length - 1) * step, n_samples=n_samples, n_windows=fit.n_windows,
        method=method, multiplicities=multiplicities, time=time, rate=rate,
        numerical_error=dict(zip(system.parameters, fit.numerical_error.tolist())),
        misfits=dict(zip([p.model.output for p in problems], fit.misfits)),
        window_scores=scores,
        warnings=warnings + _weak(system, fit.theta, fit.covariance))
    result = refine_system(result, segments, refine)
    if result.estimate == "refined":   # what the refined estimate determines
        theta = np.array([result.values[p] for p in system.parameters])
        # its residual test's and what it determines; the algebraic fit's misfit
        # warnings stay in result.algebraic (coloured output noise biases the algebraic
        # estimates, not the refined ones)
        result.warnings = result.refinement.residual_test.warnings() \
            + _weak(system, theta, result.covariance)
    return result


def _missing_term(system, problems, model, misfit, limit, shift, noisy, bounds, length,
                  multiplicities):
    """The warning of an equation whose misfit a power of its output explains: as one
    equation's adequacy test asks, the equation with the term added (a fresh parameter)
    against the equation as it is, the system around it, both fitted by least squares on
    the same windows."""
    from algid.identification._adequacy import Adequacy, missing_terms

    segments, step = problems[0].segments, problems[0].step
    if _noise_free(model, system, segments):
        return []
    where = [p.model for p in problems].index(model)
    texts = [m.equation for m in system.equations]
    position = texts.index(model.equation)

    def refit(equation, names):
        texts[position] = equation
        other = parse_system(texts, (*system.parameters,
                                     *[n for n in names if n not in system.parameters]),
                             outputs=system.outputs)
        others = [WindowProblem(m, segments, step) for m in other.equations if m.parameters]
        return _solve(others, other, noisy, bounds, length, multiplicities, "ls").misfits[where]

    window = (length - 1) * step
    found = missing_terms(Adequacy(misfit, limit, shift, None, window, window), model, refit)
    if not found.missing:
        return []
    return [f"the equation {model.equation} leaves a misfit {misfit:.3g} times what output "
            f"noise allows, and a term in {' and '.join(found.missing)} would explain most "
            f"of it (the misfit falls to {found.explained:.2g} of it): a missing term?"]


def _noise_free(model, system, segments):
    """Whether every output an equation reads is free of noise to :data:`NOISE_FREE` of
    its spread (a simulated record): its misfit is then the quadrature's error, of which
    a term fitted beside it may take half without the equation lacking it (a noise-free
    chain of four masses: ``x1**3`` took 0.52 of the first equation's)."""
    for y in system.outputs:
        if y in model.signals:
            values = [seg.values[y] for seg in segments]
            spread = float(np.std(np.concatenate(values)))
            if not difference_noise_bound(values) <= (NOISE_FREE * spread) ** 2:
                return False
    return True


def _check_hidden(hidden):
    if hidden is None:
        return ()
    if isinstance(hidden, str):
        hidden = [hidden]
    if not isinstance(hidden, (list, tuple)) or not all(isinstance(h, str) for h in hidden):
        raise ModelError(f"hidden must name signals of the equations, got {hidden!r:.60}")
    return tuple(dict.fromkeys(hidden))


def _identify_hidden(data, system, hidden, *, time, rate, window, method, multiplicities,
                     refine):
    """A linear system with hidden outputs: its input–output equations identified, their
    coefficients mapped to the parameters, then the refinement on the full system
    (:mod:`algid.identification._hidden`)."""
    from algid.identification._hidden import (
        check_identifiable,
        eliminate,
        physical_parameters,
    )
    from algid.identification._system_refinement import refine_system
    from algid.identification._system_result import SystemResult

    elimination = eliminate(system, hidden)
    check_identifiable(elimination, system.parameters)
    options = {"time": time, "rate": rate, "window": window, "method": method,
               "multiplicities": multiplicities, "refine": False}
    # one input-output equation per measured output, sharing the coefficients of det P
    io = identify_system(data, elimination.equations, elimination.coefficients, **options)
    # (the system of the input-output equations has the coefficients as its parameters,
    # in their order)
    theta, theta_covariance, others, candidates = physical_parameters(
        elimination, system.parameters, io.values, io.covariance)
    warnings = [f"input-output equation: {w}" for w in io.warnings]
    for other in others:
        warnings.append("the coefficients fit another parameter set as well: "
                        + _listed(system, other))
    measured = [s for s in system.signals if s not in hidden]
    segments, _, _ = prepare_records(data, measured, time=time, rate=rate,
                                     min_length=min_length(multiplicities))

    def refined_from(theta, theta_covariance):
        result = SystemResult(
            system=system, values=dict(zip(system.parameters, theta.tolist())),
            covariance=theta_covariance, window=io.window, n_samples=io.n_samples,
            n_windows=io.n_windows, method=method, multiplicities=io.multiplicities,
            time=time, rate=rate, window_scores=io.window_scores,
            warnings=warnings + _weak(system, theta, theta_covariance), hidden=hidden,
            elimination=elimination)
        result = refine_system(result, segments, refine)
        if result.estimate == "refined":   # (the coefficients' warnings were the start's)
            theta = np.array([result.values[p] for p in system.parameters])
            result.warnings = warnings[len(io.warnings):] + _weak(system, theta,
                                                                   result.covariance)
        return result

    result = refined_from(theta, theta_covariance)
    if candidates and result.estimate == "refined":
        result = _best_of_candidates(result, candidates, refined_from)
    elif candidates:
        result.warnings.append("the coefficients fit another parameter set nearly as "
                               "well: " + _listed(system, candidates[0][0]))
    return result


def _listed(system, theta):
    return ", ".join(f"{p}={v:.6g}" for p, v in zip(system.parameters, theta))


def _best_of_candidates(result, candidates, refined_from):
    """Of the output-error fits from the best solution of the coefficient map and from
    the others that fit the coefficients nearly as well, the one that fits the records
    best; a warning where another fits them about as well (chi-square within
    :data:`~algid.identification._hidden.NEAR_COST`)."""
    from algid.identification._hidden import NEAR_COST

    fits = [result]
    for theta, covariance in candidates:
        try:
            fit = refined_from(theta, covariance)
        except ModelError:   # (refine=True: a candidate that does not refine)
            continue
        if fit.estimate == "refined":
            fits.append(fit)
    # chi-square of each fit's simulation residuals in the first fit's noise levels
    sigma = result.noise_rms
    costs = [result.n_samples * sum(fit.noise_rms[y] ** 2 / sigma[y] ** 2 for y in sigma)
             for fit in fits]
    order = np.argsort(costs, kind="stable")
    best = fits[order[0]]
    for k in order[1:]:
        if costs[k] - costs[order[0]] <= NEAR_COST:
            best.warnings.append(
                f"another parameter set fits the records about as well (chi-square "
                f"{costs[k] - costs[order[0]]:.2g} higher): "
                + _listed(best.system, [fits[k].values[p] for p in best.system.parameters]))
    return best


def _weak(system, theta, covariance):
    """Warnings for the parameters whose standard error exceeds
    :data:`WEAK_RELATIVE_ERROR` of their value."""
    stderr = np.sqrt(np.maximum(np.diag(covariance), 0.0))
    return [f"{p} is poorly determined by these records: standard error {s:.3g} against "
            f"a value of {v:.3g}" for p, v, s in zip(system.parameters, theta, stderr)
            if s > WEAK_RELATIVE_ERROR * abs(v)]
