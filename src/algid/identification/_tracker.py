"""On-line identification: the window equations of :func:`algid.identify` on a stream.

:class:`Tracker` forms each window equation of ``identify`` as soon as the window's last
sample has arrived (the same term kernels and assembly, ``term_rows``), and accumulates
the equations: the triangular factor of the stacked ``[A | b]`` (a QR update per window,
never the normal equations), the noise covariance terms of the bias compensation, and
the lagged products that the standard errors need.  With ``half_life=h`` every sum is
weighted by ``2**(-age / h)``; ``None`` keeps every window, and the last estimate then
equals ``identify`` on the samples so far at the same window and method (to round-off),
for models without derivatives inside factors.

Causality makes the only differences: a derivative inside a factor (``sign(q')``) comes
from the centred algebraic differentiator, final :attr:`Tracker.lag` samples after its
sample, and ``sign(v)`` steps where linear interpolation puts the zero of ``v``, where
``identify`` places the crossings with its final estimate.

Standard errors are a sandwich whose middle counts the overlap of the windows (their
lagged correlations, with identify's flat-top weights) and the forgetting (the
effective number of windows ``(sum w)**2 / sum w**2``).  Alarms come from a CUSUM of
the innovations of windows that share no sample (:mod:`algid.identification`'s
``_change_detection``), tuned to a false-alarm rate per second of stream time.

The state is bounded by the window and the number of parameters, whatever the stream's
length; :meth:`Tracker.save` writes it to a NumPy ``.npz`` file (arrays, a JSON header
and their checksum, no pickled object) and :meth:`Tracker.load` checks it
(:mod:`algid.identification._tracker_file`) and continues it bit for bit.  See the
user guide, "Tracking on a stream", for the details and the measured figures.
"""

from __future__ import annotations

import math
import types

import numpy as np
from numpy.polynomial import chebyshev

from algid._record_input import check_rate, read_chunk
from algid.errors import AlgidError, InputDataError
from algid.identification._arguments import check_arguments, check_model_columns, check_seconds
from algid.identification._change_detection import (
    DEFAULT_FALSE_ALARM_RATE,
    INCREMENT_CAP,
    cusum_design,
)
from algid.identification._methods import TRACKER_METHODS
from algid.identification._records import GAP_FACTOR, UNIFORM_TOLERANCE
from algid.identification._tracker_kernels import kernels
from algid.identification._tracker_state import (
    WARMUP_DOUBLINGS,
    Pending,
    Segment,
    Sums,
    Tests,
    TrackerSetupError,
    TrackerState,
    TrackUpdate,
    Warmup,
    as_seconds,
    check_half_life,
    window_samples,
)
from algid.identification._window_kernels import (
    TERM_KERNELS,
    window_sample_weights,
)
from algid.identification._window_problem import factor_sensitivity, window_stride
from algid.identification._window_rule import MIN_SPARE_WINDOWS, check_multiplicities
from algid.models._argument import estimator_module
from algid.models._compiled import model_of
from algid.models._expression import Call, Signal
from algid.models._grammar import parse_equation
from algid.models._model import Model
from algid.models._system import is_system, parse_system
from algid.signals._differentiation import algebraic_derivative

__all__ = ["Tracker", "TrackUpdate", "DEFAULT_WARMUP", "DEFAULT_FALSE_ALARM_RATE",
           "DERIVATIVE_STEPS"]

#: Seconds of stream on which the window is first chosen when none is given (the span
#: doubles, three times at most, while identify refuses it or keeps a window of at least
#: half the longest it allows).
DEFAULT_WARMUP = 2.0

#: Steps of the (centred) differentiator of derivatives inside factors.
DERIVATIVE_STEPS = 20

#: Steps seen before the sampling step of a time column is fixed (their median).
STEP_SAMPLES = 16

def _lag_weights(overlap):
    lags = 2 * overlap
    return np.array([1.0 if lag <= overlap else 1.0 - (lag - overlap) / (lags - overlap + 1.0)
                     for lag in range(lags + 1)])


def _stride_and_overlap(length):
    """Samples between window starts, and windows that share a sample with one."""
    stride = window_stride(length)
    return stride, -(-length // stride)





class Tracker:
    """The streaming form of :func:`algid.identify`, with forgetting and change alarms.

    The method, its differences with :func:`algid.identify`, the standard errors and the
    alarms: the user guide, "Tracking on a stream".

    Parameters
    ----------
    equation : str, Model, module or list of str
        The model, as for :func:`algid.identify` (equation text, or a compiled model).
        A list of equations that share ``parameters`` makes a tracker of the system
        (:class:`~algid.identification._system_tracker.SystemTracker`: the joint window
        equations, one alarm test per equation; see the user guide, "Systems of
        equations").
    parameters : sequence of str or str
        The unknown parameters (not needed for a Model or a compiled model).
    rate : float, optional
        Sampling rate (Hz) of a stream without a time column.
    time : str, optional
        Name of the time column (default ``t`` or ``time`` when no rate is given).
    output : str, optional
        Output signal (by default the one of highest derivative order).
    window : float, optional
        Window length (s); chosen by identify's rule on the first ``warmup`` seconds
        when omitted, a span doubled (three times at most) while identify refuses it
        or keeps a window of at least half the longest it allows; with forgetting, no
        further than two thirds of the memory ``2 * half_life / ln 2``.  A stream that
        ends (``last=True``) before the next span has the window of the last span
        identify accepted.
    half_life : float, optional
        Half-life (s of stream time) of the forgetting; None keeps every window.
    method : {"bc", "ls"}
        Bias-compensated or plain least squares (as in :func:`algid.identify`).
    warmup : float
        Seconds of stream on which to choose the window first (see ``window``).
    false_alarm_rate : float
        Design false alarms per second of stream time (see the user guide, "Tracking on a
        stream").
    every : float, optional
        Report only the window ends that cross a multiple of ``every`` seconds of stream
        time (every window end by default).

    Raises
    ------
    ModelError, InputDataError
        One-line messages, as :func:`algid.identify`'s.

    Examples
    --------
    >>> import numpy as np
    >>> from algid import Tracker
    >>> t = np.arange(3000) / 100.0            # y' + 2 y = u, in steady state
    >>> w = np.array([1.0, 3.1])[:, None]
    >>> u = np.sin(w * t).sum(axis=0)
    >>> y = (np.sin(w * t - np.arctan(w / 2)) / np.hypot(2, w)).sum(axis=0)
    >>> tracker = Tracker("y' + a*y = b*u", "a b", rate=100, window=0.5)
    >>> out = tracker.update({"y": y, "u": u})
    >>> [round(float(v), 4) for v in out.values[-1]]
    [2.0, 1.0]
    """

    def __new__(cls, equation=None, parameters=None, *, rate=None, time=None, output=None,
                window=None, half_life=None, method="bc", warmup=DEFAULT_WARMUP,
                false_alarm_rate=DEFAULT_FALSE_ALARM_RATE, every=None):
        if isinstance(equation, types.ModuleType) and hasattr(equation, "EQUATIONS"):
            equation = model_of(estimator_module(equation, parameters))  # a compiled system
        if not is_system(equation):
            return super().__new__(cls)
        # a system of equations: the joint window equations on the stream
        from algid.identification._system_tracker import SystemTracker

        if output is not None:
            raise InputDataError("output: a system's tracker takes the output of each of "
                                 "its equations")
        return SystemTracker(parse_system(equation, parameters), rate=rate, time=time,
                             window=window, half_life=half_life, method=method,
                             warmup=warmup, false_alarm_rate=false_alarm_rate, every=every)

    def __init__(self, equation, parameters=None, *, rate=None, time=None, output=None,
                 window=None, half_life=None, method="bc", warmup=DEFAULT_WARMUP,
                 false_alarm_rate=DEFAULT_FALSE_ALARM_RATE, every=None):
        if method not in TRACKER_METHODS:
            raise InputDataError(f"method must be {' or '.join(map(repr, TRACKER_METHODS))} "
                                 f"for a tracker, got {method!r} (instrumental variables "
                                 f"and the weighting of 'gls' need the whole record)")
        if isinstance(equation, types.ModuleType):  # a compiled model: its own equation
            equation = model_of(estimator_module(equation, parameters))
        check_arguments(equation, parameters, time=time, rate=rate, output=output,
                        window=window, method=method, methods=TRACKER_METHODS,
                        multiplicities=(8, 12), name="custom", iterations=1)
        check_seconds(half_life_or_none=half_life, warmup=warmup,
                      false_alarm_rate=false_alarm_rate, every_or_none=every)
        model = equation if isinstance(equation, Model) else parse_equation(
            equation, parameters, output=output)
        check_model_columns(model, time)
        self.model = model
        self.multiplicities = check_multiplicities(model, (8, 12))
        self.config = {"equation": model.equation, "parameters": list(model.parameters),
                       "output": model.output, "rate": None if rate is None else
                       check_rate(rate), "time": time, "window": as_seconds(window),
                       "half_life": as_seconds(half_life), "method": method,
                       "warmup": float(warmup), "false_alarm_rate": float(false_alarm_rate),
                       "every": as_seconds(every)}
        if rate is None and time is None:
            self.config["time"] = None   # found in the first chunk (t or time)
        self.parameters = tuple(model.parameters)
        self._signals = list(model.signals)
        self._sign_terms = [i for i, term in enumerate(model.terms)
                            if isinstance(term.factor, Call) and term.factor.function == "sign"]
        self._noisy = [i for i, term in enumerate(model.terms)
                       if model.output in term.factor.signals() and i not in self._sign_terms]
        self._needs_derivatives = model.needs_derivatives   # (a property: computed)
        self.lag = DERIVATIVE_STEPS // 2 if self._needs_derivatives else 0
        self.state = TrackerState(
            warmup=Warmup(signals={n: np.empty(0) for n in self._signals}))

    # ------------------------------------------------------------------ public
    @property
    def window(self):
        """The window length (s), or None before it is chosen."""
        return self.state.window

    @property
    def half_life(self):
        """The forgetting half-life (s), or None."""
        return self.config["half_life"]

    def state_size(self):
        """Floating-point numbers in the state (bounded whatever the stream's length).

        Returns
        -------
        int
        """
        return self.state.size()

    def update(self, chunk, *, last=False):
        """Stream the next samples.

        Parameters
        ----------
        chunk : mapping, pandas.DataFrame, xarray.Dataset or control.TimeResponseData
            Column name -> samples (any number, from one), as a record of
            :func:`algid.identify`: the model's signals and the time column (or none,
            with ``rate``).  Rows holding a NaN (or a masked sample) break the stream as
            gaps do.
        last : bool, optional
            The chunk ends the stream: every window end it completes is reported,
            whatever ``every`` (the stream's last one among them).

        Returns
        -------
        TrackUpdate
            Estimates at the window ends completed by these samples.

        Raises
        ------
        InputDataError
            Missing or non-numeric columns, columns of different lengths, times that do
            not increase (the state is left as it was), dates as times (give seconds,
            or ``rate``).  Once the step is known, a window, half-life or false-alarm
            rate that cannot work at it is a ``TrackerSetupError`` (an
            ``InputDataError``), raised again by every later call: no sample can
            change it.
        """
        t, columns = self._read(chunk)
        self._out = {"t": [], "values": [], "stderr": [], "error": [], "alarms": []}
        self._every = None if last else self.config["every"]
        warm = self.state.warmup
        if warm is not None:   # (not configured)
            warm.t = np.concatenate([warm.t, t])
            for name in self._signals:
                warm.signals[name] = np.concatenate([warm.signals[name], columns[name]])
            self._configure(last)
        else:
            self._pending(t, columns)
        p = len(self.parameters)
        out = self._out
        if not out["t"] and not out["alarms"]:   # most one-sample updates
            return TrackUpdate(self.parameters, np.empty(0), np.empty((0, p)),
                               np.empty((0, p)), np.empty((0, p)), np.empty(0))
        shape = (len(out["t"]), p)
        return TrackUpdate(self.parameters, np.array(out["t"], dtype=float),
                           np.array(out["values"], dtype=float).reshape(shape),
                           np.array(out["stderr"], dtype=float).reshape(shape),
                           np.array(out["error"], dtype=float).reshape(shape),
                           np.array(out["alarms"], dtype=float))

    def save(self, path):
        """Write the whole state to a NumPy ``.npz`` file.

        The file holds the arrays, a JSON header and a SHA-256 checksum of both.

        Parameters
        ----------
        path : str or path-like
        """
        from algid.identification._tracker_file import write  # (zipfile, hashlib: on use)

        write(path, self.config, self.state.flat())

    @classmethod
    def load(cls, path):
        """A tracker continuing the stream saved by :meth:`save`.

        Parameters
        ----------
        path : str or path-like

        Returns
        -------
        Tracker or SystemTracker
            What was saved (a system's tracker from a system's file).

        Raises
        ------
        InputDataError
            A file that is not a saved tracker, altered after it was saved (its checksum),
            or whose arrays do not fit its model and configuration (one line naming the
            file and the array).
        """
        from algid.identification._system_tracker_file import FORMAT as SYSTEM_FORMAT
        from algid.identification._tracker_file import FORMAT, FormatError, check_state, read

        try:
            config, scalars, arrays = read(path)
        except FormatError as exc:
            if exc.format != SYSTEM_FORMAT:
                raise FormatError(f"{path}: a tracker saved in format {exc.format!r}; this "
                                  f"version reads {FORMAT!r} (one equation) and "
                                  f"{SYSTEM_FORMAT!r} (a system)", exc.format) from None
            config = None
        if config is None:   # a system's tracker: its own state
            from algid.identification._system_tracker import SystemTracker

            return SystemTracker.load(path)
        try:
            tracker = cls(config["equation"], config["parameters"], rate=config["rate"],
                          time=config["time"], output=config["output"],
                          window=config["window"], half_life=config["half_life"],
                          method=config["method"], warmup=config["warmup"],
                          false_alarm_rate=config["false_alarm_rate"], every=config["every"])
        except AlgidError as exc:
            raise InputDataError(f"{path}: its configuration is refused: {exc}") from None
        tracker.config = config
        check_state(path, tracker, scalars, arrays)
        return tracker

    # ------------------------------------------------------------------ input
    def _read(self, chunk):
        t, columns, time, self.state.last_stamp = read_chunk(
            chunk, self._signals, time=self.config["time"], rate=self.config["rate"],
            seen=self.state.seen, last_time=self.state.last_time,
            last_stamp=self.state.last_stamp)
        self.config["time"] = time
        self.state.seen += len(t)
        if len(t):
            self.state.last_time = float(t[-1])
        return t, columns

    # ------------------------------------------------------------------ configuration
    def _configure(self, last=False):
        """Fix the step and the window once enough samples arrived (or the stream's
        ``last`` chunk did); replay them."""
        warm = self.state.warmup
        t = warm.t
        if not len(t):   # (an empty chunk first)
            return
        if self.config["rate"] is not None:
            step = 1.0 / self.config["rate"]
        elif len(t) > STEP_SAMPLES:
            step = float(np.median(np.diff(t[:STEP_SAMPLES + 1])))
        else:
            return
        window = self.config["window"]
        cut = len(t)
        if window is None:
            tried = warm.tries
            while True:
                span = self._span(tried)
                if t[-1] - t[0] < span:   # (the span's samples are not all here)
                    warm.tries = tried
                    if not last:
                        return
                    # the stream ended first: the window of the last span identify accepted
                    window, cut = self._earlier_window(t, step, tried)
                    if window is None:
                        return
                    break
                cut = int(np.searchsorted(t, t[0] + span, side="left")) + 1
                window, near_longest = self._choose_window(t[:cut], step)
                if window is None:   # refused: the window of a shorter span, else a longer
                    window, cut = self._earlier_window(t, step, tried)
                    if window is not None:
                        break
                # a window near the longest the span allows may be short of the rule's
                # best (on 2 s of a 1 Hz mode it kept 0.16 s, on 30 s 1.4 s): the next
                # span lets it look at longer ones (not beyond the forgetting's memory,
                # whose effective windows a longer window would leave too few)
                elif not (near_longest and tried < WARMUP_DOUBLINGS
                          and self._span(tried + 1) <= self._longest_span()):
                    break
                tried += 1
                if tried > WARMUP_DOUBLINGS:
                    raise TrackerSetupError(
                        f"no window could be chosen on the first {span:g} s of the stream "
                        f"(identify refuses them); give window=")
        length = window_samples(window, step, self.multiplicities)
        self._check_half_life(length, step)
        self._derive(length, step)   # (its refusals leave the state as it was)
        state = self.state
        state.step, state.window, state.length = step, (length - 1) * step, length
        state.warmup = None
        self._start_state()
        times, held = warm.t, warm.signals   # replayed: the window's choice on the first
        self._samples(times[:cut], {n: v[:cut] for n, v in held.items()})
        if cut < len(times):
            self._samples(times[cut:], {n: v[cut:] for n, v in held.items()})

    def _check_half_life(self, length, step):
        """Refuse a half-life under which even an endless stream never holds the
        effective windows an estimate needs (it would report NaN only)."""
        stride, overlap = _stride_and_overlap(length)
        check_half_life(self.config["half_life"], length, step, stride, overlap,
                        len(self.parameters))

    def _longest_span(self):
        """The longest span (s) to which the warm-up is extended for a longer window
        (infinite without forgetting): two thirds of the forgetting's memory
        ``M = 2 h / ln 2``, the span of an endless stream's effective windows
        ``(sum w)**2 / sum w**2``.

        identify's window ``L`` on a span ``S`` leaves ``S / L`` windows, at least the
        parameters plus 8; at ``T`` s of stream the forgetting keeps about
        ``M / L * tanh(T / M)`` of them (8/9 of it where a window's starts overrun it
        by a stride).  From ``S = 2 M / 3`` that is enough from about ``T = M`` on;
        from ``S`` near ``M``, at no ``T`` in the worst case (on 30 s of a 1 Hz mode
        with a half-life of 5 s, ``S = 8 M / 9`` gave a window none of whose reports
        was determined).
        """
        half_life = self.config["half_life"]
        return math.inf if half_life is None else 2.0 / 3.0 * 2.0 * half_life / math.log(2.0)

    def _span(self, tried):
        """The warm-up's span (s) after ``tried`` steps: ``warmup`` doubled at each, the
        step that would pass :meth:`_longest_span` stopping at it (the span where identify
        refuses the samples doubles on)."""
        span, longest = self.config["warmup"], self._longest_span()
        for _ in range(tried):
            span = min(2.0 * span, longest) if span < longest else 2.0 * span
        return span

    def _earlier_window(self, t, step, tried):
        """identify's window on the longest of the spans before ``tried`` steps that it
        accepts (None if none), and that span's samples."""
        for k in range(tried - 1, -1, -1):
            cut = int(np.searchsorted(t, t[0] + self._span(k), side="left")) + 1
            window, _ = self._choose_window(t[:cut], step)
            if window is not None:
                return window, cut
        return None, len(t)

    def _choose_window(self, t, step):
        """identify's window on the warm-up's samples at times ``t`` (None where it
        refuses them), and whether it is at least half the longest its rule looked at
        (the longest that ``t`` allows): twice the span lets the rule look at windows
        twice as long, and its criterion is flat near its best (on 8 s of the Duffing
        record of ``benchmarks.tracker_window`` it kept 0.19 s where 0.23 s was the
        longest, on 16 s 1.1 s)."""
        from algid.identification._identify import identify

        record = {name: self.state.warmup.signals[name][:len(t)] for name in self._signals}
        record["__t"] = t
        try:
            # (the Tracker places the steps of a sign(q') by local fits: the window
            # identify keeps for them)
            result = identify(record, self.model, time="__t", method=self.config["method"],
                              refine=False, crossings="local")
        except AlgidError:
            return None, False
        length = result.window / step + 1
        return result.window, bool(result.window_scores) \
            and 2 * length >= max(result.window_scores)

    def _derive(self, length, step):
        """Constants that follow from the configuration: the window of ``length``
        samples, the sampling ``step`` (s)."""
        self.length = length
        self.stride, self.overlap = _stride_and_overlap(length)
        self.lag_weights = _lag_weights(self.overlap)
        self.keep = length + self.lag + 2 * DERIVATIVE_STEPS
        self.k_cusum, self.h_cusum = cusum_design(self.config["false_alarm_rate"],
                                                  self.overlap * self.stride * step)
        self.needed = 1 + MIN_SPARE_WINDOWS
        p = len(self.parameters)
        index = {q: i for i, q in enumerate(self.parameters)}
        self._noisy_columns = []   # (column, signed coefficient, derivative, term)
        for i in self._noisy:
            term = self.model.terms[i]
            self._noisy_columns.append(
                (p if term.parameter is None else index[term.parameter],
                 (-1.0 if term.parameter is None else 1.0) * term.coefficient,
                 term.derivative, i))
        # the variance of k-th differences of white noise, per unit variance
        self._central = np.array([math.comb(2 * k, k) for k in range(1, 9)], dtype=float)
        self._half_life = np.inf if self.config["half_life"] is None \
            else float(self.config["half_life"])
        # the kernels' primitives (zero at the window's start), as step_window_integrals's
        self._primitives = {(a, k): chebyshev.chebint(TERM_KERNELS[(a, k)], scl=0.5, lbnd=-1)
                            for a in self.multiplicities for k in {
                                self.model.terms[i].derivative for i in self._sign_terms}}
        self._output_terms = {i for i in self._noisy
                              if self.model.terms[i].factor == Signal(self.model.output)}
        terms = self.model.terms   # as arrays for the loops' window equations
        # the quadrature weights of a uniform window of unit step, per multiplicity, term
        self._weight_table = np.array([[window_sample_weights(None, 1.0, length, a,
                                                              term.derivative)
                                        for term in terms] for a in self.multiplicities])
        self._term_table = {
            "derivatives": np.array([term.derivative for term in terms], dtype=np.int64),
            "coefficients": np.array([float(term.coefficient) for term in terms]),
            "columns": np.array([p if term.parameter is None else index[term.parameter]
                                 for term in terms], dtype=np.int64),
            "sign_terms": np.array([i in self._sign_terms for i in range(len(terms))]),
            "noisy": np.array([(c, k, i, self._noisy.index(i))
                               for c, _, k, i in self._noisy_columns],
                              dtype=np.int64).reshape(-1, 4),
            "noisy_weights": np.array([w for _, w, _, _ in self._noisy_columns])}
        # derivative taps of the centred algebraic differentiator, from its own function
        impulses = np.eye(DERIVATIVE_STEPS + 1)
        self._taps = {}
        for _, k in self._needs_derivatives:
            rows = np.array([algebraic_derivative(e, 1.0, derivative=k) for e in impulses])
            self._taps[k] = np.ascontiguousarray(rows.T)   # row i: the estimate at sample i

    def _start_state(self):
        state = self.state
        p = len(self.parameters)
        lags = 2 * self.overlap
        m = len(self.multiplicities)
        q = p * (p + 1)
        state.sums = Sums(R=np.zeros((m, p + 1, p + 1)), G=np.zeros((m, p + 1, p + 1)),
                          U=np.zeros((lags + 1, q, q)), W=np.zeros(2),
                          bound=np.zeros((2, 8)), ring_rows=np.zeros((lags, q)),
                          ring_times=np.zeros(lags))
        state.tests = Tests(previous_test=np.full(p + 2, np.nan))
        state.row_time, state.row_valid = -np.inf, True
        state.pending = Pending(signals={name: np.empty(0) for name in self._signals})
        self._new_segment()

    def _new_segment(self):
        state = self.state
        state.sums.ring_count = 0
        state.tests.previous_test = np.full(len(self.parameters) + 2, np.nan)
        terms = range(len(self.model.terms))
        state.segment = Segment(
            signals={name: np.empty(0) for name in self._signals},
            derivatives={(name, k): np.empty(0) for name, k in self._needs_derivatives},
            factors=[np.empty(0) for _ in terms], sensitivities=[np.empty(0) for _ in terms],
            sign_times={i: np.empty(0) for i in self._sign_terms},
            sign_steps={i: np.empty(0) for i in self._sign_terms})

    # ------------------------------------------------------------------ samples
    def _pending(self, t, columns):
        """Hold samples until they can complete a window, then process them together.

        Processing does not depend on how the samples are grouped, and no window can end
        before the segment holds ``next_window * stride + length + lag`` samples (gaps
        only delay it): short chunks cost one append until then.
        """
        s = self.state
        seg = s.segment
        s.pending.t = np.concatenate([s.pending.t, t])
        for name in self._signals:
            s.pending.signals[name] = np.concatenate([s.pending.signals[name], columns[name]])
        needed = seg.next_window * self.stride + self.length + self.lag
        if self.lag:
            needed = max(needed, DERIVATIVE_STEPS + 1)
        if seg.n + len(s.pending.t) >= needed:
            self._flush()

    def _flush(self):
        s = self.state
        t = s.pending.t
        columns = {name: s.pending.signals[name] for name in self._signals}
        s.pending.t = np.empty(0)
        for name in self._signals:
            s.pending.signals[name] = np.empty(0)
        self._samples(t, columns)

    def _samples(self, t, columns):
        """Cut the samples at gaps and NaN rows (as identify's records are cut); feed each
        run of valid rows to its segment."""
        s = self.state
        n = len(t)
        if not n:
            return
        valid = np.all([np.isfinite(columns[name]) for name in self._signals], axis=0)
        rows_before = np.concatenate([[s.row_time], t[:-1]])
        valid_before = np.concatenate([[s.row_valid], valid[:-1]])
        cut = (t - rows_before > GAP_FACTOR * s.step) | ~valid_before
        s.row_time, s.row_valid = float(t[-1]), bool(valid[-1])
        if valid.all() and not cut[1:].any():   # the common case: one run
            if cut[0] and s.segment.n:
                self._new_segment()
            self._extend(t, columns)
            return
        edges = np.flatnonzero(np.diff(np.concatenate([[0], valid.astype(int), [0]])))
        for start, stop in zip(edges[::2], edges[1::2]):
            pieces = [start, *(start + 1 + np.flatnonzero(cut[start + 1:stop])), stop]
            for a, b in zip(pieces[:-1], pieces[1:]):
                if cut[a] and s.segment.n:
                    self._new_segment()
                self._extend(t[a:b], {name: columns[name][a:b] for name in self._signals})

    def _extend(self, t, columns):
        seg = self.state.segment
        seg.t = np.concatenate([seg.t, t])
        for name in self._signals:
            seg.signals[name] = np.concatenate([seg.signals[name], columns[name]])
        seg.n += len(t)
        self._derivatives()
        self._factors()
        self._windows()
        self._trim()

    def _derivatives(self):
        """Derivatives inside factors, for the samples whose centred window arrived."""
        s = self.state
        seg = s.segment
        n, first = seg.n, seg.first
        half = DERIVATIVE_STEPS // 2
        for name, k in self._needs_derivatives:
            key = (name, k)
            done = first + len(seg.derivatives[key])
            final = n - half if n > DERIVATIVE_STEPS else 0   # samples with a final estimate
            if final <= done:
                continue
            y, t = seg.signals[name], seg.t
            values = np.empty(final - done)
            width = DERIVATIVE_STEPS + 1
            for i in range(done, min(final, half)):   # the first window's edge taps
                values[i - done] = self._taps[k][i] @ y[:width] \
                    / ((t[DERIVATIVE_STEPS] - t[0]) / DERIVATIVE_STEPS) ** k
            interior = np.arange(max(done, half), final)
            if interior.size:
                lo = interior - half - first
                yw = y[lo[:, None] + np.arange(width)]
                step = (t[lo + DERIVATIVE_STEPS] - t[lo]) / DERIVATIVE_STEPS
                values[interior - done] = np.einsum("ij,j->i", yw, self._taps[k][half]) \
                    / step ** k
            seg.derivatives[key] = np.concatenate([seg.derivatives[key], values])

    def _factors(self):
        """Factor values (and output sensitivities) of the samples ready for windows."""
        s = self.state
        seg = s.segment
        first = seg.first
        ready = seg.n - self.lag if self.lag else seg.n
        if self.lag and seg.n <= DERIVATIVE_STEPS:
            ready = 0
        done = seg.ready
        if ready <= done:
            return
        lo, hi = done - first, ready - first
        t = seg.t[lo:hi]
        values = {name: seg.signals[name][lo:hi] for name in self._signals}
        for name, k in self._needs_derivatives:
            values[(name, k)] = seg.derivatives[(name, k)][lo:hi]
        output = self.model.output
        h = 1e-6 * np.maximum(np.abs(values[output]), 1e-300)
        with np.errstate(all="ignore"):
            factors = [np.asarray((term.factor.args[0] if i in self._sign_terms else
                                   term.factor).evaluate(values, t), dtype=float)
                       for i, term in enumerate(self.model.terms)]
        factors = [z if z.shape == t.shape else z * np.ones(len(t)) for z in factors]
        for i, term in enumerate(self.model.terms):
            z = factors[i]
            if not np.isfinite(z).all():
                row = int(np.flatnonzero(~np.isfinite(z))[0])
                raise InputDataError(f"the term {term.factor} is {z[row]} at t = "
                                     f"{t[row]:.6g} s: the data leave its domain")
            if i in self._sign_terms:
                self._sign_steps(i, z, t, lo)
            seg.factors[i] = np.concatenate([seg.factors[i], z])
            if i in self._noisy:
                sens = np.ones(len(t)) if i in self._output_terms else \
                    factor_sensitivity(term.factor, output, values, t, h)
                seg.sensitivities[i] = np.concatenate([seg.sensitivities[i], sens])
        seg.ready = ready

    def _sign_steps(self, i, v, t, lo):
        """Steps of ``sign(v)`` between the new samples and the one before them."""
        seg = self.state.segment
        if lo > 0:
            v = np.concatenate([seg.factors[i][lo - 1:lo], v])
            t = np.concatenate([seg.t[lo - 1:lo], t])
        z = np.sign(v)
        at = np.flatnonzero(z[1:] != z[:-1])
        fraction = v[at] / (v[at] - v[at + 1])
        seg.sign_times[i] = np.concatenate([seg.sign_times[i],
                                            t[at] + fraction * (t[at + 1] - t[at])])
        seg.sign_steps[i] = np.concatenate([seg.sign_steps[i], z[at + 1] - z[at]])

    def _trim(self):
        """Drop the samples no window or derivative will read again (bounded state)."""
        seg = self.state.segment
        start = min(seg.next_window * self.stride, seg.bound_upto - 8,
                    seg.n - self.keep)
        drop = max(0, start - seg.first)
        if drop < 4 * self.keep:   # in blocks: fewer copies
            return
        t0 = seg.t[drop]
        seg.t = seg.t[drop:]
        for name in self._signals:
            seg.signals[name] = seg.signals[name][drop:]
        for name, k in self._needs_derivatives:
            seg.derivatives[(name, k)] = seg.derivatives[(name, k)][drop:]
        for i in range(len(self.model.terms)):
            seg.factors[i] = seg.factors[i][drop:]
            if i in self._noisy:
                seg.sensitivities[i] = seg.sensitivities[i][drop:]
            if i in self._sign_terms:
                keep = seg.sign_times[i] >= t0
                seg.sign_times[i] = seg.sign_times[i][keep]
                seg.sign_steps[i] = seg.sign_steps[i][keep]
        seg.first += drop

    # ------------------------------------------------------------------ windows
    def _windows(self):
        s = self.state
        seg = s.segment
        L, stride = self.length, self.stride
        count = (seg.ready - L) // stride + 1 if seg.ready >= L else 0
        first_window = seg.next_window
        if count <= first_window:
            return
        starts = np.arange(first_window, count) * stride - seg.first
        n = len(starts)
        rows, grams = self._rows_and_grams(starts)
        ends = seg.t[starts + L - 1]
        squares, ranges = self._bound_squares(starts)
        m, q1 = len(self.multiplicities), len(self.parameters) + 1
        sums = {"R": np.empty((n, m, q1, q1)), "G": np.empty((n, m, q1, q1)),
                "W": np.empty((n, 2)), "bound": np.empty((n, 2, 8)), "decay": np.empty(n)}
        window_sums = kernels().window_sums
        window_sums(rows, grams, ends, float(s.sums.last_end), self._half_life, squares, ranges,
                    s.sums.R, s.sums.G, s.sums.W, s.sums.bound, sums["R"], sums["G"], sums["W"],
                    sums["bound"], sums["decay"])
        s.sums.last_end = float(ends[-1])
        indices = first_window + np.arange(n)
        tested = indices % self.overlap == 0
        every = self._every
        if every is None:
            report = np.ones(n, bool)
        else:   # a window end that crosses a multiple of ``every`` since the last report
            crossed = np.floor(ends / every)
            report = crossed > np.concatenate([[np.floor(s.tests.last_report / every)],
                                               crossed[:-1]])
        n_eff = sums["W"][:, 0] ** 2 / sums["W"][:, 1] / self.overlap
        wanted = (tested | report) & (n_eff >= self.needed)   # enough for one parameter
        bounds = self._bounds(sums["bound"])
        theta, stderr, error, residual, kappa = self._solve(rows, ends, sums, bounds, n_eff,
                                                             wanted, report)
        top = self.multiplicities.index(max(self.multiplicities))
        for w in np.flatnonzero(tested):
            self._test(ends[w], rows[top, w], theta[w], residual[w], kappa[w], n_eff[w])
        if np.any(report):
            s.tests.last_report = float(ends[report][-1])
        self._out["t"].extend(ends[report].tolist())
        self._out["values"].extend(theta[report])
        self._out["stderr"].extend(stderr[report])
        self._out["error"].extend(error[report])
        seg.next_window = count

    def _scores(self, rows, ends, decays, bars):
        """The lagged products of the windows' scores (their overlap and forgetting) in
        the state, and each window's HAC middle and its trace."""
        sums = self.state.sums
        n, p = bars.shape[0], bars.shape[1] - 1
        hac, trace = np.zeros((n, p, p)), np.zeros(n)
        ring = np.array([sums.ring_count], dtype=np.int64)
        kernels().window_scores(np.ascontiguousarray(rows), ends, decays, self._half_life, bars,
                                self.lag_weights, sums.U, sums.ring_rows, sums.ring_times,
                                ring, hac, trace)
        sums.ring_count = int(ring[0])
        return hac, trace

    def _solve(self, rows, ends, sums, bounds, n_eff, wanted, report):
        """Estimates, standard errors, numerical errors, CUSUM residuals and long-run
        variance factors at a chunk's window ends."""
        solve_windows, window_stderr = kernels().solve_windows, kernels().window_stderr
        n, p = len(ends), len(self.parameters)
        top = self.multiplicities.index(max(self.multiplicities))
        low = self.multiplicities.index(min(self.multiplicities))
        theta, values, lower = np.empty((n, p)), np.empty((n, p)), np.empty((n, p))
        kept = np.empty(n, dtype=np.int64)
        full, jacobian, mapping = np.empty((n, p + 1, p + 1)), np.empty((n, p, p)), \
            np.empty((n, p, p))
        solve_windows(sums["R"], sums["G"], top, low, bounds, n_eff, wanted,
                      self.config["method"] == "bc", MIN_SPARE_WINDOWS, theta, values, kept,
                      full, jacobian, mapping, lower)
        bars = np.concatenate([values, -np.ones((n, 1))], axis=1)
        hac, trace = self._scores(rows[top], ends, sums["decay"], bars)
        stderr, kappa, residual = np.empty((n, p)), np.empty(n), np.empty(n)
        window_stderr(sums["R"], top, sums["W"], bars, hac, trace,
                      full, jacobian, mapping, kept, theta, float(self.lag_weights.sum()),
                      self.overlap, stderr, kappa, residual)
        error = np.where(report[:, None], np.abs(theta - lower), np.nan)
        return theta, stderr, error, residual, kappa

    def _bound_squares(self, starts):
        """Squared output differences (orders 1 to 8) at the samples the windows add to
        the noise bound (identify's), and each window's range of them."""
        s = self.state
        seg = s.segment
        ends = starts + self.length + seg.first   # in the segment's samples
        upto = np.maximum.accumulate(np.concatenate([[max(seg.bound_upto, 0)], ends]))
        first = np.maximum(upto[:-1], 8)
        lo = int(first[0])
        hi = max(int(ends[-1]), lo)
        seg.bound_upto = int(upto[-1])
        ranges = np.stack([np.minimum(first, np.maximum(ends, first)) - lo,
                           np.maximum(ends, first) - lo], axis=1).astype(np.int64)
        squares = np.zeros((hi - lo, 8))
        if hi > lo:   # repeated differences (as identify's), elementwise: any chunking
            d = seg.signals[self.model.output][lo - 8 - seg.first:hi - seg.first]
            kernels().difference_squares(d, squares)
        return squares, ranges

    def _bounds(self, sums):
        """identify's bound on the output noise variance, per window (from its sums)."""
        bounds = np.empty(len(sums))
        kernels().noise_bounds(sums, self._central, bounds)
        return bounds

    def _test(self, end, row, theta, residual, kappa, n_eff):
        """The CUSUM step of a window that shares no sample with the last tested one."""
        s = self.state
        p = len(self.parameters)
        previous = s.tests.previous_test
        if np.all(np.isfinite(previous)):
            innovation = float(row @ np.append(previous[:p], -1.0))
            variance = previous[p] * (1.0 + p * previous[p + 1])
            if variance > 0:
                increment = min(innovation ** 2 / variance, INCREMENT_CAP)
                s.tests.cusum = max(0.0, s.tests.cusum + increment - self.k_cusum)
                if s.tests.cusum > self.h_cusum:
                    s.tests.cusum = 0.0
                    s.alarms += 1
                    self._out["alarms"].append(float(end))
        if np.all(np.isfinite(theta)):
            s.tests.previous_test = np.concatenate([theta, [residual, kappa / max(n_eff, 1e-300)
                                                         / self.overlap]])
        else:
            s.tests.previous_test = np.full(p + 2, np.nan)

    def _rows_and_grams(self, starts):
        """The window equations ``[A | b]`` (identify's kernels and ``term_rows``) and the
        covariance unit white output noise puts into them, per multiplicity: uniform
        windows in the loop, the exact weights of irregular windows' own times here."""
        window_rows, step_integrals = kernels().window_rows, kernels().step_integrals
        seg = self.state.segment
        L = self.length
        n, m, q1 = len(starts), len(self.multiplicities), len(self.parameters) + 1
        terms = self.model.terms
        first, last = int(starts[0]), int(starts[-1]) + L
        tw0, tw1 = seg.t[starts], seg.t[starts + L - 1]
        step = (tw1 - tw0) / (L - 1)
        if self.config["rate"] is not None:
            irregular = np.zeros(n, bool)
        else:
            tw = seg.t[starts[:, None] + np.arange(L)]
            grid = tw[:, :1] + step[:, None] * np.arange(L)
            irregular = np.max(np.abs(tw - grid), axis=1) > UNIFORM_TOLERANCE * step
        integrals = np.empty((m, len(terms), n))
        for i in self._sign_terms:   # each window from its own start: any chunking
            levels = np.sign(seg.factors[i][starts])
            for x, a in enumerate(self.multiplicities):
                step_integrals(seg.t, starts, L, levels, seg.sign_times[i],
                               seg.sign_steps[i], self._primitives[(a, terms[i].derivative)],
                               terms[i].derivative, integrals[x, i])
        for j in np.flatnonzero(irregular):
            tw = seg.t[starts[j]:starts[j] + L]
            for i, term in enumerate(terms):
                if i not in self._sign_terms:
                    zw = seg.factors[i][starts[j]:starts[j] + L]
                    for x, a in enumerate(self.multiplicities):
                        integrals[x, i, j] = float(
                            window_sample_weights(tw, None, L, a, term.derivative)[0] @ zw)
        fac = np.stack([seg.factors[i][first:last] for i in range(len(terms))])
        sen = np.stack([seg.sensitivities[i][first:last] for i in self._noisy]) if self._noisy \
            else np.zeros((0, last - first))
        rows, grams = np.empty((m, n, q1)), np.empty((m, n, q1, q1))
        table = self._term_table
        window_rows(fac, sen, starts - first, step, irregular, self._weight_table,
                    table["derivatives"], table["coefficients"], table["columns"],
                    table["sign_terms"], table["noisy"], table["noisy_weights"], integrals,
                    rows, grams)
        noisy = self._noisy_columns
        for j in np.flatnonzero(irregular):
            tw = seg.t[starts[j]:starts[j] + L]
            for y, (c1, w1, k1, i1) in enumerate(noisy):
                for c2, w2, k2, i2 in noisy[y:]:
                    pw = seg.sensitivities[i1][starts[j]:starts[j] + L] \
                        * seg.sensitivities[i2][starts[j]:starts[j] + L]
                    for x, a in enumerate(self.multiplicities):
                        g = window_sample_weights(tw, None, L, a, k1) \
                            * window_sample_weights(tw, None, L, a, k2)
                        v = float(g[0] @ pw) * (w1 * w2)
                        grams[x, j, c1, c2] += v
                        if (c1, k1, i1) != (c2, k2, i2):
                            grams[x, j, c2, c1] += v
        return rows, grams
