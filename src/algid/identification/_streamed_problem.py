"""The window equations of a record read in chunks: :func:`algid.identify` as a
streamed reduction.

A record longer than :data:`STREAM_SAMPLES`, or kept in a file or a Dask ``DataFrame``
(:mod:`algid.identification._record_source`), is never held whole.  Its window
equations are made in passes over its chunks, each pass holding a chunk and the last
window's samples of the run it is in:

1. :func:`scan_record` checks every chunk as the record layer checks a whole record,
   cuts the record into runs of contiguous samples (at gaps and NaN rows, as
   :func:`algid.identification._records.prepare_records` does) and sums what the
   problem's scaling and noise bound need: every factor's largest sample, and the sums
   of squares of the output's differences (:func:`noise_bound_from_sums`).
2. :meth:`StreamedProblem.prefetch` makes the rows ``[A | b]`` of several window
   lengths and multiplicities in one pass (:meth:`StreamedProblem.rows`: a pass per
   window length asked for, the rows of the previous length dropped).  The rows are
   what the solve keeps: one per window, a few per thousand samples; the samples are
   dropped chunk by chunk.
3. Where a term reads the output nonlinearly (``K3*y**3``), the noise it puts into a
   window's equation changes from window to window: its covariance is made with the
   rows, and the covariance of neighbouring windows' noise (the sandwich's middle) by a
   pass of its own once the estimate is known (:class:`_MeatPass`).  Where every term
   reads the output as itself, both are the same on every window of a uniformly
   sampled run, from one window of the kernels.

The solve, the window rule's criterion, the covariance and the adequacy test are then
those of an in-memory record (:mod:`algid.identification._identify`), and the
estimate equals the in-memory one at the same window to round-off (the window
integrals are summed in blocks rather than by FFT).  What cannot be made chunk by
chunk (:func:`stream_refusal`): a ``sign`` whose steps are placed by fits on the whole
record, a derivative inside a nonlinear factor estimated on it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from algid._record_input import TIME_COLUMNS, record_columns, refuse_infinite
from algid.errors import InputDataError
from algid.identification._records import (
    GAP_FACTOR,
    UNIFORM_TOLERANCE,
    Segment,
    check_factors,
    prepare_records,
)
from algid.identification._window_basis import exponent
from algid.identification._window_kernels import (
    block_window_integrals,
    block_window_sums,
    window_sample_weights,
)
from algid.identification._window_problem import (
    DIFFERENCE_ORDERS,
    ProblemCache,
    WindowProblem,
    factor_sensitivity,
    is_sign_factor,
    noise_bound_from_sums,
    noise_curvature,
    spread_ranges,
    term_rows,
    window_stride,
)
from algid.models._expression import Signal

__all__ = ["StreamedProblem", "RecordScan", "Run", "scan_record", "stream_refusal",
           "chunk_columns",
           "STREAM_SAMPLES", "CHUNK_SAMPLES"]

#: A record of more samples than this is identified in chunks (fewer: in memory, as
#: before; every benchmark record is shorter).
STREAM_SAMPLES = 2**18

#: Rows per chunk of a pass.
CHUNK_SAMPLES = 2**16

#: The sampling step of a record with a time column is the median step of its first
#: rows, this many (or all): what cuts its runs at gaps.
STEP_ROWS = 4096

#: A run read in chunks is taken as uniformly sampled when no sample time is further from
#: its grid than single precision rounds times (twice its rounding), within
#: this fraction of a step, or than :data:`~algid.identification._records.UNIFORM_TOLERANCE`
#: of a step; further (jitter), it is refused.
STREAM_JITTER = 1e-2

#: Runs whose sampling steps (from their ends) agree to this fraction are given their
#: common step (their noise covariances are then one for every window; the estimates
#: move by about as much, far below the noise).
SAME_STEP = 1e-9


def stream_refusal(model):
    """Why a model's window equations cannot be made chunk by chunk, or None.

    No factor may hold a derivative estimated on the whole record or a ``sign`` whose
    steps are placed on it.

    Parameters
    ----------
    model : algid.models._model.Model

    Returns
    -------
    str or None
    """
    for term in model.terms:
        if is_sign_factor(term.factor):
            return f"the steps of {term.factor} are placed on the whole record"
    if model.needs_derivatives:
        name, k = model.needs_derivatives[0]
        return (f"the derivative {name}{chr(39) * k} inside a nonlinear factor is "
                f"estimated on the whole record")
    return None


@dataclass
class Run:
    """Contiguous samples of a streamed record (rows ``[start, stop)``).

    Attributes
    ----------
    start, stop : int
        Rows of the record.
    t0, t_end : float
        Times of the first and last samples (s).
    step : float
        The sampling step in the problem's time unit (from the run's ends), set by
        :class:`StreamedProblem`.
    record : int
        Always 0 (one record).
    output_largest : float
        The output's largest absolute sample on the run (the step of its factors'
        sensitivities, as in memory).
    """

    start: int
    stop: int
    t0: float
    t_end: float
    step: float = 0.0
    record: int = 0
    output_largest: float = 0.0

    def __len__(self):
        return self.stop - self.start

    @property
    def user_step(self):
        """The sampling step (s), from the run's ends."""
        return (self.t_end - self.t0) / (len(self) - 1)


@dataclass
class RecordScan:
    """What the first pass over a streamed record found (:func:`scan_record`).

    Attributes
    ----------
    runs : list of Run
        Runs of contiguous samples at least as long as a window must be.
    step : float
        The sampling step (s): ``1 / rate``, or the median step of the first chunk.
    largest : dict
        Factor -> its largest absolute sample on the runs.
    differences : list of tuple
        Per order of :data:`DIFFERENCE_ORDERS`: the sum of squares and the count of the
        output's differences on the runs, in the unit of the output's largest sample
        (``2**e`` bringing it into ``[1, 2)``).
    rows : int
        Rows of the record.
    signals : list of str
        The signals read.
    origin : numpy.datetime64, numpy.timedelta64 or None
        The first time of a record whose times are dates or durations (its times are
        seconds from it).
    """

    runs: list
    step: float
    largest: dict
    differences: list
    rows: int = 0
    signals: list = field(default_factory=list)
    origin: object = None

    @property
    def n_samples(self):
        """Samples in the runs."""
        return sum(len(run) for run in self.runs)


class _RunSums:
    """A run being scanned: its ends, factors' largest samples, output differences."""

    def __init__(self, start, t0, factors):
        self.start, self.stop, self.t0, self.t_end = start, start, t0, t0
        self.largest = dict.fromkeys(factors, 0.0)
        # per order: the sum of squares over 4**scale, and the count (scaled by powers
        # of two chunk by chunk: no overflow or underflow at any amplitude)
        self.sums = [[0.0, 0] for _ in DIFFERENCE_ORDERS]
        self.scale = None
        self.carry = np.empty(0)

    def add(self, t, values, model):
        self.stop += len(t)
        self.t_end = float(t[-1])
        for factor in self.largest:
            with np.errstate(over="ignore", under="ignore", invalid="ignore"):
                z = np.asarray(factor.evaluate(values, t), dtype=float) * np.ones(len(t))
            self.largest[factor] = max(self.largest[factor], float(np.max(np.abs(z))))
        y = np.concatenate([self.carry, values[model.output]])
        e = exponent(y)
        if self.scale is None or e > self.scale:   # to the larger power of two
            if self.scale is not None:
                for sums in self.sums:
                    sums[0] = float(np.ldexp(sums[0], 2 * (self.scale - e)))
            self.scale = e
        scaled = np.ldexp(y, -self.scale)
        for sums, k in zip(self.sums, DIFFERENCE_ORDERS):
            d = np.diff(scaled, k)[max(0, len(self.carry) - k):]
            sums[0] += float(d @ d)
            sums[1] += len(d)
        self.carry = y[-max(DIFFERENCE_ORDERS):]


def chunk_columns(chunk, first, signals, time, rate, clock):
    """The times and signals of one chunk, checked as a record's.

    ``clock`` holds the record's first time when it is a date or a duration (the times
    are then seconds from it, as in memory: ``[origin]``, set at the first chunk).  The
    rows named in a refusal are the record's."""
    name = time or next((c for c in TIME_COLUMNS if c in chunk), None)
    if name is not None and name in chunk:
        stamps = np.asarray(chunk[name])
        if stamps.dtype.kind in "mM" and len(stamps):
            if clock[0] is None:
                clock[0] = stamps[0]
            chunk = dict(chunk)
            chunk[name] = (stamps - clock[0]) / np.timedelta64(1, "s")
    try:
        t, columns = record_columns(chunk, signals, time=time, rate=rate, first_sample=first)
        for column, values in columns.items():
            refuse_infinite(values, f"record 0: column {column!r}")
    except InputDataError as error:
        message = re.sub(r"\brow (\d+)", lambda m: f"row {first + int(m.group(1))}",
                         str(error))
        raise InputDataError(message) from None
    return t, columns


def scan_record(source, model, *, time=None, rate=None, chunk=CHUNK_SAMPLES, min_length=8):
    """The first pass over a streamed record (see the module notes).

    Parameters
    ----------
    source : object
        The record's chunks (:func:`algid.identification._record_source.record_source`).
    model : algid.models._model.Model
        The model (its signals and terms).
    time : str, optional
        Name of the time column.
    rate : float, optional
        Sampling rate (Hz) of a record without one.
    chunk : int
        Rows per chunk.
    min_length : int
        Runs shorter than this are dropped.

    Returns
    -------
    RecordScan

    Raises
    ------
    InputDataError
        As the record layer, for any chunk; or no run of ``min_length`` samples.
    """
    scan = _Scan(model, time, rate, min_length)
    return source.reduce(scan, scan.columns, chunk).finish()


class _Scan:
    """The first pass's state, fed the record's chunks in order (:meth:`feed`): in this
    process, or along a chain of tasks on a cluster (it pickles)."""

    def __init__(self, model, time, rate, min_length):
        self.model, self.time, self.rate, self.min_length = model, time, rate, min_length
        self.signals = list(model.signals)
        self.columns = self.signals + [n for n in (time, "t", "time")
                                       if n and n not in self.signals]
        self.factors = list(dict.fromkeys(term.factor for term in model.terms))
        self.runs, self.largest = [], dict.fromkeys(self.factors, 0.0)
        self.differences = [[0.0, 0] for _ in DIFFERENCE_ORDERS]   # over 4**self.scale
        self.scale = None
        self.rate, self.step = rate, None
        # the last time read (increasing), and the last one cut into runs (gaps)
        self.latest, self.last_t, self.current, self.rows = None, None, None, 0
        self.clock = [None]
        self.waiting = []   # chunks read before the step is known

    def _close(self):
        run, self.current = self.current, None
        if run is None or len(run.carry) == 0 or run.stop - run.start < self.min_length:
            return
        self.runs.append(Run(run.start, run.stop, run.t0, run.t_end,
                             output_largest=run.largest[Signal(self.model.output)]))
        for factor, value in run.largest.items():
            self.largest[factor] = max(self.largest[factor], value)
        if run.scale is not None:
            if self.scale is None or run.scale > self.scale:
                if self.scale is not None:
                    for total in self.differences:
                        total[0] = float(np.ldexp(total[0], 2 * (self.scale - run.scale)))
                self.scale = run.scale
            for total, (square, count) in zip(self.differences, run.sums):
                total[0] += float(np.ldexp(square, 2 * (run.scale - self.scale)))
                total[1] += count

    def feed(self, first, part):
        """Take the chunk of rows from ``first`` (a mapping of columns)."""
        t, columns = chunk_columns(part, first, self.signals, self.time, self.rate,
                                    self.clock)
        self.rows = first + len(t)
        if len(t) == 0:
            return
        if self.latest is not None and not t[0] > self.latest:
            raise InputDataError(f"record 0: the time does not increase at row {first}")
        self.latest = float(t[-1])
        if self.step is None:   # the median step of the first STEP_ROWS rows (or all)
            self.waiting.append((first, t, columns))
            if sum(len(w[1]) for w in self.waiting) < STEP_ROWS:
                return
            self._set_step()
            return
        self._runs(first, t, columns)

    def _set_step(self):
        """The step from the chunks waiting, then their runs."""
        t = np.concatenate([w[1] for w in self.waiting]) if self.waiting else np.zeros(0)
        if len(t) >= 2:
            self.step = float(np.median(np.diff(t)))
        elif self.rate is not None:
            self.step = 1.0 / self.rate
        else:
            self.step = np.inf   # one sample: no run
        waiting, self.waiting = self.waiting, []
        for first, t, columns in waiting:
            self._runs(first, t, columns)

    def _runs(self, first, t, columns):
        """Cut a chunk into the pieces of runs, and take them."""
        n = len(t)
        valid = np.all([~np.isnan(v) for v in columns.values()], axis=0)
        before = np.nan if self.last_t is None else self.last_t
        gap = np.diff(t, prepend=before) > GAP_FACTOR * self.step
        previous = np.concatenate([[self.current is not None], valid[:-1]])
        starts = np.flatnonzero(valid & ~(previous & ~gap))
        ends = np.flatnonzero(valid & ~np.concatenate([valid[1:] & ~gap[1:], [True]]))
        pieces = np.flatnonzero(valid)
        if pieces.size:
            # the pieces of runs in this chunk: from a run's start (or the chunk's) to its end
            edges = np.union1d(np.union1d(starts, ends + 1), [pieces[0], n])
            for lo, hi in zip(edges[:-1], edges[1:]):
                if not valid[lo]:
                    continue
                if lo in starts:
                    self._close()
                    self.current = _RunSums(first + lo, float(t[lo]), self.factors)
                values = {name: v[lo:hi] for name, v in columns.items()}
                check_factors(self.model, [Segment(0, np.arange(first + lo, first + hi),
                                                   t[lo:hi], values)])
                self.current.add(t[lo:hi], values, self.model)
        if not valid[-1]:
            self._close()
        self.last_t = float(t[-1])

    def take(self):
        """What the pass hands over chunk by chunk: nothing (it is all in the state)."""
        return None

    def absorb(self, outputs):
        """Nothing to gather (:meth:`take`)."""

    def finish(self):
        """The scan of the whole record (:class:`RecordScan`)."""
        if self.step is None:
            self._set_step()
        self._close()
        if not self.runs:
            raise InputDataError(f"no run of {self.min_length} contiguous samples without "
                                 f"gaps or NaN in the record: nothing to identify on")
        unit = exponent(self.largest[Signal(self.model.output)])
        return RecordScan(self.runs, self.step, self.largest,
                          [(float(np.ldexp(total, 2 * ((self.scale or 0) - unit))), count)
                           for total, count in self.differences],
                          self.rows, self.signals, self.clock[0])


class StreamedProblem(WindowProblem):
    """:class:`~algid.identification._window_problem.WindowProblem` of a streamed record.

    Its rows are made in passes over the record's chunks (:meth:`prefetch`) and kept;
    the samples are not.  The scaling, the noise bound and the excitation check come
    from the first pass (:class:`RecordScan`); the noise covariances of the rows, the
    same on every window, from one window of the kernels (:meth:`noise_grams`,
    :meth:`noise_meat`).

    Parameters
    ----------
    model : algid.models._model.Model
        A model :func:`stream_refusal` accepts.
    source : object
        The record's chunks.
    scan : RecordScan
        The first pass over it.
    time, rate : optional
        The time column or the sampling rate, as for :func:`scan_record`.
    chunk : int
        Rows per chunk.
    """

    def __init__(self, model, source, scan, *, time=None, rate=None, chunk=CHUNK_SAMPLES):
        self.model = model
        self.source, self.scan, self.chunk = source, scan, chunk
        self.time_column, self.rate = time, rate
        signals = scan.signals
        #: the columns read: the signals, then the time column if there is one
        self.columns = signals + [n for n in (time, "t", "time") if n and n not in signals]
        self.time_unit = float(np.ldexp(1.0, int(np.round(np.log2(scan.step)))))
        steps = np.array([run.user_step for run in scan.runs])
        common = float(np.average(steps, weights=[len(run) for run in scan.runs]))
        if np.all(np.abs(steps - common) <= SAME_STEP * common):
            steps[:] = common   # one step: one noise covariance for every window
        for run, step in zip(scan.runs, steps):
            run.step = step / self.time_unit
        self.segments = self.user_segments = scan.runs
        self.step = scan.step
        self.unit_step = scan.step / self.time_unit
        self.parameters = model.parameters
        self.output_exponent = exponent(scan.largest[Signal(model.output)])
        self.output_unit = float(np.ldexp(1.0, self.output_exponent))
        self.cache = ProblemCache()
        self._exponents = {}
        self.sign_jumps, self.first_values, self.crossings, self.steps = {}, {}, {}, {}
        self.step_rests, self.velocity_crossings = {}, False
        self._rows = {}
        #: the kernel multiplicities whose rows one pass makes together
        self.multiplicities = ()
        self._grams = {}

    def excerpts(self, samples, count, min_length):
        """The problem on ``count`` excerpts of the record, ``samples`` in all, spread
        over it (the whole record when it is no longer), each within a run, read in one
        pass and held in memory: a problem in memory, its :attr:`share` that of the
        excerpts' samples in the record's.

        Parameters
        ----------
        samples, count : int
            Samples in all, and excerpts.
        min_length : int
            Runs shorter than this are dropped.

        Returns
        -------
        WindowProblem
        """
        scan = self.scan
        ranges = [(scan.runs[i].start + start, scan.runs[i].start + stop)
                  for i, start, stop in spread_ranges([len(run) for run in scan.runs],
                                                      samples, count, min_length)]
        pieces = self.source.read(self.columns, ranges, self.chunk)
        parts = {"t": [], **{name: [] for name in scan.signals}}
        for i, (piece, (start, _)) in enumerate(zip(pieces, ranges)):
            t, columns = chunk_columns(piece, start, scan.signals, self.time_column,
                                       self.rate, [scan.origin])
            if i:   # a row between two excerpts, NaN: a break of the runs
                parts["t"].append([(parts["t"][-1][-1] + t[0]) / 2])
                for name in scan.signals:
                    parts[name].append([np.nan])
            parts["t"].append(t)
            for name in scan.signals:
                parts[name].append(columns[name])
        record = {name: np.concatenate(p) for name, p in parts.items()}
        segments, step, n_samples = prepare_records(record, self.model.signals, time="t",
                                                    min_length=min_length)
        excerpt = WindowProblem(self.model, segments, step)
        excerpt.share = n_samples / scan.n_samples
        return excerpt

    def factor_exponent(self, factor, which="measured"):
        """The power of two of a factor's largest sample (from the scan)."""
        return exponent(self.scan.largest[factor])

    def factor_largest(self, factor):
        """A factor's largest absolute sample, in its power of two."""
        return float(np.ldexp(self.scan.largest[factor], -self.factor_exponent(factor)))

    def difference_sums(self):
        """The output's :func:`difference_sums` from the scan (in its unit)."""
        return self.scan.differences

    def noise_bound(self, signal=None):
        """The bound of :meth:`WindowProblem.noise_bound` from the scan's sums."""
        if self.cache.noise_bound is None:   # (the sums are in the output's unit)
            self.cache.noise_bound = noise_bound_from_sums(self.scan.differences)
        return self.cache.noise_bound

    def rows(self, length, multiplicity, which="measured"):
        """Regressors, known side and window runs for one window length and
        multiplicity (made by a pass over the record unless :meth:`prefetch` made them)."""
        key = (length, multiplicity)
        if key not in self._rows:   # a pass for this length's multiplicities; the rows of
            # other lengths are dropped (the solves ask for one length after another)
            self._rows = {k: v for k, v in self._rows.items() if k[0] == length}
            self._grams = {k: v for k, v in self._grams.items() if k in self._rows}
            self.prefetch([(length, a) for a in (*self.multiplicities, multiplicity)])
        A, b, ids = self._rows[key]
        if len(ids) == 0:
            raise InputDataError(f"no segment holds a window of {length} samples")
        return A, b, ids

    def prefetch(self, keys):
        """Make the rows of every ``(length, multiplicity)`` of ``keys`` in one pass.

        Parameters
        ----------
        keys : sequence of tuple of int
            Window lengths (samples) and kernel multiplicities.
        """
        keys = [k for k in dict.fromkeys(keys) if k not in self._rows]
        if not keys:
            return
        rows = _RowPass(self.model, self.segments, keys, self.exponents()[2],
                        {f: self.factor_exponent(f) for f in self.scan.largest},
                        self.scan.signals, self.time_column, self.rate,
                        None if self.uniform_noise else self.noise_paths(),
                        self.output_noise_variance())
        rows.clock = [self.scan.origin]
        for key, (A, b, ids, grams) in self.source.reduce(rows, self.columns,
                                                          self.chunk).finish().items():
            self._rows[key] = (A, b, ids)
            self._grams[key] = grams

    def noise_grams(self, length, multiplicity, signal=None):
        """Per-window noise covariance of ``[A | b]`` (with every term reading the
        output as itself, the same on every window of a run: a read-only broadcast,
        :meth:`uniform_noise_grams`; else made with the rows)."""
        if self.uniform_noise:
            return self.uniform_noise_grams(length, multiplicity)
        self.rows(length, multiplicity)
        return self._grams[(length, multiplicity)].copy()   # (the solve overwrites it)

    def noise_meat(self, length, multiplicity, theta_bar, scores, stride):
        """The covariance of :func:`algid.identification._window_covariance.noise_meat`:
        its sample weights the same in every window of a run where every term reads the
        output as itself (:meth:`uniform_noise_meat`), else a pass over the record
        (:class:`_MeatPass`)."""
        if self.uniform_noise:
            return self.uniform_noise_meat(length, multiplicity, theta_bar, scores, stride)
        meat = _MeatPass(self.segments, self.windows(length), length, multiplicity,
                         theta_bar, scores, stride, self.noise_paths(), self.model,
                         self.scan.signals, self.time_column, self.rate,
                         self.output_noise_variance())
        meat.clock = [self.scan.origin]
        return self.source.reduce(meat, self.columns, self.chunk).finish()


class _RunPass:
    """A pass over the runs of a record, fed its chunks in order (:meth:`feed`): each
    run's pieces go to :meth:`_piece`, after :meth:`_start_run` at its first, and
    :meth:`_end_run` follows its last."""

    def feed(self, first, part):
        """Take the chunk of rows from ``first`` (a mapping of columns)."""
        t, columns = chunk_columns(part, first, self.signals, self.time, self.rate,
                                   self.clock)
        last = first + len(t)
        while self.run < len(self.runs) and self.runs[self.run].start < last:
            run = self.runs[self.run]
            lo, hi = max(run.start, first) - first, min(run.stop, last) - first
            if lo >= hi:   # the run starts in a later chunk
                break
            if self.buffer is None:   # a new run: no samples, no windows yet
                self._start_run()
            values = {name: v[lo:hi] for name, v in columns.items()}
            self._piece(run, t[lo:hi], values, first + lo, first + hi - run.start,
                        run.stop <= last)
            if run.stop > last:
                break
            self._end_run()
            self.buffer = None
            self.run += 1

    def _end_run(self):
        """After a run's last piece."""


class _RowPass(_RunPass):
    """A pass making the rows of several window lengths and multiplicities, fed the
    record's chunks in order (:meth:`feed`): in this process, or along a chain of tasks
    on a cluster (it pickles; :meth:`take` hands over the rows made so far)."""

    def __init__(self, model, runs, keys, shifts, units, signals, time, rate, paths=None,
                 variance=0.0):
        self.model, self.runs, self.keys, self.shifts = model, runs, keys, shifts
        self.units, self.signals, self.time, self.rate = units, signals, time, rate
        self.paths = paths                # the noise's paths (None: the same in every window)
        self.variance = variance          # the output noise's (noise_curvature)
        self.clock = [None]               # the first time of a record of dates
        self.run = 0                      # the run being read
        self.buffer, self.origin, self.done = None, 0, None
        self.blocks = {k: ([], [], [], []) for k in keys}

    def _start_run(self):
        self.buffer, self.origin = {f: np.empty(0) for f in self.units}, 0
        if self.paths:
            self.buffer.update({("sensitivity", f): np.empty(0) for *_, f, _ in self.paths})
        self.done = dict.fromkeys(self.keys, 0)

    def _piece(self, run, t, values, row, end, ended):
        """A run's samples at rows ``row ..``, its first ``end`` samples read so far."""
        _check_uniform(run, t, row)
        for f, unit in self.units.items():
            with np.errstate(over="ignore", under="ignore", invalid="ignore"):
                z = np.asarray(f.evaluate(values, t), dtype=float) * np.ones(len(t)) \
                    - noise_curvature(f, self.model.output, values, t, self.variance,
                                      1e-3 * max(run.output_largest, 1e-300))
            self.buffer[f] = np.concatenate([self.buffer[f], np.ldexp(z, -unit)])
        for f, z in _sensitivities(self.paths or (), self.model.output, values, t,
                                   run, self.variance).items():
            key = ("sensitivity", f)
            self.buffer[key] = np.concatenate([self.buffer[key], z])
        self._windows(run, end)

    def _windows(self, run, end):
        """Rows of the windows of ``run`` that end within its first ``end`` samples; the
        buffer's samples before the next window of every key are dropped."""
        buffer, origin, done = self.buffer, self.origin, self.done
        for length, multiplicity in done:
            stride = window_stride(length)
            total = (len(run) - length) // stride + 1 if len(run) >= length else 0
            ready = min(total, (end - length) // stride + 1 if end >= length else 0)
            w = done[(length, multiplicity)]
            if ready <= w:
                continue
            lo = w * stride - origin
            hi = (ready - 1) * stride + length - origin
            integrals = [block_window_integrals(buffer[term.factor][lo:hi], run.step,
                                                length, multiplicity, term.derivative, stride)
                         for term in self.model.terms]
            A, b = term_rows(self.model, integrals, self.shifts, ready - w)
            a_blocks, b_blocks, id_blocks, gram_blocks = self.blocks[(length, multiplicity)]
            a_blocks.append(A)
            b_blocks.append(b)
            id_blocks.append(np.full(ready - w, self.run))
            if self.paths:
                gram_blocks.append(self._grams(run, lo, hi, length, multiplicity, stride,
                                               ready - w))
            done[(length, multiplicity)] = ready
        keep = min(min(done[k] * window_stride(k[0]) for k in done), end)
        if keep > origin:
            for f in buffer:
                buffer[f] = buffer[f][keep - origin:]
            self.origin = keep

    def _grams(self, run, lo, hi, length, multiplicity, stride, count):
        """The noise covariances of ``count`` windows (buffer samples ``lo:hi``), as
        :meth:`WindowProblem.noise_grams` makes them in memory."""
        p = len(self.model.parameters)
        grams = np.zeros((count, p + 1, p + 1))
        paths = self.paths
        for i, (c1, w1, k1, f1, _) in enumerate(paths):
            for j, (c2, w2, k2, f2, _) in enumerate(paths[i:], start=i):
                product = self.buffer[("sensitivity", f1)][lo:hi] \
                    * self.buffer[("sensitivity", f2)][lo:hi]
                weights = window_sample_weights(None, run.step, length, multiplicity, k1) \
                    * window_sample_weights(None, run.step, length, multiplicity, k2)
                v = w1 * w2 * block_window_sums(product, weights, stride)
                grams[:, c1, c2] += v
                if j != i:
                    grams[:, c2, c1] += v
        return grams

    def take(self):
        """The rows made since the last call (put back by :meth:`absorb`)."""
        made, self.blocks = self.blocks, {k: ([], [], [], []) for k in self.keys}
        return made

    def absorb(self, outputs):
        """Put back the rows :meth:`take` handed over, in the order they were made."""
        made = [*outputs, self.take()]
        self.blocks = {k: tuple(sum((m[k][i] for m in made), []) for i in range(4))
                       for k in self.keys}

    def finish(self):
        """``{(length, multiplicity): (A, b, ids, grams)}`` of the whole record
        (``grams`` None where the noise is the same in every window)."""
        p = len(self.model.parameters)
        return {key: (np.vstack(a) if a else np.zeros((0, p)),
                      np.concatenate(b) if b else np.zeros(0),
                      np.concatenate(ids) if ids else np.zeros(0, int),
                      (np.concatenate(grams) if grams else np.zeros((0, p + 1, p + 1)))
                      if self.paths else None)
                for key, (a, b, ids, grams) in self.blocks.items()}


def _check_uniform(run, t, first):
    """Refuse samples off the uniform grid of their run (rows from ``first``)."""
    grid = run.t0 + np.arange(first - run.start, first - run.start + len(t)) * run.user_step
    off = np.abs(t - grid)
    # what single-precision times are off by (two halves of their last place), at most
    # STREAM_JITTER of a step; more is jitter: refused (in memory, exact integrals)
    quantum = np.finfo(np.float32).eps * max(abs(run.t0), abs(run.t_end))
    allowed = min(STREAM_JITTER * run.user_step, max(UNIFORM_TOLERANCE * run.user_step,
                                                     quantum))
    if len(t) and float(np.max(off)) > allowed:
        row = first + int(np.argmax(off))
        raise InputDataError(
            f"record 0: the sample at row {row} is {float(np.max(off)) / run.user_step:.3g} "
            f"steps off the uniform grid of its run: a record read in chunks must be "
            f"uniformly sampled (load it and pass it in memory, or resample it)")


def _sensitivities(paths, output, values, t, run, variance):
    """Per factor of ``paths``, its derivative with respect to the output's samples, in
    the units of the rows (as :meth:`WindowProblem.sensitivity`: the step of the central
    differences from the run's largest output sample)."""
    out = {}
    for *_, factor, shift in paths:
        if factor in out:
            continue
        if factor == Signal(output):
            out[factor] = np.ones(len(t))
        else:
            largest = max(run.output_largest, 1e-300)
            out[factor] = np.ldexp(factor_sensitivity(factor, output, values, t, 1e-6 * largest,
                                                      variance, largest), shift)
    return out


class _MeatPass(_RunPass):
    """A pass for the middle of the sandwich under output noise whose weights change
    from window to window (terms reading the output nonlinearly): that of
    :func:`algid.identification._window_covariance.noise_meat`, windows taken in blocks
    with the neighbours they share samples with."""

    def __init__(self, runs, counts, length, multiplicity, theta_bar, scores, stride, paths,
                 model, signals, time, rate, variance=0.0):
        self.runs, self.counts, self.length, self.multiplicity = runs, counts, length, \
            multiplicity
        self.stride, self.paths, self.model = stride, paths, model
        self.variance = variance          # the output noise's (noise_curvature)
        self.signals, self.time, self.rate = signals, time, rate
        self.scores = scores
        self.clock = [None]
        self.factors = [w * theta_bar[c] for c, w, *_ in paths]   # (noise_meat's)
        self.lags = -(-length // stride)
        self.run, self.first_window = 0, 0
        self.buffer, self.origin, self.done = None, 0, 0
        self.meat = np.zeros((scores.shape[1], scores.shape[1]))

    def _start_run(self):
        self.buffer = {f: np.empty(0) for *_, f, _ in self.paths}
        self.origin, self.done = 0, 0

    def _piece(self, run, t, values, row, end, ended):
        """A run's samples at rows ``row ..``, its first ``end`` samples read so far."""
        for f, z in _sensitivities(self.paths, self.model.output, values, t, run,
                                   self.variance).items():
            self.buffer[f] = np.concatenate([self.buffer[f], z])
        self._windows(run, end, ended)

    def _end_run(self):
        self.first_window += self.counts[self.run]

    def _weights(self, run, start, count):
        """The noise weight of every sample of windows ``start ..`` (``count`` of them)."""
        length, stride = self.length, self.stride
        lo = start * stride - self.origin
        weights = np.zeros((count, length))
        for (_, _, k, f, _), factor in zip(self.paths, self.factors):
            kernel = window_sample_weights(None, run.step, length, self.multiplicity, k)
            z = self.buffer[f][lo:lo + (count - 1) * stride + length]
            windows = np.lib.stride_tricks.sliding_window_view(z, length)[::stride]
            weights += factor * windows * kernel
        return weights

    def _windows(self, run, end, ended):
        """The middle's terms of the windows whose neighbours within the lags end
        within the run's first ``end`` samples (all of them at the run's end)."""
        n_win, length, stride = self.counts[self.run], self.length, self.stride
        if n_win == 0:
            return
        available = (end - length) // stride + 1 if end >= length else 0
        stop = n_win if ended else max(self.done, min(n_win, available - self.lags))
        if stop <= self.done:
            return
        start, upto = self.done, min(n_win, stop + self.lags)
        weights = self._weights(run, start, upto - start)
        g = self.scores[self.first_window + start:self.first_window + upto]
        own = stop - start
        for lag in range(min(n_win, self.lags)):
            shift = lag * stride
            pairs = min(own, upto - start - lag)
            if pairs <= 0:
                continue
            c = np.einsum("ij,ij->i", weights[:pairs, shift:], weights[lag:lag + pairs,
                                                                       :length - shift])
            cross = (g[:pairs] * c[:, None]).T @ g[lag:lag + pairs]
            self.meat += cross if lag == 0 else cross + cross.T
        self.done = stop
        keep = stop * stride
        if keep > self.origin:
            for f in self.buffer:
                self.buffer[f] = self.buffer[f][keep - self.origin:]
            self.origin = keep

    def take(self):
        """Nothing handed over chunk by chunk (the middle is a sum in the state)."""
        return None

    def absorb(self, outputs):
        """Nothing to gather (:meth:`take`)."""

    def finish(self):
        """The middle of the sandwich (``k x k``)."""
        return self.meat
