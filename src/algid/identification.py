"""Identify the parameters of a user model on whole measured records.

The algebraic method's equations hold on every window ``[t0, t0 + T]``, whatever the
state at ``t0``: each window gives one linear equation in the parameters,

    sum_p theta_p * (sum of c_i * W[D^k_i z_i] over the terms of p) = - (known terms),

where ``W[D^k z]`` is the integral of ``z`` against the term kernel of multiplicity
``a`` (:mod:`algid.window_kernels`).  The windows slide over every record (overlapping,
``length // 8`` samples apart, never across a gap), and the stacked equations are
solved for one parameter set.  Two kernel multiplicities are used, as an embedded
Runge-Kutta pair is: the estimate is that of the higher one (``a = 12``), the lower one
(``a = 8``) gives its error estimate for the window rule.  (At the short windows that
few samples per period call for, a high multiplicity is the more accurate: its kernel
vanishes to higher order at the window ends, so its sampled sum is spectrally
accurate on fewer samples; measured on the synthetic linear record at 8 samples per
period, ``a = 4`` on 12-16 sample windows has quadrature errors of about 1e-3.)

Solvers (``method``):

- ``"bc"`` (default), bias-compensated least squares.  Output noise enters both sides
  of the window equations through known kernels, so it biases least squares by
  ``sigma^2`` times a matrix the kernels give (``_Problem.noise_grams``); the
  estimate removes it (Koopmans' estimator, the generalised eigenvector of the normal
  matrix and that noise matrix), with ``sigma^2`` from the equations' misfit, capped by
  an upper bound on the output noise from the samples alone (so that a misfit that is
  not output noise, e.g. a misestimated ``sign(q')``, is not "compensated").  It needs
  no simulation, so it works in closed loop and on integrating plants.
- ``"ls"``: plain least squares (biased by output noise: by 1.2 standard errors on the
  stiffness of the synthetic linear record at 1 % noise, far more on longer windows).
- ``"iv"``: instrumental variables, the instruments being the same window integrals of
  the factors evaluated on the output simulated by the current estimate (noise-free),
  iterated as SRIVC does; for open-loop stable plants only.

A derivative inside a nonlinear factor (``sign(q')``) is estimated numerically: by
the algebraic differentiator :func:`algid.differentiation.algebraic_derivative` when
it is available, else by a local polynomial (Savitzky-Golay) derivative.  Its zeros
come late where ``q''`` jumps (a Coulomb term), so for a model of second order in ``q``
the crossings are then placed by fits of ``q`` with the motion the model gives it there
(:mod:`algid.sign_crossings`), the equations solved again, twice (:data:`CROSSING_PASSES`:
each pass with the parameters of the one before), with the steps of ``sign(q')``
integrated exactly (:func:`algid.window_kernels.step_window_integrals`).

Standard errors come from a sandwich over the window index.  Its middle is the
residuals' own covariance, a HAC (heteroscedasticity and autocorrelation consistent)
estimate: the residuals of overlapping windows are correlated over ``length / stride``
windows, and the lag weights are flat up to that lag and taper linearly to zero at twice
it (a flat-top kernel: Newey-West's Bartlett weights underestimate such a correlation).
Where the misfit is no larger than white output noise could make it (its variance per
unit of noise weight at most the bound that the samples alone put on the output noise,
``_Problem.noise_bound``), the covariance that such noise puts into the window
equations is also computed: known from the kernels and the factors' sensitivities,
including the correlation of overlapping windows
(:func:`algid.window_covariance.noise_meat`), times the noise variance.  It replaces the
HAC one where the HAC variances are at most :data:`AGREEMENT` times its own for every
parameter.  A misfit that does not change between noise realisations (the aliasing of a
sampled ``y**3``) inflates the HAC estimate a little, and then counts only through the
noise variance; a misfit that is not output noise at all (a force disturbance, noise on
an input, a misestimated ``sign(q')``) inflates it more, and the HAC estimate is kept.

Window rule (``window=None``): on a geometric grid of window lengths (ratio 1.25, from
``a_max + 4`` samples up to a thirtieth of the data, so that the HAC covariance sees at
least 30 independent windows), estimate with both multiplicities.  A parameter's error
on a window is the larger of its standard error and of the difference between the two
multiplicities (the bias estimate, as an embedded Runge-Kutta pair estimates its step
error), relative to the parameter (or, near zero, to the value whose term is 5 % of the
known side), divided by the smallest such error that parameter reaches on the grid; the
window minimising the worst parameter's ratio is kept (:func:`window_criterion`).
"""

from __future__ import annotations

from math import comb

import numpy as np

from algid.adequacy import model_adequacy
from algid.bias_compensation import bias_compensated, solve_equilibrated
from algid.errors import InputDataError, ModelError
from algid.expression import Call, Signal
from algid.grammar import parse_equation
from algid.identification_arguments import check_arguments, check_memory, check_model_columns
from algid.model import Model
from algid.records import check_factors, estimate_derivative, prepare_records
from algid.sign_crossings import crossing_jumps, crossing_motion, sign_factor
from algid.window_covariance import hac_meat, noise_meat
from algid.window_kernels import (
    step_window_integrals,
    uniform_window_integrals,
    window_integrals,
    window_noise_products,
)

__all__ = ["identify", "METHODS", "MULTIPLICITIES", "AGREEMENT", "CROSSING_PASSES",
           "window_criterion", "window_grid"]

#: Solvers: bias-compensated least squares (default), least squares, instrumental variables.
METHODS = ("ls", "bc", "iv")

#: Kernel multiplicities stacked in every estimate (their difference drives the window rule).
MULTIPLICITIES = (8, 12)

#: A term this small next to the known side (5 %) counts as negligible in the window rule.
NEGLIGIBLE_TERM = 0.05

#: The covariance of output noise through the kernels replaces the residuals' own (HAC)
#: where the latter's variances are at most this many times the former's.
AGREEMENT = 4.0

#: Solves with the crossings of ``sign(q')`` placed by the model's motion (the second
#: with the first's parameters: noise-free friction loop, M 1.3e-6 -> 5.8e-7).
CROSSING_PASSES = 2

#: Windows overlap: a window starts every ``length // WINDOW_OVERLAP`` samples.
WINDOW_OVERLAP = 8


def window_grid(n_min, n_max, ratio=1.25):
    """Geometric grid of window lengths (samples) between ``n_min`` and ``n_max``.

    Parameters
    ----------
    n_min, n_max : int
        Shortest and longest window (samples).
    ratio : float
        Ratio of successive lengths (before rounding).

    Returns
    -------
    list of int
    """
    grid, n = [], float(n_min)
    while n <= n_max:
        if not grid or int(round(n)) != grid[-1]:
            grid.append(int(round(n)))
        n *= ratio
    return grid


class _Problem:
    """Channel samples of a model on the segments of the records."""

    def __init__(self, model, segments, step):
        self.model = model
        self.segments = segments
        self.step = step
        self.parameters = model.parameters
        self.factors = {}
        self.sign_jumps = {}   # sign factor -> jump of q'' (refined crossings)
        self.first_values = {}  # parameter -> first estimate (the crossings' local fits)
        # (sign factor, segment) -> refined crossings: (time, step of the sign, first
        # sample of the fit, derivative of the time with respect to those samples)
        self.crossings = {}
        # (sign factor, which, segment) -> (first value, times and sizes of its steps)
        self.steps = {}

    def factor_samples(self, factor, which="measured"):
        key = (factor, which)
        if key not in self.factors:
            samples = []
            for seg in self.segments:
                values = seg.values if which == "measured" else seg.simulated
                if isinstance(factor, Call) and factor.function == "sign":
                    refine = which == "measured" and factor in self.sign_jumps
                    motion = crossing_motion(self.model, self.first_values, values,
                                             seg.t) if refine else None
                    z, steps, crossings = sign_factor(
                        factor.args[0].evaluate(values, seg.t), seg.t,
                        position=values[self.model.output] if refine else None,
                        jump=self.sign_jumps.get(factor), motion=motion)
                    self.steps[(factor, which, len(samples))] = steps
                    if refine:
                        self.crossings[(factor, len(samples))] = crossings
                else:
                    z = np.asarray(factor.evaluate(values, seg.t), dtype=float) \
                        * np.ones(len(seg))
                samples.append(z)
            self.factors[key] = samples
        return self.factors[key]

    def rows(self, length, multiplicity, which="measured"):
        """Regressors ``A``, known side ``b`` and window ids for one multiplicity."""
        stride = max(1, length // WINDOW_OVERLAP)
        index = {p: i for i, p in enumerate(self.parameters)}
        blocks_a, blocks_b, ids = [], [], []
        for s, seg in enumerate(self.segments):
            if len(seg) < length:
                continue
            n_win = (len(seg) - length) // stride + 1
            A = np.zeros((n_win, len(self.parameters)))
            b = np.zeros(n_win)
            for term in self.model.terms:
                z = self.factor_samples(term.factor, which)[s]
                steps = self.steps.get((term.factor, which, s))
                if steps is not None:
                    w = step_window_integrals(seg.t, *steps, length, multiplicity,
                                              term.derivative, stride)
                elif seg.step is not None:
                    w = uniform_window_integrals(z, seg.step, length, multiplicity,
                                                 term.derivative, stride)
                else:
                    w = window_integrals(z, seg.t, length, multiplicity, term.derivative,
                                         stride)
                if term.parameter is None:
                    b -= term.coefficient * w
                else:
                    A[:, index[term.parameter]] += term.coefficient * w
            blocks_a.append(A)
            blocks_b.append(b)
            ids.append(np.full(n_win, s))
        if not blocks_a:
            raise InputDataError(f"no segment holds a window of {length} samples")
        return np.vstack(blocks_a), np.concatenate(blocks_b), np.concatenate(ids)

    def sensitivity(self, factor):
        """Derivative of a factor with respect to the measured output, per segment
        (``None`` where the factor does not read the output's plain samples)."""
        key = (factor, "sensitivity")
        if key not in self.factors:
            output = self.model.output
            if output not in factor.signals():
                self.factors[key] = None
            elif factor == Signal(output):
                self.factors[key] = [np.ones(len(seg)) for seg in self.segments]
            else:
                sensitivities = []
                for seg in self.segments:
                    y = seg.values[output]
                    h = 1e-6 * max(float(np.max(np.abs(y))), 1e-300)
                    up, down = dict(seg.values), dict(seg.values)
                    up[output], down[output] = y + h, y - h
                    sensitivities.append(
                        (np.asarray(factor.evaluate(up, seg.t), dtype=float)
                         - np.asarray(factor.evaluate(down, seg.t), dtype=float))
                        / (2 * h) * np.ones(len(seg)))
                self.factors[key] = sensitivities
        return self.factors[key]

    def noise_bound(self):
        """An upper bound on the variance of white noise on the output samples.

        The ``k``-th difference of the samples has the variance ``C(2k, k) sigma^2`` of
        white noise plus that of the signal's difference (signal and noise being
        uncorrelated, on any sample grid): each ``k`` bounds ``sigma^2`` from above, and
        the smallest of ``k = 1 .. 8`` is kept.  Tight when the signal is smooth on the
        sample grid; loose (harmless) at a few samples per period.
        """
        if "noise_bound" not in self.factors:
            y = [seg.values[self.model.output] for seg in self.segments]
            bounds = []
            for k in range(1, 9):
                d = [np.diff(v, k) for v in y if len(v) > k]
                count = sum(len(v) for v in d)
                if count:
                    bounds.append(sum(float(v @ v) for v in d) / count / comb(2 * k, k))
            self.factors["noise_bound"] = min(bounds) if bounds else np.inf
        return self.factors["noise_bound"]

    def noise_grams(self, length, multiplicity):
        """Per-window covariance of the noise that unit white output noise puts into
        the columns ``[A | b]`` of :meth:`rows` (shape ``(windows, p + 1, p + 1)``).

        Output noise enters every term whose factor reads the output, linearly to first
        order (through the factor's sensitivity), and then the window integral: the
        covariance of two columns is a window sum of the product of sensitivities
        against the product of the two term kernels' weights.
        """
        stride = max(1, length // WINDOW_OVERLAP)
        p = len(self.parameters)
        index = {q: i for i, q in enumerate(self.parameters)}
        noisy = []   # (column, coefficient, derivative, factor)
        for term in self.model.terms:
            if self.sensitivity(term.factor) is None:
                continue
            if term.parameter is None:
                noisy.append((p, -term.coefficient, term.derivative, term.factor))
            else:
                noisy.append((index[term.parameter], term.coefficient, term.derivative,
                              term.factor))
        blocks = []
        for s, seg in enumerate(self.segments):
            if len(seg) < length:
                continue
            n_win = (len(seg) - length) // stride + 1
            grams = np.zeros((n_win, p + 1, p + 1))
            for i, (c1, w1, k1, f1) in enumerate(noisy):
                for j, (c2, w2, k2, f2) in enumerate(noisy[i:], start=i):
                    product = self.sensitivity(f1)[s] * self.sensitivity(f2)[s]
                    v = w1 * w2 * window_noise_products(
                        product, seg.t, seg.step, length, (multiplicity, k1),
                        (multiplicity, k2), stride)
                    grams[:, c1, c2] += v
                    if j != i:
                        grams[:, c2, c1] += v
            blocks.append(grams)
        return np.concatenate(blocks)


class _Fit:
    """One estimate on one window length: parameters, covariance, diagnostics."""

    def __init__(self, theta, covariance, separate, scale, residuals, n_windows):
        self.theta = theta
        self.covariance = covariance
        self.separate = separate          # multiplicity -> estimate alone
        self.scale = scale                # effect of a unit parameter error on the equation
        self.residuals = residuals
        self.n_windows = n_windows

    @property
    def stderr(self):
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))

    def relative_error(self):
        """Per parameter: max(standard error, multiplicity difference), relative to the
        parameter (or to the value whose term is 5 % of the known side, for a parameter
        near zero)."""
        values = list(self.separate.values())
        difference = np.abs(values[0] - values[-1])
        reference = np.maximum(np.abs(self.theta), NEGLIGIBLE_TERM / self.scale)
        return np.maximum(self.stderr, difference) / reference


def _solve(problem, length, multiplicities, instruments=None, method="ls"):
    """Estimates of every multiplicity on windows of ``length`` samples; the result is
    that of the highest multiplicity (the most accurate quadrature), the others serve
    as its error check."""
    separate = {}
    for a in multiplicities:
        A, b, ids = problem.rows(length, a)
        variance = None
        weights = A
        if instruments is not None:
            Z = weights = instruments[a][0]
            theta = solve_equilibrated(Z.T @ A, Z.T @ b)
            scores, jacobian = Z * (b - A @ theta)[:, None], Z.T @ A
        elif method == "bc":
            theta, scores, jacobian, variance = bias_compensated(
                A, b, problem.noise_grams(length, a), problem.noise_bound())
        else:
            theta = np.linalg.lstsq(A, b, rcond=None)[0]
            scores, jacobian = A * (b - A @ theta)[:, None], A.T @ A
        separate[a] = (theta, A, b, ids, scores, jacobian, variance, weights)
    top = max(multiplicities)
    theta, A, b, ids, scores, jacobian, variance, weights = separate[top]
    r = b - A @ theta
    bread = np.linalg.pinv(jacobian)
    theta_bar = np.append(theta, -1.0)
    if variance is None:  # least squares: the misfit per unit of white-noise variance
        noise_weight = float(np.einsum("i,wij,j->", theta_bar,
                                       problem.noise_grams(length, top), theta_bar))
        variance = float(r @ r) / noise_weight if noise_weight > 0 else np.inf
        if not variance <= problem.noise_bound():
            variance = None
    stride = max(1, length // WINDOW_OVERLAP)
    # the residuals' own covariance, and, where the misfit is no larger than white output
    # noise could make it, that of such noise through the kernels: kept if the former
    # is at most AGREEMENT times it for every parameter (a misfit that does not change
    # between noise realisations inflates the former a little; a misfit that is not
    # output noise at all, a force disturbance or noise on an input, inflates it more)
    covariance = bread @ hac_meat(scores, ids, int(np.ceil(length / stride))) @ bread.T
    if variance is not None:
        analytic = bread @ (variance * noise_meat(problem, length, top, theta_bar, weights,
                                                  stride)) @ bread.T
        if np.all(np.diag(covariance) <= AGREEMENT * np.diag(analytic)):
            covariance = analytic
    scale = np.sqrt(np.mean(A ** 2, axis=0)) / max(float(np.sqrt(np.mean(b ** 2))), 1e-300)
    return _Fit(theta, covariance, {a: v[0] for a, v in separate.items()}, scale, r,
                len(ids))


def _add_derivatives(model, segments, estimator):
    for seg in segments:
        for name, k in model.needs_derivatives:
            seg.values[(name, k)] = estimator(seg.values[name], seg.t, k, seg.step)


def _derivative_estimate(y, t, order, step):
    """Derivative inside a nonlinear factor: the algebraic differentiator when the
    installed algid has it, else a local polynomial (Savitzky-Golay) derivative."""
    try:
        from algid.differentiation import algebraic_derivative
    except ImportError:
        return estimate_derivative(y, t, order, step)
    if step is not None:
        return algebraic_derivative(y, step, derivative=order)
    return algebraic_derivative(y, time=t, derivative=order)


def _length_of(window, step, segments):
    if window is None:
        return None
    window = float(window)
    if not np.isfinite(window) or window <= 0:
        raise InputDataError(f"window must be a positive number of seconds, got {window}")
    length = int(round(window / step)) + 1
    longest = max(len(s) for s in segments)
    if length > longest:
        raise InputDataError(f"window {window:g} s ({length} samples) is longer than the "
                             f"longest run of contiguous samples ({longest})")
    return length


def _check_multiplicities(model, multiplicities):
    multiplicities = tuple(int(a) for a in multiplicities)
    if not multiplicities:
        raise ModelError("give at least one kernel multiplicity")
    low = min(multiplicities)
    if low < model.order:
        raise ModelError(f"kernel multiplicity {low} is below the model order "
                         f"{model.order}")
    return multiplicities


def _min_length(multiplicities):
    # a kernel of multiplicity a vanishes to order a at both window ends; with fewer
    # than a + 4 samples its sampled sum is no longer spectrally accurate (measured on
    # the synthetic records at 8 samples per period: a = 8 on 11 samples biases the
    # stiffness by several standard errors, on 12-16 samples it does not)
    return max(8, max(multiplicities) + 4)


def window_criterion(fits):
    """The window rule's criterion on a grid of fits ``{length: _Fit}``.

    A parameter's relative error on a window is the larger of its standard error and of
    the difference between the two multiplicities (the bias estimate), relative to the
    parameter (or, for a parameter near zero, to the value at which its term would be
    5 % of the known side).  Each parameter's relative error is divided by the smallest
    it reaches on the grid, and the criterion is that of the worst parameter: the rule
    keeps every parameter near its best precision.  (The worst relative error alone is
    dominated by the least determined parameter, often an offset, and leaves the
    others' choice to chance; absolute standard errors alone favour long windows where
    output noise shrinks every estimate towards zero.)

    Parameters
    ----------
    fits : dict
        Window length (samples) -> the fit on that window (with both multiplicities).

    Returns
    -------
    dict
        Window length -> criterion (finite values only); the rule keeps the smallest.
    """
    lengths = list(fits)
    relative = [fits[n].relative_error() for n in lengths]
    relative = np.array(relative)
    best = np.min(np.where(relative > 0, relative, np.inf), axis=0)
    best = np.where(np.isfinite(best), best, 1.0)
    scores = {}
    for n, row in zip(lengths, relative):
        value = float(np.max(row / best))
        if np.isfinite(value):
            scores[n] = value
    return scores


def choose_window(problem, multiplicities, *, n_max=None, method="ls"):
    """Window length (samples) by the rule of this module; also every grid point's
    criterion ``{length: value}``."""
    longest = max(len(s) for s in problem.segments)
    n_min = _min_length(multiplicities)
    total = sum(len(s) for s in problem.segments)
    # at least 30 independent windows: the HAC covariance needs many of them
    n_max = min(n_max or total // 30, longest, 4096)
    grid = window_grid(n_min, max(n_min, n_max))
    fits = {}
    for length in grid:
        try:
            fits[length] = _solve(problem, length, multiplicities, method=method)
        except (np.linalg.LinAlgError, InputDataError):
            continue
    scores = window_criterion(fits) if fits else {}
    if not scores:
        raise InputDataError("no window length gives a solvable system: the records are "
                             "too short or the signals do not excite the model")
    return min(scores, key=scores.get), scores


def _simulated_values(problem, theta, model):
    """Noise-free output of the current estimate on every segment (instruments)."""
    from algid.model_simulation import fit_initial_state, simulate_model

    parameters = dict(zip(model.parameters, theta))
    # fixed-step RK4 on cubic-spline inputs: instruments need not be accurate, only
    # noise-free and correlated with the regressors
    options = {"method": "RK4", "substeps": 4, "interpolation": "cubic"}
    for seg in problem.segments:
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
    problem.factors = {k: v for k, v in problem.factors.items() if k[1] == "measured"}
    return True


def identify(data, equation, parameters=None, *, time=None, rate=None, output=None,
             window=None, method="bc", multiplicities=MULTIPLICITIES, name="custom",
             iterations=3):
    """Identify the parameters of a model equation on measured records.

    Parameters
    ----------
    data : mapping or list of mappings
        Column name -> samples; a list of records is identified together.  Rows may be
        missing from a record with a time column (gaps), and NaN samples are dropped.
    equation : str or Model
        The model, e.g. ``"M*q'' + Fv*q' + Fc*sign(q') + off = F"``.
    parameters : sequence of str or str
        The unknown parameters (not needed when ``equation`` is a Model).
    time : str, optional
        Name of the time column; by default a column ``t`` or ``time``.
    rate : float, optional
        Sampling rate (Hz) of records without a time column (with one, it must agree
        with it: :data:`algid.records.RATE_TOLERANCE`).
    output : str, optional
        Output signal; by default the signal of highest derivative order.
    window : float, optional
        Window length (s); chosen from the data when omitted (see the module notes).
    method : {"bc", "ls", "iv"}
        Bias-compensated least squares (the default: it removes the bias that white
        output noise causes and needs no simulation, so it also works in closed loop
        and on integrating plants), plain least squares, or instrumental variables from
        the output simulated by the current estimate (open-loop stable plants only;
        about 10 to 20 times slower).  See the module notes.
    multiplicities : tuple of int
        Kernel multiplicities stacked (each at least the model order).
    name : str
        Label of the model.
    iterations : int
        Instrumental-variable iterations.

    Returns
    -------
    IdentificationResult
        With ``warnings`` when the model does not explain the data within the noise
        (:mod:`algid.adequacy`).

    Raises
    ------
    ModelError, InputDataError
        One-line messages for a bad equation, an argument of the wrong type, unusable
        data, or records too large for the memory available.
    """
    from algid.identification_result import IdentificationResult

    multiplicities = check_arguments(
        equation, parameters, time=time, rate=rate, output=output, window=window,
        method=method, methods=METHODS, multiplicities=multiplicities, name=name,
        iterations=iterations)
    model = equation if isinstance(equation, Model) else parse_equation(
        equation, parameters, output=output, name=name)
    check_model_columns(model, time)
    check_memory(data, model)
    multiplicities = _check_multiplicities(model, multiplicities)
    segments, step, n_samples = prepare_records(data, model.signals, time=time, rate=rate,
                                                min_length=_min_length(multiplicities))
    _add_derivatives(model, segments, _derivative_estimate)
    check_factors(model, segments)
    problem = _Problem(model, segments, step)
    length = _length_of(window, step, segments)
    scores = None
    if length is None:
        length, scores = choose_window(problem, multiplicities,
                                       method="bc" if method == "iv" else method)
    fit = _solve(problem, length, multiplicities, method="bc" if method == "iv" else method)
    for _ in range(CROSSING_PASSES):  # again, crossings of sign(q') placed by the model
        # (same window: re-chosen, it varied with the noise and so did its quadrature bias)
        problem.first_values = dict(zip(model.parameters, fit.theta))
        problem.sign_jumps = crossing_jumps(model, problem.first_values)
        if not problem.sign_jumps:
            break
        problem.factors = {k: v for k, v in problem.factors.items()
                           if not (isinstance(k, tuple) and k[0] in problem.sign_jumps)}
        fit = _solve(problem, length, multiplicities, method="bc" if method == "iv" else method)
    if method == "iv":
        for _ in range(iterations):
            if not _simulated_values(problem, fit.theta, model):
                raise InputDataError("instrumental variables: the simulated output of the "
                                     "first estimate diverges; use method='bc'")
            instruments = {a: problem.rows(length, a, "simulated") for a in multiplicities}
            fit = _solve(problem, length, multiplicities, instruments)
    adequacy = model_adequacy(problem, length, fit, _solve, method, _min_length(multiplicities),
                              max(1, length // WINDOW_OVERLAP))
    return IdentificationResult(
        model=model, values=dict(zip(model.parameters, fit.theta.tolist())),
        covariance=fit.covariance, window=(length - 1) * step, n_samples=n_samples,
        n_windows=fit.n_windows, method=method, multiplicities=multiplicities,
        time=time, rate=rate, window_scores=scores,
        separate={a: dict(zip(model.parameters, v.tolist())) for a, v in fit.separate.items()},
        adequacy=adequacy, warnings=adequacy.warnings())
