"""Checks of the chunks of a stream (:class:`algid.OnlineEstimator`).

A chunk must continue the stream: finite samples, equally long, time strictly
increasing from the previous chunk on and uniform: every step within
:func:`~algid._signal_checks.step_tolerance` of the step (``1e-4`` of it, or a few ulp of
the times), or within twice the decimal rounding of the times
(:func:`~algid._signal_checks.rounding_quantum`).  Without a given step, the step is the
mean step of the first chunk (with the sample before it, if the first chunk was one
sample).  Anything else is an
:class:`~algid.errors.InputDataError` whose one-line message names the stream sample.

A chunk must also leave the estimator usable: its channels finite (a user model's
``log(y)`` of a negative ``y`` is NaN) and within :func:`amplitude_limits`, so that
one absurd sample cannot turn every later estimate into NaN or overflow
(:func:`check_amplitudes`, :func:`check_channels`).  A refused chunk changes nothing.
"""

from __future__ import annotations

import math
import numbers
from functools import cache

import numpy as np

from algid._record_input import refuse_not_increasing, refuse_unequal_lengths
from algid._scaling import AMPLITUDE_BITS, check_amplitude_range
from algid._signal_checks import UNIFORM_RTOL, as_signal, rounding_quantum, step_tolerance
from algid.errors import InputDataError

__all__ = ["check_signals_call", "check_chunk", "check_signals_chunk", "compiled_scan",
           "float_sample", "amplitude_limits", "check_amplitudes",
           "check_channels", "compiled_within", "half_period", "MAX_HALF_PERIOD_SAMPLES"]

_FLOAT64 = np.dtype(np.float64)


def _fmt(value) -> str:
    return f"{float(value):.10g}"


def _check_sample(t, f, x, n, t_last, dt):
    """:func:`check_chunk` for one sample given as three numbers (faster)."""
    t, f, x = float(t), float(f), float(x)
    if not (math.isfinite(t) and math.isfinite(f) and math.isfinite(x)):
        for name, v in zip(("t", "f", "x"), (t, f, x)):
            as_signal(np.array([v]), name=name, time=name == "t", of=_chunk(n))
    if t_last is not None:
        step = t - t_last
        if not step > 0:
            refuse_not_increasing(np.array([t]), "time 't'", previous=t_last, first=n,
                                  unit="stream sample")
        if dt is None:
            dt = step
        elif abs(step - dt) > UNIFORM_RTOL * dt and \
                abs(step - dt) > step_tolerance(max(abs(t), abs(t_last)), dt) and \
                _beyond_rounding(np.array([t_last, t]), dt, abs(step - dt)):
            # (the tolerance is at least UNIFORM_RTOL * dt: the common case needs no more)
            _refuse_step(step, n, dt)
    samples = np.array((t, f, x))  # one allocation; the three rows are views of it
    return samples[0:1], samples[1:2], samples[2:3], dt


def _chunk(n):
    """Names the chunk in the messages."""
    return f"the chunk starting at stream sample {n}"


def _refuse_step(step, n, dt):
    """The refusal of a step that is not the stream's (:func:`check_experiment`'s words)."""
    raise InputDataError(f"time 't' is not uniformly sampled: step {_fmt(step)} at stream "
                         f"sample {n} where {_fmt(dt)} is expected; the estimator needs "
                         f"uniform sampling (resample first)")


def _beyond_rounding(times, dt, deviation):
    """Whether a step's ``deviation`` from ``dt`` is more than the decimal rounding of
    ``times`` explains: twice the quantum, one for the step and one for ``dt`` (taken
    from the rounded times of the first chunk), plus the representation error."""
    quantum = rounding_quantum(times, dt)
    return deviation > step_tolerance(float(np.max(np.abs(times))), dt) + 2.0 * quantum


def _first_step(t, t_last):
    """The step of a stream taken from its first chunk ``t`` (after the sample at
    ``t_last``, if any): the mean step over the chunk, None from a single time."""
    if t_last is not None:
        return (float(t[-1]) - t_last) / t.size
    if t.size > 1:
        return float(t[-1] - t[0]) / (t.size - 1)
    return None


def _scan_chunk(scan, t, f, x, t_last, dt):
    """The checks in one compiled pass, for 1-D contiguous float64 arrays of equal,
    nonzero length that pass every check; ``None`` otherwise."""
    if not (type(t) is np.ndarray and type(f) is np.ndarray and type(x) is np.ndarray):
        return None
    m = t.size
    if not (m and t.ndim == 1 and f.shape == t.shape and x.shape == t.shape
            and t.dtype == _FLOAT64 and f.dtype == _FLOAT64 and x.dtype == _FLOAT64
            and t.flags.c_contiguous and f.flags.c_contiguous and x.flags.c_contiguous):
        return None
    if dt is None:  # the mean step of the first chunk, as the general check takes it
        dt = _first_step(t, t_last)
    step = math.nan if dt is None else dt
    magnitude = max(abs(float(t[0])), abs(float(t[-1])),
                    0.0 if t_last is None else abs(t_last))
    tolerance = math.nan if dt is None else step_tolerance(magnitude, step)
    if not scan(t, f, x, math.nan if t_last is None else t_last, step, tolerance):
        return None
    return t, f, x, dt


def float_sample(t, f, x):
    """One sample given as three floats, or as three float64 arrays of one element.

    Parameters
    ----------
    t, f, x : object
        A chunk, as given to :meth:`algid.OnlineEstimator.update`.

    Returns
    -------
    tuple of float or None
        ``(t, f, x)`` as floats; None for any other form (not checked further).
    """
    if type(t) is float and type(f) is float and type(x) is float:
        return t, f, x
    if type(t) is np.ndarray and type(f) is np.ndarray and type(x) is np.ndarray and \
            t.shape == f.shape == x.shape == (1,) and \
            t.dtype is _FLOAT64 and f.dtype is _FLOAT64 and x.dtype is _FLOAT64:
        return t.item(0), f.item(0), x.item(0)
    return None


def check_chunk(t, f, x, *, n, t_last, dt, scan=None):
    """Check the next chunk of a stream.

    Parameters
    ----------
    t, f, x : float or array_like
        The chunk: times, input and output samples.
    n : int
        Stream index of the chunk's first sample.
    t_last : float or None
        Time of the previous sample (None at the start).
    dt : float or None
        The sampling step, if known.
    scan : callable, optional
        :func:`compiled_scan`, to check float64 arrays in one compiled pass.

    Returns
    -------
    t, f, x : ndarray
        The chunk as float64 1-D arrays.
    dt : float or None
        The step (taken from the chunk if it was not known and can be).

    Raises
    ------
    InputDataError
        Not 1-D numbers, NaN or inf, different lengths, time not increasing (within the
        chunk or from the previous one) or not uniform.
    """
    sample = float_sample(t, f, x)
    if sample is not None:  # one sample, fast
        return _check_sample(*sample, n, t_last, dt)
    if scan is not None:
        checked = _scan_chunk(scan, t, f, x, t_last, dt)
        if checked is not None:
            return checked
    if all(isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_))
           for v in (t, f, x)):
        try:
            return _check_sample(t, f, x, n, t_last, dt)
        except OverflowError:   # (an integer beyond floating point: named below)
            pass
    if all(isinstance(v, np.ndarray) and not isinstance(v, np.ma.MaskedArray)
           and v.shape == (1,) and v.dtype.kind in "fiu" for v in (t, f, x)):
        return _check_sample(t[0], f[0], x[0], n, t_last, dt)
    t, f, x = (_chunk_signal(values, name, n) for name, values in
               (("t", t), ("f", f), ("x", x)))
    refuse_unequal_lengths({"t": t, "f": f, "x": x},
                           _chunk(n))
    if t.size == 0:
        return t, f, x, dt
    refuse_not_increasing(t, "time 't'", previous=t_last, first=n, unit="stream sample")
    full = t if t_last is None else np.concatenate(([t_last], t))
    first = n - (full.size - t.size)  # stream index of full[0]
    steps = np.diff(full)
    taken_here = dt is None
    if dt is None and steps.size:
        dt = _first_step(t, t_last)
    if dt is not None and steps.size:
        deviation = np.abs(steps - dt)
        i = int(np.argmax(deviation))
        tolerance = step_tolerance(max(abs(full[0]), abs(full[-1])), dt)
        if deviation[i] > tolerance and _beyond_rounding(full, dt, deviation[i]):
            off = deviation > tolerance
            # (of two steps, the smaller: their median would be their mean)
            median = float(np.median(steps)) if steps.size > 2 else float(np.min(steps))
            if taken_here and (np.abs(steps - median) > tolerance).any():
                # a gap moved the mean step: name the step off the median
                dt, off = median, np.abs(steps - median) > tolerance
            if off.all() and np.ptp(steps) <= tolerance:  # uniform, at another step
                raise InputDataError(
                    f"time 't' steps by {_fmt(steps[0])} from stream sample {first + 1} "
                    f"where {_fmt(dt)} is expected (a rate of {_fmt(1 / steps[0])} Hz, "
                    f"not {_fmt(1 / dt)})")
            i = int(np.argmax(np.abs(steps - dt)))  # the step farthest off
            _refuse_step(steps[i], first + i + 1, dt)
    return t, f, x, dt


def _chunk_signal(values, name, n):
    """One signal of a chunk as float64 samples (a single number is one sample, an empty
    array no sample), refused in :func:`~algid._signal_checks.as_signal`'s words."""
    if not isinstance(values, np.ma.MaskedArray):  # (as_signal refuses masked samples)
        try:
            values = np.asarray(values)
        except (TypeError, ValueError):
            pass   # as_signal names it
        else:
            if values.ndim == 1 and values.size == 0:
                return np.empty(0)
            if values.ndim == 0:
                values = values.reshape(1)
    return as_signal(values, name=name, time=name == "t", of=_chunk(n))


def check_signals_call(name, f, x, signals, *, takes_pair, names, missing):
    """Refuse a call of :meth:`algid.OnlineEstimator.update` that mixes its two forms.

    Parameters
    ----------
    name : str
        The model's name (for the messages).
    f, x, signals
        The arguments of the call.
    takes_pair : bool
        Whether the model also takes ``update(t, f, x)``.
    names : sequence of str
        The signals the model reads.
    missing : callable
        ``missing(signals)``: the first signal of ``names`` not in ``signals``, or None.

    Raises
    ------
    InputDataError
        Both forms given, ``f, x`` for a model that needs ``signals=``, half of the
        pair, ``signals`` not a mapping, or a signal missing.
    """
    if signals is not None and (f is not None or x is not None):
        raise InputDataError("give either f and x or signals=, not both")
    if signals is None and not takes_pair:
        raise InputDataError(f"model {name!r} reads the signals {', '.join(names)}: "
                             "use update(t, signals={name: samples, ...})")
    if signals is None:
        raise InputDataError("update needs both f and x (or signals=)")
    if not hasattr(signals, "items"):
        raise InputDataError(f"update needs signals=, a mapping of signal name -> samples "
                             f"({', '.join(names)}), for model {name!r}")
    absent = missing(signals)
    if absent is not None:
        raise InputDataError(f"model {name!r} needs the signal {absent!r} "
                             f"(given: {', '.join(map(str, signals)) or 'none'})")


def check_signals_chunk(t, signals, names, *, n, t_last, dt, scan=None):
    """Check the next chunk of a stream of named signals (``update(t, signals=...)``).

    Parameters
    ----------
    t : float or array_like
        The chunk's times.
    signals : mapping
        Signal name -> samples at ``t``; those not in ``names`` are ignored.
    names : sequence of str
        The signals to check (every one must be in ``signals``: the caller checked).
    n, t_last, dt, scan
        As in :func:`check_chunk`.

    Returns
    -------
    t : ndarray
        The times as a float64 1-D array.
    checked : dict
        Name -> samples as float64 1-D arrays, for every name of ``names``.
    dt : float or None
        The step (taken from the chunk if it was not known and can be).

    Raises
    ------
    InputDataError
        As :func:`check_chunk`, naming the signal.
    """
    # the time axis (given as its own companions), then every signal
    t, _, _, dt = check_chunk(t, t, t, n=n, t_last=t_last, dt=dt, scan=scan)
    checked = {}
    for name in names:
        values = signals[name]
        if (type(values) is np.ndarray and values.dtype == _FLOAT64 and values.ndim == 1
                and values.size == t.size and values.size
                and (math.isfinite(values[0]) if values.size == 1
                     else np.isfinite(values).all())):
            checked[name] = values  # the common case, checked quickly
            continue
        values = _chunk_signal(values, str(name), n)
        refuse_unequal_lengths({"t": t, str(name): values},
                               _chunk(n))
        checked[name] = values
    return t, checked, dt


@cache
def compiled_scan():
    """The value checks of :func:`check_chunk` on float64 samples, compiled (needs
    numba): ``scan(t, f, x, t_prev, dt, tolerance)`` is True when ``t``, ``f``, ``x``
    are finite and every step of ``t`` (from ``t_prev`` on, unless NaN) is positive
    and within ``tolerance`` of ``dt`` (unless NaN)."""
    import numba

    from algid._compile_notice import watch

    watch()

    # reductions in any order (vectorised); the result does not depend on the order:
    # a sum of v * 0 is NaN if and only if some v is not finite
    @numba.njit("boolean(float64[::1], float64[::1], float64[::1], float64, float64, float64)",
                cache=True, nogil=True, fastmath={"reassoc"})
    def scan(t, f, x, t_prev, dt, tolerance):
        nan_if_bad = 0.0
        for i in range(t.shape[0]):
            nan_if_bad += t[i] * 0.0 + f[i] * 0.0 + x[i] * 0.0
        if nan_if_bad != 0.0:
            return False
        violations = 0
        if t_prev == t_prev:
            step = t[0] - t_prev
            violations += (not step > 0.0) + (abs(step - dt) > tolerance)
        for i in range(t.shape[0] - 1):
            step = t[i + 1] - t[i]
            violations += (not step > 0.0) + (abs(step - dt) > tolerance)
        return violations == 0

    return scan


#: Largest half period of re-anchoring, in samples: sample counts up to ``2**53`` are
#: exact in floating point.
MAX_HALF_PERIOD_SAMPLES = 2**53


def half_period(period, dt, points):
    """Samples in half a re-anchoring period (:class:`algid.OnlineEstimator`).

    Parameters
    ----------
    period : float
        The requested ``reset_period`` [s].
    dt : float
        The sampling step [s].
    points : int
        Points of the quadrature rule: the fewest samples of a half period.

    Returns
    -------
    int
        ``round(period / (2 dt))``.

    Raises
    ------
    InputDataError
        Fewer than ``points`` or more than :data:`MAX_HALF_PERIOD_SAMPLES` samples.
    """
    halves = period / (2.0 * dt)
    if not halves <= MAX_HALF_PERIOD_SAMPLES:  # also inf
        longest = 2 * MAX_HALF_PERIOD_SAMPLES * dt
        raise InputDataError(
            f"reset_period {_fmt(period)} s is too long for step {_fmt(dt)} s: at most "
            f"{_fmt(longest)} s (2**54 steps, beyond which sample counts are not exact in "
            f"floating point); use reset_period=None never to re-anchor")
    half = int(round(halves))
    if half < points:
        raise InputDataError(
            f"reset_period {_fmt(period)} s is too short for step {_fmt(dt)} s: half a "
            f"period must hold at least {points} samples (reset_period >= "
            f"{_fmt(2 * points * dt)} s)")
    return half




def amplitude_limits(module, divisors, scale):
    """The largest absolute sample of every channel that a stream takes.

    Parameters
    ----------
    module : module
        The generated estimator module (``PARAMETERS``).
    divisors : sequence of float
        Every channel's divisor (a known mass), in ``CHANNELS`` order.
    scale : float or None
        The power of two the samples are multiplied by (:mod:`algid._scaling`); None
        for 1.

    Returns
    -------
    tuple of float
        ``2**(AMPLITUDE_BITS // n) * divisor / scale`` per channel, in the units of the
        samples given (inf where that overflows).
    """
    bits = AMPLITUDE_BITS // len(module.PARAMETERS)
    unit = 1.0 if scale is None else float(scale)
    limits = []
    for divisor in divisors:
        try:
            limits.append(math.ldexp(float(divisor), bits) / unit)
        except OverflowError:
            limits.append(math.inf)
    return tuple(limits)


def _unit_phrase(module, divisor):
    bits = AMPLITUDE_BITS // len(module.PARAMETERS)
    mass = "" if divisor == 1.0 else f", times the mass {_fmt(divisor)} it is divided by"
    return (f"2**{bits} times the stream's unit, set by its first chunk{mass}: beyond it "
            f"the products of the estimator's integrals overflow")


def check_amplitudes(module, names, samples, limits, divisors, *, n, within=None,
                     new_scale=False, scale=None):
    """Refuse a chunk with a sample beyond its channel's :func:`amplitude_limits`.

    Parameters
    ----------
    module : module
        The generated estimator module.
    names : sequence of str
        The signals' names, for the message.
    samples : sequence of ndarray
        The chunk's finite samples of every signal, in the units given.
    limits : sequence of float
        Their limits (:func:`amplitude_limits`).
    divisors : sequence of float
        Their divisors (a known mass), for the message.
    n : int
        Stream index of the chunk's first sample.
    within : callable, optional
        :func:`compiled_within`, to check the two signals (``f``, ``x``) in one compiled
        pass.
    new_scale : bool, optional
        Whether the chunk sets the stream's scale: its signals, divided by their
        divisors, must then also fit together in floating point, as a record's must
        (:func:`algid._scaling.check_amplitude_range`).
    scale : float or None, optional
        The stream's scale (:mod:`algid._scaling`), with ``new_scale``.

    Raises
    ------
    InputDataError
        Naming the signal, the sample and the limit; the stream is unchanged.
    """
    if new_scale:
        check_amplitude_range(names, samples, divisors, scale, len(module.PARAMETERS))
    if within is not None:  # the common case, in one compiled pass
        f, x = samples
        if type(f) is np.ndarray and type(x) is np.ndarray and f.dtype is _FLOAT64 and \
                x.dtype is _FLOAT64 and f.flags.c_contiguous and x.flags.c_contiguous and \
                within(f, x, *limits):
            return
    for name, values, limit, divisor in zip(names, samples, limits, divisors):
        if values.size and not (values.max() <= limit and -values.min() <= limit):
            i = int(np.argmax(np.abs(values)))
            raise InputDataError(
                f"signal {name!r} reaches {_fmt(values[i])} at stream sample {n + i}, beyond "
                f"{_fmt(limit)} ({_unit_phrase(module, divisor)}); the chunk is refused, "
                f"the stream is unchanged")


def check_channels(module, channels, limits, *, n, signals, first=0, scale=None):
    """Refuse a chunk of a user model with a signal or channel not finite or too large.

    Parameters
    ----------
    module : module
        The generated estimator module (``CHANNELS``, ``FACTORS``, ``PARAMETERS``).
    channels : sequence of ndarray
        The chunk's channels (:class:`algid.models._compiled.ChannelStream`), ``CHANNELS``
        order, from its sample ``first`` on.
    limits : sequence of float
        Their limits (:func:`amplitude_limits`).
    signals : mapping
        The chunk's measured signals, as given: each is held to the limit of a channel
        (also in the warm-up of a differentiator, whose past samples it becomes).
    n : int
        Stream index of the chunk's first sample.
    first : int, optional
        Index in the chunk of the channels' first sample.
    scale : float, optional
        The power of two the signals are multiplied by before the channels are
        computed (:mod:`algid._scaling`).

    Raises
    ------
    InputDataError
        Naming the signal or the channel and its expression, the stream sample and the
        signals there; the stream is unchanged.
    """
    factors = getattr(module, "FACTORS", {})
    unit = 1.0 if scale is None else float(scale)
    signal_limit = amplitude_limits(module, (1.0,), scale)[0]
    # (label, samples, limit, index of the first in the chunk, their unit)
    checks = [(f"signal {name!r}", np.asarray(values), signal_limit, 0, 1.0)
              for name, values in signals.items()]
    checks += [(f"channel {name!r} = {factors[name]}" if name in factors
                else f"signal {name!r}", np.asarray(values), limit, first, unit)
               for name, values, limit in zip(module.CHANNELS, channels, limits)]
    for what, values, limit, offset, shown in checks:
        if not values.size or (values.max() <= limit and -values.min() <= limit):
            continue  # (NaN fails both comparisons)
        i = int(np.argmax(~(np.abs(values) <= limit)))
        where = offset + i
        at = ", ".join(f"{s} = {_fmt(np.asarray(v).reshape(-1)[where])}"
                       for s, v in signals.items())
        value = float(values[i])
        if math.isfinite(value):
            raise InputDataError(
                f"{what} reaches {_fmt(value / shown)} at stream sample {n + where} ({at}), "
                f"beyond {_fmt(limit / shown)} ({_unit_phrase(module, 1.0)}); the chunk is "
                f"refused, the stream is unchanged")
        kind = "NaN" if value != value else "infinite"
        raise InputDataError(
            f"{what} is {kind} at stream sample {n + where} ({at}): outside the domain of "
            f"its function, or an overflow; the chunk is refused, the stream is unchanged")


@cache
def compiled_within():
    """The test of :func:`check_amplitudes` on two float64 arrays, compiled (needs
    numba): ``within(f, x, limit_f, limit_x)`` is True when every ``|f| <= limit_f``
    and ``|x| <= limit_x`` (False for NaN)."""
    import numba

    from algid._compile_notice import watch

    watch()

    @numba.njit("boolean(float64[::1], float64[::1], float64, float64)", cache=True,
                nogil=True)
    def within(f, x, limit_f, limit_x):
        beyond = 0
        for i in range(f.shape[0]):  # counts, without branches: the loop vectorises
            beyond += (not abs(f[i]) <= limit_f) + (not abs(x[i]) <= limit_x)
        return beyond == 0

    return within
