"""The file of a saved system tracker (:class:`~algid.identification._system_tracker.
SystemTracker`): its state as flat arrays and scalars, and their checks on load.

The archive is that of :mod:`algid.identification._tracker_file` (``.npz`` of ``.npy``
members, a JSON header, a SHA-256 checksum of both, nothing unpickled), in its own
format.  :func:`restore` refuses, in one line naming the array, every array whose shape
the system and the configuration do not give, or whose values cannot be a state's
(non-finite sums, negative weights, counters beyond the buffer), before any of it
reaches the tracker.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from algid._record_input import RATE_TOLERANCE
from algid.errors import InputDataError
from algid.identification._tracker_state import MAX_WINDOW_SAMPLES, WARMUP_DOUBLINGS
from algid.identification._window_problem import DIFFERENCE_ORDERS, MULTIPLICITIES
from algid.identification._window_rule import min_length

__all__ = ["FORMAT", "CONFIG", "flat_state", "restore"]

#: The format of the file.
FORMAT = "algid.SystemTracker/2"   # (2: divided equations hold their ratios)

_NUMBER = (type(None), int, float)

#: Configuration key -> the types its value may have.
CONFIG = {"equations": (list,), "parameters": (list,), "outputs": (list,), "rate": _NUMBER,
          "time": (type(None), str), "window": _NUMBER, "half_life": _NUMBER,
          "method": (str,), "warmup": (int, float), "false_alarm_rate": (int, float),
          "every": _NUMBER}

#: Largest counter accepted.
_MAX_COUNT = 2**62


def _noise_keys(tracker):
    """Per equation with parameters: the noisy outputs it reads (its noise sums)."""
    return [[y for y in tracker._noisy if y in model.signals] for model in tracker.models]


def flat_state(tracker):
    """The tracker's state as string keys to arrays and scalars.

    Parameters
    ----------
    tracker : SystemTracker

    Returns
    -------
    dict
    """
    configured = tracker.length is not None
    state = {"seen": int(tracker._seen), "last_time": float(tracker._last_time),
             "last_stamp": float(tracker._last_stamp),
             "configured": configured, "warmup": float(tracker._warmup),
             "next_start": int(tracker._next_start), "weight_sum": float(tracker._weight_sum),
             "run_windows": int(tracker._run_windows),
             "last_report": math.nan if tracker._last_report is None
             else float(tracker._last_report),
             "has_sums": tracker._sums is not None,
             "has_weights": tracker._weights is not None,
             "has_products": tracker._products is not None,
             "has_previous": tracker._previous_test is not None,
             "buffer_t": tracker._buffer_t, "cusum": tracker._cusum}
    if configured:
        state.update(length=int(tracker.length), step=float(tracker.step))
    for name in tracker._signals:
        state[f"buffer/{name}"] = tracker._buffer[name]
    for y in tracker._noisy:
        state[f"differences/{y}"] = tracker._differences[y]
        state[f"tail/{y}"] = tracker._tail[y]
    if tracker._sums is not None:
        for a in MULTIPLICITIES:
            for e, sums in enumerate(tracker._sums[a]):
                state[f"sums/{a}/{e}/normal"] = sums["normal"]
                for y, g in sums["noise"].items():
                    state[f"sums/{a}/{e}/noise/{y}"] = g
        if tracker._weights is None:   # the warm-up's windows, per equation
            first = tracker._first
            P = len(tracker.parameters)
            state["first_phi"] = np.array([[phi for phi, _ in window] for window in first]
                                          ).reshape(len(first), len(tracker.models), P + 1)
            for y in tracker._noisy:
                state[f"first_grams/{y}"] = np.array(
                    [[grams.get(y, np.zeros((P + 1, P + 1))) for _, grams in window]
                     for window in first]).reshape(len(first), len(tracker.models), P + 1,
                                                   P + 1)
    if tracker._weights is not None:
        state["weights"] = np.asarray(tracker._weights, dtype=float)
    if state["has_products"]:
        state["products"] = tracker._products
        state["recent"] = np.array(list(tracker._recent)).reshape(
            len(tracker._recent), tracker._products.shape[0])
    if tracker._previous_test is not None:
        theta_bar, covariance, variances = tracker._previous_test
        state.update(previous_theta_bar=theta_bar, previous_covariance=covariance,
                     previous_variances=np.asarray(variances, dtype=float))
    return state


def _fail(path, what):
    raise InputDataError(f"{path}: {what}")


def _flag(path, scalars, key):
    value = scalars.get(key)
    if not isinstance(value, bool):
        _fail(path, f"scalar {key!r} is {value!r}, not true or false")
    return value


def _count(path, scalars, key, most=_MAX_COUNT):
    value = scalars.get(key)
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= most:
        _fail(path, f"scalar {key!r} is {value!r}, not a count up to {most}")
    return value


def _number(path, scalars, key, rule):
    value = scalars.get(key)
    ok = isinstance(value, float) and {
        "positive": math.isfinite(value) and value > 0,
        "nonnegative": math.isfinite(value) and value >= 0,
        "time": value == -math.inf or math.isfinite(value),
        "time_or_nan": not math.isinf(value)}[rule]
    if not ok:
        _fail(path, f"scalar {key!r} is {value!r}")
    return value


def _array(path, arrays, key, shape, finite=True, nan=False):
    """The array ``key``, float64 of ``shape`` (None: any length on that axis)."""
    value = arrays.pop(key, None)
    if value is None:
        _fail(path, f"no array {key!r}")
    if value.dtype != np.float64 or value.ndim != len(shape) or any(
            want is not None and have != want for have, want in zip(value.shape, shape)):
        _fail(path, f"array {key!r} is {value.dtype} of shape {value.shape}, not float64 of "
                    f"shape {tuple('n' if n is None else n for n in shape)}")
    if finite and not (np.all(np.isfinite(value)) or (nan and not np.any(np.isinf(value)))):
        _fail(path, f"array {key!r} holds values that are not finite")
    return np.array(value)


def _check_window(path, tracker, length, step, t):
    """The saved window against the kernels, the configuration and the samples held."""
    shortest = min_length(MULTIPLICITIES)
    if length < shortest:
        _fail(path, f"scalar 'length' is {length}, shorter than the kernels need ({shortest})")
    if tracker._window is not None and length != int(round(tracker._window / step)) + 1:
        _fail(path, f"scalar 'length' is {length}, not the configured window "
                    f"{tracker._window:g} s at the step {step:g} s")
    if tracker.rate is not None and abs(step * tracker.rate - 1.0) > RATE_TOLERANCE:
        _fail(path, f"scalar 'step' is {step!r}, not the configured rate's")
    if len(t) > 1:
        held = float(np.median(np.diff(t)))
        if abs(held - step) > RATE_TOLERANCE * step:
            _fail(path, f"scalar 'step' is {step!r}, not the step of the samples held "
                        f"({held:g} s)")


def restore(path, tracker, scalars, arrays):
    """Check a saved state against ``tracker`` (made from the saved configuration) and
    set it.

    Parameters
    ----------
    path : str or path-like
        Named in messages.
    tracker : SystemTracker
    scalars, arrays : dict
        As :func:`algid.identification._tracker_file.read` returns them.

    Raises
    ------
    InputDataError
        One line naming the scalar or the array.
    """
    arrays = dict(arrays)
    known = {"seen", "last_time", "last_stamp", "configured", "warmup", "next_start", "weight_sum",
             "run_windows", "last_report", "has_sums", "has_weights", "has_products",
             "has_previous", "length", "step"}
    extra = sorted(set(scalars) - known)
    if extra:
        _fail(path, f"scalar {extra[0]!r} is no part of a system tracker's state")
    P, k = len(tracker.parameters), len(tracker.models)
    t = _array(path, arrays, "buffer_t", (None,))
    n = len(t)
    if n > 1 and not np.all(np.diff(t) > 0):
        _fail(path, "array 'buffer_t' does not increase")
    buffer = {name: _array(path, arrays, f"buffer/{name}", (n,), nan=True)
              for name in tracker._signals}
    seen = _count(path, scalars, "seen")
    if seen < n:
        _fail(path, f"scalar 'seen' is {seen}, fewer than the {n} samples held")
    last_time = _number(path, scalars, "last_time", "time")
    if n and last_time != t[-1]:
        _fail(path, f"scalar 'last_time' is {last_time!r}, not the last time held")
    last_stamp = _number(path, scalars, "last_stamp", "time_or_nan") \
        if "last_stamp" in scalars else math.nan   # (files of earlier versions: none)
    warmup = _number(path, scalars, "warmup", "positive")
    if not tracker._first_warmup <= warmup <= tracker._first_warmup * 2 ** (WARMUP_DOUBLINGS + 1):
        _fail(path, f"scalar 'warmup' is {warmup!r}, not a span the warm-up reaches")
    next_start = _count(path, scalars, "next_start", 0)   # (0 after every chunk)
    weight_sum = _number(path, scalars, "weight_sum", "nonnegative")
    run_windows = _count(path, scalars, "run_windows")
    last_report = _number(path, scalars, "last_report", "time_or_nan")
    if not math.isnan(last_report) and last_report > last_time:
        _fail(path, f"scalar 'last_report' is {last_report!r}, after the last sample")
    configured = _flag(path, scalars, "configured")
    has_sums, has_weights = _flag(path, scalars, "has_sums"), _flag(path, scalars, "has_weights")
    has_products = _flag(path, scalars, "has_products")
    has_previous = _flag(path, scalars, "has_previous")
    if (has_sums or has_weights or has_products or has_previous) and not configured \
            or (has_weights or has_products or has_previous) and not has_sums \
            or has_previous and not has_weights or has_weights != has_products \
            or has_sums != (weight_sum > 0) or not weight_sum <= seen:
        _fail(path, "its flags are not those of any state (sums, weights and tests before "
                    "the window)")
    cusum = _array(path, arrays, "cusum", (k,))
    if np.any(cusum < 0):
        _fail(path, "array 'cusum' holds negative values")
    orders = len(DIFFERENCE_ORDERS)
    differences = {y: _array(path, arrays, f"differences/{y}", (orders, 2))
                   for y in tracker._noisy}
    tails = {y: _array(path, arrays, f"tail/{y}", (None,)) for y in tracker._noisy}
    if any(len(tail) > max(DIFFERENCE_ORDERS) for tail in tails.values()) \
            or any(np.any(d < 0) for d in differences.values()):
        _fail(path, "its noise sums are not a state's")
    if configured:
        length = _count(path, scalars, "length", MAX_WINDOW_SAMPLES)
        step = _number(path, scalars, "step", "positive")
        _check_window(path, tracker, length, step, t)
        try:
            tracker._set_window(length, step)
        except InputDataError as exc:
            _fail(path, f"its window is refused: {exc}")
    noise_keys = _noise_keys(tracker)
    q1 = P + 1
    sums = None
    if has_sums:
        sums = {a: [{"normal": _array(path, arrays, f"sums/{a}/{e}/normal", (q1, q1)),
                     "noise": {y: _array(path, arrays, f"sums/{a}/{e}/noise/{y}", (q1, q1))
                               for y in noise_keys[e]}}
                    for e in range(k)] for a in MULTIPLICITIES}
    first = []
    if has_sums and not has_weights:
        phi = _array(path, arrays, "first_phi", (None, k, q1))
        grams = {y: _array(path, arrays, f"first_grams/{y}", (len(phi), k, q1, q1))
                 for y in tracker._noisy}
        first = [[(phi[w, e], {y: grams[y][w, e] for y in noise_keys[e]}) for e in range(k)]
                 for w in range(len(phi))]
    weights = None
    if has_weights:
        weights = _array(path, arrays, "weights", (k,))
        with np.errstate(over="ignore", under="ignore"):
            unusable = np.any(weights <= 0) or not np.all(np.isfinite(weights ** 4)) \
                or np.any(weights ** 2 < 1e-300)
        if unusable:
            _fail(path, "array 'weights' holds values that are not positive numbers of a "
                        "usable size")
    products, recent = None, deque()
    if has_products:
        v = (1 + len(tracker._noisy)) * P * q1
        products = _array(path, arrays, "products", (v, v))
        rows = _array(path, arrays, "recent", (None, v))
        if len(rows) > 2 * tracker.overlap:
            _fail(path, f"array 'recent' holds {len(rows)} windows, more than the "
                        f"{2 * tracker.overlap} lags")
        recent = deque(rows)
    previous = None
    if has_previous:
        theta_bar = _array(path, arrays, "previous_theta_bar", (q1,))
        variances = _array(path, arrays, "previous_variances", (k,))
        if np.any(variances < 0) or theta_bar[-1] != -1.0:
            _fail(path, "its last test's estimate or variances are not a state's")
        previous = (theta_bar, _array(path, arrays, "previous_covariance", (P, P)),
                    [float(v) for v in variances])
    if arrays:
        _fail(path, f"array {sorted(arrays)[0]!r} is no part of a system tracker's state")
    tracker._buffer_t, tracker._buffer, tracker._seen = t, buffer, seen
    tracker._last_time, tracker._warmup, tracker._next_start = last_time, warmup, next_start
    tracker._last_stamp = last_stamp
    tracker._weight_sum, tracker._run_windows = weight_sum, run_windows
    if not math.isnan(last_report):
        tracker._last_report = last_report
    tracker._cusum, tracker._differences, tracker._tail = cusum, differences, tails
    # (Python floats, as the tracker holds them: NumPy's squares round otherwise)
    tracker._sums = sums
    tracker._weights = None if weights is None else [float(w) for w in weights]
    tracker._products, tracker._first = products, first
    tracker._recent, tracker._previous_test = recent, previous
