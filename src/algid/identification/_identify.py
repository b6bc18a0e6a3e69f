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
output simulated by the current estimate (open-loop stable plants).

The time and every column are scaled by powers of two and the equations solved in an
orthonormal basis of their regressors (:mod:`algid.identification._window_basis`), so
that any units give the same window and estimates.  Standard errors come from a
sandwich over the window index: the residuals' own (HAC) covariance, or the covariance
that white output noise puts into the equations where the two agree
(:mod:`algid.identification._window_covariance`).  Without ``window`` the length is
chosen on a grid by the worst parameter's error (:func:`window_criterion`).  The
crossings of a ``sign(q')`` are placed by fits of ``q`` with the motion the model gives
it (:mod:`algid.identification._sign_crossings`), and the equations solved again.
What the records cannot determine is refused, naming the parameters.

The user guide, "How identify works", gives the equations, the solvers, the
covariance, the window rule and the crossings in full.
"""

from __future__ import annotations

import types
from dataclasses import dataclass, field
from math import comb
from typing import NamedTuple

import numpy as np

from algid.errors import InputDataError, ModelError
from algid.identification._adequacy import misfit_ratio, missing_terms, model_adequacy
from algid.identification._arguments import check_arguments, check_memory, check_model_columns
from algid.identification._bias_compensation import solve_equilibrated
from algid.identification._methods import METHODS
from algid.identification._records import (
    Segment,
    check_factors,
    estimate_derivative,
    prepare_records,
)
from algid.identification._sign_crossings import crossing_jumps, crossing_motion, sign_factor
from algid.identification._window_basis import (
    WindowBasis,
    check_excited,
    check_finite,
    exponent,
    separability,
)
from algid.identification._window_covariance import hac_meat, noise_meat, sandwich
from algid.identification._window_kernels import (
    step_window_integrals,
    uniform_window_integrals,
    window_integrals,
    window_noise_products,
    window_sample_weights,
)
from algid.identification._window_rule import (
    WindowFit,
    check_multiplicities,
    choose_window,
    min_length,
    window_advice,
    window_criterion,
    window_grid,
    window_length,
)
from algid.models._argument import estimator_module
from algid.models._compiled import model_of
from algid.models._expression import Call, Signal
from algid.models._grammar import parse_equation
from algid.models._model import Model
from algid.models._system import is_system
from algid.signals._differentiation import algebraic_derivative

__all__ = ["identify", "METHODS", "MULTIPLICITIES", "AGREEMENT", "CROSSING_PASSES",
           "window_criterion", "window_grid"]

#: Kernel multiplicities stacked in every estimate (their difference drives the window rule).
MULTIPLICITIES = (8, 12)

#: The covariance of output noise through the kernels replaces the residuals' own (HAC)
#: where the latter's variances are at most this many times the former's.
AGREEMENT = 4.0

#: Solves with the crossings of ``sign(q')`` placed by the model's motion (the second
#: with the first's parameters: noise-free friction loop, M 1.3e-6 -> 5.8e-7).
CROSSING_PASSES = 2

#: Windows overlap: a window starts every ``length // WINDOW_OVERLAP`` samples.
WINDOW_OVERLAP = 8

#: Round-off standard error of the solution, per sample of a window, relative to the
#: known side (in the orthonormal basis of :mod:`algid.identification._window_basis`).
ROUNDOFF = 4 * np.finfo(float).eps


class _Samples(NamedTuple):
    """A factor's samples per segment, over ``2**exponent`` (the power of two of the
    largest)."""

    values: list
    exponent: int


@dataclass
class _Cache:
    """What the solves of one :class:`_Problem` reuse, one field per kind.

    The measured output never changes: its noise bound stays, and so do the samples of
    a factor until its crossings are placed again (:meth:`forget_factors`); the samples
    of the simulated output go at every new simulation (:meth:`forget_simulated`).
    """

    samples: dict = field(default_factory=dict)   # (factor, which) -> _Samples
    # factor -> derivative with respect to the measured output per segment (None: the
    # factor does not read it), in the units of the measured samples
    sensitivities: dict = field(default_factory=dict)
    noise_bound: float | None = None
    excited: bool = False   # check_excited passed

    def forget_factors(self, factors):
        """Forget the samples and sensitivities of ``factors`` (their crossings moved)."""
        self.samples = {k: v for k, v in self.samples.items() if k[0] not in factors}
        self.sensitivities = {k: v for k, v in self.sensitivities.items()
                              if (k[0] if isinstance(k, tuple) else k) not in factors}

    def forget_simulated(self):
        """Forget the samples of the simulated output (a new simulation); the measured
        rows' excitation is checked again at the next solve, the crossings having moved
        since the first check (later repeats find the same)."""
        self.samples = {k: v for k, v in self.samples.items() if k[1] == "measured"}
        self.excited = False


class _Problem:
    """Channel samples of a model on the segments of the records.

    Internally the time is counted in :attr:`time_unit`, a power of two near the median
    sampling step, from the first sample of each segment (:attr:`segments`; the records'
    own times are in :attr:`user_segments`), and the samples of every factor are divided
    by a power of two bringing the largest into ``[1, 2)`` (the output's, the unit of the
    output noise, is :attr:`output_unit`).  The columns of :meth:`rows` are then each in
    a power of two of their own (:meth:`exponents`): ``theta_p`` is the solution for
    column ``p`` times ``2**(E_b - E_p)``.  Powers of two are exact: the results do not
    depend on the units of the records, and nothing overflows or underflows.
    """

    def __init__(self, model, segments, step):
        self.model = model
        self.time_unit = float(np.ldexp(1.0, int(np.round(np.log2(step)))))
        self.user_segments = segments
        self.segments = [Segment(s.record, s.rows, (s.t - s.t[0]) / self.time_unit, s.values,
                                 None if s.step is None else s.step / self.time_unit)
                         for s in segments]
        self.step = step                        # the records' median step (s)
        self.unit_step = step / self.time_unit  # the same in the internal time
        self.parameters = model.parameters
        self.output_exponent = exponent([s.values[model.output] for s in segments])
        self.output_unit = float(np.ldexp(1.0, self.output_exponent))
        self.cache = _Cache()
        self._exponents = {}
        self.sign_jumps = {}   # sign factor -> jump of q'' (refined crossings)
        self.first_values = {}  # parameter -> first estimate (the crossings' local fits)
        # (sign factor, segment) -> refined crossings: (time, step of the sign, first sample
        # of the fit, derivative of the time with respect to those samples)
        self.crossings = {}
        self.steps = {}  # (sign factor, which, segment) -> (first value, its steps' times, sizes)

    @property
    def exact_columns(self):
        """Columns of :meth:`rows` whose terms do not read the output (inputs, offsets,
        drifts): no output noise enters them."""
        output = self.model.output
        return [i for i, p in enumerate(self.parameters)
                if not any(output in t.factor.signals()
                           for t in self.model.terms if t.parameter == p)]

    def factor_samples(self, factor, which="measured"):
        """Samples of a factor per segment, over the power of two of its largest."""
        key = (factor, which)
        if key not in self.cache.samples:
            samples, steps, crossings = [], [], []
            for seg in self.user_segments:
                values = seg.values if which == "measured" else seg.simulated
                if isinstance(factor, Call) and factor.function == "sign":
                    refine = which == "measured" and factor in self.sign_jumps
                    motion = crossing_motion(self.model, self.first_values, values,
                                             seg.t) if refine else None
                    z, step, crossing = sign_factor(
                        factor.args[0].evaluate(values, seg.t), seg.t,
                        position=values[self.model.output] if refine else None,
                        jump=self.sign_jumps.get(factor), motion=motion)
                    steps.append(step)
                    crossings.append(crossing if refine else None)
                else:
                    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
                        z = np.asarray(factor.evaluate(values, seg.t), dtype=float) \
                            * np.ones(len(seg))
                    steps.append(None)
                    crossings.append(None)
                samples.append(z)
            if not all(np.all(np.isfinite(z)) for z in samples):
                raise InputDataError(f"the factor {factor} is not finite on these records "
                                     f"(out of the floating-point range at these "
                                     f"amplitudes?): express the signals in other units")
            e = exponent(samples)
            unit = self.time_unit
            moves = np.ldexp(1.0, self.output_exponent) / unit
            for s, seg in enumerate(self.user_segments):
                samples[s] = np.ldexp(samples[s], -e)
                if steps[s] is not None:   # in the internal time and the factor's unit
                    level, times, sizes = steps[s]
                    self.steps[(factor, which, s)] = (
                        np.ldexp(level, -e), (np.asarray(times) - seg.t[0]) / unit,
                        np.ldexp(np.asarray(sizes, dtype=float), -e))
                if crossings[s] is not None:
                    self.crossings[(factor, s)] = [
                        ((time - seg.t[0]) / unit, np.ldexp(size, -e), first, fit * moves)
                        for time, size, first, fit in crossings[s]]
            self.cache.samples[key] = _Samples(samples, e)
        return self.cache.samples[key].values

    def exponents(self, which="measured"):
        """Powers of two of the columns of :meth:`rows` and of its known side, and of
        every term within its column (``{term index: shift}``, at most 0)."""
        unit = int(np.round(np.log2(self.time_unit)))
        own = []
        for term in self.model.terms:
            self.factor_samples(term.factor, which)
            own.append(self.cache.samples[(term.factor, which)].exponent
                       - term.derivative * unit)
        key = (which, tuple(own))
        if key in self._exponents:
            return self._exponents[key]
        columns = {}
        for term, e in zip(self.model.terms, own):
            columns[term.parameter] = max(columns.get(term.parameter, e), e)
        shifts = {i: e - columns[term.parameter]
                  for i, (term, e) in enumerate(zip(self.model.terms, own))}
        self._exponents[key] = (np.array([columns[p] for p in self.parameters]),
                                columns.get(None, 0), shifts)
        return self._exponents[key]

    def term_scale(self, term, which="measured"):
        """The power of two of a term within its column of :meth:`rows`."""
        return float(np.ldexp(1.0, self.exponents(which)[2][self.model.terms.index(term)]))

    @np.errstate(over="ignore")  # equations that overflow are refused by check_finite
    def rows(self, length, multiplicity, which="measured"):
        """Regressors ``A``, known side ``b`` and window ids for one multiplicity (each
        column in its power of two, :meth:`exponents`)."""
        stride = max(1, length // WINDOW_OVERLAP)
        shifts = self.exponents(which)[2]
        blocks_a, blocks_b, ids = [], [], []
        for s, seg in enumerate(self.segments):
            if len(seg) < length:
                continue
            n_win = (len(seg) - length) // stride + 1
            integrals = []
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
                integrals.append(w)
            A, b = term_rows(self.model, integrals, shifts, n_win)
            blocks_a.append(A)
            blocks_b.append(b)
            ids.append(np.full(n_win, s))
        if not blocks_a:
            raise InputDataError(f"no segment holds a window of {length} samples")
        return np.vstack(blocks_a), np.concatenate(blocks_b), np.concatenate(ids)

    def to_rows(self, theta, which="measured"):
        """The solution of :meth:`rows` that parameter values make."""
        columns, known, _ = self.exponents(which)
        return np.ldexp(theta, columns - known)

    def excitation(self, length, multiplicity, A, b):
        """Per column of ``A`` and for ``b``, their rms over the largest they could be
        for factors of the same largest samples (at most about 1; round-off for a term
        that vanishes on the records)."""
        shifts = self.exponents()[2]
        bound = np.zeros(len(self.parameters) + 1)
        index = {p: i for i, p in enumerate(self.parameters)}
        for i, term in enumerate(self.model.terms):
            z = self.factor_samples(term.factor)
            largest = max(float(np.max(np.abs(v))) for v in z)
            kernel = np.sum(np.abs(window_sample_weights(None, self.unit_step, length,
                                                         multiplicity, term.derivative)))
            column = len(self.parameters) if term.parameter is None else index[term.parameter]
            bound[column] += abs(term.coefficient) * np.ldexp(kernel * largest, shifts[i])
        rms = np.sqrt(np.mean(np.column_stack([A, b]) ** 2, axis=0))
        return np.where(bound > 0, rms / np.where(bound > 0, bound, 1.0), 0.0)

    def sensitivity(self, factor, signal=None):
        """Derivative of a factor with respect to a measured signal (by default the
        output), per segment (``None`` where the factor does not read the signal's plain
        samples), both in their units (the powers of two of :meth:`factor_samples` and
        :meth:`signal_exponent`)."""
        signal = self.model.output if signal is None else signal
        cache = self.cache.sensitivities
        key = factor if signal == self.model.output else (factor, signal)
        if key not in cache:
            self.factor_samples(factor)
            shift = self.signal_exponent(signal) \
                - self.cache.samples[(factor, "measured")].exponent
            if signal not in factor.signals():
                cache[key] = None
            elif factor == Signal(signal):
                cache[key] = [np.ones(len(seg)) for seg in self.segments]
            else:
                cache[key] = [np.ldexp(factor_sensitivity(factor, signal, seg.values,
                                                          seg.t), shift)
                              for seg in self.user_segments]
        return cache[key]

    def signal_exponent(self, signal):
        """The power of two of a measured signal's largest sample on the segments (the
        unit of its noise variance)."""
        if signal == self.model.output:
            return self.output_exponent
        return exponent([s.values[signal] for s in self.user_segments])

    def noise_bound(self, signal=None):
        """An upper bound on the variance of white noise on the output samples (in the
        output's unit, :attr:`output_unit`), or on another signal's (in the unit of
        :meth:`signal_exponent`).

        The ``k``-th difference of the samples has the variance ``C(2k, k) sigma^2`` of
        white noise plus that of the signal's difference (signal and noise being
        uncorrelated, on any sample grid): each ``k`` bounds ``sigma^2`` from above, and
        the smallest of ``k = 1 .. 8`` is kept.  Tight when the signal is smooth on the
        sample grid; loose (harmless) at a few samples per period.
        """
        if signal is not None and signal != self.model.output:
            return difference_noise_bound(
                [np.ldexp(seg.values[signal], -self.signal_exponent(signal))
                 for seg in self.segments])
        if self.cache.noise_bound is None:
            y = [np.ldexp(seg.values[self.model.output], -self.output_exponent)
                 for seg in self.segments]
            self.cache.noise_bound = difference_noise_bound(y)
        return self.cache.noise_bound

    def noise_grams(self, length, multiplicity, signal=None):
        """Per-window covariance of the noise that unit white output noise (or noise on
        another measured ``signal``, in its unit) puts into the columns ``[A | b]`` of
        :meth:`rows` (shape ``(windows, p + 1, p + 1)``).

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
            if self.sensitivity(term.factor, signal) is None:
                continue
            weight = term.coefficient * self.term_scale(term)
            if term.parameter is None:
                noisy.append((p, -weight, term.derivative, term.factor))
            else:
                noisy.append((index[term.parameter], weight, term.derivative, term.factor))
        blocks = []
        for s, seg in enumerate(self.segments):
            if len(seg) < length:
                continue
            n_win = (len(seg) - length) // stride + 1
            grams = np.zeros((n_win, p + 1, p + 1))
            for i, (c1, w1, k1, f1) in enumerate(noisy):
                for j, (c2, w2, k2, f2) in enumerate(noisy[i:], start=i):
                    product = self.sensitivity(f1, signal)[s] \
                        * self.sensitivity(f2, signal)[s]
                    v = w1 * w2 * window_noise_products(
                        product, seg.t, seg.step, length, (multiplicity, k1),
                        (multiplicity, k2), stride)
                    grams[:, c1, c2] += v
                    if j != i:
                        grams[:, c2, c1] += v
            blocks.append(grams)
        return np.concatenate(blocks)


def difference_noise_bound(y):
    """The bound of :meth:`_Problem.noise_bound` on samples ``y`` (one array per segment)."""
    bounds = []
    for k in range(1, 9):
        d = [np.diff(v, k) for v in y if len(v) > k]
        count = sum(len(v) for v in d)
        if count:
            bounds.append(sum(float(v @ v) for v in d) / count / comb(2 * k, k))
    return min(bounds) if bounds else np.inf


def term_rows(model, integrals, shifts, n_win):
    """Regressors ``A`` and known side ``b`` from every term's window integrals (in the
    order of ``model.terms``), each term times its coefficient and its power of two
    ``shifts[i]`` within its column (the window equations of the module notes)."""
    index = {p: i for i, p in enumerate(model.parameters)}
    A, b = np.zeros((n_win, len(model.parameters))), np.zeros(n_win)
    for i, (term, w) in enumerate(zip(model.terms, integrals)):
        w = np.ldexp(term.coefficient * w, shifts[i])
        if term.parameter is None:
            b -= w
        else:
            A[:, index[term.parameter]] += w
    return A, b


def factor_sensitivity(factor, output, values, t, h=None):
    """Derivative of a factor's samples with respect to the output's (central differences
    of step ``h``, by default 1e-6 of the largest output sample)."""
    y = values[output]
    h = 1e-6 * max(float(np.max(np.abs(y))), 1e-300) if h is None else h
    up, down = dict(values), dict(values)
    up[output], down[output] = y + h, y - h
    difference = (np.asarray(factor.evaluate(up, t), dtype=float)
                  - np.asarray(factor.evaluate(down, t), dtype=float))
    return difference / (2 * h) * np.ones(len(t))


class _Solution(NamedTuple):
    """The solve of one multiplicity's window equations (:func:`_solve_multiplicity`),
    in the orthonormal basis of :class:`WindowBasis`."""

    phi: np.ndarray            # the solution in the basis
    basis: WindowBasis
    ids: np.ndarray            # the segment of each window
    scores: np.ndarray         # the estimating equations per window
    jacobian: np.ndarray       # their derivative
    variance: float | None     # the noise variance of a correction (None: none)
    capped: bool               # whether that variance is the noise bound
    weights: np.ndarray        # the regressors or instruments of the scores
    separation: object         # the separability check (highest multiplicity), or None
    grams: np.ndarray | None   # per-window noise covariances of [A | b] in the basis


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
    variance, capped = None, False
    weights = basis.A
    if instruments is not None:
        Z = weights = basis.instruments(instruments)
        phi = solve_equilibrated(Z.T @ basis.A, Z.T @ basis.b)
        scores, jacobian = Z * (basis.b - basis.A @ phi)[:, None], Z.T @ basis.A
    else:
        phi, scores, jacobian, variance, capped = METHODS[method].solve(
            basis.A, basis.b, grams, problem.noise_bound())
    return _Solution(phi, basis, ids, scores, jacobian, variance, capped, weights,
                     separation, grams)


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
    variance, capped = solution.variance, solution.capped
    r = basis.b - basis.A @ phi
    bread = np.linalg.pinv(solution.jacobian)
    theta_s = basis.theta(phi)
    theta_bar = np.append(theta_s, -1.0)   # in the units of the rows (noise_meat)
    stride = max(1, length // WINDOW_OVERLAP)
    noise = None
    if variance is None and not capped:  # least squares: misfit per unit noise variance
        weight = float(np.einsum("i,wij,j->", np.append(phi, -1.0), solution.grams,
                                 np.append(phi, -1.0)))
        variance = float(r @ r) / weight if weight > 0 else np.inf
        if not variance <= problem.noise_bound():
            variance, capped = problem.noise_bound(), True
    # the per-window noise matrices: their memory for noise_meat's
    solution = solution._replace(grams=None)
    if variance is not None and np.isfinite(variance) and variance > 0:
        beta = np.ldexp(1.0, -basis.b_shift)
        noise = variance * beta ** 2 * noise_meat(problem, length, top, theta_bar,
                                                  solution.weights, stride)
    covariance, middle = sandwich(
        bread, hac_meat(solution.scores, ids, int(np.ceil(length / stride))), noise,
        AGREEMENT, floor=ROUNDOFF * length * np.linalg.norm(basis.b), middle=True)
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


def _add_derivatives(model, segments, estimator):
    for seg in segments:
        for name, k in model.needs_derivatives:
            seg.values[(name, k)] = estimator(seg.values[name], seg.t, k, seg.step)


def _derivative_estimate(y, t, order, step):
    """Derivative inside a nonlinear factor: the algebraic differentiator."""
    if step is not None:
        return algebraic_derivative(y, step, derivative=order)
    return algebraic_derivative(y, time=t, derivative=order)


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


def _least_squares_misfit(segments, step, equation, parameters, output, length, multiplicities):
    """Misfit of another equation on the same signals, fitted by least squares."""
    problem = _Problem(parse_equation(equation, parameters, output=output), segments, step)
    fit = _solve(problem, length, multiplicities, method="ls")
    return misfit_ratio(problem, length, max(fit.separate), problem.to_rows(fit.theta))


def identify(data, equation, parameters=None, *, time=None, rate=None, output=None,
             window=None, method="bc", multiplicities=MULTIPLICITIES, name="custom",
             iterations=3, refine="auto"):
    """Identify the parameters of a model equation on measured records.

    Parameters
    ----------
    data : record or list of records
        A record: a mapping of column name -> samples, a pandas ``DataFrame`` (time as
        a column or as its index), an xarray ``Dataset`` or a python-control
        ``TimeResponseData``; a list of records is identified together.  Rows may be
        missing from a record with a time column (gaps), and NaN (or masked) samples
        are dropped (an infinite one is refused).
    equation : str, Model or module
        The model, e.g. ``"M*q'' + Fv*q' + Fc*sign(q') + off = F"``, or a compiled
        model (:func:`algid.compile_equation`): the same model argument as
        :func:`algid.estimate` and :class:`algid.OnlineEstimator`.
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
    method : {"bc", "ls", "iv"}
        Bias-compensated least squares (the default: it removes the bias that white
        output noise causes and needs no simulation, so it also works in closed loop
        and on integrating plants), plain least squares, or instrumental variables from
        the output simulated by the current estimate (open-loop stable plants only;
        slower: it simulates the model at every iteration).  See the user guide, "How
        identify works".
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

    Returns
    -------
    IdentificationResult
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
    from algid.identification._output_error import (
        check_refine,
        refine_result,
        simulates_stably,
    )
    from algid.identification._result import IdentificationResult

    if is_system(equation):   # several equations sharing parameters
        from algid.identification._system_identify import identify_system

        if output is not None:
            raise ModelError("output: a system of equations takes outputs=[...] through "
                             "algid.models.parse_system, one per equation")
        return identify_system(data, equation, parameters, time=time, rate=rate,
                               window=window, method=method, multiplicities=multiplicities,
                               name=name, refine=refine)
    refine = check_refine(refine)
    if isinstance(equation, types.ModuleType):  # a compiled model: its own equation
        equation = model_of(estimator_module(equation, parameters))
    multiplicities = check_arguments(
        equation, parameters, time=time, rate=rate, output=output, window=window,
        method=method, methods=METHODS, multiplicities=multiplicities, name=name,
        iterations=iterations)
    model = equation if isinstance(equation, Model) else parse_equation(
        equation, parameters, output=output, name=name)
    check_model_columns(model, time)
    check_memory(data, model)
    multiplicities = check_multiplicities(model, multiplicities)
    segments, step, n_samples = prepare_records(data, model.signals, time=time, rate=rate,
                                                min_length=min_length(multiplicities))
    _add_derivatives(model, segments, _derivative_estimate)
    check_factors(model, segments)
    problem = _Problem(model, segments, step)
    length = window_length(window, step, problem, multiplicities)
    scores, separations = None, {}
    if length is None:
        length, scores = choose_window(problem, multiplicities, _solve, method=method,
                                       separations=separations)
    fit = _solve(problem, length, multiplicities, method=method)
    for _ in range(CROSSING_PASSES):  # again, crossings of sign(q') placed by the model
        # (same window: re-chosen, it varied with the noise and so did its quadrature bias)
        problem.first_values = dict(zip(model.parameters, fit.theta))
        problem.sign_jumps = crossing_jumps(model, problem.first_values)
        if not problem.sign_jumps:
            break
        problem.cache.forget_factors(problem.sign_jumps)
        fit = _solve(problem, length, multiplicities, method=method)
    if METHODS[method].instrumental:
        for _ in range(iterations):
            if not _simulated_values(problem, fit.theta, model):
                raise InputDataError("instrumental variables: the simulated output of the "
                                     "first estimate diverges; use method='bc'")
            instruments = {a: problem.rows(length, a, "simulated") for a in multiplicities}
            fit = _solve(problem, length, multiplicities, instruments)
    adequacy = model_adequacy(problem, length, fit, _solve, method, min_length(multiplicities),
                              max(1, length // WINDOW_OVERLAP))
    # where the misfit is output noise, a combination no better determined than the
    # noise or the misfit is free; where it is more, the model's error may be the cause
    noise_like = adequacy.misfit <= adequacy.misfit_limit
    if not noise_like:  # would a term the model lacks explain most of the misfit?
        adequacy = missing_terms(adequacy, model, lambda eq, names: _least_squares_misfit(
            segments, step, eq, names, model.output, length, multiplicities))

    grid_scores = scores

    def advice():
        # which windows would separate the parameters, or how much less noise: for an
        # explicit window the grid of the automatic rule is solved now (only when refused
        # or warned, so a clean fixed-window call costs no more than before)
        nonlocal grid_scores
        if not separations:
            try:
                grid_scores = choose_window(problem, multiplicities, _solve, method=method,
                                            separations=separations)[1]
            except (InputDataError, ModelError, np.linalg.LinAlgError):
                return ""
        return window_advice(separations, step, grid_scores)

    if noise_like and (fit.separation.free or fit.separation.misfit_free):
        raise ModelError(f"{fit.separation.message(model.parameters)}; {advice()}".rstrip("; "))
    weak = fit.separation.poorly_separated(adequacy.adequate)
    idle = _idle_records(data, segments, length, step)
    separation = fit.separation.warnings(model.parameters, adequacy.adequate,
                                         advice() if weak else "")
    unstable = []
    if METHODS[method].instrumental and model.is_linear and not simulates_stably(
            model, dict(zip(model.parameters, fit.theta.tolist()))):
        # its instruments came from simulations of a stable start; the end is not
        unstable = ["the instrumental-variable estimate's model is not stable: its "
                    "simulation on these records diverges, and so would its instruments "
                    "(use method='bc')"]
    result = IdentificationResult(
        model=model, values=dict(zip(model.parameters, fit.theta.tolist())),
        covariance=fit.covariance, window=(length - 1) * step, n_samples=n_samples,
        n_windows=fit.n_windows, method=method, multiplicities=multiplicities,
        time=time, rate=rate, window_scores=scores,
        separate={a: dict(zip(model.parameters, v.tolist())) for a, v in fit.separate.items()},
        numerical_error=dict(zip(model.parameters, fit.numerical_error.tolist())),
        adequacy=adequacy,
        warnings=adequacy.warnings() + separation + idle + unstable)
    # (what the records can determine holds for a refined estimate too; whether the
    # model explains them is asked of its simulation residuals instead)
    return refine_result(result, segments, step, refine, separation + idle + unstable)
