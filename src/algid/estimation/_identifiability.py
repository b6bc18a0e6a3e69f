"""Whether a record determines the parameters of a model at all.

The algebraic estimate solves ``P(t) theta = Q(t)``.  Data that cannot determine a
parameter make ``P`` singular in exact arithmetic, and the computed estimate is then
round-off divided by round-off: a constant output gives a value of ``B`` (the
coefficient of ``x'``) that means nothing, and a zero force on ``m x'' + c x' + k x =
F`` gives ``m = c = k = 0``.  Such records are refused, naming the parameter.

The test looks at ``P`` and ``Q`` at the end of the record, ``T``: their entries are
sums, with small integer coefficients, of kernels ``int_0^T (T - tau)**(l - 1) /
(l - 1)! * tau**p * s(tau) dtau`` of the channels ``s``.  After a batch estimate they
are the integrals the estimator's state holds (no extra cost); otherwise (the
``lowpass`` path) they are computed from the moments ``int_0^T u**k s dtau`` (``u = tau
/ T``) with the weights of the 8-point rule of :mod:`algid.signals._quadrature` (exact for
polynomials of degree 7, so a constant signal cancels to round-off).  Each entry is
compared with the size its terms could have, ``sum |coefficient| * max|s| * T**(p + l)
* p! / (p + l)!``:

- a parameter whose column of ``P`` is below :data:`IDENTIFIABILITY_RTOL` of that size
  in every row is not excited by the data (``x`` constant: ``x' = 0`` and ``B`` is
  free);
- a known side ``Q`` below it in every row leaves the parameters' common scale free
  (``F = 0`` on ``m x'' + c x' + k x = F``);
- columns that are each excited but dependent (the smallest singular value of ``P``
  with its rows and then its columns normalised below the tolerance) leave a
  combination free; the parameters with the largest weights in it are named.

The tolerances lie far above the round-off of constant or proportional data and far
below the sizes of any record the estimator can use: long before the column of ``B``
falls to the tolerance (a step response long settled), the estimate of ``B`` has lost
its accuracy.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np

from algid.errors import InputDataError
from algid.estimation._core import integrator_layout
from algid.signals._quadrature import cumulative_integral

__all__ = ["IDENTIFIABILITY_RTOL", "MIN_SAMPLES", "check_identifiable", "undetermined",
           "undetermined_in_stream"]

#: Relative size below which a column of ``P`` (or the known side ``Q``, or the
#: smallest singular value of the normalised ``P``) counts as zero.
IDENTIFIABILITY_RTOL = 1e-10
_POINTS = 8
#: Fewer samples than this are not judged.
MIN_SAMPLES = _POINTS
_BLOCK = 2**13  # the powers of a block stay in cache


@cache
def _end_weights(points):
    """Weights of the first and last ``points`` samples in the total integral (unit
    step) by the rule of ``points`` points; every other sample weighs 1."""
    edge = 3 * points
    short = np.array([cumulative_integral(row, 1.0, points=points)[-1]
                      for row in np.eye(edge)])
    return short[:points], short[-points:]


@cache
def _linear_maps(module):
    """``(A_P, A_Q)``: the coefficients of every kernel in every entry of ``P`` and
    ``Q`` (``regressors_packed`` is linear in the kernels)."""
    n = len(module.KERNELS)
    columns_p, columns_q = [], []
    for k in range(n):
        unit = [0.0] * n
        unit[k] = 1.0
        P, Q = module.regressors_packed(unit)
        columns_p.append(np.array([[float(v) for v in row] for row in P]))
        columns_q.append(np.array([float(v) for v in Q]))
    return np.stack(columns_p, axis=-1), np.stack(columns_q, axis=-1)


@cache
def _with_terms(module):
    """Masks of the entries of ``P`` and ``Q`` that have terms (of a system's stacked
    rows, the others are zero whatever the data)."""
    map_p, map_q = _linear_maps(module)
    return np.any(map_p != 0, axis=-1), np.any(map_q != 0, axis=-1)


def _entries(module, values, sizes):
    """``P``, ``Q`` from the kernels' values, and the sizes their terms could have."""
    map_p, map_q = _linear_maps(module)
    return map_p @ values, map_q @ values, np.abs(map_p) @ sizes, np.abs(map_q) @ sizes


def _kernels_at_end(module, channels, dt):
    """Every kernel of ``module.KERNELS`` at the last sample, and the size it could
    have (``max|s| * T**(p + l) * p! / (p + l)!``)."""
    n = channels[0].size
    T = np.float64((n - 1) * dt)  # powers overflow to inf, never raise
    highest = max(power + level - 1 for _, power, level in module.KERNELS)
    moments = np.zeros((len(channels), highest + 1))
    largest = np.array([max(float(c.max()), -float(c.min())) for c in channels])
    powers = np.empty((highest + 1, min(_BLOCK, n)))
    for start in range(0, n, _BLOCK):  # blocks: no array of n powers is ever formed
        stop = min(start + _BLOCK, n)
        rows = powers[:, :stop - start]
        rows[0] = 1.0
        np.multiply(np.arange(start, stop), 1.0 / (n - 1), out=rows[min(1, highest)])
        for k in range(2, highest + 1):
            np.multiply(rows[k - 1], rows[1], out=rows[k])
        for c, channel in enumerate(channels):
            moments[c] += rows @ channel[start:stop]
    if n >= 3 * _POINTS:
        head, tail = _end_weights(_POINTS)  # the corrections of the rule at both ends
        for rows, correction in ((np.arange(_POINTS), head - 1.0),
                                 (np.arange(n - _POINTS, n), tail - 1.0)):
            powers = np.vander(rows / (n - 1), highest + 1, increasing=True)
            block = np.stack([c[rows] for c in channels])
            moments += (block * correction) @ powers
    else:  # a short record: the rule itself
        powers = np.vander(np.arange(n) / (n - 1), highest + 1, increasing=True)
        moments = np.array([[cumulative_integral(c * powers[:, k], 1.0, points=_POINTS)[-1]
                             for k in range(highest + 1)] for c in channels])
    moments *= dt
    stacked = channels
    names = list(module.CHANNELS)
    values, sizes = [], []
    for signal, power, level in module.KERNELS:
        c = names.index(signal)
        if level == 0:
            values.append(T**power * float(stacked[c][-1]))
            sizes.append(T**power * largest[c])
            continue
        total = sum(math.comb(level - 1, j) * (-1) ** j * moments[c, power + j]
                    for j in range(level))
        values.append(T ** (power + level - 1) / math.factorial(level - 1) * total)
        sizes.append(largest[c] * T ** (power + level) * math.factorial(power)
                     / math.factorial(power + level))
    return np.array(values), np.array(sizes)


def _kernels_from_state(state, largest, last):
    """Every kernel at the last sample as the estimator computed it (the integrals of
    its chains, held in the state after the record), and the size it could have, from
    the largest absolute value and the last value of every channel (divided by its
    divisor)."""
    module = state.model
    layout = integrator_layout(module)
    T = np.float64((state.n_seen - 1) * state.dt)  # powers overflow to inf
    values, sizes = [], []
    for (signal, power, level), (lvl, row) in zip(module.KERNELS, layout.kernels):
        c = list(module.CHANNELS).index(signal)
        if level == 0:
            values.append(T**power * last[c])
        else:
            values.append(float(state.integrals[layout.level_start(lvl) + row]))
        sizes.append(largest[c] * T ** (power + level) * math.factorial(power)
                     / math.factorial(power + level))
    return np.array(values), np.array(sizes)


def undetermined(module, channels, dt, *, rtol=IDENTIFIABILITY_RTOL, state=None):
    """What the record cannot determine, as a phrase, or None if it determines all.

    Parameters
    ----------
    module : module
        Generated estimator module (``KERNELS``, ``CHANNELS``, ``PARAMETERS``,
        ``regressors_packed``).
    channels : sequence of ndarray
        The channels as the estimator takes them (``CHANNELS`` order), uniformly
        sampled with step ``dt``.
    dt : float
        Sampling step.
    rtol : float, optional
        Relative size below which a column, the known side or the normalised
        smallest singular value counts as zero.
    state : algid.estimation._core.EstimatorState, optional
        The estimator's state after the whole record (from a fresh state): the
        kernels are then read from its integrals, at no cost, instead of computed.

    Returns
    -------
    str or None
        E.g. ``"B (its column of P vanishes: the term it multiplies is not excited)"``.

    Raises
    ------
    InputDataError
        If the kernels overflow or underflow (a time span or step so extreme that
        ``T**k`` leaves the floating-point range): nothing can be judged, nor
        estimated.
    """
    if channels[0].size < MIN_SAMPLES:
        return None
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        if state is not None and state.n_seen == channels[0].size:
            if state.channel_max is not None:  # tracked with the numerical error
                largest, last = state.channel_max, state.channel_last
            else:
                largest = [max(float(c.max()), -float(c.min())) / d
                           for c, d in zip(channels, state.divisors)]
                last = [float(c[-1]) / d for c, d in zip(channels, state.divisors)]
            values, sizes = _kernels_from_state(state, largest, last)
            nonzero = all(float(v) > 0 for v in largest)
        else:
            arrays = [np.asarray(c, dtype=float) for c in channels]
            values, sizes = _kernels_at_end(module, arrays, dt)
            nonzero = all(np.any(a != 0) for a in arrays)
        P, Q, size_p, size_q = _entries(module, values, sizes)
    span = (channels[0].size - 1) * dt
    with np.errstate(over="ignore", under="ignore"):
        powers = np.float64(span) ** np.array([p + lv for _, p, lv in module.KERNELS])
    if not (np.isfinite(powers).all() and (powers > 0).all()):
        raise InputDataError(
            f"the estimator's integrals overflow or underflow over a time span of "
            f"{span:.4g} s (step {dt:.4g} s): express the time in other units")
    if not (np.isfinite(P).all() and np.isfinite(Q).all() and np.isfinite(size_p).all()
            and np.isfinite(size_q).all()):  # the time is fine: the amplitudes are not
        reach = ", ".join(f"{name!r} {float(np.max(np.abs(c))):.4g}"
                          for name, c in zip(module.CHANNELS, channels))
        raise InputDataError(
            f"the estimator's integrals overflow over a time span of {span:.4g} s: the "
            f"channels reach {reach} (as the estimator takes them, after any rescaling by "
            f"a power of two, before any division by the mass): express the signals in "
            f"other units")
    tiny = np.finfo(float).tiny
    held_p, held_q = _with_terms(module)
    if nonzero and (np.any(size_p[held_p] < tiny) or np.any(size_q[held_q] < tiny)):
        # no channel is zero, yet an entry's size is subnormal or 0: it underflowed and
        # lost its digits (the verdict would call it unexcited); an entry without
        # terms (a parameter absent from a system's equation) is 0 whatever the data
        raise InputDataError(
            f"the estimator's integrals underflow over a time span of {span:.4g} s (step "
            f"{dt:.4g} s): express the time in other units")
    kind, free = _verdict(module, P, Q, size_p, size_q, rtol)
    if kind is None:  # determined, if the products of its entries are in range
        filter_order = 0 if state is None else state.filter_order
        if not _cramer_in_range(module, P, Q, span, filter_order):
            # a model of measured signals alone had its amplitudes brought into range
            # (algid._scaling); others may have extreme ones
            reach = "" if not getattr(module, "FACTORS", {}) else " with channels reaching " + \
                ", ".join(f"{name!r} {float(np.max(np.abs(c))):.4g}"
                          for name, c in zip(module.CHANNELS, channels))
            largest = [float(np.max(np.abs(c))) for c in channels if np.size(c)]
            spread = max(largest) / min(a for a in largest if a > 0)
            advice = ("express the time or the signals in other units" if reach else
                      f"express the time in other units, or the signals in units closer to "
                      f"one another (their largest values differ by a factor {spread:.3g}, "
                      f"which no common unit brings into range)" if spread > 2.0**64 else
                      "express the time in other units")
            raise InputDataError(
                f"the estimator's products of integrals overflow or underflow over a time "
                f"span of {span:.4g} s (step {dt:.4g} s){reach}: {advice}")
    parameters = list(module.PARAMETERS)
    named = " and ".join(parameters[j] for j in free)
    if kind == "silent":
        if len(free) > 1:
            return (f"{named} (the terms they multiply are not excited: their columns of "
                    f"P(t) vanish)")
        return f"{named} (the term it multiplies is not excited: its column of P(t) vanishes)"
    if kind == "scale":
        return (f"the scale of {', '.join(parameters)} (the known side of the equation "
                f"is zero: the input {module.INPUT!r} does not excite it)")
    if kind == "dependent":
        return (f"{named} separately (the terms they multiply are proportional over the "
                f"record)")
    return None


def _cramer_in_range(module, P, Q, span, filter_order):
    """Whether Cramer's numerators and denominator at the end, integrated by the filter
    (about ``span**p / p!`` times them), are normal floating-point numbers, not zero:
    the verdict found ``P`` regular and ``Q`` not zero, so an exact zero underflowed
    (a true parameter of 0 gives a numerator of round-off, not 0)."""
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        numerators, denominator = module.cramer(P.tolist(), Q.tolist())
    if float(denominator) == 0.0 or any(float(v) == 0.0 for v in numerators):
        return False  # (exactly 0 from products of entries that are not: underflow)
    gain = filter_order * math.log2(span) - math.log2(math.factorial(filter_order))
    for value in (*numerators, denominator):
        value = abs(float(value))
        if not math.isfinite(value):
            return False
        if value and not -1022 <= math.log2(value) + gain <= 1023:
            return False
    return True


def _verdict(module, P, Q, size_p, size_q, rtol):
    """``(kind, parameter indices)``: ``("silent", ...)`` for columns of ``P`` below
    ``rtol`` of their size, ``("scale", all)`` for a vanishing known side,
    ``("dependent", ...)`` for a combination left free, ``(None, ())`` if ``P`` and ``Q``
    determine every parameter."""
    with np.errstate(divide="ignore", invalid="ignore"):
        relative_p = np.where(size_p > 0, np.abs(P) / size_p, 0.0)
        relative_q = np.where(size_q > 0, np.abs(Q) / size_q, 0.0)
    n = len(module.PARAMETERS)
    silent = tuple(j for j in range(n) if np.max(relative_p[:, j]) < rtol)
    if silent:
        return "silent", silent
    if np.max(relative_q) < rtol:
        return "scale", tuple(range(n))
    # rows (one more integration each: another power of T) and then columns scaled to
    # unit norm; a combination of the parameters is free when the smallest singular
    # value is at round-off.  (Not the determinant: the product of all the singular
    # values is small for a model of five parameters that the data determine well.)
    # (each row first divided by its largest entry: the norms of entries near the ends
    # of the floating-point range neither overflow nor underflow)
    rows = P / _nonzero(np.max(np.abs(P), axis=1))[:, None]
    rows /= _nonzero(np.linalg.norm(rows, axis=1))[:, None]
    normalised = rows / _nonzero(np.linalg.norm(rows, axis=0))
    _, singular, vt = np.linalg.svd(normalised)
    if singular[-1] < rtol:
        free = np.abs(vt[-1])
        return "dependent", tuple(j for j in range(n) if free[j] > 0.1 * free.max())
    return None, ()


def _nonzero(norms):
    """The norms, with 1 for a zero (whose row or column stays zero)."""
    return np.where(norms > 0, norms, 1.0)


def undetermined_in_stream(state, rtol=IDENTIFIABILITY_RTOL):
    """The parameters that the samples seen so far leave undetermined, from the state.

    The test of :func:`undetermined`, on the kernels the estimator holds after its last
    sample and the largest channel values since the origin (``state.channel_max``).

    Parameters
    ----------
    state : algid.estimation._core.EstimatorState
        After at least :data:`MIN_SAMPLES` samples, with ``channel_max`` set.
    rtol : float, optional
        As for :func:`undetermined`.

    Returns
    -------
    tuple of int or None
        Indices (in ``PARAMETERS`` order) of the undetermined parameters, empty if the
        data determine them all; None where nothing can be judged (too few samples, or
        integrals out of the floating-point range).
    """
    if state.n_seen < MIN_SAMPLES or state.channel_max is None:
        return None
    module = state.model
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        values, sizes = _kernels_from_state(state, state.channel_max, state.channel_last)
        P, Q, size_p, size_q = _entries(module, values, sizes)
    if not (np.isfinite(P).all() and np.isfinite(Q).all() and np.isfinite(size_p).all()
            and np.isfinite(size_q).all()):
        return None
    return _verdict(module, P, Q, size_p, size_q, rtol)[1]


def check_identifiable(module, channels, dt, *, rtol=IDENTIFIABILITY_RTOL, state=None):
    """Raise if the record cannot determine the parameters (see :func:`undetermined`).

    Parameters
    ----------
    module : module
        Generated estimator module.
    channels : sequence of ndarray
        The channels, in ``CHANNELS`` order.
    dt : float
        Sampling step.
    rtol : float, optional
        As for :func:`undetermined`.
    state : algid.estimation._core.EstimatorState, optional
        As for :func:`undetermined`.

    Raises
    ------
    InputDataError
        ``"the data cannot determine B (...)"``, or the time span overflows the
        integrals (see :func:`undetermined`).
    """
    what = undetermined(module, channels, dt, rtol=rtol, state=state)
    if what is not None:
        raise InputDataError(f"the data cannot determine {what}")

