"""The estimator core: one state, one ``advance`` per backend.

Like :func:`scipy.signal.lfilter` with ``zi``, the estimator of a model is a function
of explicit state::

    state = new_state(module, points=6, filter_order=2, dt=1e-3)
    estimates, state = advance(state, channels)          # channels: (n_channels, m)
    estimates, state = advance(state, more_channels)     # continues where it stopped

A batch estimate is a fresh state and one chunk; a stream is successive chunks, with
the same numbers bit for bit however it is cut (within one backend).  The channels are
the signals that drive the generated module's integrator chains, in its ``CHANNELS``
order.  At every sample the core steps every chain ``(signal, power, depth)`` with the
causal rule of :mod:`algid.signals._quadrature`, evaluates ``P``, ``Q`` and Cramer's
numerators and denominator with the generated algebra, integrates those
``filter_order`` more times (the invariant filter ``1/s**p``) and divides (NaN where the
denominator is zero or not finite).

The state (:class:`EstimatorState`, laid out by :func:`integrator_layout`) holds per
integrator its integral and its last ``points - 1`` integrand samples, the samples since
the origin and, during the start-up, the first samples.  The start-up is decided here,
once, for every backend; a rule of more than :data:`EARLY_POINTS` points gives its first
estimate as early as that rule would (:func:`first_estimate`).  The backends, ``"numpy"``
(:mod:`algid.estimation._core_numpy`) and ``"numba"`` (:mod:`algid.estimation._core_numba`,
``algid[fast]``), perform the same operations in the same order.  The user guide, "How
streaming works", has the start-up and the backends in full.
"""

from __future__ import annotations

import dataclasses
from functools import cache
from types import ModuleType

import numpy as np

from algid.errors import InputDataError
from algid.estimation._backends import require_backend
from algid.estimation._options import check_filter_order, check_quadrature_points

__all__ = ["EstimatorState", "IntegratorLayout", "integrator_layout", "layout_of", "new_state",
           "advance", "advance_rows", "output_array", "first_estimate", "shortest_record",
           "EARLY_POINTS"]

#: Rules of more points than this report their first estimates as early as this one,
#: from the rules of as many points as samples have arrived (:func:`first_estimate`).
EARLY_POINTS = 6


def first_estimate(points: int) -> int:
    """The first sample after the origin that has an estimate.

    A rule of ``q <= EARLY_POINTS`` points has its first estimate at sample ``q - 1``,
    once its start-up is complete.  A rule of more points reports samples
    ``EARLY_POINTS - 1 .. q - 2`` with the rules of ``n + 1`` points (the polynomial
    through all the samples so far), then its own from sample ``q - 1`` on.

    Parameters
    ----------
    points : int
        Points of the quadrature rule.

    Returns
    -------
    int
        ``min(points, EARLY_POINTS) - 1``: the estimates of the samples before it are NaN.
    """
    return min(int(points), EARLY_POINTS) - 1


def shortest_record(points: int) -> int:
    """The fewest samples a batch estimate takes: twice the samples up to the first
    estimate, at least 8 (12 for the rules of 6 to 9 points, which report from the
    same sample).

    Parameters
    ----------
    points : int
        Points of the quadrature rule.

    Returns
    -------
    int
    """
    return max(2 * (first_estimate(points) + 1), 8)


@dataclasses.dataclass
class EstimatorState:
    """Everything an estimator remembers between chunks; its size does not grow.

    Attributes
    ----------
    model : module
        The generated estimator module (:func:`algid.models._registry.load_model`).
    points : int
        Points of the quadrature rule.
    filter_order : int
        Order ``p`` of the invariant filter ``1/s**p``.
    dt : float
        Sampling step [s].
    divisors : ndarray, shape (n_channels,)
        Every channel is divided by its divisor before use (a known mass).
    n_seen : int
        Samples since the time origin.
    integrals : ndarray, shape (n_integrators,)
        Integral of every integrator up to the last sample.
    history : ndarray, shape (n_integrators, points - 1)
        The last ``points - 1`` integrand samples of every integrator, oldest first.
    startup : ndarray, shape (n_channels, points)
        The first samples of the channels while fewer than ``points`` have arrived.
    companion : EstimatorState or None
        The state of the companion estimator that
        :func:`algid.estimation._numerical_error.advance_with_error` compares with, advanced with
        this one; None without.
    recent_errors : ndarray or None
        With a companion: the last raw numerical errors (:mod:`algid.estimation._numerical_error`).
    channel_max, channel_last : ndarray or None
        With a companion: the largest absolute value of every channel since the time
        origin, and its last value (both divided by its divisor), for the
        identifiability checks.
    propagation : Propagation or None
        With a companion whose estimate can be propagated: what the propagation
        carries (:mod:`algid.estimation._error_propagation`); None without.
    undetermined : tuple of int
        With a companion: the parameters (indices) that the data left undetermined at
        the last check (:mod:`algid.estimation._numerical_error`).
    early : bool
        Whether samples ``first_estimate(points) .. points - 2`` get the estimates of
        the rules of fewer points (:func:`first_estimate`); False for an estimator whose
        first samples nobody reads (a re-anchored one, before it is reported), which
        then skips their integrations and leaves them NaN.
    """

    model: ModuleType
    points: int
    filter_order: int
    dt: float
    divisors: np.ndarray
    n_seen: int
    integrals: np.ndarray
    history: np.ndarray
    startup: np.ndarray
    companion: EstimatorState | None = None
    recent_errors: np.ndarray | None = None
    channel_max: np.ndarray | None = None
    channel_last: np.ndarray | None = None
    undetermined: tuple = ()
    early: bool = True
    propagation: object = None

    def copy(self) -> EstimatorState:
        """An independent state that continues from the same point.

        Returns
        -------
        EstimatorState
            A copy whose arrays are not shared with this state (the model is shared).
        """
        return dataclasses.replace(self, divisors=self.divisors.copy(),
                                   integrals=self.integrals.copy(),
                                   history=self.history.copy(), startup=self.startup.copy(),
                                   companion=None if self.companion is None
                                   else self.companion.copy(),
                                   recent_errors=None if self.recent_errors is None
                                   else self.recent_errors.copy(),
                                   channel_max=None if self.channel_max is None
                                   else self.channel_max.copy(),
                                   channel_last=None if self.channel_last is None
                                   else self.channel_last.copy(),
                                   propagation=None if self.propagation is None
                                   else self.propagation.copy())

    def restart(self, early: bool = True) -> None:
        """Move the time origin to the next sample (re-anchoring): forget the past.

        Parameters
        ----------
        early : bool, optional
            The new value of :attr:`early`, for this state and its companion.
        """
        self.early = early
        self.n_seen = 0
        self.integrals.fill(0.0)
        self.history.fill(0.0)
        self.startup.fill(0.0)
        if self.companion is not None:
            self.companion.restart(early)
        if self.recent_errors is not None:
            self.recent_errors.fill(0.0)
        if self.channel_max is not None:
            self.channel_max.fill(0.0)
        if self.propagation is not None:
            self.propagation.active = False
            self.propagation.captured.clear()
        self.undetermined = ()

    def magnitude(self) -> float:
        """Largest absolute value held: integrals, carried and buffered samples.

        Returns
        -------
        float
            The largest absolute value, 0.0 if nothing is held.
        """
        held = [self.integrals, self.history]
        if self.n_seen < self.points:
            held.append(self.startup[:, :self.n_seen])
        own = max([0.0] + [float(np.max(np.abs(a))) for a in held if a.size])
        return own if self.companion is None else max(own, self.companion.magnitude())


@dataclasses.dataclass(frozen=True)
class IntegratorLayout:
    """Where every integrator of a model sits in :class:`EstimatorState`.

    Attributes
    ----------
    chains : tuple of (channel, power, depth)
        The chains of the generated module, with the index of their channel.
    levels : tuple of tuple of int
        ``levels[l - 1]``: the chains that have a level ``l``, in state order.  The
        integrators of chain level ``l`` are consecutive, level after level; then come
        the filter integrators, filter level after filter level, each with the
        numerators in ``PARAMETERS`` order and the denominator last.
    kernels : tuple of (level, row)
        For every entry of ``KERNELS``: its level and its row among ``levels[level -
        1]`` (the chain's index for level 0).
    n_chain_integrators : int
    n_lanes : int
        Numerators and denominator: ``len(PARAMETERS) + 1``.
    """

    chains: tuple
    levels: tuple
    kernels: tuple
    n_chain_integrators: int
    n_lanes: int

    def n_integrators(self, filter_order: int) -> int:
        """Number of integrators with a filter of order ``filter_order``.

        Parameters
        ----------
        filter_order : int
            Order ``p`` of the invariant filter ``1/s**p``.

        Returns
        -------
        int
            Chain integrators plus ``n_lanes * filter_order`` filter integrators.
        """
        return self.n_chain_integrators + self.n_lanes * filter_order

    def level_start(self, level: int) -> int:
        """Index of the first integrator of chain level ``level >= 1``.

        For ``level = depth + 1`` this is the index of the first filter integrator.

        Parameters
        ----------
        level : int
            Chain level, ``1 .. depth + 1``.

        Returns
        -------
        int
            Index in :attr:`EstimatorState.integrals`.
        """
        return sum(len(rows) for rows in self.levels[:level - 1])


def layout_of(chains, kernels, channels, n_parameters) -> IntegratorLayout:
    """The :class:`IntegratorLayout` of the tables of a generated module.

    Chains are ordered by decreasing depth (stable), so that the chains that have a
    given level come first and a level is a contiguous block of rows.

    Parameters
    ----------
    chains : sequence of (signal, power, depth)
        ``CHAINS`` of the generated module.
    kernels : sequence of (signal, power, level)
        ``KERNELS`` of the generated module.
    channels : sequence of str
        ``CHANNELS`` of the generated module (the signal names, in channel order).
    n_parameters : int
        Number of ``PARAMETERS`` of the generated module.

    Returns
    -------
    IntegratorLayout
        The layout.
    """
    channels = tuple(channels)
    order = sorted(range(len(chains)), key=lambda c: -chains[c][2])
    ordered = tuple((channels.index(chains[c][0]), chains[c][1], chains[c][2]) for c in order)
    depth = max(d for _, _, d in ordered)
    levels = tuple(tuple(i for i, (_, _, d) in enumerate(ordered) if d >= level)
                   for level in range(1, depth + 1))
    where = {(chains[c][0], chains[c][1]): i for i, c in enumerate(order)}
    placed = tuple((level, where[(signal, power)]) for signal, power, level in kernels)
    return IntegratorLayout(chains=ordered, levels=levels, kernels=placed,
                            n_chain_integrators=sum(len(rows) for rows in levels),
                            n_lanes=n_parameters + 1)


@cache
def integrator_layout(module: ModuleType) -> IntegratorLayout:
    """The :class:`IntegratorLayout` of a generated module (see :func:`layout_of`)."""
    return layout_of(module.CHAINS, module.KERNELS, module.CHANNELS, len(module.PARAMETERS))


def new_state(module, *, points, filter_order, dt, divisors=None) -> EstimatorState:
    """A fresh state, with the time origin at the next sample.

    Parameters
    ----------
    module : module
        Generated estimator module (:func:`algid.models._registry.load_model`).
    points : int
        Points of the quadrature rule (see :mod:`algid.signals._quadrature`).
    filter_order : int
        Order ``p >= 0`` of the invariant filter ``1/s**p``.
    dt : float
        Sampling step [s].
    divisors : sequence of float, optional
        One per channel: the channel is divided by it (default: all 1).

    Returns
    -------
    EstimatorState

    Raises
    ------
    InputDataError
        If an option is invalid.
    """
    check_filter_order(filter_order)
    check_quadrature_points(points)
    n_channels = len(module.CHANNELS)
    div = np.ones(n_channels) if divisors is None else np.array(divisors, dtype=float)
    for name, values in (("dt", np.array([dt], dtype=float)), ("divisors", div)):
        if values.shape != ((n_channels,) if name == "divisors" else (1,)) or \
                not (np.isfinite(values).all() and (values > 0).all()):
            raise InputDataError(f"{name} must be positive numbers, got {values.tolist()!r}"
                                 if name == "divisors" else
                                 f"dt must be a positive number, got {dt!r}")
    n_int = integrator_layout(module).n_integrators(int(filter_order))
    return EstimatorState(model=module, points=int(points), filter_order=int(filter_order),
                          dt=float(dt), divisors=div, n_seen=0, integrals=np.zeros(n_int),
                          history=np.zeros((n_int, points - 1)),
                          startup=np.zeros((n_channels, points)))


_FLOAT64 = np.dtype(np.float64)
_RUNNERS = {}


def _as_channels(state, channels):
    """The chunk as a tuple of equally long float64 1-D arrays, one per channel."""
    n_channels = len(state.divisors)
    if type(channels) is tuple and len(channels) == n_channels:
        shape = channels[0].shape if type(channels[0]) is np.ndarray else None
        if shape is not None and len(shape) == 1:
            for r in channels:  # already what the backends take?
                if not (type(r) is np.ndarray and r.dtype is _FLOAT64 and r.shape == shape
                        and r.flags.c_contiguous):
                    break
            else:
                return channels
    try:
        rows = tuple(np.ascontiguousarray(c, dtype=np.float64) for c in channels)
    except (TypeError, ValueError):
        raise InputDataError("channels must be a sequence of 1-D arrays of numbers") from None
    if len(rows) != n_channels or any(r.ndim != 1 or r.shape != rows[0].shape for r in rows):
        raise InputDataError(f"channels must be {n_channels} equally long 1-D arrays "
                             f"({', '.join(state.model.CHANNELS)}), got shapes "
                             f"{[r.shape for r in rows]}")
    return rows


def advance(state, channels, *, backend="numpy", out=None):
    """Estimates over one chunk of samples, advancing ``state``.

    Parameters
    ----------
    state : EstimatorState
        From :func:`new_state`; updated in place (and returned).
    channels : array_like, shape (n_channels, m), or sequence of n_channels arrays
        The chunk: samples of every channel in the generated module's ``CHANNELS``
        order, uniformly sampled with ``state.dt`` and continuing the samples seen
        before (the caller checks this).  ``m`` may be 0.
    backend : {"numpy", "numba"}, optional
        Which implementation advances the state.  Default ``"numpy"``.
    out : ndarray, shape (n_parameters, m), optional
        Float64 array to write the estimates into.

    Returns
    -------
    estimates : ndarray, shape (n_parameters, m)
        Row ``i`` estimates ``PARAMETERS[i]``; NaN for the first
        ``first_estimate(points)`` samples after the origin and where the denominator
        is zero or not finite.
    state : EstimatorState
        The same object, advanced past the chunk.
    """
    rows = _as_channels(state, channels)
    m = rows[0].size
    model = state.model
    out = output_array(out, (len(model.PARAMETERS), m))
    return advance_rows(state, rows, out, backend), state


def output_array(out, shape, name="out"):
    """``out`` checked to be a float64 array of ``shape``, or a new one if it is None.

    Parameters
    ----------
    out : ndarray or None
        The array given by the caller.
    shape : tuple of int
        The shape it must have.
    name : str, optional
        Its name in the message.

    Returns
    -------
    ndarray

    Raises
    ------
    InputDataError
        ``out`` is not a float64 array of that shape.
    """
    if out is None:
        return np.empty(shape)
    if not (type(out) is np.ndarray and out.shape == shape and out.dtype is _FLOAT64):
        if not (isinstance(out, np.ndarray) and out.shape == shape
                and out.dtype == np.float64):
            raise InputDataError(f"{name} must be a float64 array of shape {shape}, got "
                                 f"{getattr(out, 'shape', None)} {getattr(out, 'dtype', None)}")
    return out


def advance_rows(state, rows, out, backend="numpy"):
    """:func:`advance` on a chunk that is known to be well formed (no checks).

    For callers that advance several states on the same checked chunk (an estimator
    and its companion, :mod:`algid.estimation._numerical_error`).

    Parameters
    ----------
    state : EstimatorState
        Updated in place.
    rows : tuple of ndarray
        One C-contiguous float64 1-D array per channel, all of one length ``m``, in the
        model's ``CHANNELS`` order.
    out : ndarray, shape (n_parameters, m)
        Float64 array the estimates are written into.
    backend : {"numpy", "numba"}, optional
        Default ``"numpy"``.

    Returns
    -------
    ndarray
        ``out``.
    """
    run = _RUNNERS.get(backend)
    if run is None:
        run = _RUNNERS[backend] = require_backend(backend)
    m = rows[0].size
    if not m:
        return out
    model = state.model
    q = state.points
    seen = state.n_seen
    if seen >= q:  # the stream is under way: the common case
        run(state, integrator_layout(model), rows, out)
        return out
    if seen == 0 and m >= q:  # the chunk starts at the origin: integrate it at once
        run(state, integrator_layout(model), rows, out, from_origin=True)
        if state.early:
            _early_estimates(state, rows, out, 0, run)
        return out
    # the start-up: buffer samples 0 .. q - 1
    done = min(q - seen, m)
    for c, row in enumerate(rows):
        state.startup[c, seen:seen + done] = row[:done]
    out[:, :done] = np.nan
    state.n_seen = seen + done
    if state.early:
        _early_estimates(state, tuple(state.startup[:, :seen + done]), out[:, :done], seen,
                         run)
    if state.n_seen == q:  # sample q - 1 arrived: integrate from the origin
        first = np.empty((out.shape[0], q))
        run(state, integrator_layout(model), tuple(state.startup), first, from_origin=True)
        out[:, done - 1] = first[:, -1]
    if done < m:
        run(state, integrator_layout(model), tuple(r[done:] for r in rows), out[:, done:])
    return out


def _early_estimates(state, samples, out, offset, run):
    """Estimates of the samples ``first_estimate(q) .. q - 2`` that ``samples`` (the
    first samples from the origin) reach, by the rules of fewer points, into ``out``
    (whose column ``j`` is sample ``offset + j``)."""
    stop = min(samples[0].size, state.points - 1)
    for n in range(max(first_estimate(state.points), offset), stop):
        early = new_state(state.model, points=n + 1, filter_order=state.filter_order,
                          dt=state.dt, divisors=state.divisors)
        column = np.empty((out.shape[0], n + 1))
        run(early, integrator_layout(state.model), tuple(s[:n + 1] for s in samples), column,
            from_origin=True)
        out[:, n - offset] = column[:, -1]
