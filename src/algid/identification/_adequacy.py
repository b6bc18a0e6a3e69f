"""Whether a model explains the records within the noise: the adequacy test of
:func:`algid.identify`.

A right model leaves in its window equations only what noise puts there; a wrong one
(a missing term, a wrong derivative order, a delay between the channels) leaves a
systematic misfit, and its estimates then depend on how the data are weighted, or a
term it lacks explains the misfit.  The test asks three questions:

1. *Misfit*: the residual energy of the equations (highest multiplicity) per unit of
   white output-noise weight, ``r^T r / (theta_bar^T Q theta_bar)`` (``Q`` from
   ``WindowProblem.noise_grams``), over the bound the samples put on the output-noise
   variance (``WindowProblem.noise_bound``).  Output noise gives at most about 1 at any noise
   level (the bound is above the true variance); the limit is :data:`MISFIT_LIMIT`,
   raised on few independent windows to a chi-square quantile (:func:`misfit_limit`).
2. *Shift*: the estimates on windows twice as long (lower frequencies) and half as long
   (higher; their error counts the multiplicities' difference, their quadrature being
   the less accurate) against the result's: a model that holds gives the same
   parameters, within the standard errors.  The shift is the largest ``|theta_2 -
   theta_1| / sqrt(se_1^2 + se_2^2)`` over the parameters; the limit :data:`SHIFT_LIMIT`.
3. *Missing term* (asked only when the misfit exceeds its limit): the equation with
   a power of the output added (:data:`POWERS`: ``y``, ``y**2``, ``y**3``; fresh
   parameters), fitted by least squares on the same windows, against the model so
   fitted: a term that leaves less than :data:`EXPLAINED` of the misfit explains it
   (:func:`missing_terms`), so that a linear model of a cubic spring warns even where
   its estimates hardly shift.

It warns when the misfit exceeds its limit and the shift does or a term explains it.
The misfit alone warns of nothing: input noise or an unmodelled disturbance (the EMPS
force) is not output noise either, but where it does not move the estimates their HAC
standard errors already count it.  Nor the shift alone: with a loose noise bound (few
samples per period, Silverbox) estimates that fit within it may still move.  Its hits
and false alarms are measured by ``python -m benchmarks.adequacy`` (the user guide,
"Real data: identify", sums them up).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from algid.errors import AlgidError, InputDataError
from algid.identification._methods import METHODS

__all__ = ["Adequacy", "model_adequacy", "missing_terms", "misfit_ratio", "misfit_limit",
           "MISFIT_LIMIT", "MISFIT_FALSE_ALARM", "SHIFT_LIMIT", "EXPLAINED", "POWERS"]

#: Misfit (per unit of output-noise weight, over the noise bound) beyond which the
#: residuals are not output noise; raised, on few independent windows, to the level
#: that output noise exceeds with probability :data:`MISFIT_FALSE_ALARM`.
MISFIT_LIMIT = 2.0

#: Probability that the misfit of white output noise exceeds the raised limit.
MISFIT_FALSE_ALARM = 1e-4

#: Shift of the estimates between window lengths (in standard errors of the difference)
#: beyond which the misfit biases them.
SHIFT_LIMIT = 5.0

#: Share of the model's misfit below which the model with a candidate term leaves it:
#: the term explains most of the misfit.
EXPLAINED = 0.5

#: Powers of the output tried as the terms a model may lack (the first: the output).
POWERS = (1, 2, 3)


@dataclass(frozen=True)
class Adequacy:
    """The adequacy test of an identified model (see the module notes).

    Attributes
    ----------
    misfit : float
        Residual energy per unit of output-noise weight over the output-noise bound.
    misfit_limit : float
        The limit it is compared with.
    shift : float
        Largest difference between the estimates on the two window lengths, in
        standard errors of the difference (NaN when no second window fits).
    parameter : str or None
        The parameter that shifts most.
    window, other_window : float
        The window of the result and the one compared with (s).
    missing : tuple of str
        Terms that, added to the equation, explain most of its misfit (empty when none
        does or the misfit is within its limit).
    explained : float
        The misfit with those terms over the model's (least squares, same window; NaN
        when not asked).

    Examples
    --------
    >>> from algid.identification import identify
    >>> from algid.simulation import simulate
    >>> sim = simulate("sine", frequency=3.0, duration=10.0, rate=100.0, noise_std=1e-4, seed=0)
    >>> record = {"t": sim.t, "f": sim.f, "x": sim.x}
    >>> result = identify(record, "x'' + B*x' + K*x = f", "B K")
    >>> adequacy = result.adequacy
    >>> adequacy.adequate, adequacy.misfit < adequacy.misfit_limit, adequacy.warnings()
    (True, True, [])
    """

    misfit: float
    misfit_limit: float
    shift: float
    parameter: str | None
    window: float
    other_window: float
    missing: tuple = ()
    explained: float = np.nan

    @property
    def adequate(self):
        """False when the misfit, beyond its limit, shifts the estimates or has a cause.

        A cause: a term the model lacks that explains most of it (``missing``).
        """
        return not (self.misfit > self.misfit_limit
                    and (self.shift > SHIFT_LIMIT or bool(self.missing)))

    def warnings(self):
        """One-line warnings (none for an adequate model).

        Returns
        -------
        list of str
        """
        if self.adequate:
            return []
        lines = []
        if self.missing:
            terms = " and ".join(self.missing)
            lines.append(f"the model leaves a misfit {self.misfit:.3g} times what output noise "
                         f"allows, and a term in {terms} would explain most of it (the "
                         f"misfit falls to {self.explained:.2g} of it): a missing term?")
        if not self.shift > SHIFT_LIMIT:
            return lines
        return lines + [f"the model does not explain the data within the noise: the equations' "
                f"misfit is {self.misfit:.3g} times what output noise allows, and "
                f"{self.parameter} on {self.other_window:.4g} s windows differs from "
                f"its estimate on {self.window:.4g} s windows by {self.shift:.3g} "
                f"standard errors (a missing term, a wrong derivative order or a delay "
                f"between the signals?)"]


def misfit_ratio(problem, length, multiplicity, theta):
    """The misfit of the window equations over what white output noise allows.

    Their residual energy per unit of white output-noise weight, over the output-noise
    bound (inf when the bound is zero and the misfit is not).

    Parameters
    ----------
    problem : algid.identification._window_problem.WindowProblem
        The windowed problem (``rows``, ``noise_grams``, ``noise_bound``).
    length, multiplicity : int
        Window length (samples) and kernel multiplicity.
    theta : numpy.ndarray
        The estimate, in the units of ``problem.rows`` (``problem.to_rows``).

    Returns
    -------
    float
    """
    A, b, _ = problem.rows(length, multiplicity)
    r = b - A @ theta
    theta_bar = np.append(theta, -1.0)
    weight = float(np.einsum("i,wij,j->", theta_bar, problem.noise_grams(length, multiplicity),
                             theta_bar))
    energy = float(r @ r)
    bound = problem.noise_bound()
    if energy == 0:
        return 0.0
    if not (weight > 0 and bound > 0):
        return np.inf
    return energy / weight / bound


def model_adequacy(problem, length, fit, solve, method, min_length, stride):
    """The adequacy test of an identified model (see the module notes).

    Parameters
    ----------
    problem : algid.identification._window_problem.WindowProblem
        The windowed problem the estimate was made on.
    length : int
        Its window length (samples).
    fit : algid.identification._identify._Fit
        The estimate (``theta``, ``stderr``, ``n_windows``, and ``separate``: the
        estimate of every kernel multiplicity).
    solve : callable
        ``solve(problem, length, multiplicities, instruments, method=...)``: the
        estimate on windows of another length (``algid.identification._identify._solve``).
    method : str
        Its method, a name of :data:`algid.identification._methods.METHODS` (an
        instrumental one: instruments from the simulated output, as the estimate's).
    min_length : int
        Shortest window the multiplicities allow (samples).
    stride : int
        Samples between the starts of the estimate's consecutive windows.

    Returns
    -------
    Adequacy
    """
    step = problem.step
    multiplicities = tuple(fit.separate)
    misfit = misfit_ratio(problem, length, max(fit.separate), problem.to_rows(fit.theta))
    longest = max(len(s) for s in problem.segments)
    shift, parameter, other = np.nan, None, np.nan
    # half as long windows have a less accurate quadrature: their own error counts the
    # multiplicities' difference (the window rule's bias estimate)
    for candidate in (2 * length - 1, (length + 1) // 2):
        if not min_length <= candidate <= longest:
            continue
        try:
            instruments = None if not METHODS[method].instrumental else {
                a: problem.rows(candidate, a, "simulated") for a in multiplicities}
            second = solve(problem, candidate, multiplicities, instruments, method=method)
        except (InputDataError, np.linalg.LinAlgError):
            continue
        error = second.stderr
        if candidate < length:
            separate = list(second.separate.values())
            error = np.maximum(error, np.abs(separate[0] - separate[-1]))
        difference = np.abs(second.theta - fit.theta)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.where(difference > 0, difference / np.hypot(fit.stderr, error), 0.0)
        worst = int(np.argmax(z))
        if not z[worst] <= shift:   # the larger of the two (NaN: the first)
            shift, parameter = float(z[worst]), problem.parameters[worst]
            other = (candidate - 1) * step
    return Adequacy(misfit, misfit_limit(fit.n_windows, length, len(fit.theta), stride),
                    shift, parameter, (length - 1) * step, other)


def missing_terms(adequacy, model, refit):
    """The adequacy test with the terms the model lacks that explain most of its misfit.

    Each power of the output in :data:`POWERS` (then all of them together, if none does
    alone) is added to the equation with a fresh parameter; it explains the misfit when
    the equation's least-squares misfit falls below :data:`EXPLAINED` of the model's.
    A candidate whose fit is refused (inseparable from the model's terms) is skipped.

    Parameters
    ----------
    adequacy : Adequacy
        The test of the model.
    model : algid.models._model.Model
        The model (``equation``, ``parameters``, ``signals``, ``output``).
    refit : callable
        ``refit(equation, parameters)``: the misfit of an equation fitted by least
        squares on the model's window (raising :class:`algid.errors.AlgidError` when
        refused).

    Returns
    -------
    Adequacy
        ``adequacy`` with ``missing`` and ``explained`` set.
    """
    taken = set(model.parameters) | set(model.signals)
    prefix = "_c"
    while any(name.startswith(prefix) for name in taken):
        prefix += "c"  # a leading "__" is reserved
    candidates = {model.output + (f"**{p}" if p > 1 else ""): f"{prefix}{p}" for p in POWERS}
    left, equals, right = model.equation.partition("=")

    def misfit(terms):
        added = " + ".join(f"{candidates[t]}*{t}" for t in terms)
        equation = f"{left.rstrip()} + {added} {equals}{right}" if terms else model.equation
        try:
            with np.errstate(all="ignore"):
                return refit(equation, list(model.parameters) + [candidates[t] for t in terms])
        except (AlgidError, np.linalg.LinAlgError):
            return np.nan

    base = misfit(())
    if not base > 0:
        return replace(adequacy, missing=(), explained=np.nan)
    shares = {(t,): misfit((t,)) / base for t in candidates}
    if not any(share < EXPLAINED for share in shares.values()):
        shares[tuple(candidates)] = misfit(tuple(candidates)) / base
    best = min(shares, key=lambda terms: (not shares[terms] < EXPLAINED, len(terms),
                                          np.nan_to_num(shares[terms], nan=np.inf)))
    if not shares[best] < EXPLAINED:
        return replace(adequacy, missing=(), explained=float(np.nanmin(
            [*shares.values(), np.inf])))
    return replace(adequacy, missing=best, explained=float(shares[best]))


def misfit_limit(n_windows, length, n_parameters, stride):
    """The misfit limit on ``n_windows`` windows of ``length`` samples.

    The larger of :data:`MISFIT_LIMIT` and the level that white output noise exceeds
    with probability :data:`MISFIT_FALSE_ALARM`, its residual energy being chi-square
    with as many degrees of freedom as independent windows, less the parameters.

    Parameters
    ----------
    n_windows, length, n_parameters : int
        Windows stacked, their length (samples) and the parameters estimated.
    stride : int
        Samples between the starts of consecutive windows.

    Returns
    -------
    float
    """
    from scipy.special import gammaincinv

    freedom = max(1.0, n_windows * stride / length - n_parameters)
    quantile = 2.0 * gammaincinv(freedom / 2.0, 1.0 - MISFIT_FALSE_ALARM) / freedom
    return max(MISFIT_LIMIT, float(quantile))
