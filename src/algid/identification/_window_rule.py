"""The window rule of :func:`algid.identify` and the limits of a window's length.

A window must hold enough samples for the kernels (:func:`min_length`: a kernel of
multiplicity ``a`` vanishes to order ``a`` at both window ends, and its sampled sum is
spectrally accurate from about ``a + 4`` samples on) and leave enough non-overlapping
windows for the covariance of the estimate (:func:`needed_windows`: the parameters plus
:data:`MIN_SPARE_WINDOWS`; the HAC covariance estimates a ``p x p`` middle from the
residuals).  An explicit window outside these limits is refused (:func:`window_length`),
and the automatic rule (:func:`choose_window`) only looks at windows within them: on a
geometric grid of lengths (:func:`window_grid`, ratio 1.25, from :func:`min_length` up
to the longest window that leaves :func:`needed_windows` non-overlapping ones,
:func:`longest_window`, which is also a grid point), it keeps the one minimising
:func:`window_criterion`, among those on which the parameters are separable
(:mod:`algid.identification._window_basis`: within the output noise and the equations'
misfit); where no window is, the one that separates them best.  (The grid used to stop
at a thirtieth of the data and 4096 samples: on 30 s records at 1 kHz of a 1 Hz mode it
stopped at 0.89 s where 2.5 s was allowed and the best windows were near 1.4 s, and on
2 s records of 1.7 periods it refused parameters that windows past 0.07 s separate.)
Where the parameters are refused or poorly separated, :func:`window_advice` says which
windows, in seconds, separate them, or how much less noise would.
"""

from __future__ import annotations

import numpy as np

from algid.errors import InputDataError, ModelError
from algid.identification._window_basis import (
    FREE_NOISE_RATIO,
    WEAK_NOISE_RATIO,
    WEAK_RATIO,
)

__all__ = ["WindowFit", "check_multiplicities", "window_grid", "grid_lengths",
           "window_criterion", "coarse_to_fine",
           "choose_window", "window_advice", "noise_factor", "window_length", "min_length",
           "longest_window",
           "independent_windows", "needed_windows", "MIN_SPARE_WINDOWS", "NEGLIGIBLE_TERM",
           "HAC_WINDOWS"]

#: Non-overlapping windows needed beyond one per parameter.
MIN_SPARE_WINDOWS = 8

#: Non-overlapping windows the automatic rule asks of a window whose standard errors come
#: from the residuals' own (HAC) covariance: with fewer, that estimate of a ``p x p``
#: middle is too noisy to compare windows by (on the EMPS records, windows of 14 made the
#: friction model's error look 30 times smaller than on short windows, and the rule
#: kept an estimate of M 4 % from the published value, 7 reported standard errors).  A
#: covariance of the output noise through the kernels needs no more than
#: :func:`needed_windows`.
HAC_WINDOWS = 30

#: The automatic rule solves every ``RULE_COARSE``-th length of its grid, then those
#: between the best one's neighbours (:func:`choose_window`): 15 lengths in place of 32
#: on a record of 10**5 samples.
RULE_COARSE = 3

#: A term this small next to the known side (5 %) counts as negligible in the window rule.
NEGLIGIBLE_TERM = 0.05


class WindowFit:
    """One estimate on one window length: parameters, covariance, diagnostics.

    Everything in the records' units.

    Parameters
    ----------
    theta : numpy.ndarray
        The estimate (of the highest multiplicity).
    covariance : numpy.ndarray
        Its covariance.
    separate : dict
        Multiplicity -> the estimate of that multiplicity alone.
    scale : numpy.ndarray
        Per parameter, the effect of a unit error on the equations, relative to their
        known side.
    residuals : numpy.ndarray
        The residuals of the window equations.
    n_windows : int
        Windows stacked.
    separation : Separability, optional
        :func:`algid.identification._window_basis.separability` of the highest multiplicity.
    noise_model : bool
        Whether the covariance is that of output noise through the kernels (else the
        residuals' own, HAC, which needs many independent windows: :data:`HAC_WINDOWS`).
    """

    def __init__(self, theta, covariance, separate, scale, residuals, n_windows,
                 separation=None, noise_model=False):
        self.noise_model = noise_model
        self.theta = theta
        self.covariance = covariance
        self.separate = separate          # multiplicity -> estimate alone
        self.scale = scale                # effect of a unit parameter error on the equation
        self.residuals = residuals
        self.n_windows = n_windows
        self.separation = separation      # Separability of the highest multiplicity
        # how far the estimate moves with the derivatives inside nonlinear factors
        # estimated on twice as long a differentiator window (set by identify)
        self.differentiator_error = 0.0

    @property
    def stderr(self):
        """Per parameter: the standard error."""
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))

    @property
    def numerical_error(self):
        """Per parameter: the difference between the lowest and highest multiplicity,
        plus :attr:`differentiator_error`."""
        values = [self.separate[a] for a in sorted(self.separate)]
        return np.abs(values[-1] - values[0]) + self.differentiator_error

    @property
    def negligible(self):
        """Per parameter: the value whose term is 5 % of the known side
        (:data:`NEGLIGIBLE_TERM`) on this window."""
        return NEGLIGIBLE_TERM / self.scale

    def relative_error(self, negligible=None):
        """Per parameter: max(standard error, numerical error), relative to the value.

        Relative to the parameter, or, for a parameter near zero, to the value whose term
        is 5 % of the known side.

        Parameters
        ----------
        negligible : numpy.ndarray, optional
            That value per parameter; by default this window's (:attr:`negligible`).

        Returns
        -------
        numpy.ndarray
        """
        negligible = self.negligible if negligible is None else negligible
        reference = np.maximum(np.abs(self.theta), negligible)
        return np.maximum(self.stderr, self.numerical_error) / reference


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


def independent_windows(problem, length):
    """Windows of ``length`` samples that share no sample, over the segments.

    Parameters
    ----------
    problem : object
        The windowed problem of :func:`algid.identify` (its ``segments``).
    length : int
        Samples per window.

    Returns
    -------
    int
    """
    return sum(len(seg) // length for seg in problem.segments)


def needed_windows(problem):
    """Non-overlapping windows a window length must leave.

    The parameters plus :data:`MIN_SPARE_WINDOWS` (the HAC covariance estimates a
    ``p x p`` middle from the residuals); the automatic rule's longest window too.

    Parameters
    ----------
    problem : object
        The windowed problem of :func:`algid.identify` (its ``parameters``).

    Returns
    -------
    int
    """
    return len(problem.parameters) + MIN_SPARE_WINDOWS


def window_length(window, step, problem, multiplicities):
    """Samples of an explicit window, refused if outside the limits of this module.

    Parameters
    ----------
    window : float or None
        Window length (s); None for the automatic rule.
    step : float
        Sampling step (s).
    problem : object
        The windowed problem of :func:`algid.identify`.
    multiplicities : tuple of int
        Kernel multiplicities.

    Returns
    -------
    int or None
        Samples per window (None for ``window=None``).

    Raises
    ------
    InputDataError
        One line with the limits in seconds, for a window too short for the kernels,
        longer than the records, or leaving too few non-overlapping windows.
    """
    if window is None:
        return None
    window = float(window)
    if not np.isfinite(window) or window <= 0:
        raise InputDataError(f"window must be a positive number of seconds, got {window}")
    shortest = min_length(multiplicities)
    samples = window / step + 1
    longest = max(len(s) for s in problem.segments)
    limits = (f"use {(shortest - 1) * step:.4g} s ({shortest} samples) to "
              f"{longest_window(problem, shortest) * step:.4g} s")
    if samples < shortest - 0.5:
        raise InputDataError(f"window {window:g} s ({samples:.3g} samples) is shorter than "
                             f"the kernels of multiplicity {max(multiplicities)} need; "
                             f"{limits}")
    if samples > longest + 0.5:
        raise InputDataError(f"window {window:g} s ({samples:.3g} samples) is longer than "
                             f"the longest run of contiguous samples ({longest}); {limits}")
    length = int(round(samples - 1)) + 1
    count, needed = independent_windows(problem, length), needed_windows(problem)
    if count < needed:
        raise InputDataError(f"window {window:g} s ({length} samples) leaves {count} "
                             f"non-overlapping windows for {len(problem.parameters)} "
                             f"parameters (need {needed}); {limits}")
    return length


def longest_window(problem, shortest):
    """The longest window that leaves the non-overlapping windows needed.

    Parameters
    ----------
    problem : object
        The windowed problem of :func:`algid.identify`.
    shortest : int
        The shortest window (samples).

    Returns
    -------
    int
        Its span in sampling steps (samples less one).
    """
    needed = needed_windows(problem)
    longest = max(len(s) for s in problem.segments)
    while longest > shortest and independent_windows(problem, longest) < needed:
        longest = max(shortest, min(longest - 1, int(longest / 1.05)))
    return longest - 1


def check_multiplicities(model, multiplicities):
    """The kernel multiplicities as a tuple of int, refused if none or below the order.

    Parameters
    ----------
    model : algid.models._model.Model
        The model (its ``order``).
    multiplicities : sequence of int
        Kernel multiplicities.

    Returns
    -------
    tuple of int

    Raises
    ------
    ModelError
        No multiplicity, or one below the model order.
    """
    multiplicities = tuple(int(a) for a in multiplicities)
    if not multiplicities:
        raise ModelError("give at least one kernel multiplicity")
    low = min(multiplicities)
    if low < model.order:
        raise ModelError(f"kernel multiplicity {low} is below the model order "
                         f"{model.order}")
    return multiplicities


def min_length(multiplicities):
    """The fewest samples per window for the kernels of ``multiplicities``.

    Parameters
    ----------
    multiplicities : tuple of int
        Kernel multiplicities.

    Returns
    -------
    int
    """
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
    # one reference per parameter near zero for the whole grid: the known side's
    # window average shrinks on windows long against the signals' periods (the kernel
    # filters out the resonance), so each window's own 5 % value grows with the window
    # and an offset's relative error with it, though its standard error does not (on
    # 30 s records of a 1 Hz mode the offset's own ratio drove the choice from 1.4 s,
    # near the others' best, to 0.9 s)
    negligible = np.median([fits[n].negligible for n in lengths], axis=0)
    relative = [fits[n].relative_error(negligible) for n in lengths]
    relative = np.array(relative)
    best = np.min(np.where(relative > 0, relative, np.inf), axis=0)
    best = np.where(np.isfinite(best), best, 1.0)
    scores = {}
    for n, row in zip(lengths, relative):
        value = float(np.max(row / best))
        if np.isfinite(value):
            scores[n] = value
    return scores


def grid_lengths(problem, multiplicities, n_max=None):
    """The window lengths the automatic rule solves (:func:`choose_window`).

    Parameters
    ----------
    problem : object
        The windowed problem of :func:`algid.identify`.
    multiplicities : tuple of int
        Kernel multiplicities.
    n_max : int, optional
        Longest window (samples), as in :func:`choose_window`.

    Returns
    -------
    list of int
        Increasing lengths (samples); empty for records too short for any window.
    """
    n_min = min_length(multiplicities)
    allowed = longest_window(problem, n_min) + 1
    n_max = allowed if n_max is None else min(n_max, allowed)
    grid = [n for n in window_grid(n_min, max(n_min, n_max))
            if independent_windows(problem, n) >= needed_windows(problem)]
    # the longest window too (the grid may stop up to a ratio short of it): where the
    # parameters separate only on the longest windows, a fixed window there would
    # determine them, and the rule must not refuse what a fixed window determines
    if grid and n_max > grid[-1] * 1.05 \
            and independent_windows(problem, n_max) >= needed_windows(problem):
        grid.append(n_max)
    return grid


def choose_window(problem, multiplicities, solve, *, n_max=None, method="ls",
                  separations=None):
    """Window length (samples) by the rule of this module.

    Parameters
    ----------
    problem : object
        The windowed problem of :func:`algid.identify`.
    multiplicities : tuple of int
        Kernel multiplicities.
    solve : callable
        ``solve(problem, length, multiplicities, method=method)`` -> a fit with
        ``relative_error()`` and ``separation`` (a
        :class:`algid.identification._window_basis.Separability`).
    n_max : int, optional
        Longest window (samples); by default the longest that leaves
        :func:`needed_windows` non-overlapping windows (:func:`longest_window`).
    method : str
        Solver.
    separations : dict, optional
        Filled with ``{length: Separability}`` of every grid point solved (for
        :func:`window_advice`).

    Returns
    -------
    length : int
        The window kept.
    scores : dict
        Every grid point's criterion ``{length: value}``.

    Raises
    ------
    InputDataError
        Records too short for any window.
    """
    grid = grid_lengths(problem, multiplicities, n_max)
    n_min = min_length(multiplicities)
    if not grid:
        raise InputDataError(f"the records are too short: windows of at least {n_min} "
                             f"samples must leave {needed_windows(problem)} non-overlapping "
                             f"ones ({independent_windows(problem, n_min)} here)")
    fits = {}

    def solve_at(lengths):
        for length in lengths:
            if length not in fits:
                try:
                    fits[length] = _candidate(problem, length, multiplicities, solve, method)
                except np.linalg.LinAlgError:
                    continue

    coarse_to_fine(grid, solve_at, lambda: _select(problem, fits)[0] if fits else None)
    if separations is not None:
        separations.update({n: f.separation for n, f in fits.items()})
    return _select(problem, fits)


def coarse_to_fine(grid, solve_at, best):
    """Solve every :data:`RULE_COARSE`-th length of ``grid`` (and its last), then the
    lengths between the best one's neighbours there: the rule's criterion varies slowly
    with the length.

    Parameters
    ----------
    grid : list of int
        The lengths the rule may keep, increasing.
    solve_at : callable
        ``solve_at(lengths)`` solves those of ``lengths`` not yet solved.
    best : callable
        ``best()`` -> the best length among those solved, or None (none solved).
    """
    solve_at(grid[::RULE_COARSE] + grid[-1:])
    chosen = best()
    if chosen is not None:
        i = grid.index(chosen)
        solve_at(grid[max(0, i - RULE_COARSE + 1):i + RULE_COARSE])


def _select(problem, fits):
    """The rule's choice among ``fits`` (``{length: fit}``), and their criterion."""
    # windows whose standard errors can be compared: those of the output noise's
    # covariance, or HAC ones over enough independent windows (HAC_WINDOWS); the others
    # are kept only where none of these separates the parameters (short records).  A
    # window that separates them reliably comes first from either: the best by the
    # criterion among the comparable ones was often one that separates them weakly
    # (benchmarks.short_records, 4 s: 16 of 100 warned "poorly separated"; the weighted
    # method's Duffing records: 45 of 100), whose standard errors are less reliable
    trusted = {n: f for n, f in fits.items()
               if f.noise_model or independent_windows(problem, n) >= HAC_WINDOWS}
    for reliable in (True, False):
        for pool in (trusted, fits):
            scores = window_criterion(pool) if pool else {}
            separating = [n for n in scores if _separates(fits[n].separation)
                          and (not reliable or _reliable(fits[n].separation))]
            if separating:
                return min(separating, key=scores.get), scores
    scores = window_criterion(fits) if fits else {}
    if not scores:
        raise InputDataError("no window length gives a solvable system: the records are "
                             "too short or the signals do not excite the model")
    # if none does, the one that separates them best (a model of too high an order, or
    # one whose own error is the misfit on every window: algid.identify decides which,
    # once it has tested the model's adequacy on that window)
    return max(scores, key=lambda n: (fits[n].separation.noise_ratio >= FREE_NOISE_RATIO,
                                      fits[n].separation.ratio)), scores


def _candidate(problem, length, multiplicities, solve, method):
    """The fit of one candidate length, on the problem the rule solves it on (its
    ``for_window_rule``: the same equations, summed more cheaply, maybe on excerpts);
    its covariance as on every window of the records."""
    view = problem.for_window_rule(length)
    try:
        fit = solve(view, length, multiplicities, method=method)
    except (np.linalg.LinAlgError, InputDataError, ModelError):
        if view.share == 1.0:
            raise
        # excerpts that do not show what the records do (an input that moves once)
        view = problem.for_window_rule(length, every_window=True)
        fit = solve(view, length, multiplicities, method=method)
    fit.covariance = fit.covariance * view.share
    return fit


def _reliable(separation):
    return separation.ratio >= WEAK_RATIO and separation.noise_ratio >= WEAK_NOISE_RATIO


def _separates(separation):
    return not (separation.free or separation.misfit_free)


def noise_factor(separation):
    """How many times smaller the output noise (relative to the signals) would have to be
    for ``separation`` to separate the parameters reliably (1 if it does).

    Where the misfit is output noise of relative size ``e``, the smallest singular value
    of the unit-column regressors is about ``sqrt(s**2 + e**2)`` for a signal part
    ``s``, so ``ratio**2 - 1`` grows as the signal-to-noise ratio squared; the noise
    test's ratio is ``1 + S / (sigma**2 N)``, so ``noise_ratio - 1`` grows the same way.

    Parameters
    ----------
    separation : Separability

    Returns
    -------
    float
    """
    factors = [1.0]
    for value, target in ((separation.ratio ** 2 - 1, WEAK_RATIO ** 2 - 1),
                          (separation.noise_ratio - 1, WEAK_NOISE_RATIO - 1)):
        if np.isfinite(value):
            factors.append(np.sqrt(target / value) if value > 0 else np.inf)
    return float(max(factors))


def window_advice(separations, step, scores=None):
    """What would separate the parameters: which windows, or how much less noise.

    Parameters
    ----------
    separations : dict
        ``{length: Separability}`` over the grid of :func:`choose_window`.
    step : float
        Sampling step (s).
    scores : dict, optional
        The grid's criterion (:func:`window_criterion`): among the windows that separate
        the parameters reliably, the one to try is the best by it.

    Returns
    -------
    str
        One clause (no full stop), empty without ``separations``.
    """
    if not separations:
        return ""
    lengths = sorted(separations)

    def seconds(n):
        return f"{(n - 1) * step:.4g} s"

    reliable = [n for n in lengths if _reliable(separations[n])]
    separating = [n for n in lengths if _separates(separations[n])]
    if reliable:
        best = min(reliable, key=lambda n: scores.get(n, np.inf)) if scores \
            else max(reliable, key=lambda n: separations[n].ratio)
        return (f"windows of {seconds(reliable[0])} to {seconds(reliable[-1])} separate "
                f"them reliably on these records: try window={(best - 1) * step:.4g}")
    best = max(lengths, key=lambda n: (_separates(separations[n]),
                                       -noise_factor(separations[n])))
    factor = noise_factor(separations[best])
    if separating:
        where = (f"windows of {seconds(separating[0])} to {seconds(separating[-1])} "
                 f"separate them, none reliably")
    else:
        where = (f"no window these records allow ({seconds(lengths[0])} to "
                 f"{seconds(lengths[-1])}) separates them")
    clause = (f"{where} (the best, {seconds(best)}: separability "
              f"{separations[best].ratio:.3g}, noise separability "
              f"{separations[best].noise_ratio:.3g}); output noise about {factor:.2g} times "
              f"smaller relative to the signals (a larger excitation) would separate them "
              f"reliably")
    if best == lengths[-1] and len(lengths) > 1 \
            and noise_factor(separations[lengths[-2]]) > factor:
        # separability still growing at the longest window: longer records allow longer
        clause += (f", and so might longer records (windows past {seconds(best)}: the "
                   f"separation grows with the window here)")
    return clause
