"""The state of an :class:`algid.Tracker`: typed, bounded, and flat for its file.

A tracker holds its stream's counters (:class:`TrackerState`); before its window is
chosen, the warm-up's samples (:class:`Warmup`); then the accumulated window equations
(:class:`Sums`), the change test's memory (:class:`Tests`), the samples held until they
can complete a window (:class:`Pending`) and the current run of contiguous samples
(:class:`Segment`: its samples and the values computed from them that windows still
read).  Arrays are float64 and 1-D in time unless said otherwise; every size is bounded
by the window and the number of parameters, whatever the stream's length.

:meth:`TrackerState.flat` names every scalar and array by a string key (``"seg_n"``,
``"fac:0"``, ...), the layout of the saved file
(:mod:`algid.identification._tracker_file`); :meth:`TrackerState.from_flat` reads it back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from algid.errors import InputDataError
from algid.identification._window_rule import MIN_SPARE_WINDOWS, min_length

__all__ = ["TrackerState", "TrackUpdate", "TrackerSetupError", "Warmup", "Sums", "Tests",
           "Pending", "Segment", "MAX_WINDOW_SAMPLES", "WARMUP_DOUBLINGS", "check_half_life",
           "window_samples",
           "as_seconds"]

#: Longest window (samples) a tracker accepts: its state holds a few arrays of a
#: window's samples.
MAX_WINDOW_SAMPLES = 2**20

#: Doublings of the warm-up span at most, while the window's choice is refused or is at
#: least half the longest window the span allows.
WARMUP_DOUBLINGS = 3


def _empty():
    return np.empty(0)


class TrackerSetupError(InputDataError):
    """A refusal of the tracker's configuration once the stream shows its sampling step
    (a window, half-life or false-alarm rate that cannot work at it): no later sample
    can change it, unlike a refusal of the samples of one chunk."""


def as_seconds(value):
    """An optional duration as a Python float (NumPy scalars too: a configuration is
    saved as JSON, and a float32 would round the forgetting)."""
    return None if value is None else float(value)


def window_samples(window, step, multiplicities):
    """The samples of a tracker's window of ``window`` seconds at ``step``, or the
    refusal of a window longer than a tracker keeps or shorter than the kernels need
    (both trackers' words).

    Parameters
    ----------
    window, step : float
        Seconds.
    multiplicities : tuple of int
        The kernels' multiplicities.

    Returns
    -------
    int

    Raises
    ------
    TrackerSetupError
    """
    samples = window / step + 1
    if samples > MAX_WINDOW_SAMPLES:  # (before any array of that length is made)
        raise TrackerSetupError(f"window {window:g} s ({samples:.3g} samples) is longer "
                                f"than a tracker keeps ({MAX_WINDOW_SAMPLES} samples, "
                                f"{(MAX_WINDOW_SAMPLES - 1) * step:.4g} s at this rate)")
    length = int(round(window / step)) + 1
    shortest = min_length(multiplicities)
    if length < shortest:
        raise TrackerSetupError(f"window {window:g} s ({length} samples) is shorter than the "
                                f"kernels of multiplicity {max(multiplicities)} need; "
                                f"use at least {(shortest - 1) * step:.4g} s")
    return length


def check_half_life(half_life, length, step, stride, overlap, parameters):
    """Refuse a half-life under which even an endless stream never holds the effective
    windows an estimate of ``parameters`` parameters needs (it would report NaN, or a
    system's tracker noise).

    Parameters
    ----------
    half_life : float or None
    length : int
        Samples per window.
    step : float
        Sampling step (s).
    stride, overlap : int
        Samples between window starts, and windows that share a sample with one.
    parameters : int

    Raises
    ------
    TrackerSetupError
    """
    if half_life is None:
        return
    ratio = 2.0 ** (-stride * step / half_life)  # weight of a window over the next's
    # (sum w)**2 / sum w**2 of the geometric weights of an endless stream
    most = (1.0 + ratio) / (1.0 - ratio) / overlap if ratio < 1.0 else math.inf
    needed = parameters + MIN_SPARE_WINDOWS  # (as the solvers require)
    if most < needed:
        n = needed * overlap
        shortest = stride * step * math.log(2.0) / math.log((n + 1) / (n - 1))
        raise TrackerSetupError(f"half_life {half_life:g} s is too short for the window "
                                f"{(length - 1) * step:.4g} s: it leaves at most "
                                f"{most:.2g} effective windows where the "
                                f"{parameters} parameters need {needed}; use at "
                                f"least {shortest:.4g} s")


@dataclass
class Warmup:
    """Samples held until the sampling step and the window are fixed.

    Attributes
    ----------
    t : numpy.ndarray
        Their times.
    signals : dict
        Signal name -> samples.
    tries : int
        Doublings of the warm-up span tried for the window (at most
        :data:`WARMUP_DOUBLINGS`).
    """

    t: np.ndarray = field(default_factory=_empty)
    signals: dict = field(default_factory=dict)
    tries: int = 0


@dataclass
class Sums:
    """The accumulated window equations (with forgetting) and their lagged products.

    Attributes
    ----------
    R, G : numpy.ndarray
        Shape ``(m, p + 1, p + 1)`` per multiplicity: the triangular factor of the
        stacked ``[A | b]`` and the noise covariance of the bias compensation.
    U : numpy.ndarray
        Shape ``(lags + 1, q, q)``: lagged products of the scores (standard errors).
    W : numpy.ndarray
        Shape ``(2,)``: the sums of the window weights and of their squares.
    bound : numpy.ndarray
        Shape ``(2, 8)``: sums of the output's squared differences (the noise bound).
    last_end : float
        Time of the last window end accumulated (NaN before the first).
    ring_rows, ring_times : numpy.ndarray
        The last ``lags`` windows' score rows and end times.
    ring_count : int
        Windows held in the ring.
    """

    R: np.ndarray
    G: np.ndarray
    U: np.ndarray
    W: np.ndarray
    bound: np.ndarray
    ring_rows: np.ndarray
    ring_times: np.ndarray
    last_end: float = math.nan
    ring_count: int = 0


@dataclass
class Tests:
    """The change test's memory (a CUSUM of innovations of disjoint windows).

    Attributes
    ----------
    cusum : float
        The statistic.
    previous_test : numpy.ndarray
        Shape ``(p + 2,)``: the last tested window's estimate, residual variance and
        long-run factor (NaN when it had none).
    last_report : float
        Time of the last window end reported.
    """

    previous_test: np.ndarray
    cusum: float = 0.0
    last_report: float = -math.inf


@dataclass
class Pending:
    """Samples held until they can complete a window (processed together: the result
    does not depend on the chunking).

    Attributes
    ----------
    t : numpy.ndarray
    signals : dict
        Signal name -> samples.
    """

    t: np.ndarray = field(default_factory=_empty)
    signals: dict = field(default_factory=dict)


@dataclass
class Segment:
    """The current run of contiguous samples: a gap or a NaN row starts a new one.

    Counters are in the segment's samples; the arrays hold its samples from ``first``
    (those before are dropped once no window or derivative reads them).

    Attributes
    ----------
    n : int
        Samples of the segment seen.
    first : int
        Index of the arrays' first sample.
    ready : int
        Samples whose factors are computed.
    next_window : int
        Index of the next window to form.
    bound_upto : int
        Samples whose squared differences are in the noise bound.
    t : numpy.ndarray
        Times, from ``first``.
    signals : dict
        Signal name -> samples, from ``first``.
    derivatives : dict
        ``(signal, order)`` -> derivative estimates, from ``first`` (derivatives inside
        factors).
    factors, sensitivities : list of numpy.ndarray
        Per term: its factor's values and the output sensitivity of a noisy term (empty
        for the others), from ``first`` up to ``ready``.
    sign_times, sign_steps : dict
        Per ``sign()`` term: the times and the signed sizes of the steps of its sign.
    """

    t: np.ndarray = field(default_factory=_empty)
    signals: dict = field(default_factory=dict)
    derivatives: dict = field(default_factory=dict)
    factors: list = field(default_factory=list)
    sensitivities: list = field(default_factory=list)
    sign_times: dict = field(default_factory=dict)
    sign_steps: dict = field(default_factory=dict)
    n: int = 0
    first: int = 0
    ready: int = 0
    next_window: int = 0
    bound_upto: int = 0


@dataclass
class TrackerState:
    """Everything a tracker carries from one chunk to the next.

    Attributes
    ----------
    seen : int
        Samples received.
    last_time : float
        Time of the last sample received.
    last_stamp : float
        With ``rate=`` and a time column beside it, the column's last value (NaN: none).
    alarms : int
        Alarms raised.
    warmup : Warmup or None
        The warm-up's samples; None once the window is chosen (``configured``).
    step, window : float or None
        The sampling step and the window (s), once chosen.
    length : int or None
        The window in samples.
    row_time : float
        Time of the last sample seen by the cutting at gaps.
    row_valid : bool
        Whether it was valid (a NaN row cuts the stream).
    sums, tests, pending, segment
        Once configured (:class:`Sums`, :class:`Tests`, :class:`Pending`,
        :class:`Segment`).
    """

    seen: int = 0
    last_time: float = -math.inf
    last_stamp: float = math.nan
    alarms: int = 0
    warmup: Warmup | None = field(default_factory=Warmup)
    step: float | None = None
    window: float | None = None
    length: int | None = None
    row_time: float = -math.inf
    row_valid: bool = True
    sums: Sums | None = None
    tests: Tests | None = None
    pending: Pending | None = None
    segment: Segment | None = None

    @property
    def configured(self):
        """Whether the sampling step and the window are fixed."""
        return self.warmup is None

    def size(self):
        """Numbers in the state (bounded whatever the stream's length).

        Returns
        -------
        int
        """
        return int(sum(np.size(v) for v in self.flat().values()))

    # ---------------------------------------------------------------- the file's keys
    def flat(self):
        """Every scalar and array by its key in the saved file.

        Returns
        -------
        dict
            String key -> float, int, bool or float64 array.
        """
        out = {"seen": self.seen, "last_time": self.last_time,
               "configured": self.configured, "alarms": self.alarms}
        if not math.isnan(self.last_stamp):
            out["last_stamp"] = self.last_stamp
        if not self.configured:
            warm = self.warmup
            if warm.tries:
                out["warm_tries"] = warm.tries
            out["warm_t"] = warm.t
            out.update({f"warm:{name}": v for name, v in warm.signals.items()})
            return out
        sums, tests, seg = self.sums, self.tests, self.segment
        out.update(step=self.step, window=self.window, length=self.length,
                   row_time=self.row_time, row_valid=self.row_valid,
                   R=sums.R, G=sums.G, U=sums.U, W=sums.W, bound=sums.bound,
                   last_end=sums.last_end, ring_rows=sums.ring_rows,
                   ring_times=sums.ring_times, ring_count=sums.ring_count,
                   cusum=tests.cusum, previous_test=tests.previous_test,
                   last_report=tests.last_report, pend_t=self.pending.t,
                   seg_n=seg.n, seg_first=seg.first, seg_ready=seg.ready,
                   next_window=seg.next_window, bound_upto=seg.bound_upto, buf_t=seg.t)
        out.update({f"pend:{name}": v for name, v in self.pending.signals.items()})
        out.update({f"buf:{name}": v for name, v in seg.signals.items()})
        out.update({f"der:{name}:{k}": v for (name, k), v in seg.derivatives.items()})
        out.update({f"fac:{i}": v for i, v in enumerate(seg.factors)})
        out.update({f"sen:{i}": v for i, v in enumerate(seg.sensitivities)})
        out.update({f"steps_t:{i}": v for i, v in seg.sign_times.items()})
        out.update({f"steps_s:{i}": v for i, v in seg.sign_steps.items()})
        return out

    @classmethod
    def from_flat(cls, flat, signals, derivatives, terms, sign_terms):
        """The state of :meth:`flat`'s keys (checked beforehand: every key present).

        Parameters
        ----------
        flat : dict
            Key -> value, as :meth:`flat` writes them.
        signals : sequence of str
            The model's signals.
        derivatives : sequence of (str, int)
            The derivatives inside factors.
        terms : int
            Number of the model's terms.
        sign_terms : sequence of int
            The terms of ``sign()``.

        Returns
        -------
        TrackerState
        """
        state = cls(seen=flat["seen"], last_time=flat["last_time"], alarms=flat["alarms"],
                    last_stamp=flat.get("last_stamp", math.nan))
        if not flat["configured"]:
            state.warmup = Warmup(flat["warm_t"], {n: flat[f"warm:{n}"] for n in signals},
                                  flat.get("warm_tries", 0))
            return state
        state.warmup = None
        state.step, state.window, state.length = flat["step"], flat["window"], flat["length"]
        state.row_time, state.row_valid = flat["row_time"], flat["row_valid"]
        state.sums = Sums(R=flat["R"], G=flat["G"], U=flat["U"], W=flat["W"],
                          bound=flat["bound"], ring_rows=flat["ring_rows"],
                          ring_times=flat["ring_times"], last_end=flat["last_end"],
                          ring_count=flat["ring_count"])
        state.tests = Tests(previous_test=flat["previous_test"], cusum=flat["cusum"],
                            last_report=flat["last_report"])
        state.pending = Pending(flat["pend_t"], {n: flat[f"pend:{n}"] for n in signals})
        state.segment = Segment(
            t=flat["buf_t"], signals={n: flat[f"buf:{n}"] for n in signals},
            derivatives={(n, k): flat[f"der:{n}:{k}"] for n, k in derivatives},
            factors=[flat[f"fac:{i}"] for i in range(terms)],
            sensitivities=[flat[f"sen:{i}"] for i in range(terms)],
            sign_times={i: flat[f"steps_t:{i}"] for i in sign_terms},
            sign_steps={i: flat[f"steps_s:{i}"] for i in sign_terms},
            n=flat["seg_n"], first=flat["seg_first"], ready=flat["seg_ready"],
            next_window=flat["next_window"], bound_upto=flat["bound_upto"])
        return state


@dataclass
class TrackUpdate:
    """What :meth:`Tracker.update` reports for one chunk.

    Attributes
    ----------
    parameters : tuple of str
    t : numpy.ndarray
        Times of the window ends reported (the stream's time of their last sample).
    values, stderr, numerical_error : numpy.ndarray
        Shape ``(len(t), p)``: estimates, standard errors and numerical errors (NaN
        until the parameters are determined).
    alarms : numpy.ndarray
        Times of the alarms raised in the chunk.

    Examples
    --------
    >>> import numpy as np
    >>> from algid import Tracker
    >>> t = np.arange(2000) / 100.0
    >>> u = np.sin(t) + np.sin(3.1 * t)
    >>> y = (np.sin(t - np.arctan(0.5)) / np.hypot(2, 1)
    ...      + np.sin(3.1 * t - np.arctan(1.55)) / np.hypot(2, 3.1))
    >>> out = Tracker("y' + a*y = b*u", "a b", rate=100, window=0.5).update({"y": y, "u": u})
    >>> len(out) == len(out.t), out.parameters, round(float(out["a"][-1]), 4)
    (True, ('a', 'b'), 2.0)
    """

    parameters: tuple
    t: np.ndarray
    values: np.ndarray
    stderr: np.ndarray
    numerical_error: np.ndarray
    alarms: np.ndarray = field(default_factory=lambda: np.empty(0))

    def __len__(self):
        return len(self.t)

    def __getitem__(self, name):
        return self.values[:, self.parameters.index(name)]

    def last(self):
        """The last estimates.

        Returns
        -------
        dict
            ``{parameter: value}`` (empty before any window end).
        """
        return {} if not len(self.t) else dict(zip(self.parameters,
                                                   self.values[-1].tolist()))
