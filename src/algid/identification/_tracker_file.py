"""The file of a saved :class:`algid.Tracker`: write, read, and check it.

A saved state is a ``.npz`` archive (stored, not compressed) of ``.npy`` members: the
state's arrays ``s/<key>``, a JSON ``header`` (format, configuration, scalars) and a
``checksum``: the SHA-256 of the header's text and of every array's name, dtype, shape
and bytes.  Nothing is unpickled.  :func:`read` refuses a file altered after saving (its
checksum), and :func:`check_state` every array and scalar that the configuration and
the model do not allow (kind, shape, finiteness, the segment's counters), so that no
state reaches the compiled loops with an array shorter than they index: a
hand-made file with a matching checksum is refused there, one line naming the problem.

The table of the state's keys is :func:`state_layout`.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import zipfile

import numpy as np

from algid._record_input import RATE_TOLERANCE, STEP_RANGE
from algid.errors import AlgidError, InputDataError
from algid.identification._tracker_state import (
    MAX_WINDOW_SAMPLES,
    WARMUP_DOUBLINGS,
    TrackerState,
)

__all__ = ["FORMAT", "FormatError", "write", "read", "check_state", "state_layout"]

#: The format of the file (3: the checksum and the checks on load).
FORMAT = "algid.Tracker/3"

_CONFIG = {"equation": (str,), "parameters": (list,), "output": (str,),
           "rate": (type(None), int, float), "time": (type(None), str),
           "window": (type(None), int, float), "half_life": (type(None), int, float),
           "method": (str,), "warmup": (int, float), "false_alarm_rate": (int, float),
           "every": (type(None), int, float)}

_HEADER = {"format", "config", "scalars", "floats"}


class FormatError(InputDataError):
    """A saved tracker of another format than the one asked for (:attr:`format`)."""

    def __init__(self, message, format):
        super().__init__(message)
        self.format = format


def _check_path(path):
    if not isinstance(path, (str, os.PathLike)):
        raise InputDataError(f"a tracker's file is a path (str or path-like), got "
                             f"{type(path).__name__}")


def _checksum(header_text, arrays):
    digest = hashlib.sha256(header_text.encode("utf-8"))
    for name in sorted(arrays):
        value = arrays[name]
        digest.update(json.dumps([name, value.dtype.str, list(value.shape)]).encode())
        digest.update(np.ascontiguousarray(value).tobytes())
    return digest.hexdigest()


def write(path, config, state, fmt=FORMAT):
    """Write ``state`` (the tracker's, flat: :meth:`TrackerState.flat`) and ``config``
    to ``path``.

    Parameters
    ----------
    path : str or path-like
    config : dict
    state : dict
        String keys to arrays or scalars (floats are written as their ``repr``: exact).
    fmt : str
        The format written in the header (a system's tracker has its own).
    """
    arrays, scalars = {}, {}
    for key, value in state.items():
        if isinstance(value, np.ndarray):
            arrays[f"s/{key}"] = value
        else:
            value = value.item() if isinstance(value, np.generic) else value
            scalars[key] = float(value) if isinstance(value, float) else value
    header = json.dumps({"format": fmt, "config": config, "scalars": {
        k: (repr(v) if isinstance(v, float) else v) for k, v in scalars.items()},
        "floats": [k for k, v in scalars.items() if isinstance(v, float)]})
    checksum = _checksum(header, arrays)
    _check_path(path)
    try:
        with open(path, "wb") as f:
            np.savez(f, header=np.array(header), checksum=np.array(checksum), **arrays)
    except OSError as exc:
        raise InputDataError(f"{path}: cannot write the tracker's state "
                             f"({exc.strerror or exc})") from None


def _members(path, archive):
    """The archive's arrays, each read only after its header promises no more bytes
    than the member holds."""
    out = {}
    for info in archive.infolist():
        name = info.filename
        if not name.endswith(".npy") or info.compress_type != zipfile.ZIP_STORED:
            raise InputDataError(f"{path}: not a saved tracker (member {name!r})")
        with archive.open(info) as member:
            version = np.lib.format.read_magic(member)
            read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) \
                else np.lib.format.read_array_header_2_0
            shape, _, dtype = read_header(member)
        if dtype.hasobject or math.prod(shape) * dtype.itemsize > info.file_size:
            raise InputDataError(f"{path}: member {name!r} is damaged ({dtype}, "
                                f"shape {shape}, {info.file_size} bytes)")
        with archive.open(info) as member:
            out[name[:-4]] = np.lib.format.read_array(member, allow_pickle=False)
    return out


def read(path, fmt=FORMAT, schema=None):
    """The configuration, scalars and arrays saved in ``path``, checksum verified.

    Parameters
    ----------
    path : str or path-like
    fmt : str
        The format expected.
    schema : dict, optional
        Configuration key -> the types its value may have (default: the Tracker's).

    Returns
    -------
    config, scalars, arrays : dict
        ``arrays`` keyed by the state's keys, native float64 or as saved.

    Raises
    ------
    InputDataError
        A missing, truncated or altered file, or one that is not a saved tracker.
    """
    _check_path(path)
    try:
        with zipfile.ZipFile(path) as archive:
            members = _members(path, archive)
    except FileNotFoundError:
        raise InputDataError(f"{path}: not a saved tracker (file not found)") from None
    except AlgidError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, NotImplementedError,
            RuntimeError) as exc:
        # (a cut file, a plain .npy, a damaged or encrypted member: what zipfile and numpy
        # raise)
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputDataError(f"{path}: not a saved tracker ({reason})") from None
    texts = {}
    for name in ("header", "checksum"):
        value = members.pop(name, None)
        if value is None or value.dtype.kind != "U" or value.shape != ():
            raise InputDataError(f"{path}: not a saved tracker (no {name})")
        texts[name] = str(value)
        if name == "header":   # (an older format has no checksum: named as such)
            header = _header(path, texts["header"], fmt, _CONFIG if schema is None else schema)
    if any(not name.startswith("s/") for name in members):
        extra = next(name for name in members if not name.startswith("s/"))
        raise InputDataError(f"{path}: not a saved tracker (member {extra!r})")
    if texts["checksum"] != _checksum(texts["header"], members):
        raise InputDataError(f"{path}: altered after it was saved (its checksum does not "
                            f"match its contents)")
    scalars = {k: (float(v) if k in header["floats"] else v)
               for k, v in header["scalars"].items()}
    return header["config"], scalars, {name[2:]: value for name, value in members.items()}


def _header(path, text, fmt, schema):
    """The parsed header, its structure and the types of its entries checked."""
    try:
        header = json.loads(text)
    except (ValueError, RecursionError):
        header = None
    if not isinstance(header, dict) or "format" not in header:
        raise InputDataError(f"{path}: not a saved tracker (its header is not one)")
    if header["format"] != fmt:
        raise FormatError(f"{path}: a tracker saved in format {header['format']!r}; this "
                          f"version reads {fmt!r} here", header["format"])
    if set(header) != _HEADER:
        raise InputDataError(f"{path}: the header holds {sorted(header)}, not "
                            f"{sorted(_HEADER)}")
    config, scalars, floats = header["config"], header["scalars"], header["floats"]
    if not isinstance(config, dict) or set(config) != set(schema):
        held = sorted(config) if isinstance(config, dict) else type(config).__name__
        raise InputDataError(f"{path}: the header's config holds {held}, not "
                            f"{sorted(schema)}")
    for key, kinds in schema.items():
        value = config[key]
        if isinstance(value, bool) or not isinstance(value, kinds) or (
                isinstance(value, list) and not all(isinstance(q, str) for q in value)):
            raise InputDataError(f"{path}: config {key!r} is {value!r}")
    if not isinstance(scalars, dict) or not isinstance(floats, list) \
            or not all(isinstance(k, str) and k in scalars for k in floats):
        raise InputDataError(f"{path}: the header's scalars are not a saved tracker's")
    for key, value in scalars.items():
        if key in floats:
            try:
                float(value)
            except (TypeError, ValueError):
                raise InputDataError(f"{path}: scalar {key!r} is {value!r}, not a number") \
                    from None
        elif not isinstance(value, int):   # (bool is an int)
            raise InputDataError(f"{path}: scalar {key!r} is {value!r}")
    return header


# ---------------------------------------------------------------------- the state's table
#: Scalars of every state: the rule each value must follow.
SCALARS = {"seen": "count", "last_time": "time", "configured": "bool", "alarms": "count"}

#: Scalars present in some states only (tries of the window's choice; the last value of
#: a time column beside ``rate=``).
OPTIONAL = {"warm_tries": "tries", "last_stamp": "finite"}

#: Largest counter accepted (a sample count far beyond any stream, within int64).
_MAX_COUNT = 2**62

#: Scalars of a configured state.
CONFIGURED = {"step": "positive", "window": "positive", "length": "count",
              "last_end": "time_or_nan", "cusum": "nonnegative", "last_report": "time",
              "ring_count": "count", "row_time": "time", "row_valid": "bool",
              "seg_n": "count", "seg_first": "count", "seg_ready": "count",
              "next_window": "count", "bound_upto": "count"}


def _scalar_ok(rule, value):
    if rule == "bool":
        return isinstance(value, bool)
    if rule in ("count", "tries"):   # (int64 in the compiled loops; tries: the doublings)
        return isinstance(value, int) and not isinstance(value, bool) \
            and 0 <= value <= (WARMUP_DOUBLINGS if rule == "tries" else _MAX_COUNT)
    if not isinstance(value, float):
        return False
    return {"positive": math.isfinite(value) and value > 0,
            "nonnegative": math.isfinite(value) and value >= 0,
            "time": value == -math.inf or math.isfinite(value),
            "finite": math.isfinite(value),
            "time_or_nan": not math.isinf(value)}[rule]


def state_layout(tracker, configured):
    """Every array of a tracker's state: its shape and what its values may hold.

    Parameters
    ----------
    tracker : Tracker
        Constructed from the saved configuration (and, for a configured state, its
        constants derived: ``overlap``).
    configured : bool
        Whether the window is chosen (the state of the windows) or not (the warm-up's
        samples only).

    Returns
    -------
    dict
        Key -> ``(shape, values)``: ``shape`` a tuple of ints and of names of lengths
        that every array naming them must share; ``values`` ``"finite"`` or
        ``"no_inf"`` (NaN marks a missing sample).
    """
    signals = tracker._signals
    if not configured:
        return {"warm_t": (("warm",), "finite"),
                **{f"warm:{n}": (("warm",), "no_inf") for n in signals}}
    p, m = len(tracker.parameters), len(tracker.multiplicities)
    q, lags = p * (p + 1), 2 * tracker.overlap
    layout = {"R": ((m, p + 1, p + 1), "finite"), "G": ((m, p + 1, p + 1), "finite"),
              "U": ((lags + 1, q, q), "finite"), "W": ((2,), "finite"),
              "bound": ((2, 8), "finite"), "previous_test": ((p + 2,), "no_inf"),
              "ring_rows": ((lags, q), "finite"), "ring_times": ((lags,), "finite"),
              "pend_t": (("pend",), "finite"), "buf_t": (("buf",), "finite")}
    for name in signals:
        layout[f"pend:{name}"] = (("pend",), "no_inf")
        layout[f"buf:{name}"] = (("buf",), "finite")
    for name, k in tracker._needs_derivatives:
        layout[f"der:{name}:{k}"] = ((f"der:{name}:{k}",), "finite")
    for i in range(len(tracker.model.terms)):
        layout[f"fac:{i}"] = (("fac",), "finite")
        layout[f"sen:{i}"] = (("fac",) if i in tracker._noisy else (0,), "finite")
        if i in tracker._sign_terms:
            layout[f"steps_t:{i}"] = ((f"steps:{i}",), "finite")
            layout[f"steps_s:{i}"] = ((f"steps:{i}",), "finite")
    return layout


def _check_keys(path, expected, held, what):
    missing, extra = sorted(set(expected) - set(held)), sorted(set(held) - set(expected))
    if missing or extra:
        raise InputDataError(f"{path}: not this tracker's state ({what}"
                            + (f" missing {', '.join(missing)}" if missing else "")
                            + (";" if missing and extra else "")
                            + (f" unexpected {', '.join(extra)}" if extra else "") + ")")


def check_state(path, tracker, scalars, arrays):
    """Make ``tracker`` hold the saved state, each scalar and array checked.

    Parameters
    ----------
    path : str or path-like
        The file (named in the refusals).
    tracker : Tracker
        Constructed from the saved configuration.
    scalars, arrays : dict
        As :func:`read` returns them.

    Raises
    ------
    InputDataError
        A key missing or unexpected, a scalar out of its range, an array of another
        dtype, shape or with non-finite values where the state holds finite ones, or
        counters that do not match the arrays' lengths.
    """
    configured = scalars.get("configured")
    if not isinstance(configured, bool):
        raise InputDataError(f"{path}: scalar 'configured' is {configured!r}")
    rules = {**SCALARS, **(CONFIGURED if configured else {})}
    _check_keys(path, rules, set(scalars) - set(OPTIONAL), "scalars:")
    for key, value in scalars.items():
        if not _scalar_ok({**rules, **OPTIONAL}[key], value):
            raise InputDataError(f"{path}: scalar {key!r} is {value!r}")
    if configured:
        from algid.identification._window_rule import min_length

        length, step, rate = scalars["length"], scalars["step"], tracker.config["rate"]
        low, high = STEP_RANGE
        if not low <= step <= high or (rate is not None
                                       and abs(step * rate - 1.0) > RATE_TOLERANCE):
            raise InputDataError(f"{path}: sampling step {step!r} s is not one a tracker "
                                 f"uses{'' if rate is None else f' at {rate:g} Hz'}")
        if not min_length(tracker.multiplicities) <= length <= MAX_WINDOW_SAMPLES + 1 \
                or scalars["window"] != (length - 1) * scalars["step"]:
            raise InputDataError(f"{path}: window of {length} samples of "
                                f"{scalars['step']!r} s is not {scalars['window']!r} s or "
                                f"not one a tracker uses")
        try:
            tracker._derive(length, scalars["step"])
        except AlgidError as exc:
            raise InputDataError(f"{path}: {exc}") from None
    layout = state_layout(tracker, configured)
    _check_keys(path, layout, arrays, "arrays:")
    lengths = {}
    state = {}
    for key, (shape, values) in layout.items():
        array = arrays[key]
        if array.dtype.kind != "f" or array.dtype.itemsize != 8 \
                or array.ndim != len(shape):
            raise InputDataError(f"{path}: array {key!r} is {array.dtype} of shape "
                                f"{array.shape}, not float64 of {len(shape)} dimension"
                                f"{'s' if len(shape) != 1 else ''}")
        for axis, (size, want) in enumerate(zip(array.shape, shape)):
            if isinstance(want, str):   # a length that arrays share
                held, first = lengths.setdefault(want, (size, key))
                if size != held:
                    raise InputDataError(f"{path}: array {key!r} has {size} samples where "
                                        f"{first!r} has {held} (they must agree)")
            elif size != want:
                raise InputDataError(f"{path}: array {key!r} has shape {array.shape}; this "
                                    f"tracker's has {want} along axis {axis}")
        array = np.ascontiguousarray(array, dtype=np.float64)   # (native byte order)
        if np.isinf(array).any() or (values == "finite" and np.isnan(array).any()):
            raise InputDataError(f"{path}: array {key!r} holds non-finite values")
        state[key] = array
    if configured:
        _check_counters(path, tracker, scalars, {k: v[0] for k, v in lengths.items()})
    tracker.state = TrackerState.from_flat(
        {**scalars, **state}, tracker._signals, tracker._needs_derivatives,
        len(tracker.model.terms), tracker._sign_terms)


def _check_counters(path, tracker, s, lengths):
    """The segment's counters against the arrays' lengths: every index the window
    loops form from them falls inside the arrays."""
    first, ready, n = s["seg_first"], s["seg_ready"], s["seg_n"]
    held = lengths.get("buf", 0)
    ok = (first <= ready <= n and held == n - first and lengths.get("fac", 0) == ready - first
          and all(lengths[k] <= held for k in lengths if k.startswith("der:"))
          and first <= s["next_window"] * tracker.stride
          and (s["next_window"] == 0
               or (s["next_window"] - 1) * tracker.stride + tracker.length <= ready)
          and s["bound_upto"] <= ready and (first == 0 or first <= s["bound_upto"] - 8))
    if not ok:
        raise InputDataError(f"{path}: the segment's counters (samples {n}, first {first}, "
                            f"ready {ready}, next window {s['next_window']}, bound "
                            f"{s['bound_upto']}) do not match its arrays ({held} samples)")
