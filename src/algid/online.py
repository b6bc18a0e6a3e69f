"""On-line (streaming) algebraic estimation: ``algid.OnlineEstimator``.

The batch estimator (:func:`algid.estimate`) computes every kernel over a whole record.
:class:`OnlineEstimator` computes the same numbers from a stream of samples that
arrives in chunks of any size (one sample or thousands), with a state whose size does
not depend on the length of the stream.

Realisation
-----------
The generated module of a model (:mod:`algid.generated`) lists in ``CHAINS`` the
integrator chains that realise its kernels as a time-varying linear system: state
``l`` of the chain ``(signal, power, depth)`` is the ``l``-fold integral of
``tau**power * signal`` (``tau`` is the time since the origin), driven by state
``l - 1``.  The estimator steps these chains with the causal ``q``-point rule of
:mod:`algid.quadrature` (``q = quadrature_order``), evaluates ``P`` and ``Q`` with the
generated ``regressors``, Cramer's rule with the generated ``cramer``, then steps ``p``
more integrators (``p = filter_order``, the invariant filter ``1/s**p``) on every
numerator and on the denominator, and divides.  Each integrator keeps its running sum
and the last ``q - 1`` samples of its integrand; nothing else of the past is kept.
Within a chunk the step is vectorised (``numpy.correlate`` over the carried samples
and the chunk, then a cumulative sum from the carried sum), and the arithmetic is done
in the same order as in the batch estimator, so the estimates do not depend on how the
stream is cut into chunks and equal those of :func:`algid.estimate` on the same
samples to round-off (bit for bit with the same sampling step).  Chunks of fewer than
:data:`VECTOR_MIN_CHUNK` samples take a per-sample loop over Python floats instead,
which is faster for them and computes the same numbers.

Engines
-------
The realisation above, in NumPy, is the reference (``engine="numpy"``).  With numba
installed (``pip install "algid[fast]"``) the estimator runs by default on the
compiled engine of :mod:`algid.engine` (``engine="numba"``): each estimator of a time
origin is an :class:`algid.engine.EngineState`, which the compiled loop advances over
every chunk.  It performs the same arithmetic in the same order, so its estimates
equal those of :func:`algid.estimate` with ``engine="numba"`` bit for bit in any
chunking, and those of the NumPy engine to round-off (bit for bit on the platforms
tested).  There the chunks are checked in one compiled pass, and single samples (given
as floats or one-element arrays) take a short path that calls the compiled loop
directly: chunks of a thousand samples run at nearly the speed of the batch estimator,
single samples at a few microseconds each.  Each restart of an estimator costs more:
the engine processes the first ``q`` samples after an origin with NumPy, as the batch
estimator does (some hundreds of microseconds), which dominates with short reset
periods (at :data:`TRACKING_RESET_PERIOD` and 1 kHz, a restart every 25 samples).
``engine="auto"`` (the default) is ``"numba"`` when numba can be imported: for a
stream what counts is the cost of each call, which the compiled engine keeps small.

Start-up
--------
The rule of ``q`` points integrates the first ``q - 2`` intervals with the polynomial
through samples ``0 .. q - 1`` (see :mod:`algid.quadrature`), so nothing can be
computed before sample ``q - 1`` has arrived.  The estimator holds up to ``q - 1``
samples in a start-up buffer and returns NaN for samples ``0 .. q - 2`` (the batch
estimator returns NaN there too); the first estimate is that of sample ``q - 1``,
returned by the call that delivers it.  Afterwards every call returns the estimates of
exactly the samples it was given: the estimator is causal, with no delay.

Re-anchoring the time origin (``reset_period``)
-----------------------------------------------
The weights ``tau**k`` and the iterated integrals grow without bound, and an estimate
that uses the whole past cannot follow a change of the parameters.  Because the method
does not depend on the initial conditions, the time origin may be moved to any
sample: the estimator restarts there, with all integrals zero, as if the stream began
at that sample.  With ``reset_period=T`` two estimators run staggered by ``T/2``:
estimator A restarts at samples ``0, N, 2N, ...`` and estimator B at ``N/2, 3N/2,
...``, where ``N/2 = round(T / (2 dt))`` samples (the period actually used is ``N dt``,
see :attr:`OnlineEstimator.reset_period`).  At every sample the estimate reported is
that of the estimator whose window is the older one, of age between ``N/2`` and
``N - 1`` samples (before B starts, that of A).  Hence

- the estimate at time ``t`` uses only data from ``(t - T, t]``; a change of the
  parameters is followed, exactly for noise-free data, once the reported window starts
  after the change, at the latest ``T`` after it;
- each restarted estimator has ``T/2`` to converge before it is reported, and its
  integrals never span more than ``T``, so all internal magnitudes are bounded;
- the estimates of a window equal those of :func:`algid.estimate` on the data from the
  window's origin on.

The price is a second estimator (twice the arithmetic) and the loss of the averaging
over the whole record, which matters with noisy data.  ``reset_period=None`` (the
default) never restarts and reproduces the batch estimator.  For tracking changes in
noise-free or nearly noise-free data at about 1 kHz, :data:`TRACKING_RESET_PERIOD` is a
good choice; see its description.

Examples
--------
>>> import numpy as np, algid
>>> t, f, x = algid.simulate("step", m=1, c=2, k=3, duration=1.0)
>>> est = algid.OnlineEstimator(dt=1e-3)
>>> r = est.update(t[:500], f[:500], x[:500])     # a chunk of 500 samples
>>> r = est.update(t[500:], f[500:], x[500:])     # the rest
>>> round(r.final()["B"], 6), round(r.final()["K"], 6)
(2.0, 3.0)
"""

from __future__ import annotations

import math
import numbers
from functools import lru_cache

import numpy as np

from algid.errors import InputDataError
from algid.estimator import (DEFAULT_FILTER_ORDER, DEFAULT_QUADRATURE_ORDER, _check_options,
                             _choose_engine, _known_mass, _with_physical_parameters,
                             load_model)
from algid.quadrature import rule_weights, startup_samples
from algid.result import EstimationResult
from algid.validation import UNIFORM_RTOL, as_signal, positive_number

__all__ = ["OnlineEstimator", "run_stream", "TRACKING_RESET_PERIOD", "VECTOR_MIN_CHUNK"]

#: Reset period [s] suggested for following changes of the parameters in noise-free
#: or nearly noise-free data at about 1 kHz with the default options (filter order 2,
#: 6-point rule).  Measured on the paper's system (B = 2, K = 3) and after changes to
#: K = 5 or B = 1, for step and sine inputs: a window started in mid-stream comes
#: within 0.1 % 5-7 ms after its origin (13 ms for a sine from rest; within 1e-6 after
#: 5-20 ms, 68 ms for a step response that has settled), inside the half period of
#: 25 ms before it is reported, and the estimates are within 0.1 % of the new values
#: once the reported window starts after the change: 25-48 ms after it (at most one
#: period).  Short windows do not average measurement noise: with noise of 1e-4 m on
#: ``x`` they are useless at this period, and periods of seconds are needed.
TRACKING_RESET_PERIOD = 0.05

#: With ``engine="numpy"``, chunks of at least this many samples are processed
#: vectorised; shorter ones with a per-sample loop.  Both compute the same numbers.
VECTOR_MIN_CHUNK = 6

_FLOAT64 = np.dtype(np.float64)


def _fmt(value) -> str:
    return f"{float(value):.10g}"


# --------------------------------------------------------------------------------------
# integrators
# --------------------------------------------------------------------------------------


class _IntegratorBank:
    """``rows`` integrator chains of ``depth`` levels stepped with the ``q``-point rule.

    Level 0 is the input; level ``l`` the cumulative integral of level ``l - 1``.  The
    state is, per level ``l >= 1``, the running sum of the unscaled increments (the
    integral divided by the step), and, per level ``l < depth``, the last ``q - 1``
    samples of that level (the integrand of the next).  The arithmetic follows
    :func:`algid.quadrature.cumulative_integral` step for step.
    """

    def __init__(self, rows: int, depth: int, order: int):
        self.rows = rows
        self.depth = depth
        self.order = order
        self.regular, self.startup = rule_weights(order)
        self.weights = tuple(float(w) for w in self.regular)
        self._sums = np.zeros((depth, rows))
        self._hist = np.zeros((depth, rows, order - 1))
        self._lists = None  # the state as Python lists while the per-sample loop runs

    def reset(self):
        self._sums.fill(0.0)
        self._hist.fill(0.0)
        self._lists = None

    def arrays(self):
        """The state as arrays ``(sums, hist)``, for vectorised steps."""
        if self._lists is not None:
            self._sums[...], self._hist[...] = self._lists
            self._lists = None
        return self._sums, self._hist

    def lists(self):
        """The state as nested lists ``(sums, hist)``, for per-sample steps (updated in
        place by :func:`_step_lists`)."""
        if self._lists is None:
            self._lists = (self._sums.tolist(), self._hist.tolist())
        return self._lists

    def start(self, y, h):
        """Levels over the first ``m >= q`` samples ``y`` (shape ``(rows, m)``)."""
        q = self.order
        m = y.shape[1]
        sums_state, hist_state = self.arrays()
        levels = [y]
        for level in range(self.depth):
            inc = np.empty((self.rows, m - 1))
            for i in range(self.rows):
                inc[i, q - 2:] = np.correlate(y[i], self.regular, mode="valid")
                if q > 2:
                    inc[i, : q - 2] = self.startup @ y[i, :q]
            out = np.empty((self.rows, m))
            out[:, 0] = 0.0
            np.cumsum(inc, axis=1, out=out[:, 1:])
            sums_state[level] = out[:, -1]
            hist_state[level] = y[:, m - (q - 1):]
            out[:, 1:] *= h
            levels.append(out)
            y = out
        return levels

    def run(self, y, h):
        """Levels over ``m`` further samples ``y`` (shape ``(rows, m)``), vectorised."""
        m = y.shape[1]
        sums_state, hist_state = self.arrays()
        levels = [y]
        for level in range(self.depth):
            carried = np.concatenate((hist_state[level], y), axis=1)
            acc = np.empty((self.rows, m + 1))
            acc[:, 0] = sums_state[level]
            for i in range(self.rows):
                acc[i, 1:] = np.correlate(carried[i], self.regular, mode="valid")
            sums = np.cumsum(acc, axis=1)
            sums_state[level] = sums[:, -1]
            hist_state[level] = carried[:, m:]
            out = sums[:, 1:]
            out *= h
            levels.append(out)
            y = out
        return levels


def _step_lists(y, sums, hist, weights, h):
    """One sample through a bank held as Python lists: ``y`` (rows,) -> all levels.

    ``sums[l][i]`` and ``hist[l][i]`` (a list of ``q - 1`` floats) are updated in place.
    The increment is accumulated in the order of ``numpy.correlate``.
    """
    w_last = weights[-1]
    w_hist = weights[:-1]
    levels = [y]
    for sums_l, hist_l in zip(sums, hist):
        nxt = []
        for i, yi in enumerate(y):
            past = hist_l[i]
            acc = 0.0
            for w, v in zip(w_hist, past):
                acc += w * v
            acc += w_last * yi
            s = sums_l[i] + acc
            sums_l[i] = s
            del past[0]
            past.append(yi)
            nxt.append(s * h)
        levels.append(nxt)
        y = nxt
    return levels


# --------------------------------------------------------------------------------------
# one estimator with one time origin
# --------------------------------------------------------------------------------------


class _Window:
    """The estimator with its time origin at the sample after the last restart."""

    def __init__(self, gen, order, filter_order):
        self.gen = gen
        self.order = order
        self.filter_order = filter_order
        self.chains = _IntegratorBank(len(gen.CHAINS), max(c[2] for c in gen.CHAINS), order)
        self.filters = (_IntegratorBank(len(gen.PARAMETERS) + 1, filter_order, order)
                        if filter_order else None)
        # (kernel name, chain index, level) for every state of every chain
        self.kernel_index = [(gen.kernel_name(sig, power, level), c, level)
                             for c, (sig, power, depth) in enumerate(gen.CHAINS)
                             for level in range(depth + 1)]
        self.rows = [(0 if sig == gen.INPUT else 1, power) for sig, power, _ in gen.CHAINS]
        self.restart(origin_time=float("nan"))

    def restart(self, *, origin_time):
        self.n = 0  # samples since the origin
        self.h = None  # sampling step, set by feed
        self.origin_time = origin_time
        self.buffer = []  # start-up: (u, x) chunks before sample q - 1
        self.chains.reset()
        if self.filters is not None:
            self.filters.reset()

    def state_magnitude(self) -> float:
        """Largest absolute value of the integrals (running sums times the step) and of
        the carried samples."""
        mags = [0.0]
        for bank in (self.chains, self.filters):
            if bank is not None and self.h is not None:
                sums, hist = bank.arrays()
                mags += [float(np.max(np.abs(sums))) * self.h, float(np.max(np.abs(hist)))]
        mags += [float(np.max(np.abs(a))) for chunk in self.buffer for a in chunk]
        return max(mags)

    def _integrands(self, u, x, h):
        """Level 0 of every chain: ``tau**power * signal``, shape ``(chains, m)``."""
        m = u.size
        tau = (self.n + np.arange(m)) * h
        signals = (u, x)
        y = np.empty((len(self.rows), m))
        powers = {}
        for row, (sig, power) in enumerate(self.rows):
            if power == 0:
                y[row] = signals[sig]
            else:
                if power not in powers:
                    powers[power] = tau**power
                np.multiply(powers[power], signals[sig], out=y[row])
        return y

    def _finish(self, numerators, denominator):
        undefined = ~np.isfinite(denominator) | (denominator == 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            return [np.where(undefined, np.nan, num / denominator) for num in numerators]

    def feed(self, u, x, h):
        """Estimates (list of arrays, in the order of PARAMETERS) for ``m`` new samples."""
        self.h = h
        m = u.size
        q = self.order
        if self.n < q:  # start-up: wait for sample q - 1
            if self.n + m < q:
                self.buffer.append((u.copy(), x.copy()))
                self.n += m
                return [np.full(m, np.nan) for _ in self.gen.PARAMETERS]
            old = self.n
            self.buffer.append((u, x))
            u_all = np.concatenate([b[0] for b in self.buffer])
            x_all = np.concatenate([b[1] for b in self.buffer])
            self.buffer = []
            self.n = 0
            est = self._vector(u_all, x_all, h, start=True)
            self.n = old + m
            return [e[old:] for e in est]
        if m >= VECTOR_MIN_CHUNK:
            est = self._vector(u, x, h, start=False)
        else:
            est = self._loop(u, x, h)
        self.n += m
        return est

    def _vector(self, u, x, h, *, start):
        gen = self.gen
        y = self._integrands(u, x, h)
        levels = self.chains.start(y, h) if start else self.chains.run(y, h)
        kern = {name: levels[level][c] for name, c, level in self.kernel_index}
        P, Q = gen.regressors(kern)
        numerators, denominator = gen.cramer(P, Q)
        m = u.size
        if self.filters is not None:
            stacked = np.empty((len(numerators) + 1, m))
            stacked[:-1] = numerators
            stacked[-1] = denominator
            out = (self.filters.start(stacked, h) if start else self.filters.run(stacked, h))[-1]
            numerators, denominator = out[:-1], out[-1]
        est = self._finish(numerators, denominator)
        if start:
            for e in est:
                e[: startup_samples(self.order)] = np.nan
        return est

    def _loop(self, u, x, h):
        """The same arithmetic as :meth:`_vector`, one sample at a time on floats."""
        gen = self.gen
        n0 = self.n
        w = self.chains.weights
        c_sums, c_hist = self.chains.lists()
        filt = self.filters
        if filt is not None:
            f_sums, f_hist = filt.lists()
        index = self.kernel_index
        rows = self.rows
        nan = float("nan")
        inf = float("inf")
        out = []
        for j, (uj, xj) in enumerate(zip(u.tolist(), x.tolist())):
            tau = (n0 + j) * h
            signals = (uj, xj)
            # tau**power as NumPy computes it (power 2 is a product, see _integrands)
            y = [signals[sig] if power == 0 else
                 tau * signals[sig] if power == 1 else
                 tau * tau * signals[sig] if power == 2 else
                 float((np.array([tau]) ** power)[0]) * signals[sig]
                 for sig, power in rows]
            levels = _step_lists(y, c_sums, c_hist, w, h)
            P, Q = gen.regressors({name: levels[level][c] for name, c, level in index})
            numerators, denominator = gen.cramer(P, Q)
            if filt is not None:
                last = _step_lists([*numerators, denominator], f_sums, f_hist, w, h)[-1]
                numerators, denominator = last[:-1], last[-1]
            if denominator == 0 or denominator != denominator or abs(denominator) == inf:
                out.append([nan] * len(numerators))
            else:
                out.append([num / denominator for num in numerators])
        return list(np.array(out, dtype=float).reshape(len(out), -1).T)


class _EngineWindow:
    """The estimator with its time origin at the sample after the last restart, on the
    compiled engine: an :class:`algid.engine.EngineState`."""

    def __init__(self, gen, order, filter_order, step, divisor):
        from algid import engine
        self.state = engine.make_state(gen, order, filter_order, step=step,
                                       input_divisor=divisor)
        self.origin_time = float("nan")

    def restart(self, *, origin_time):
        self.state.reset()
        self.origin_time = origin_time

    def state_magnitude(self) -> float:
        """As :meth:`_Window.state_magnitude`."""
        state = self.state
        mags = [0.0, float(np.max(np.abs(state.sums))) * state.step,
                float(np.max(np.abs(state.windows)))]
        if 0 < state.n_seen < state.quadrature_order:  # the start-up buffer
            mags.append(float(np.max(np.abs(state._startup[:, :state.n_seen]))))
        return max(mags)


@lru_cache(maxsize=None)
def _compiled_scan():
    """The checks of :meth:`OnlineEstimator._check_chunk` on the values of float64
    samples, compiled (for ``engine="numba"``): ``scan(t, f, x, t_prev, h, tolerance)``
    is True when ``t``, ``f``, ``x`` are finite and every step of ``t`` (from
    ``t_prev`` on, unless NaN) is positive and within ``tolerance`` of ``h`` (unless
    NaN)."""
    import numba

    # reductions in any order (vectorised); the result does not depend on the order:
    # a sum of v * 0 is NaN if and only if some v is not finite
    @numba.njit("boolean(float64[::1], float64[::1], float64[::1], float64, float64, float64)",
                cache=True, nogil=True, fastmath={"reassoc"})
    def scan(t, f, x, t_prev, h, tolerance):
        nan_if_bad = 0.0
        for i in range(t.shape[0]):
            nan_if_bad += t[i] * 0.0 + f[i] * 0.0 + x[i] * 0.0
        if nan_if_bad != 0.0:
            return False
        violations = 0
        if t_prev == t_prev:
            step = t[0] - t_prev
            violations += (not step > 0.0) + (abs(step - h) > tolerance)
        for i in range(t.shape[0] - 1):
            step = t[i + 1] - t[i]
            violations += (not step > 0.0) + (abs(step - h) > tolerance)
        return violations == 0

    return scan


# --------------------------------------------------------------------------------------
# the public estimator
# --------------------------------------------------------------------------------------


class OnlineEstimator:
    """Algebraic parameter estimator for a stream of samples, fed chunk by chunk.

    Fed the samples of a record in chunks of any sizes, it returns the same estimates
    as :func:`algid.estimate` on the whole record (with ``reset_period=None``), using a
    state of constant size.  See :mod:`algid.online` for the realisation, the start-up
    and the re-anchoring of the time origin.

    Parameters
    ----------
    model : str, optional
        ``"msd"`` (default) or ``"msd_mass"``; see :func:`algid.available_models`.
    filter_order : int, optional
        ``p`` of the invariant filter ``1/s**p`` (0 = none).  Default 2.
    quadrature_order : int, optional
        Points of the quadrature rule (2 = trapezoid).  Default 6.
    mass : float, optional
        Known mass [kg] (model ``"msd"`` only): ``f`` is then the force and the results
        also hold ``c = B m`` and ``k = K m``.
    dt : float, optional
        Sampling step [s].  Give at most one of ``dt`` and ``rate``; with neither, the
        step is taken from the first two samples of the stream.  Every step of the
        stream must be within ``1e-4 dt`` of it.
    rate : float, optional
        Sampling rate [Hz], ``dt = 1 / rate``.
    reset_period : float, optional
        Re-anchor the time origin every ``reset_period`` seconds, with two estimators
        staggered by half a period (see :mod:`algid.online`); rounded to an even number
        of samples, each half at least ``quadrature_order`` samples.  ``None``
        (default) never re-anchors.  :data:`TRACKING_RESET_PERIOD` suits tracking.
    engine : {"auto", "numpy", "numba"}, optional
        ``"numpy"``: the NumPy realisation of :mod:`algid.online`.  ``"numba"``: the
        compiled engine of :mod:`algid.engine` (needs ``algid[fast]``; several times
        faster for chunks of any size).  Both give the same numbers (bit for bit on
        the platforms tested).  ``"auto"`` (default): ``"numba"`` if numba is
        installed, else ``"numpy"``.

    Attributes
    ----------
    parameters : tuple of str
        Names of the estimates returned (as in :func:`algid.estimate`).
    engine : str
        The engine in use: ``"numpy"`` or ``"numba"``.

    Notes
    -----
    The equality with :func:`algid.estimate` is bit for bit when both use the same
    step.  The batch estimator takes ``(t[-1] - t[0]) / (n - 1)``; on a grid such as
    ``np.arange(n) / 1000`` that may differ from ``dt`` by an ulp, and ill-conditioned
    estimates (the first few samples, or weak excitation) magnify that to about 1e-7
    relative.  Memory is constant: per integrator its running sum and its last
    ``quadrature_order - 1`` integrand samples, plus a start-up buffer of fewer than
    ``quadrature_order`` samples.

    Raises
    ------
    ModelError
        Unknown model, or ``mass`` given for a model that estimates the mass.
    InputDataError
        A bad option (also ``engine="numba"`` without numba installed).

    Examples
    --------
    >>> import algid
    >>> t, f, x = algid.simulate("sine", duration=2.0)
    >>> est = algid.OnlineEstimator(rate=1000.0, reset_period=0.5)
    >>> for i in range(0, t.size, 100):
    ...     r = est.update(t[i:i + 100], f[i:i + 100], x[i:i + 100])
    >>> round(r.final()["K"], 6)
    3.0
    """

    def __init__(self, model="msd", *, filter_order=DEFAULT_FILTER_ORDER,
                 quadrature_order=DEFAULT_QUADRATURE_ORDER, mass=None, dt=None, rate=None,
                 reset_period=None, engine="auto"):
        self._gen = gen = load_model(model)
        _check_options(filter_order, quadrature_order)
        # a stream takes numba whenever it can: there the cost per call matters most
        self.engine = _choose_engine(engine, 0, None, min_samples=0)
        mass = _known_mass(gen, model, mass)
        if dt is not None and rate is not None:
            raise InputDataError("give at most one of dt and rate")
        self._given_dt = (positive_number(dt, name="dt") if dt is not None
                          else 1.0 / positive_number(rate, name="rate") if rate is not None else None)
        self._requested_period = (None if reset_period is None
                                  else positive_number(reset_period, name="reset_period"))
        self.model = model
        self.filter_order = int(filter_order)
        self.quadrature_order = int(quadrature_order)
        self.mass = mass
        self.parameters = tuple(gen.PARAMETERS) + (("c", "k") if mass is not None else ())
        if reset_period is not None and self._given_dt is not None:
            self._half_period(self._given_dt)  # check early
        if self.engine == "numba":
            from algid.engine import run_chunk
            self._run_chunk = run_chunk
            self._scan = _compiled_scan()
            self._step = self._given_dt  # the step of the engine states (None: not set)
            self._n_core = len(gen.PARAMETERS)  # rows computed by the engine
            # rows of B and K, from which those of c and k follow with the mass
            self._mass_rows = (() if mass is None else
                               (gen.PARAMETERS.index("B"), gen.PARAMETERS.index("K")))
            self._discard = np.empty((self._n_core, 64))  # estimates of the other window
            self._one_f = np.empty(1)
            self._one_x = np.empty(1)
            self._discard_one = np.empty((self._n_core, 1))
            self._sample_shape = (len(self.parameters), 1)

            def window():
                return _EngineWindow(gen, self.quadrature_order, self.filter_order,
                                     self._given_dt or 1.0, 1.0 if mass is None else mass)
        else:
            self._scan = None

            def window():
                return _Window(gen, self.quadrature_order, self.filter_order)
        self._windows = [window() for _ in range(1 if reset_period is None else 2)]
        self.reset()

    # ---------------------------------------------------------------- state

    def reset(self):
        """Forget the stream: the next sample is the first (and the new time origin).

        A step given as ``dt`` or ``rate`` is kept; one taken from the stream is
        forgotten.
        """
        self._h = self._given_dt
        self._half = None if self._h is None or self._requested_period is None \
            else self._half_period(self._h)
        self._n = 0
        self._t_last = None
        self._reported = 0
        for w in self._windows:
            w.restart(origin_time=float("nan"))

    def _half_period(self, h):
        half = int(round(self._requested_period / (2.0 * h)))
        need = self.quadrature_order
        if half < need:
            raise InputDataError(
                f"reset_period {_fmt(self._requested_period)} s is too short for step "
                f"{_fmt(h)} s: half a period must hold at least {need} samples "
                f"(reset_period >= {_fmt(2 * need * h)} s)")
        return half

    @property
    def n_seen(self) -> int:
        """Number of samples received since the start (or the last :meth:`reset`)."""
        return self._n

    @property
    def dt(self):
        """Sampling step [s] (``None`` until known)."""
        return self._h

    @property
    def startup_samples(self) -> int:
        """Samples ``0 .. startup_samples - 1`` of the stream get NaN estimates."""
        return startup_samples(self.quadrature_order)

    @property
    def reset_period(self):
        """Re-anchoring period actually used [s]: ``2 * round(T / (2 dt)) * dt``
        (``None`` without re-anchoring; the requested value until ``dt`` is known)."""
        if self._requested_period is None:
            return None
        if self._half is None:
            return self._requested_period
        return 2 * self._half * self._h

    @property
    def t_origin(self) -> float:
        """Time origin of the estimate returned last: the time of the first sample of
        its window (the first sample of the stream without re-anchoring; NaN before any
        sample)."""
        return self._windows[self._reported].origin_time

    @property
    def window_origins(self) -> tuple:
        """Time origins of the running estimators (one, or two with re-anchoring; NaN
        for one not started yet)."""
        return tuple(w.origin_time for w in self._windows)

    @property
    def state_magnitude(self) -> float:
        """Largest absolute value held in the state: the integrals of every chain and
        filter, and the carried samples of their integrands (a check that re-anchoring
        keeps them bounded)."""
        return max(w.state_magnitude() for w in self._windows)

    def __repr__(self):
        period = "" if self._requested_period is None else f", reset_period={self.reset_period:g}"
        return (f"<OnlineEstimator model={self.model!r} filter_order={self.filter_order} "
                f"quadrature_order={self.quadrature_order}{period} engine={self.engine!r} "
                f"n_seen={self._n}>")

    # ---------------------------------------------------------------- input checks

    def _check_sample(self, t, f, x):
        """:meth:`_check_chunk` for one sample given as three numbers (faster)."""
        where = f"in the chunk starting at stream sample {self._n}"
        values = (float(t), float(f), float(x))
        for name, v in zip(("t", "f", "x"), values):
            if not math.isfinite(v):
                what = "NaN" if v != v else ("inf" if v > 0 else "-inf")
                raise InputDataError(f"signal {name!r} has {what} at row 0 {where}")
        h = self._h
        if self._t_last is not None:
            step = values[0] - self._t_last
            if not step > 0:
                raise InputDataError(
                    f"time 't' is not increasing at stream sample {self._n}: "
                    f"{_fmt(values[0])} after {_fmt(self._t_last)}")
            if h is None:
                h = step
            elif abs(step - h) > UNIFORM_RTOL * h:
                raise InputDataError(
                    f"time 't' is not uniformly sampled at stream sample {self._n}: "
                    f"step {_fmt(step)} where {_fmt(h)} is expected")
        return (np.array(values[:1]), np.array(values[1:2]), np.array(values[2:]), h)

    def _scan_chunk(self, t, f, x):
        """:meth:`_check_chunk` in one compiled pass (``engine="numba"``), for 1-D
        contiguous float64 arrays of equal, nonzero length that pass every check;
        ``None`` otherwise (then :meth:`_check_chunk` says what is wrong)."""
        if not (type(t) is np.ndarray and type(f) is np.ndarray and type(x) is np.ndarray):
            return None
        m = t.size
        if not (m and t.ndim == 1 and f.shape == t.shape and x.shape == t.shape
                and t.dtype == _FLOAT64 and f.dtype == _FLOAT64 and x.dtype == _FLOAT64
                and t.flags.c_contiguous and f.flags.c_contiguous and x.flags.c_contiguous):
            return None
        h, t_last = self._h, self._t_last
        if h is None:  # the first step, as _check_chunk takes it
            if t_last is not None:
                h = float(t[0]) - t_last
            elif m > 1:
                h = float(t[1] - t[0])
        nan = math.nan
        step = nan if h is None else h
        if not self._scan(t, f, x, nan if t_last is None else t_last, step,
                          UNIFORM_RTOL * step):
            return None
        return t, f, x, h

    def _check_chunk(self, t, f, x):
        if self._scan is not None:
            checked = self._scan_chunk(t, f, x)
            if checked is not None:
                return checked
        if all(isinstance(v, numbers.Real) for v in (t, f, x)):
            return self._check_sample(t, f, x)
        if all(isinstance(v, np.ndarray) and v.shape == (1,) and v.dtype.kind in "fiu"
               for v in (t, f, x)):
            return self._check_sample(t[0], f[0], x[0])
        where = f"in the chunk starting at stream sample {self._n}"
        arrays = []
        for name, values in (("t", t), ("f", f), ("x", x)):
            try:
                arr = np.asarray(values)
            except (TypeError, ValueError):
                raise InputDataError(f"signal {name!r} is not a 1-D array of numbers "
                                     f"{where}") from None
            if arr.ndim == 0:
                arr = arr.reshape(1)
            if arr.ndim == 1 and arr.size == 0:
                arrays.append(np.empty(0))
                continue
            try:
                arrays.append(as_signal(arr, name=name))
            except InputDataError as exc:
                raise InputDataError(f"{exc} {where}") from None
        t, f, x = arrays
        if not t.size == f.size == x.size:
            raise InputDataError(f"signals have different lengths {where}: 't' has {t.size}, "
                                 f"'f' has {f.size}, 'x' has {x.size}")
        if t.size == 0:
            return t, f, x, self._h
        full = t if self._t_last is None else np.concatenate(([self._t_last], t))
        first = self._n - (full.size - t.size)  # stream index of full[0]
        steps = np.diff(full)
        bad = np.flatnonzero(~(steps > 0))
        if bad.size:
            i = int(bad[0])
            raise InputDataError(
                f"time 't' is not increasing at stream sample {first + i + 1}: "
                f"{_fmt(full[i + 1])} after {_fmt(full[i])}")
        h = self._h
        if h is None and steps.size:
            h = float(steps[0])
        if h is not None and steps.size:
            dev = np.abs(steps - h)
            i = int(np.argmax(dev))
            if dev[i] > UNIFORM_RTOL * h:
                raise InputDataError(
                    f"time 't' is not uniformly sampled at stream sample {first + i + 1}: "
                    f"step {_fmt(steps[i])} where {_fmt(h)} is expected")
        return t, f, x, h

    # ---------------------------------------------------------------- estimation

    def update(self, t, f, x) -> EstimationResult:
        """Take the next samples of the stream and return their estimates.

        Parameters
        ----------
        t : float or array_like
            Sample times [s], continuing the stream (strictly increasing, uniform step).
        f : float or array_like
            Input at those times (as for :func:`algid.estimate`).
        x : float or array_like
            Measured displacement at those times.

        Returns
        -------
        EstimationResult
            Estimates at the given times, computed from the samples up to each of them.
            NaN for the first ``startup_samples`` samples of the stream, and where the
            denominator is zero (no excitation yet).

        Raises
        ------
        InputDataError
            Bad samples: not 1-D numbers, NaN or inf, different lengths, time not
            increasing (within the chunk or from the previous chunk) or not uniform.
            The state is left unchanged.
        """
        if self.engine == "numba":  # a single sample takes a short path
            if isinstance(t, float) and isinstance(f, float) and isinstance(x, float):
                result = self._update_sample(t, f, x)
                if result is not None:
                    return result
            elif (type(t) is np.ndarray and type(f) is np.ndarray and type(x) is np.ndarray
                  and t.shape == f.shape == x.shape == (1,) and t.dtype == _FLOAT64
                  and f.dtype == _FLOAT64 and x.dtype == _FLOAT64):
                result = self._update_sample(t[0], f[0], x[0])
                if result is not None:
                    return result
        t, f, x, h = self._check_chunk(t, f, x)
        half = self._half
        if half is None and self._requested_period is not None and h is not None:
            half = self._half_period(h)
        # checks done: from here on the state changes
        self._h, self._half = h, half
        m = t.size
        if m:
            if self._n == 0:
                self._windows[0].origin_time = float(t[0])
            self._t_last = float(t[-1])
        if self.engine == "numba":
            estimates = dict(zip(self.parameters, self._feed_engine(t, f, x, h, half)))
            self._n += m
            return EstimationResult(t=t, estimates=estimates, model=self.model,
                                    filter_order=self.filter_order,
                                    quadrature_order=self.quadrature_order, mass=self.mass)
        u = f / self.mass if self.mass is not None else f
        if self._requested_period is None:
            est = self._windows[0].feed(u, x, h) if m else [np.empty(0)
                                                           for _ in self._gen.PARAMETERS]
            self._n += m
        else:
            est = self._feed_staggered(t, u, x, h, half)
        estimates = _with_physical_parameters(dict(zip(self._gen.PARAMETERS, est)), self.mass)
        return EstimationResult(t=t, estimates=estimates, model=self.model,
                                filter_order=self.filter_order,
                                quadrature_order=self.quadrature_order, mass=self.mass)

    def _update_sample(self, t, f, x):
        """:meth:`update` for one sample given as floats, on the compiled engine, when
        it continues a stream in progress: no start-up, no restart of an estimator
        and no error.  ``None`` otherwise (the state is then unchanged, and
        :meth:`update` takes the general path)."""
        h, t_last = self._h, self._t_last
        if t_last is None or h is None:
            return None
        step = t - t_last  # a good step also means that t is finite
        if not (step > 0.0 and abs(step - h) <= UNIFORM_RTOL * h and math.isfinite(f)
                and math.isfinite(x)):
            return None
        q = self.quadrature_order
        windows = self._windows
        first = windows[0].state
        if first.n_seen < q:
            return None
        n = self._n
        half = self._half
        second = None
        if half is not None:  # re-anchoring
            k, phase = divmod(n, half)
            if phase == 0:  # an estimator restarts at this sample
                return None
            if k:  # the second estimator runs from half a period on
                second = windows[1].state
                if second.n_seen < q:
                    return None
                if k % 2 == 0:  # the older window is reported: B in half periods 2, 4, ...
                    first, second = second, first
                self._reported = 0 if k % 2 else 1
        fs, xs = self._one_f, self._one_x
        fs[0] = f
        xs[0] = x
        out = np.empty(self._sample_shape)
        # the compiled loop of algid.engine.run_chunk, called directly on the one sample
        first._advance(fs, xs, out if self.mass is None else out[:self._n_core], first.sums,
                       first.windows, first.n_seen, first.step, first.input_divisor,
                       first.filter_order, first._work)
        first.n_seen += 1
        if second is not None:
            second._advance(fs, xs, self._discard_one, second.sums, second.windows,
                            second.n_seen, second.step, second.input_divisor,
                            second.filter_order, second._work)
            second.n_seen += 1
        if self.mass is not None:
            mass, core = self.mass, self._n_core
            for j, row in enumerate(self._mass_rows):
                out[core + j, 0] = out[row, 0] * mass
        self._n = n + 1
        self._t_last = float(t)
        return EstimationResult(t=np.array((t,)), estimates=dict(zip(self.parameters, out)),
                                model=self.model, filter_order=self.filter_order,
                                quadrature_order=self.quadrature_order, mass=self.mass)

    def _feed_engine(self, t, f, x, h, half):
        """Estimates of a checked chunk on the compiled engine, shape ``(len(parameters),
        m)``."""
        run_chunk = self._run_chunk
        m = t.size
        out = np.empty((len(self.parameters), m))
        core = self._n_core
        est = out if out.shape[0] == core else out[:core]
        windows = self._windows
        if h is not None and h != self._step:  # the step, once known
            for window in windows:
                window.state.step = h
            self._step = h
        if half is None:  # no re-anchoring (or only the first sample so far)
            run_chunk(windows[0].state, f, x, out=est)
        else:
            # pieces between multiples of half a period: there the reported estimator
            # does not change and neither restarts
            n0 = self._n
            pos = 0
            while pos < m:
                k, phase = divmod(n0 + pos, half)
                end = min(m, pos + half - phase)
                if phase == 0:  # A restarts at 0, N, 2N, ..., B at N/2, 3N/2, ...
                    windows[k % 2].restart(origin_time=float(t[pos]))
                # the older window is reported: A in half periods 0, 1, 3, 5, ..., B in
                # 2, 4, ...
                reported = 0 if k == 0 or k % 2 else 1
                run_chunk(windows[reported].state, f[pos:end], x[pos:end],
                          out=est[:, pos:end])
                if k:
                    if self._discard.shape[1] < end - pos:
                        self._discard = np.empty((core, max(end - pos,
                                                            2 * self._discard.shape[1])))
                    run_chunk(windows[1 - reported].state, f[pos:end], x[pos:end],
                              out=self._discard[:, :end - pos])
                self._reported = reported
                pos = end
        for j, row in enumerate(self._mass_rows):
            np.multiply(out[row], self.mass, out=out[core + j])
        return out

    def _feed_staggered(self, t, u, x, h, half):
        m = t.size
        if half is None:  # only the first sample, step not known yet
            self._n += m
            return self._windows[0].feed(u, x, h)
        n0, period = self._n, 2 * half
        n = n0 + np.arange(m)
        k = n // half  # index of the half period holding each sample
        # the older window is reported: A (0) in half periods 0, 1, 3, 5, ...; B (1) in 2, 4, ...
        reported = np.where((k == 0) | (k % 2 == 1), 0, 1)
        est = [np.full(m, np.nan) for _ in self._gen.PARAMETERS]
        for i, window in enumerate(self._windows):
            phase = i * half  # A restarts at samples 0, N, 2N, ...; B at N/2, 3N/2, ...
            pos = max(0, phase - n0)  # B waits for sample N/2
            while pos < m:
                age = (n0 + pos - phase) % period
                if age == 0:
                    window.restart(origin_time=float(t[pos]))
                end = min(m, pos + period - age)
                out = window.feed(u[pos:end], x[pos:end], h)
                take = reported[pos:end] == i
                for e, o in zip(est, out):
                    e[pos:end][take] = o[take]
                pos = end
        self._reported = int(reported[-1]) if m else self._reported
        self._n += m
        return est


# --------------------------------------------------------------------------------------
# long streams
# --------------------------------------------------------------------------------------


def run_stream(estimator, chunks, *, true_values=None, settle_time=0.0):
    """Feed a stream to an estimator and summarise it without keeping it.

    For long-stream checks and benchmarks: memory does not grow with the stream.

    Parameters
    ----------
    estimator : OnlineEstimator
    chunks : iterable of (t, f, x)
        The stream, chunk by chunk.
    true_values : dict or callable, optional
        Parameter name -> true value, or a function of the chunk's times returning
        such a dict (values may be arrays over the chunk).
    settle_time : float, optional
        Errors are accumulated over samples with ``t >= settle_time`` only.

    Returns
    -------
    dict
        ``n_samples``, ``n_chunks``, ``final`` (last estimates), ``max_state_magnitude``
        (over the chunk ends), and with ``true_values``: ``max_rel_error`` (name ->
        largest ``|estimate / true - 1|`` after ``settle_time``; NaN estimates count as
        inf) and ``n_undefined`` (NaN estimates after ``settle_time``).
    """
    n_samples = n_chunks = 0
    max_state = 0.0
    max_err = {}
    n_undefined = 0
    result = None
    for t, f, x in chunks:
        result = estimator.update(t, f, x)
        n_samples += result.t.size
        n_chunks += 1
        max_state = max(max_state, estimator.state_magnitude)
        if true_values is None:
            continue
        truth = true_values(result.t) if callable(true_values) else true_values
        keep = result.t >= settle_time
        if not keep.any():
            continue
        for name, value in truth.items():
            est = result.estimates[name][keep]
            ref = np.broadcast_to(value, result.t.shape)[keep]
            err = np.abs(est / ref - 1.0)
            undefined = ~np.isfinite(err)
            n_undefined += int(np.count_nonzero(~np.isfinite(est)))
            worst = np.inf if undefined.any() else float(np.max(err))
            max_err[name] = max(max_err.get(name, 0.0), worst)
    summary = {"n_samples": n_samples, "n_chunks": n_chunks,
               "final": result.final() if result is not None and result.t.size else {},
               "max_state_magnitude": max_state}
    if true_values is not None:
        summary["max_rel_error"] = max_err
        summary["n_undefined"] = n_undefined
    return summary
