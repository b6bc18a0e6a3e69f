"""On-line identification of a system of equations that share parameters.

:class:`SystemTracker` is what :class:`algid.Tracker` becomes given a list of
equations: the joint window equations of :mod:`algid.identification._system_identify`,
formed as soon as each window's last sample has arrived and accumulated with
exponential forgetting (``half_life``; None keeps every window).

- **The window**: given, or chosen by :func:`algid.identify` on the first ``warmup``
  seconds (the span doubled, three times at most, while it refuses them, leaves a
  parameter poorly determined or keeps a window of at least half the longest they
  allow).
- **Rows in physical units**: each block of new windows is made by a
  :class:`~algid.identification._window_problem.WindowProblem` on the samples that
  hold them, whose powers of two are undone (exactly), so that the rows of every block
  add up.  Per equation, the sums are ``sum w Phi^T Phi`` and, per noisy output,
  ``sum w G`` (the noise covariance the window kernels give it); the outputs' noise
  bounds accumulate the sums of their samples' differences.
- **The solve** at every window end: Koopmans' estimator on the sums, each equation
  weighted by the inverse rms of its residuals on the first windows (fixed then).
- **Standard errors**: a sandwich whose middle is that of identify (the windows'
  estimating equations and their lagged products over the overlap, squared forgetting
  weights) at the current estimate: the estimating equations are linear in it, so their
  components' products are what accumulates (bounded: ``(k p (p + 1))**2`` numbers for
  ``p`` parameters and ``k - 1`` noisy outputs).
- **Alarms**: one CUSUM per equation (:mod:`algid.identification._change_detection`),
  on the innovations of windows that share no sample: a window's rows at the estimate
  made before its first sample, divided by their predicted standard deviation (the
  equation's residual scatter so far, plus the estimate's uncertainty along the rows).
  Each CUSUM is tuned to its share of ``false_alarm_rate``; an alarm restarts them all.

The state is the last window's samples and sums of fixed size.  Nonlinear factors that
need derivatives of the signals (``sign(q')``) are not tracked in systems.
"""

from __future__ import annotations

import math
from collections import deque
from typing import NamedTuple

import numpy as np

from algid._record_input import check_rate, read_chunk
from algid.errors import AlgidError, InputDataError, ModelError
from algid.identification._arguments import check_seconds
from algid.identification._change_detection import (
    DEFAULT_FALSE_ALARM_RATE,
    INCREMENT_CAP,
    cusum_design,
)
from algid.identification._homogeneous import divisions, row_map, to_physical
from algid.identification._records import GAP_FACTOR, Segment
from algid.identification._system_identify import equation_weight, solve_normal
from algid.identification._system_result import WEAK_RELATIVE_ERROR
from algid.identification._tracker_kernels import compile_loops
from algid.identification._tracker_state import (
    WARMUP_DOUBLINGS,
    TrackUpdate,
    as_seconds,
    check_half_life,
    window_samples,
)
from algid.identification._window_problem import (
    DIFFERENCE_ORDERS,
    MULTIPLICITIES,
    WindowProblem,
    noise_bound_from_sums,
    window_stride,
)
from algid.identification._window_rule import MIN_SPARE_WINDOWS

__all__ = ["SystemTracker"]

#: Seconds of stream on which the window is chosen when none is given.
DEFAULT_WARMUP = 2.0




class _Solved(NamedTuple):
    """The estimate at one window end."""

    theta: np.ndarray
    stderr: np.ndarray
    error: np.ndarray
    theta_bar: np.ndarray     # (theta, -1), with the ratios of divided equations
    covariance: np.ndarray    # of theta_bar[:-1]


class SystemTracker:
    """The streaming form of :func:`algid.identify` on a system of equations.

    Made by :class:`algid.Tracker` given a list of equations; see the module notes.

    Parameters
    ----------
    system : algid.models.SystemModel
    rate, time, window, half_life, method, warmup, false_alarm_rate, every
        As for :class:`algid.Tracker` (the false-alarm rate is the whole system's).

    Examples
    --------
    >>> import numpy as np
    >>> from algid import Tracker, simulate_system
    >>> t = np.arange(0, 20, 0.01)
    >>> u = np.sin(1.3 * t) + np.sin(4.1 * t)
    >>> eqs = ["x1' + a*x1 = u", "x2' + x2 = b*x1"]
    >>> y = simulate_system(eqs, {"a": 2.0, "b": 0.5}, t, {"u": u})
    >>> tracker = Tracker(eqs, "a b", rate=100, window=1.0)
    >>> out = tracker.update({"u": u, **y})
    >>> {p: round(v, 3) for p, v in out.last().items()}
    {'a': 2.0, 'b': 0.5}
    """

    def __init__(self, system, *, rate=None, time=None, window=None, half_life=None,
                 method="bc", warmup=DEFAULT_WARMUP,
                 false_alarm_rate=DEFAULT_FALSE_ALARM_RATE, every=None):
        for model in system.equations:
            if model.needs_derivatives:
                raise ModelError(f"the equation {model.equation} needs derivatives inside a "
                                 f"factor, which a system's tracker does not estimate")
        if method not in ("bc", "ls"):
            raise InputDataError(f"method must be 'bc' or 'ls' for a tracker, got {method!r}")
        check_seconds(window_or_none=window, half_life_or_none=half_life, warmup=warmup,
                      false_alarm_rate=false_alarm_rate, every_or_none=every)
        compile_loops()   # its bias compensation, solved at every report
        self.system = system
        self.parameters = tuple(system.parameters)
        self.models = [m for m in system.equations if m.parameters]
        # equations without a known term, in the ratios of their parameters to a pivot
        self._divisions = divisions(self.models, self.parameters)
        self._row_maps = {d.equation: row_map(len(self.parameters) + 1, d)
                          for d in self._divisions}
        self.rate = None if rate is None else check_rate(rate)
        self.time = time
        self.method = method
        # (Python floats: a NumPy float32 would round the forgetting, and not the same
        # way once saved and loaded)
        self.half_life = as_seconds(half_life)
        self.every = as_seconds(every)
        self.false_alarm_rate = float(false_alarm_rate)
        self._warmup = self._first_warmup = float(warmup)
        self._window = as_seconds(window)
        self._signals = list(system.signals)
        self._noisy = [y for y in system.outputs
                       if any(y in m.signals for m in self.models)]
        self._buffer_t = np.empty(0)
        self._buffer = {n: np.empty(0) for n in self._signals}
        self._seen = 0
        self._last_time = -np.inf
        self._last_stamp = np.nan   # the time column's beside rate= (read_chunk)
        self.length = None          # samples per window
        self.step = None
        self._next_start = 0        # buffer index of the next window's first sample
        self._sums = None
        self._weights = None
        self._recent = deque()
        self._differences = {y: np.zeros((len(DIFFERENCE_ORDERS), 2)) for y in self._noisy}
        self._tail = {y: np.empty(0) for y in self._noisy}
        self._weight_sum = 0.0      # the windows, forgotten as the sums are
        self._run_windows = 0       # windows since the current run began (the tests')
        self._cusum = np.zeros(len(self.models))
        self._previous_test = None  # (theta_bar, covariance, residual variance per equation)
        self._alarms = []
        self._last_report = None    # the last window end reported under ``every``
        self._products = None       # the HAC middle's products, once weights are set
        self._first = []            # the warm-up's windows, until then

    # ------------------------------------------------------------------ public
    @property
    def window(self):
        """The window length (s), or None before it is chosen."""
        return None if self.length is None else (self.length - 1) * self.step

    @property
    def config(self):
        """The configuration, as :meth:`save` writes it (JSON types)."""
        return {"equations": [m.equation for m in self.system.equations],
                "parameters": list(self.parameters), "outputs": list(self.system.outputs),
                "rate": self.rate, "time": self.time, "window": self._window,
                "half_life": self.half_life, "method": self.method,
                "warmup": self._first_warmup, "false_alarm_rate": self.false_alarm_rate,
                "every": self.every}

    def save(self, path):
        """Write the whole state to a NumPy ``.npz`` file (as :meth:`algid.Tracker.save`:
        arrays, a JSON header and a SHA-256 checksum of both).

        Parameters
        ----------
        path : str or path-like
        """
        from algid.identification._system_tracker_file import FORMAT, flat_state
        from algid.identification._tracker_file import write

        write(path, self.config, flat_state(self), FORMAT)

    @classmethod
    def load(cls, path):
        """A system's tracker continuing the stream saved by :meth:`save`.

        Parameters
        ----------
        path : str or path-like

        Returns
        -------
        SystemTracker

        Raises
        ------
        InputDataError
            A file that is not a saved system tracker, altered after it was saved, or
            whose arrays do not fit its system and configuration (one line).
        """
        from algid.identification._system_tracker_file import CONFIG, FORMAT, restore
        from algid.identification._tracker_file import read
        from algid.models._system import parse_system

        config, scalars, arrays = read(path, FORMAT, CONFIG)
        try:
            tracker = cls(parse_system(config["equations"], config["parameters"],
                                       outputs=config["outputs"]),
                          rate=config["rate"], time=config["time"], window=config["window"],
                          half_life=config["half_life"], method=config["method"],
                          warmup=config["warmup"], false_alarm_rate=config["false_alarm_rate"],
                          every=config["every"])
        except AlgidError as exc:
            raise InputDataError(f"{path}: its configuration is refused: {exc}") from None
        restore(path, tracker, scalars, arrays)
        return tracker

    def update(self, chunk, *, last=False):
        """Stream the next samples (as :meth:`algid.Tracker.update`).

        Parameters
        ----------
        chunk : mapping, pandas.DataFrame, xarray.Dataset or control.TimeResponseData
            Column name -> samples: every measured signal of the equations and the time
            column (or none, with ``rate``).
        last : bool
            The chunk ends the stream (its last window end is reported whatever
            ``every``).

        Returns
        -------
        algid.identification.TrackUpdate
        """
        t, columns = self._read(chunk)
        self._accumulate_noise(columns)
        self._out = []
        self._alarms = []
        self._last = last
        self._buffer_t = np.concatenate([self._buffer_t, t])
        for name in self._signals:
            self._buffer[name] = np.concatenate([self._buffer[name], columns[name]])
        try:
            if self.length is None:
                self._configure(last)
            if self.length is not None:
                self._windows()
        except (np.linalg.LinAlgError, OverflowError, FloatingPointError) as exc:
            largest = max((float(np.nanmax(np.abs(v))) for v in self._buffer.values()
                           if np.isfinite(v).any()), default=0.0)
            raise InputDataError(
                f"the system tracker's sums left the range of floating point ({exc}) on "
                f"signals of magnitude {largest:.3g}: express them in other units") from None
        p = len(self.parameters)
        alarms = np.array(self._alarms, dtype=float)
        if not self._out:
            return TrackUpdate(self.parameters, np.empty(0), np.empty((0, p)),
                               np.empty((0, p)), np.empty((0, p)), alarms)
        t_out, values, stderr, error = (np.array(x, dtype=float) for x in zip(*self._out))
        return TrackUpdate(self.parameters, t_out, values.reshape(-1, p),
                           stderr.reshape(-1, p), error.reshape(-1, p), alarms)

    # ------------------------------------------------------------------ input
    def _read(self, chunk):
        t, columns, self.time, self._last_stamp = read_chunk(
            chunk, self._signals, time=self.time, rate=self.rate, seen=self._seen,
            last_time=self._last_time, last_stamp=self._last_stamp)
        self._seen += len(t)
        if len(t):
            self._last_time = float(t[-1])
        return t, columns

    # ------------------------------------------------------------------ set-up
    def _configure(self, last):
        t = self._buffer_t
        if len(t) < 2:
            return
        span = t[-1] - t[0]
        needed = self._warmup if self._window is None else 0.0
        if span < needed and not last:
            return
        step = float(np.median(np.diff(t)))
        length = None
        if self._window is not None:
            length = window_samples(self._window, step, MULTIPLICITIES)
        else:
            from algid.identification._system_identify import identify_system

            record = {"t": t, **self._buffer}
            more = not last and span < self._first_warmup * 2 ** WARMUP_DOUBLINGS
            try:
                fit = identify_system(record, self.system, refine=False, method=self.method)
            except (InputDataError, ModelError):
                if more:
                    self._warmup = 2 * span
                    return
                raise
            length = int(round(fit.window / step)) + 1
            # a window of at least half the longest the span allows may want more data
            # (as the Tracker of one equation), and so do poorly determined parameters
            # (a span shorter than the slowest mode's period): the span doubles
            longest = len(t) // (len(self.parameters) + MIN_SPARE_WINDOWS)
            values = np.array([fit.values[p] for p in self.parameters])
            stderr = np.array([fit.stderr[p] for p in self.parameters])
            weak = np.any(stderr > WEAK_RELATIVE_ERROR * np.abs(values))
            if more and (2 * length >= longest or weak):
                self._warmup = 2 * span
                return
        self._set_window(length, step)

    def _set_window(self, length, step):
        """The window of ``length`` samples at ``step`` and the constants that follow
        (refused before the tracker counts as configured: every later chunk is too)."""
        stride = window_stride(length)
        overlap = int(math.ceil(length / stride))
        check_half_life(self.half_life, length, step, stride, overlap, len(self.parameters))
        self._k_cusum, self._h_cusum = cusum_design(
            self.false_alarm_rate, overlap * stride * step, tests=len(self.models))
        self.step, self.length, self.stride, self.overlap = step, length, stride, overlap
        self.decay = 1.0 if self.half_life is None else \
            2.0 ** (-self.stride * step / self.half_life)

    # ------------------------------------------------------------------ windows
    def _windows(self):
        """Every window the buffer completes, run by run (a gap, missing rows or a NaN,
        ends a run: windows never cross it); the buffer keeps what later windows need."""
        while True:
            t = self._buffer_t
            finite = np.all([np.isfinite(self._buffer[n]) for n in self._signals], axis=0)
            breaks = np.flatnonzero(np.concatenate(
                [[not finite[0]] if len(t) else [],
                 (np.diff(t) > GAP_FACTOR * self.step) | ~finite[1:]]))
            if not breaks.size:
                self._process(self._next_start, len(t))
                self._drop(slice(self._next_start, None))
                self._next_start = 0
                return
            cut = int(breaks[0])
            self._process(self._next_start, cut)
            self._drop(slice(cut if finite[cut] else cut + 1, None))
            self._next_start = 0
            self._recent.clear()   # windows across the break are not neighbours
            self._run_windows = 0

    def _drop(self, keep):
        self._buffer_t = self._buffer_t[keep]
        for n in self._signals:
            self._buffer[n] = self._buffer[n][keep]

    def _process(self, start, stop):
        """Every window of the buffer's samples ``[start, stop)`` (a run without gap)."""
        count = (stop - start - self.length) // self.stride + 1
        if count <= 0:
            return
        end = start + (count - 1) * self.stride + self.length
        seg_t = self._buffer_t[start:end]
        values = {n: self._buffer[n][start:end] for n in self._signals}
        segment = Segment(0, np.arange(len(seg_t)), seg_t, values, self.step)
        blocks = {a: self._rows(segment, a) for a in MULTIPLICITIES}
        ends = seg_t[self.length - 1::self.stride][:count]
        top = max(MULTIPLICITIES)
        for w in range(count):
            self._add(blocks, w)
            tested = self._run_windows % self.overlap == 0
            self._run_windows += 1
            if self._weights is None:
                continue
            solved = self._solve()
            if tested:
                self._test(ends[w], [phi[w] for phi, _ in blocks[top]], solved)
            if self._report(ends[w], w == count - 1):
                self._out.append((ends[w], solved.theta, solved.stderr, solved.error))
        self._next_start = start + count * self.stride

    def _report(self, end, final):
        if self.every is None or (final and self._last):
            return True
        previous = self._last_report
        if previous is None or math.floor(end / self.every) > math.floor(previous / self.every):
            self._last_report = end
            return True
        return False

    def _rows(self, segment, a):
        """Per equation: rows ``[A | b]`` in the system's columns and physical units, and
        per noisy output the noise covariances per unit variance."""
        P = len(self.parameters)
        out = []
        for e, model in enumerate(self.models):
            problem = WindowProblem(model, [segment], self.step)
            A, b, _ = problem.rows(self.length, a)
            columns, known, _ = problem.exponents()
            where = [self.parameters.index(p) for p in model.parameters]
            scale = np.ones(P + 1)
            scale[where] = np.ldexp(1.0, columns)
            scale[P] = np.ldexp(1.0, known)
            phi = np.zeros((len(b), P + 1))
            phi[:, where] = A
            phi[:, P] = b
            phi *= scale
            grams = {}
            index = [*where, P]
            for y in self._noisy:
                if y not in model.signals:
                    continue
                g = problem.noise_grams(self.length, a, y)
                unit = np.ldexp(1.0, -problem.signal_exponent(y))
                full = np.zeros((len(b), P + 1, P + 1))
                full[np.ix_(np.arange(len(b)), index, index)] = g
                grams[y] = full * (scale[None, :, None] * scale[None, None, :]) * unit ** 2
            M = self._row_maps.get(e)
            if M is not None:   # divided by its pivot (module _homogeneous)
                phi = phi @ M.T
                grams = {y: np.einsum("ij,wjk,lk->wil", M, g, M) for y, g in grams.items()}
            out.append((phi, grams))
        return out

    def _accumulate_noise(self, columns):
        """The sums of the new samples' differences (the noise bounds), a NaN ending a
        run as a gap does."""
        for y in self._noisy:
            new = columns[y]
            for run in np.split(new, np.flatnonzero(~np.isfinite(new))):
                run = run[np.isfinite(run)]
                tail = self._tail[y]
                v = np.concatenate([tail, run])
                for i, k in enumerate(DIFFERENCE_ORDERS):
                    if len(v) > k:
                        d = np.diff(v, k)[len(tail) - min(len(tail), k):]
                        self._differences[y][i] += (float(d @ d), len(d))
                self._tail[y] = v[-max(DIFFERENCE_ORDERS):]
            if new.size and not np.isfinite(new[-1]):
                self._tail[y] = np.empty(0)

    def _bounds(self):
        return {y: noise_bound_from_sums(sums) for y, sums in self._differences.items()}

    def _test(self, end, rows, solved):
        """The CUSUM step of a window that shares no sample with the last tested one:
        each equation's row at the estimate of that window."""
        P = len(self.parameters)
        if self._previous_test is not None:
            theta_bar, covariance, variances = self._previous_test
            for e, phi in enumerate(rows):
                innovation = float(phi @ theta_bar)
                variance = variances[e] + float(phi[:P] @ covariance @ phi[:P])
                if not variance > 0:
                    continue
                increment = min(innovation ** 2 / variance, INCREMENT_CAP)
                self._cusum[e] = max(0.0, self._cusum[e] + increment - self._k_cusum)
                if self._cusum[e] > self._h_cusum:
                    self._cusum[:] = 0.0
                    self._alarms.append(float(end))
                    break
        top = max(MULTIPLICITIES)
        variances = [float(solved.theta_bar @ sums["normal"] @ solved.theta_bar)
                     / self._weight_sum for sums in self._sums[top]]
        self._previous_test = (solved.theta_bar, solved.covariance, variances)

    def _add(self, blocks, w):
        P = len(self.parameters)
        if self._sums is None:
            self._sums = {a: [{"normal": np.zeros((P + 1, P + 1)),
                               "noise": {y: np.zeros((P + 1, P + 1)) for y in grams}}
                              for _, grams in blocks[a]] for a in MULTIPLICITIES}
        for a in MULTIPLICITIES:
            for sums, (phi, grams) in zip(self._sums[a], blocks[a]):
                sums["normal"] *= self.decay
                sums["normal"] += np.outer(phi[w], phi[w])
                for y, g in grams.items():
                    sums["noise"][y] *= self.decay
                    sums["noise"][y] += g[w]
        self._weight_sum = self.decay * self._weight_sum + 1.0
        top = max(MULTIPLICITIES)
        if self._weights is None:
            # weights from the first windows: each equation's residual rms at a first
            # solve with its rows of unit norm (as identify's)
            self._first.append([(phi[w], {y: g[w] for y, g in grams.items()})
                                for phi, grams in blocks[top]])
            # as many windows as the warm-up span holds (weights from a few windows let
            # an equation without a known term drift to its trivial solution)
            wanted = max(2 * self.overlap + P,
                         int(self._first_warmup / (self.stride * self.step)))
            if len(self._first) >= wanted:
                self._set_weights()
            return
        self._score([(phi[w], {y: g[w] for y, g in grams.items()})
                     for phi, grams in blocks[top]])

    def _set_weights(self):
        rows = list(zip(*self._first))   # per equation: [(phi, grams)] over windows
        first = [1.0 / max(np.linalg.norm([r[0] for r in eq]), 1e-300) for eq in rows]
        theta_bar = self._koopmans(max(MULTIPLICITIES), first)[0]
        self._weights = [equation_weight(np.array([row[0] @ theta_bar for row in eq]),
                                         np.array([row[0] for row in eq]), theta_bar)
                         for eq in rows]
        for window in self._first:
            self._score(window)
        self._first = []

    def _koopmans(self, a, weights):
        bounds = self._bounds()
        normal = sum(w ** 2 * s["normal"] for w, s in zip(weights, self._sums[a]))
        noise = sum(w ** 2 * sum(bounds[y] * g for y, g in s["noise"].items())
                    for w, s in zip(weights, self._sums[a]))
        theta_bar, variance = solve_normal(normal, noise, self.method)
        return theta_bar, variance, normal, noise

    def _score(self, window):
        """A window's estimating equations into the HAC middle, as the components that
        multiply the estimate: ``score = sum_c coef_c K_c theta_bar`` with ``K_0 = -sum_i
        w_i^2 phi_i[:p] phi_i^T`` and ``K_j = sum_i w_i^2 G_ij[:p]`` (``coef_j`` the noise
        variance of output ``j``), so that the middle is exact at every new estimate:
        ``L T L^T``, ``T`` the weighted sum of the products of the windows' flattened
        components over the overlap's lags (squared forgetting weights)."""
        P = len(self.parameters)
        parts = np.zeros((1 + len(self._noisy), P, P + 1))
        for w, (phi, grams) in zip(self._weights, window):
            parts[0] -= w ** 2 * np.outer(phi[:P], phi)
            for k, y in enumerate(self._noisy, start=1):
                if y in grams:
                    parts[k] += w ** 2 * grams[y][:P]
        v = parts.ravel()
        if self._products is None:
            self._products = np.zeros((v.size, v.size))
        self._products *= self.decay ** 2
        self._products += np.outer(v, v)
        lags = 2 * self.overlap
        for lag, previous in enumerate(reversed(self._recent), start=1):
            weight = 1.0 if lag <= self.overlap else \
                1.0 - (lag - self.overlap) / (lags - self.overlap + 1.0)
            cross = np.outer(v, previous) * (weight * self.decay ** lag)
            self._products += cross + cross.T
        self._recent.append(v)
        if len(self._recent) > lags:
            self._recent.popleft()

    def _meat(self, theta_bar, variance):
        """The HAC middle at ``theta_bar`` (see :meth:`_score`)."""
        P = len(self.parameters)
        bounds = self._bounds()
        coef = np.array([1.0] + [variance * bounds[y] for y in self._noisy])
        # L[a, (c, a', k)] = coef_c theta_bar_k [a == a']
        L = np.einsum("c,ab,k->acbk", coef, np.eye(P), theta_bar).reshape(P, -1)
        return L @ self._products @ L.T

    def _solve(self):
        P = len(self.parameters)
        top = max(MULTIPLICITIES)
        theta_bar, variance, normal, noise = self._koopmans(top, self._weights)
        jacobian = normal[:P, :P] - variance * noise[:P, :P]
        d = np.sqrt(np.abs(np.diag(jacobian)))
        d[d == 0] = 1.0
        bread = np.linalg.pinv(jacobian / d[:, None] / d[None, :]) / d[:, None] / d[None, :]
        values, vectors = np.linalg.eigh(self._meat(theta_bar, variance))
        meat = (vectors * np.abs(values)) @ vectors.T
        covariance = bread @ meat @ bread.T
        # (the rows of divided equations hold ratios: the physical values, and theirs)
        theta, physical = to_physical(theta_bar[:P], self._divisions, covariance)
        stderr = np.sqrt(np.maximum(np.diag(physical), 0.0))
        others = [to_physical(self._koopmans(a, self._weights)[0][:P], self._divisions)[0]
                  for a in MULTIPLICITIES if a != top]
        error = np.max([np.abs(o - theta) for o in others], axis=0) if others \
            else np.full(P, np.nan)
        return _Solved(theta, stderr, error, theta_bar, covariance)
