"""The window equations of one model equation on the segments of measured records.

:class:`WindowProblem` holds a model's factor samples per segment, scaled by powers of
two (the time in a power of two near the sampling step, every factor's largest sample in
``[1, 2)``), and makes the window equations ``A theta = b`` of one window length and
kernel multiplicity (:meth:`WindowProblem.rows`), the covariance that white noise on a
measured signal puts into them (:meth:`WindowProblem.noise_grams`) and a bound on that
noise's variance from the samples' differences (:meth:`WindowProblem.noise_bound`).
:func:`algid.identify` solves them for one equation
(:mod:`algid.identification._identify`), and for a system of equations that share
parameters (:mod:`algid.identification._system_identify`).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from math import comb
from typing import NamedTuple

import numpy as np

from algid.errors import InputDataError
from algid.identification._model_velocity import (
    initial_velocity,
    simulate_velocity,
    velocity_equation,
)
from algid.identification._records import Segment
from algid.identification._sign_crossings import crossing_motion, sign_factor
from algid.identification._window_basis import exponent
from algid.identification._window_covariance import noise_meat
from algid.identification._window_kernels import (
    block_window_sums,
    step_window_integrals,
    uniform_window_integrals,
    window_integrals,
    window_noise_products,
    window_sample_weights,
)
from algid.models._expression import Call, Constant, Signal
from algid.signals._differentiation import DEFAULT_WINDOW_STEPS, algebraic_derivative

__all__ = ["WindowProblem", "ProblemCache", "FactorSamples", "term_rows", "is_sign_factor",
           "factor_sensitivity", "noise_curvature", "difference_noise_bound",
           "difference_sums", "noise_bound_from_sums", "noise_variance_from_sums",
           "DIFFERENCE_ORDERS", "FLAT_DIFFERENCES", "add_derivatives",
           "derivative_estimate", "derivative_noise_gain", "DERIVATIVE_SAMPLES",
           "MULTIPLICITIES",
           "WINDOW_OVERLAP", "window_stride",
           "spread_ranges", "RULE_WINDOWS", "RULE_EXCERPTS"]

#: Kernel multiplicities stacked in every estimate (their difference drives the window rule).
MULTIPLICITIES = (8, 12)

#: Windows overlap: a window starts every ``length // WINDOW_OVERLAP`` samples.
WINDOW_OVERLAP = 8


#: The window rule solves a candidate length on at most about this many windows
#: (:meth:`WindowProblem.for_window_rule`): the short windows of long records are
#: otherwise the bulk of its cost (at 10**5 samples, lengths under 120 samples took
#: 70 % of it), though the standard errors they give, scaled to the whole record, are
#: those of every window.
RULE_WINDOWS = 2048

#: Excerpts of the records a candidate length is solved on, when it is solved on some
#: (each excerpt's windows cost their own solve overhead: 8 took twice as long as 4).
RULE_EXCERPTS = 4


def spread_ranges(sizes, samples, count, min_length=1):
    """``count`` ranges of about ``samples`` samples in all, spread evenly over segments
    of ``sizes`` samples, each within one segment.

    Parameters
    ----------
    sizes : sequence of int
        Samples per segment.
    samples, count : int
        Samples in all, and ranges.
    min_length : int
        Ranges shorter than this (at the end of a segment) are dropped.

    Returns
    -------
    list of tuple of int
        ``(segment, start, stop)``, in order and disjoint (every segment whole when
        they hold no more than ``samples``).
    """
    total = int(sum(sizes))
    if total <= samples:
        return [(i, 0, int(n)) for i, n in enumerate(sizes)]
    ranges, size = [], samples // count
    ends = np.cumsum(sizes)
    for k in range(count):
        at = int((k + 0.5) * total / count)
        i = int(np.searchsorted(ends, at, side="right"))
        start = max(0, min(at - int(ends[i] - sizes[i]) - size // 2, int(sizes[i]) - size))
        if ranges and ranges[-1][0] == i:   # disjoint, in order
            start = max(start, ranges[-1][2])
        stop = min(int(sizes[i]), start + size)
        if stop - start >= min_length:
            ranges.append((i, start, stop))
    return ranges


def _piece(segment, start, stop):
    """Samples ``start:stop`` of a segment, as a segment."""
    return Segment(segment.record, segment.rows[start:stop], segment.t[start:stop],
                   {name: v[start:stop] for name, v in segment.values.items()},
                   segment.step)


def window_stride(length):
    """Samples between the starts of consecutive windows of ``length`` samples
    (:data:`WINDOW_OVERLAP` windows hold each sample).

    Parameters
    ----------
    length : int

    Returns
    -------
    int
    """
    return max(1, length // WINDOW_OVERLAP)

#: Orders of the samples' differences that bound the variance of white noise on them.
DIFFERENCE_ORDERS = range(1, 9)

#: Three consecutive orders of differences whose noise bounds agree within this ratio
#: show the output's noise, not its signal (:func:`noise_variance_from_sums`).
FLAT_DIFFERENCES = 1.15


class FactorSamples(NamedTuple):
    """A factor's samples per segment, over ``2**exponent`` (the power of two of the
    largest)."""

    values: list
    exponent: int


@dataclass
class ProblemCache:
    """What the solves of one :class:`WindowProblem` reuse, one field per kind.

    The measured output never changes: its noise bound stays, and so do the samples of
    a factor until its crossings are placed again (:meth:`forget_factors`); the samples
    of the simulated output go at every new simulation (:meth:`forget_simulated`).
    """

    samples: dict = field(default_factory=dict)   # (factor, which) -> FactorSamples
    # factor -> derivative with respect to the measured output per segment (None: the
    # factor does not read it), in the units of the measured samples
    sensitivities: dict = field(default_factory=dict)
    noise_bound: float | None = None
    noise_variance: float | None = None   # (output_noise_variance, in the output's unit)
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


class WindowProblem:
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
        self.cache = ProblemCache()
        self._exponents = {}
        self.sign_jumps = {}   # sign factor -> jump of q'' (refined crossings)
        self.first_values = {}  # parameter -> first estimate (the crossings' local fits)
        # (sign factor, segment) -> refined crossings: (time, step of the sign, first sample
        # of the fit, derivative of the time with respect to those samples)
        self.crossings = {}
        self.steps = {}  # (sign factor, which, segment) -> (first value, its steps' times, sizes)
        # (sign factor, which, segment) -> samples of what the steps leave (the effective
        # sign where the model's velocity sticks)
        self.step_rests = {}
        #: place the steps of ``sign(q')`` by the model's own velocity at
        #: :attr:`first_values` (:mod:`algid.identification._model_velocity`), not by
        #: local fits of ``q``
        self.velocity_crossings = False
        #: The differentiator window of the derivatives inside nonlinear factors, in
        #: multiples of its default (``derivative_estimate``'s ``widen``).
        self.derivative_widen = 1
        self._derivative_gain = {}   # (segment, order) -> derivative_noise_gain
        #: whether the rows are direct sums and the noise's covariance, where it is the
        #: same in every window, made once per segment (:meth:`for_window_rule`)
        self.direct_sums = False
        #: the share of the records' windows these segments hold (:meth:`for_window_rule`;
        #: the excerpts of a record read in chunks)
        self.share = 1.0

    def for_window_rule(self, length, every_window=False):
        """This problem for the window rule's candidate of ``length`` samples.

        The same equations summed another way, cheaper: the rows summed directly over
        the windows (a few multiplications per sample and term where an FFT of the
        record takes 20 times as long); where every term reads the output as itself on
        uniform segments, the noise's covariance from one window's weights; and where
        the records hold more than :data:`RULE_WINDOWS` windows of that length, those
        of :data:`RULE_EXCERPTS` excerpts spread over them, :attr:`share` of the whole
        (a covariance on them, times ``share``, is one on every window).  A fit's own
        numbers come from the problem itself.  A model with ``sign`` factors, whose
        crossings are placed on the whole record, is solved on every window.

        Parameters
        ----------
        length : int
        every_window : bool
            Never excerpts.

        Returns
        -------
        WindowProblem
        """
        counts, view = self.windows(length), None
        excerpts = not every_window and sum(counts) > RULE_WINDOWS \
            and not any(is_sign_factor(term.factor) for term in self.model.terms)
        if excerpts:
            stride = window_stride(length)
            samples = RULE_WINDOWS * stride + RULE_EXCERPTS * (length - stride)
            pieces = [_piece(self.user_segments[i], start, stop)
                      for i, start, stop in spread_ranges(
                          [len(seg) for seg in self.segments], samples, RULE_EXCERPTS,
                          length)]
            view = WindowProblem(self.model, pieces, self.step) if pieces else None
        if view is not None and sum(view.windows(length)):
            view.cache.noise_bound = self.noise_bound()   # (the records')
            view.cache.excited = True   # (checked on the records by the fit)
            view.share = self.share * sum(view.windows(length)) / sum(counts)
        else:
            view = copy.copy(self)
        view.direct_sums = True
        return view

    @property
    def uniform_noise(self):
        """Whether output noise enters every window of a segment alike: every term that
        reads the output reads it as itself, on uniformly sampled segments."""
        output = Signal(self.model.output)
        return all(seg.step is not None for seg in self.segments) \
            and all(term.factor == output for term in self.model.terms
                    if self.model.output in term.factor.signals())

    def windows(self, length):
        """Windows of ``length`` samples per segment.

        Parameters
        ----------
        length : int

        Returns
        -------
        list of int
        """
        stride = window_stride(length)
        return [(len(seg) - length) // stride + 1 if len(seg) >= length else 0
                for seg in self.segments]

    def noise_paths(self):
        """The terms that read the output: ``(column, weight, derivative, factor,
        shift)`` each, ``shift`` the power of two of its sensitivity."""
        p = len(self.parameters)
        index = {q: i for i, q in enumerate(self.parameters)}
        paths = []
        for term in self.model.terms:
            if self.model.output not in term.factor.signals():
                continue
            weight = term.coefficient * self.term_scale(term)
            shift = self.output_exponent - self.factor_exponent(term.factor)
            if term.parameter is None:
                paths.append((p, -weight, term.derivative, term.factor, shift))
            else:
                paths.append((index[term.parameter], weight, term.derivative, term.factor,
                              shift))
        return paths

    def uniform_noise_grams(self, length, multiplicity):
        """:meth:`noise_grams` where output noise enters every window of a segment
        alike (:attr:`uniform_noise`): one matrix per sampling step, broadcast
        (read-only) to the windows.

        Parameters
        ----------
        length, multiplicity : int

        Returns
        -------
        numpy.ndarray, shape (windows, p + 1, p + 1)
        """
        p = len(self.parameters)
        paths = self.noise_paths()
        counts = self.windows(length)
        blocks, made = [], {}
        for seg, count in zip(self.segments, counts):
            if count == 0:
                continue
            if seg.step in made:
                blocks.append((made[seg.step], count))
                continue
            gram = np.zeros((p + 1, p + 1))
            for i, (c1, w1, k1, _, _) in enumerate(paths):
                for j, (c2, w2, k2, _, _) in enumerate(paths[i:], start=i):
                    v = w1 * w2 * float(np.sum(
                        window_sample_weights(None, seg.step, length, multiplicity, k1)
                        * window_sample_weights(None, seg.step, length, multiplicity, k2)))
                    gram[c1, c2] += v
                    if j != i:
                        gram[c2, c1] += v
            made[seg.step] = gram
            blocks.append((gram, count))
        if len(made) == 1:
            return np.broadcast_to(blocks[0][0], (sum(counts), p + 1, p + 1))
        return np.concatenate([np.broadcast_to(g, (c, p + 1, p + 1)) for g, c in blocks])

    def uniform_noise_meat(self, length, multiplicity, theta_bar, scores, stride):
        """:meth:`noise_meat` where output noise enters every window of a segment alike
        (:attr:`uniform_noise`): the sample weights of one window, a number per lag.

        Parameters
        ----------
        length, multiplicity, theta_bar, scores, stride
            As in :meth:`noise_meat`.

        Returns
        -------
        numpy.ndarray, shape (k, k)
        """
        paths = self.noise_paths()
        meat = np.zeros((scores.shape[1], scores.shape[1]))
        first = 0
        for seg, n_win in zip(self.segments, self.windows(length)):
            if n_win == 0:
                continue
            g = scores[first:first + n_win]
            first += n_win
            weights = np.zeros(length)
            for column, weight, derivative, _, _ in paths:   # (noise_meat's factors)
                weights += weight * theta_bar[column] * window_sample_weights(
                    None, seg.step, length, multiplicity, derivative)
            for lag in range(min(n_win, -(-length // stride))):
                shift = lag * stride
                c = float(weights[shift:] @ weights[:length - shift])
                cross = c * (g[:n_win - lag].T @ g[lag:])
                meat += cross if lag == 0 else cross + cross.T
        return meat

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
            samples, steps, crossings, rests = [], [], [], {}
            for seg in self.user_segments:
                values = seg.values if which == "measured" else seg.simulated
                if is_sign_factor(factor):
                    refine = which == "measured" and factor in self.sign_jumps
                    path = self._model_velocity(factor, values, seg.t) if refine else None
                    if path is not None:   # the model's own velocity: no fit of q
                        z, step, crossing, refine = path.sign, path.steps, None, False
                        if np.any(path.rest):
                            rests[len(samples)] = path.rest
                    else:
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
                        variance = self.output_noise_variance()
                        if which == "measured" and variance > 0:
                            z = z - noise_curvature(
                                factor, self.model.output, values, seg.t, variance,
                                gains=self._derivative_gains(factor, len(samples)))
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
                self.steps.pop((factor, which, s), None)   # (an earlier placement's)
                self.step_rests.pop((factor, which, s), None)
                self.crossings.pop((factor, s), None)
                if s in rests:
                    self.step_rests[(factor, which, s)] = np.ldexp(rests[s], -e)
                if steps[s] is not None:   # in the internal time and the factor's unit
                    level, times, sizes = steps[s]
                    self.steps[(factor, which, s)] = (
                        np.ldexp(level, -e), (np.asarray(times) - seg.t[0]) / unit,
                        np.ldexp(np.asarray(sizes, dtype=float), -e))
                if crossings[s] is not None:
                    self.crossings[(factor, s)] = [
                        ((time - seg.t[0]) / unit, np.ldexp(size, -e), first, fit * moves)
                        for time, size, first, fit in crossings[s]]
            self.cache.samples[key] = FactorSamples(samples, e)
        return self.cache.samples[key].values

    def _model_velocity(self, factor, values, t):
        """The model's velocity on one segment at :attr:`first_values`
        (:func:`simulate_velocity`), where :attr:`velocity_crossings` asks for it and the
        estimate gives a stable, dissipative velocity; else None."""
        if not self.velocity_crossings:
            return None
        equation = velocity_equation(self.model, self.first_values, values, t)
        if equation is None:
            return None
        start = initial_velocity(t, values[self.model.output], *equation)
        return simulate_velocity(t, *equation, v0=start)

    def output_noise_variance(self):
        """The output noise's variance, in the output's own units squared, where the
        samples' differences show it (:func:`noise_variance_from_sums`; else 0): what
        :func:`noise_curvature` removes the mean of."""
        if self.cache.noise_variance is None:
            self.cache.noise_variance = noise_variance_from_sums(self.difference_sums())
        with np.errstate(over="ignore"):   # (signals near the floating-point range)
            variance = np.ldexp(self.cache.noise_variance, 2 * self.output_exponent)
        return float(variance) if np.isfinite(variance) else 0.0

    def _derivative_gains(self, factor, s):
        """Per derivative of the output that ``factor`` reads, the noise gain of its
        estimate on segment ``s`` (:func:`derivative_noise_gain`, once per segment and
        order), or None."""
        seg = self.user_segments[s]
        gains = {}
        for k in (k for name, k in factor.derivatives() if name == self.model.output):
            if (s, k) not in self._derivative_gain:
                try:
                    gain = derivative_noise_gain(seg.t, k, seg.step, self.derivative_widen)
                except InputDataError:   # a segment shorter than the wider window keeps
                    gain = derivative_noise_gain(seg.t, k, seg.step)   # its derivative
                self._derivative_gain[(s, k)] = gain
            gains[(self.model.output, k)] = self._derivative_gain[(s, k)]
        return gains or None

    def difference_sums(self):
        """:func:`difference_sums` of the output on the segments, in its unit."""
        return difference_sums([np.ldexp(seg.values[self.model.output],
                                         -self.output_exponent) for seg in self.segments])

    def factor_exponent(self, factor, which="measured"):
        """The power of two of a factor's largest sample (that of :meth:`factor_samples`)."""
        self.factor_samples(factor, which)
        return self.cache.samples[(factor, which)].exponent

    def factor_largest(self, factor):
        """A factor's largest absolute sample, in its power of two (at most 2)."""
        return max(float(np.max(np.abs(v))) for v in self.factor_samples(factor))

    def exponents(self, which="measured"):
        """Powers of two of the columns of :meth:`rows` and of its known side, and of
        every term within its column (``{term index: shift}``, at most 0)."""
        unit = int(np.round(np.log2(self.time_unit)))
        own = [self.factor_exponent(term.factor, which) - term.derivative * unit
               for term in self.model.terms]
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
        stride = window_stride(length)
        shifts = self.exponents(which)[2]
        blocks_a, blocks_b, ids = [], [], []
        for s, seg in enumerate(self.segments):
            if len(seg) < length:
                continue
            n_win = (len(seg) - length) // stride + 1
            integrals = []
            direct = self._direct_integrals(s, length, multiplicity, which)
            for i, term in enumerate(self.model.terms):
                z = self.factor_samples(term.factor, which)[s]
                steps = self.steps.get((term.factor, which, s))
                if i in direct:
                    w = direct[i]
                elif steps is not None:
                    w = step_window_integrals(seg.t, *steps, length, multiplicity,
                                              term.derivative, stride)
                    rest = self.step_rests.get((term.factor, which, s))
                    if rest is not None:   # (what is not a step: where the mass sticks)
                        w = w + (window_integrals(rest, seg.t, length, multiplicity,
                                                  term.derivative, stride)
                                 if seg.step is None else uniform_window_integrals(
                                     rest, seg.step, length, multiplicity,
                                     term.derivative, stride))
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

    def _direct_integrals(self, s, length, multiplicity, which):
        """Term index -> window integrals on segment ``s`` summed directly, the terms of
        one factor at once (:attr:`direct_sums` on a uniform segment; else none)."""
        seg = self.segments[s]
        if not self.direct_sums or seg.step is None:
            return {}
        by_factor = {}
        for i, term in enumerate(self.model.terms):
            if (term.factor, which, s) not in self.steps:
                by_factor.setdefault(term.factor, []).append(i)
        integrals = {}
        count = self.windows(length)[s]
        for factor, terms in by_factor.items():
            kernels = np.array([window_sample_weights(None, seg.step, length, multiplicity,
                                                      self.model.terms[i].derivative)
                                for i in terms])
            z = self.factor_samples(factor, which)[s]
            if isinstance(factor, Constant):   # (the same integral in every window)
                sums = np.repeat(z[0] * np.sum(kernels, axis=1)[:, None], count, axis=1)
            else:
                sums = block_window_sums(z, kernels, window_stride(length))
            integrals.update(zip(terms, sums))
        return integrals

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
            largest = self.factor_largest(term.factor)
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
                variance = self.output_noise_variance() \
                    if signal == self.model.output else 0.0
                cache[key] = [np.ldexp(factor_sensitivity(factor, signal, seg.values,
                                                          seg.t, variance=variance), shift)
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
        if self.direct_sums and signal is None and self.uniform_noise:
            return self.uniform_noise_grams(length, multiplicity)
        stride = window_stride(length)
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


    def noise_meat(self, length, multiplicity, theta_bar, scores, stride):
        """The covariance that unit white output noise gives ``sum_w scores_w e_w``
        (:func:`algid.identification._window_covariance.noise_meat`).

        Parameters
        ----------
        length, multiplicity : int
            Samples per window and kernel multiplicity.
        theta_bar : numpy.ndarray
            The parameters followed by -1.
        scores : numpy.ndarray, shape (windows, k)
            The weights of every window.
        stride : int
            Samples between the starts of consecutive windows.

        Returns
        -------
        numpy.ndarray, shape (k, k)
        """
        if self.direct_sums and self.uniform_noise:
            return self.uniform_noise_meat(length, multiplicity, theta_bar, scores, stride)
        return noise_meat(self, length, multiplicity, theta_bar, scores, stride)


def is_sign_factor(factor):
    """Whether a term's factor is ``sign(...)``: a piecewise-constant signal whose window
    integrals are exact sums over its steps (placed on the whole record)."""
    return isinstance(factor, Call) and factor.function == "sign"


def difference_sums(y):
    """The sums of squares and counts of the differences of every order of
    :data:`DIFFERENCE_ORDERS` of samples ``y`` (one array per segment)."""
    sums = []
    for k in DIFFERENCE_ORDERS:
        d = [np.diff(v, k) for v in y if len(v) > k]
        sums.append((sum(float(v @ v) for v in d), sum(len(v) for v in d)))
    return sums


def difference_noise_bound(y):
    """The bound of :meth:`WindowProblem.noise_bound` on samples ``y`` (one array per segment)."""
    return noise_bound_from_sums(difference_sums(y))


def _order_bounds(sums):
    return [total / count / comb(2 * k, k) if count else np.inf
            for (total, count), k in zip(sums, DIFFERENCE_ORDERS)]


def noise_bound_from_sums(sums):
    """The noise bound from the sums of squares and counts of the differences of each
    order of :data:`DIFFERENCE_ORDERS` (accumulated over a record or a stream)."""
    bounds = [b for b in _order_bounds(sums) if np.isfinite(b)]
    return min(bounds) if bounds else np.inf


def noise_variance_from_sums(sums):
    """The output noise's variance where the differences show it, else 0.

    White noise gives every order ``k`` of differences the variance ``C(2k, k) var``,
    so its bounds (:func:`noise_bound_from_sums`) agree from order to order; where the
    signal's own differences make the smallest one (a noise-free or undersampled
    record), they do not.  The smallest bound is taken as the variance where it and its
    neighbours (three consecutive orders) agree within :data:`FLAT_DIFFERENCES`.

    Parameters
    ----------
    sums : list of (float, int)
        As in :func:`noise_bound_from_sums`.

    Returns
    -------
    float
    """
    bounds = _order_bounds(sums)
    best = int(np.argmin(bounds))
    lo = min(max(best - 1, 0), len(bounds) - 3)
    near = bounds[lo:lo + 3]
    if not (np.all(np.isfinite(near)) and bounds[best] > 0):
        return 0.0
    return float(bounds[best]) if max(near) <= FLAT_DIFFERENCES * bounds[best] else 0.0


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


#: The step of the second difference in a derivative inside a factor, in standard
#: deviations of that derivative's estimate (:func:`noise_curvature`).
CURVATURE_STEP = 1.0


def noise_curvature(factor, output, values, t, variance, h=None, gains=None):
    """What white output noise of ``variance`` adds to a factor's mean, to remove from its
    samples: ``variance / 2`` times its second derivative in the output, and, for each
    derivative of the output it reads, the estimate's noise variance over 2 times the
    second derivative in that.

    ``E[f(y + e)] = f(y) + f''(y) var / 2 + ...``: a cubic spring's ``y**3`` on a noisy
    output has the mean ``y**3 + 3 var y``, a term in ``y`` that biases the linear
    stiffness by ``-3 var K3`` (on a Duffing record at 25 dB, 0.8 of the Cramér–Rao
    bound).  The second difference (step ``1e-3`` of the largest output sample) is exact
    for powers up to 3, so ``y**3 - 3 var y`` and ``y**2 - var`` are unbiased; other
    smooth factors keep a bias of order ``var**2``.  A derivative inside the factor
    comes from the algebraic differentiator, whose estimate carries the noise ``var``
    times its ``gains`` (:func:`derivative_noise_gain`): quadratic damping's
    ``abs(y')*y'`` has the mean ``abs(y')*y' + var_d sign(y')`` where ``y'`` is well
    above that noise (on 20 s at 30 dB the damping was 6.7 standard errors low).  The
    covariance of the output's noise with a first derivative's is zero (the centred
    differentiator weighs the sample itself by zero); of higher derivatives it is left
    out.  Factors that do not read the output, or read it plainly, are left as they
    are (0 is returned), as are derivatives without ``gains``.

    Parameters
    ----------
    factor : Expression
    output : str
    values : mapping
        The signals' samples (the factor's arguments; derivatives under ``(name, k)``).
    t : numpy.ndarray
    variance : float
        The output noise's variance, in the output's units squared.
    h : float, optional
        The step of the second difference; by default ``1e-3`` of the largest output
        sample of ``values`` (a record read in chunks gives its run's).
    gains : mapping, optional
        ``(output, k)`` -> the noise gain of that derivative's estimate per sample.

    Returns
    -------
    numpy.ndarray or float
    """
    if not variance > 0 or output not in factor.signals() or factor == Signal(output):
        return 0.0
    reads = factor.derivatives()
    curvature = 0.0
    arguments = [(output, 1e-3 * max(float(np.max(np.abs(values[output]))), 1e-300)
                  if h is None else h, 1.0)] \
        if not any(name == output for name, _ in reads) else []
    for key in ((name, k) for name, k in reads if name == output):
        if gains is not None and key in gains:
            # the step: the estimate's own noise, so that a kink (abs, at y' = 0) is
            # smoothed as the noise smooths it (polynomials: exact at any step)
            spread = np.sqrt(variance * gains[key]) * CURVATURE_STEP
            arguments.append((key, np.maximum(spread, 1e-300), gains[key]))
    for key, step, gain in arguments:
        f = []
        for k in (-1, 0, 1):
            shifted = dict(values)
            shifted[key] = values[key] + k * step
            f.append(np.asarray(factor.evaluate(shifted, t), dtype=float))
        second = f[2] - 2 * f[1] + f[0]
        if np.all(np.abs(second) <= 64 * np.finfo(float).eps * (np.abs(f[2]) + np.abs(f[0]))):
            continue   # linear in it (y*u): round-off, not curvature
        curvature = curvature + 0.5 * variance * gain * second / step ** 2
    return curvature


def derivative_noise_gain(t, order, step, widen=1):
    """The variance that white noise of unit variance on the samples gives the estimate
    of :func:`derivative_estimate` at each sample: ``sum_j M[i, j]**2``, the estimate
    being ``M y``.

    Exact on any grid by linearity: unit impulses further apart than a window (in
    samples) never reach the same estimate, so one estimate per residue of the
    samples modulo that distance gives every row's weights.

    Parameters
    ----------
    t : numpy.ndarray
        The sample times of a segment.
    order, step, widen
        As in :func:`derivative_estimate`.

    Returns
    -------
    numpy.ndarray
    """
    t = np.asarray(t, dtype=float)
    median = step if step is not None else float(np.median(np.diff(t)))
    window = widen * DEFAULT_WINDOW_STEPS * median
    reach = int(np.max(np.searchsorted(t, t + 1.5 * window) - np.arange(len(t)))) + 1
    reach = min(reach, len(t))
    gain = np.zeros(len(t))
    for residue in range(reach):
        impulses = np.zeros(len(t))
        impulses[residue::reach] = 1.0
        gain += derivative_estimate(impulses, t, order, step, widen) ** 2
    return gain


def factor_sensitivity(factor, output, values, t, h=None, variance=0.0, largest=None):
    """Derivative of a factor's samples with respect to the output's (central differences
    of step ``h``, by default 1e-6 of the largest output sample); with ``variance``, of
    the factor less its :func:`noise_curvature` (its step from ``largest``, the largest
    output sample of the segment, by default of ``values``)."""
    y = values[output]
    largest = max(float(np.max(np.abs(y))), 1e-300) if largest is None else largest
    h = 1e-6 * largest if h is None else h
    sides = []
    for shift in (h, -h):
        moved = dict(values)
        moved[output] = y + shift
        sides.append(np.asarray(factor.evaluate(moved, t), dtype=float)
                     - noise_curvature(factor, output, moved, t, variance, 1e-3 * largest))
    return (sides[0] - sides[1]) / (2 * h) * np.ones(len(t))


#: The fewest contiguous samples the differentiator of a derivative inside a nonlinear
#: factor needs (its default window on a uniform grid): shorter segments are dropped,
#: as those shorter than a window are.
DERIVATIVE_SAMPLES = DEFAULT_WINDOW_STEPS + 1


def add_derivatives(model, segments, estimator):
    for seg in segments:
        for name, k in model.needs_derivatives:
            seg.values[(name, k)] = estimator(seg.values[name], seg.t, k, seg.step)


def derivative_estimate(y, t, order, step, widen=1):
    """Derivative inside a nonlinear factor: the algebraic differentiator, on its default
    window or on one ``widen`` times as long (the differentiator's error check)."""
    window = None
    if widen != 1:
        window = widen * DEFAULT_WINDOW_STEPS * (
            step if step is not None else float(np.median(np.diff(t))))
    if step is not None:
        return algebraic_derivative(y, step, derivative=order, window=window)
    return algebraic_derivative(y, time=t, derivative=order, window=window)
