"""On-line (streaming) algebraic estimation: ``algid.OnlineEstimator``.

:class:`OnlineEstimator` computes the numbers of the batch estimator
(:func:`algid.estimate`) from a stream of samples that arrives in chunks of any size,
with a state whose size does not depend on the length of the stream.  Each estimator is
a state of the estimator core (:mod:`algid.estimation._core`), advanced chunk by chunk
by the backend ``engine`` chooses, so the estimates do not depend on how the stream is
cut and equal those of :func:`algid.estimate`, bit for bit with the same step and
backend.  The estimator is causal, with no delay; the first samples' estimates are NaN
as in batch.

``reset_period=T`` re-anchors the time origin, which the method allows because it does
not depend on the initial conditions: two estimators run staggered by ``T/2``, each
restarting every ``T`` (:func:`algid.estimation._reanchoring.anchor_plan`), and the one
with the older origin is reported.  The estimate at ``t`` then uses only data from
``(t - T, t]``, follows a change of the parameters within ``T``, and keeps every
internal magnitude bounded, at the price of twice the arithmetic and of the averaging
over the whole record.  ``reset_period=None`` (the default) reproduces the batch
estimator.  The user guide, "How streaming works", explains the state, the start-up and
the re-anchoring in full.

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

import numpy as np

from algid.models._argument import estimator_module, measured_signals, takes_pair
from algid._scaling import amplitude_scale, scalable
from algid._signal_checks import UNIFORM_RTOL, positive_number
from algid._record_input import (
    is_record,
    is_timeresponse,
    record_columns,
    refuse_nonfinite,
    timeresponse_pair,
)
from algid.errors import InputDataError
import algid.estimation._core as core
from algid.estimation._backends import choose_engine
from algid.estimation._late_origin import advance_best, late_twin
from algid.estimation._long_stream import run_stream
from algid.estimation._numerical_error import (
    advance_rows_with_error,
    sample_stepper,
    with_companion,
)
from algid.estimation._options import (
    DEFAULT_FILTER_ORDER,
    channel_divisors,
    check_filter_order,
    known_mass,
    quadrature_points_option,
    with_mass_scaled,
)
from algid.estimation._reanchoring import anchor_plan
from algid.estimation._result import EstimationResult
from algid.estimation._stream_checks import (
    amplitude_limits,
    check_amplitudes,
    check_channels,
    check_chunk,
    check_signals_call,
    check_signals_chunk,
    compiled_scan,
    compiled_within,
    float_sample,
    half_period,
)
from algid.models._compiled import ChannelStream

__all__ = ["OnlineEstimator", "run_stream", "TRACKING_RESET_PERIOD"]

#: Reset period [s] suggested for following changes of the parameters in noise-free or
#: nearly noise-free data at about 1 kHz with filter order 2 (measured with the 6-point
#: rule, whose first estimates the 8-point default shares), on the paper's system
#: (B = 2, K = 3) and after changes to K = 5 or B = 1, step and sine inputs: an estimator
#: restarted in mid-stream comes within 0.1 % 5-7 ms after its origin (13 ms for a sine
#: from rest; within 1e-6 after 5-20 ms, 68 ms for a settled step response), inside the
#: half period of 25 ms before it is reported, and the estimates are within 0.1 % of the
#: new values once the reported estimator's origin is after the change: 25-48 ms after
#: it (at most one period).  Short periods do not average measurement noise: with noise
#: of 1e-4 m on ``x`` they are useless here, and periods of seconds are needed.
TRACKING_RESET_PERIOD = 0.05


class OnlineEstimator:
    """Algebraic parameter estimator for a stream of samples, fed chunk by chunk.

    Fed the samples of a record in chunks of any sizes, it returns the same estimates
    as :func:`algid.estimate` on the whole record (with ``reset_period=None``), using a
    state of constant size.  See :mod:`algid.estimation._online` for the realisation, the start-up
    and the re-anchoring of the time origin.

    Parameters
    ----------
    model : str or module, optional
        ``"msd"`` (default) or ``"msd_mass"`` (see :func:`algid.available_models`),
        equation text with its ``parameters`` (several signals, offsets, drifts,
        nonlinear factors), or a compiled model (:func:`algid.compile_equation`): the
        same model argument as :func:`algid.estimate` and :func:`algid.identify`.
    parameters : str or sequence of str, optional
        The unknown parameters of equation text.
    filter_order : int, optional
        ``p`` of the invariant filter ``1/s**p`` (0 = none).  Default 2.
    quadrature_points : int, optional
        Points of the quadrature rule (2 = trapezoid).  Default
        :data:`~algid.estimation._options.DEFAULT_QUADRATURE_POINTS` (8).
    mass : float, optional
        Known mass [kg] (models that declare it, e.g. ``"msd"``): ``f`` is then the
        force and the results also hold the quantities it scales (``c = B m``,
        ``k = K m``).
    dt : float, optional
        Sampling step [s].  Give at most one of ``dt`` and ``rate``; with neither, the
        step is the mean step of the first chunk (of the first two samples if the
        first chunk is one sample).  Every step of the stream must be within ``1e-4
        dt`` of it, or within what the precision or the decimal rounding of the times
        explains (see :mod:`algid.estimation._stream_checks`).  A step so inferred
        depends on the first chunk in its last bits: give ``dt`` or ``rate`` for
        numbers that do not depend on the chunking (see the notes).
    rate : float, optional
        Sampling rate [Hz], ``dt = 1 / rate``.
    reset_period : float, optional
        Re-anchor the time origin every ``reset_period`` seconds, with two estimators
        staggered by half a period (see :mod:`algid.estimation._online`); rounded to an even number
        of samples, each half at least ``quadrature_points`` and at most ``2**53``
        samples.  ``None`` (default) never re-anchors.  ``TRACKING_RESET_PERIOD`` (0.05 s) suits tracking.
    engine : {"auto", "numpy", "numba"}, optional
        The backend of the estimator core: ``"numpy"``, or ``"numba"`` (needs
        ``algid[fast]``; several times faster for chunks of any size).  Both give the
        same numbers (bit for bit on the platforms tested).  ``"auto"`` (default):
        ``"numba"`` if numba is installed, else ``"numpy"``.
    derivative_window : float, optional
        For a model with a derivative inside a nonlinear factor (``sign(q')``): the
        window ``T`` [s] of the causal algebraic differentiator that estimates it
        (:class:`algid.signals.CausalDifferentiator`).  Default 20 sampling
        steps.  Such a model needs ``dt`` or ``rate``.
    derivative_extra_orders : {0, 1, 2}, optional
        0 (default): the minimal differentiator, the least noisy, which lags by half
        its window.  1 or 2: exact at the sample for polynomials of 1 or 2 more
        degrees, so without lag on smooth signals, but noisier.
    time : str, optional
        The time column of the records given to :meth:`update` (default ``t`` or
        ``time``; without one, the times come from ``rate`` or ``dt``).
    output : str, optional
        With equation text: the output signal.
    late_origin : bool, optional
        As for :func:`algid.estimate`: a twin from an origin 64 samples later, reported
        where its numerical error is three times smaller (the same numbers as the batch
        estimate).  Not with ``reset_period``.  Default False.

    Attributes
    ----------
    parameters : tuple of str
        Names of the estimates returned (as in :func:`algid.estimate`).
    engine : str
        The backend in use: ``"numpy"`` or ``"numba"``.
    signals : tuple of str
        The measured signals the model reads (``update(t, signals={...})``).

    Notes
    -----
    The equality with :func:`algid.estimate` is bit for bit when both use the same
    step.  The batch estimator takes ``(t[-1] - t[0]) / (n - 1)``; on a grid such as
    ``np.arange(n) / 1000`` that may differ from ``dt`` by an ulp, and ill-conditioned
    estimates (the first few samples, or weak excitation) magnify that to about 1e-7
    relative.  Memory is constant: per integrator its integral and its last
    ``quadrature_points - 1`` integrand samples, plus a start-up buffer of fewer than
    ``quadrature_points`` samples.

    User models.  The channels of the model (its factors: ``y**3``, ``sign(y)``,
    ``y*u``, the ``1`` of an offset, time ``t``) are computed from every chunk's
    samples, then advance the same core; :func:`algid.estimate` with the same
    ``signals`` gives the same numbers.  A derivative inside a factor (``sign(q')``)
    is estimated by the causal algebraic differentiator, from the last
    ``derivative_window`` seconds only: it lags by half the window
    (:attr:`derivative_delay`; none with ``derivative_extra_orders`` 1 or 2 on smooth
    signals), and the estimator's time origin is the first sample with a derivative
    estimate, ``derivative_window`` after the first sample of the stream
    (:attr:`startup_samples` counts both).  It equals
    :func:`algid.estimate` with ``differentiator="causal"``, bit for bit with the same
    step.  With ``reset_period`` the core re-anchors as for the built-in models; the
    differentiator runs on, unaffected.  With ``engine="numba"`` (the default when
    numba is installed) the first :meth:`update` compiles the model's loop, which takes
    tens of seconds or more for a model of five parameters.

    Raises
    ------
    ModelError
        Unknown model, or ``mass`` given for a model that takes none.
    InputDataError
        A bad option (also ``engine="numba"`` without numba installed, and no ``dt`` or
        ``rate`` for a model with a derivative inside a factor).

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

    def __init__(self, model="msd", parameters=None, *, filter_order=DEFAULT_FILTER_ORDER,
                 quadrature_points=None, mass=None, dt=None, rate=None, reset_period=None,
                 engine="auto", derivative_window=None,
                 derivative_extra_orders=0, late_origin=False, time=None, output=None):
        self._module = module = estimator_module(model, parameters, output=output)
        self._time_column = time
        self.filter_order = check_filter_order(filter_order)
        self.quadrature_points = quadrature_points_option(quadrature_points)
        # a stream takes numba whenever it can: there the cost per call matters most
        self.engine = choose_engine(engine, 0, None, min_samples=0)
        self.mass = known_mass(module, mass)
        if dt is not None and rate is not None:
            raise InputDataError("give at most one of dt and rate")
        self._given_dt = (positive_number(dt, name="dt") if dt is not None
                          else 1.0 / positive_number(rate, name="rate") if rate is not None
                          else None)
        self._requested_period = (None if reset_period is None
                                  else positive_number(reset_period, name="reset_period"))
        self.model = module.MODEL
        self.parameters = tuple(module.PARAMETERS) + (
            tuple(module.MASS_SCALED) if self.mass is not None else ())
        if reset_period is not None and self._given_dt is not None:
            half_period(self._requested_period, self._given_dt, self.quadrature_points)
        self._scan, self._within = ((compiled_scan(), compiled_within())
                                    if self.engine == "numba" else (None, None))
        self._states = [with_companion(core.new_state(module, points=self.quadrature_points,
                                                      filter_order=self.filter_order,
                                                      dt=self._given_dt or 1.0,
                                                      divisors=channel_divisors(module,
                                                                                self.mass)))
                        for _ in range(1 if reset_period is None else 2)]
        if late_origin not in (True, False) or (late_origin and reset_period is not None):
            raise InputDataError(f"late_origin must be True or False, and False with "
                                 f"reset_period; got {late_origin!r}")
        self._twin = late_twin(self._states[0]) if late_origin else None
        self._origins = [math.nan] * len(self._states)
        self._discard = np.empty((len(module.PARAMETERS), 0))
        self._discard_error = np.empty(0)
        # per-stream constants of update()
        self._channel_order = tuple(0 if name == module.INPUT else 1
                                    for name in module.CHANNELS)
        self._n_parameters = len(module.PARAMETERS)
        divisors = tuple(self._states[0].divisors.tolist())
        self._unit_limits = amplitude_limits(module, divisors, None)
        self._pair_divisors = divisors if self._channel_order == (0, 1) else divisors[::-1]
        self._scalable = scalable(module)
        self._mass_scaled = self.parameters[len(module.PARAMETERS):]
        # user models: channels computed from the signals of every chunk
        self._channel_stream = ChannelStream(module, self._given_dt,
                                             derivative_window=derivative_window,
                                             derivative_extra_orders=derivative_extra_orders)
        self.signals = self._channel_stream.signals
        self._takes_pair = takes_pair(module)
        # one sample as floats: the short path of update() (_update_sample)
        self._sample_path = self._takes_pair and self._twin is None
        self._steppers = None
        self._result = EstimationResult(  # the template of the results of one sample
            t=np.empty(0), estimates={name: np.empty(0) for name in self.parameters},
            model=self.model, filter_order=self.filter_order,
            quadrature_points=self.quadrature_points, mass=self.mass,
            mass_scaled=self._mass_scaled)
        self._discard_sample = (np.empty((self._n_parameters, 1)), np.empty(1))
        self.reset()

    def reset(self):
        """Forget the stream: the next sample is the first (and the new time origin).

        A step given as ``dt`` or ``rate`` is kept; one taken from the stream is
        forgotten.
        """
        self._dt = self._given_dt
        self._half = None if self._dt is None or self._requested_period is None \
            else half_period(self._requested_period, self._dt, self.quadrature_points)
        self._n = 0
        self._warmed = 0  # stream samples spent on the differentiator's warm-up
        self._channel_stream.reset()
        self._t_last = None
        self._scale = None
        self._limits = self._pair_limits(None)
        self._reported = 0
        for i, state in enumerate(self._states):
            state.restart()
            self._origins[i] = math.nan
        if self._twin is not None:
            self._twin.restart()

    @property
    def n_seen(self) -> int:
        """Number of samples received since the start (or the last :meth:`reset`)."""
        return self._n + self._warmed

    @property
    def dt(self):
        """Sampling step [s] (``None`` until known)."""
        return self._dt

    @property
    def startup_samples(self) -> int:
        """Samples ``0 .. startup_samples - 1`` of the stream get NaN estimates.

        The start-up of the estimator (:func:`algid.estimation._core.first_estimate`), after the
        warm-up of the differentiator of a model with a derivative inside a factor.
        """
        return core.first_estimate(self.quadrature_points) + self._channel_stream.warmup

    @property
    def derivative_delay(self) -> float:
        """Delay [s] of the derivative estimates inside factors (0 if there are none).

        The causal minimal estimator returns the derivative delayed by half its window
        (default kernel; :func:`algid.signals._differentiation.differentiator_delay`); with
        ``derivative_extra_orders`` 1 or 2 it is exact at the sample on polynomials of
        that many more degrees (0 here).
        """
        return self._channel_stream.delay

    @property
    def reset_period(self):
        """Re-anchoring period actually used [s]: ``2 * round(T / (2 dt)) * dt``.

        ``None`` without re-anchoring; the requested value until ``dt`` is known.
        """
        if self._requested_period is None:
            return None
        if self._half is None:
            return self._requested_period
        return 2 * self._half * self._dt

    @property
    def t_origin(self) -> float:
        """Time origin of the estimate returned last.

        It is the time of the first sample its estimator has seen (the first sample of
        the stream without re-anchoring; NaN before any sample).
        """
        return self._origins[self._reported]

    @property
    def anchor_origins(self) -> tuple:
        """Time origins of the running estimators.

        One, or two with re-anchoring; NaN for one not started yet.
        """
        return tuple(self._origins)

    @property
    def state_magnitude(self) -> float:
        """Largest absolute value held in the state.

        It covers the integrals of every chain and filter, and the carried samples of
        their integrands (a check that re-anchoring keeps them bounded).
        """
        return max(state.magnitude() for state in self._states)

    def __repr__(self):
        period = "" if self._requested_period is None else f", reset_period={self.reset_period:g}"
        return (f"<OnlineEstimator model={self.model!r} filter_order={self.filter_order} "
                f"quadrature_points={self.quadrature_points}{period} engine={self.engine!r} "
                f"n_seen={self._n}>")

    def update(self, t, f=None, x=None, *, signals=None) -> EstimationResult:
        """Take the next samples of the stream and return their estimates.

        Parameters
        ----------
        t : float or array_like or mapping
            Sample times [s], continuing the stream (strictly increasing, uniform step).
            Or a record chunk, as :func:`algid.identify` takes records: named columns,
            with a time column or, without one, times following on from the previous
            chunk at the estimator's ``rate`` (or ``dt``).
        f : float or array_like
            Input at those times (as for :func:`algid.estimate`), for a model of the
            two channels input and output (the built-in models).
        x : float or array_like
            Measured output at those times.
        signals : mapping, optional
            Instead of ``f`` and ``x``: measured signal name -> samples at ``t`` (every
            name of :attr:`signals`; others are ignored).  Needed for a model of
            several signals or nonlinear factors.

        Returns
        -------
        EstimationResult
            Estimates at the given times, computed from the samples up to each of them.
            NaN for the first ``startup_samples`` samples, where the denominator is zero,
            and for parameters the samples do not determine (``numerical_error`` inf;
            judged at 64, 128, ..., 65536 samples, then every 65536, and every 64th
            of the samples seen while undetermined:
            :mod:`algid.estimation._numerical_error`).

        Raises
        ------
        InputDataError
            Bad samples: not 1-D numbers (booleans included), masked, NaN or inf,
            different lengths, time not increasing (within the chunk or from the
            previous chunk) or not uniform; beyond the stream's amplitude limit, or a
            channel of a user model not finite (:mod:`algid.estimation._stream_checks`); a missing
            signal; ``f``, ``x`` for a model that needs ``signals=`` or both given.  The
            state is left unchanged.

        Notes
        -----
        The samples are multiplied by a power of two chosen from the first chunk with
        a nonzero sample when their amplitude is extreme (:mod:`algid._scaling`); the
        estimates do not change, bit for bit, and stay equal to the batch ones.
        """
        if is_timeresponse(t) and self._takes_pair and f is None and x is None \
                and signals is None:   # the paper's form, as estimate takes it
            t, f, x = timeresponse_pair(t)
        elif is_record(t):
            if f is not None or x is not None or signals is not None:
                raise InputDataError("give a record chunk alone, without f, x or signals")
            rate = None if self._given_dt is None else 1.0 / self._given_dt
            t, columns = record_columns(t, measured_signals(self._module),
                                        time=self._time_column, rate=rate,
                                        first_sample=self.n_seen, every_sample=True,
                                        what=f"the chunk starting at stream sample "
                                             f"{self.n_seen}", one_number=True, stream=True)
            refuse_nonfinite(columns, f"the chunk starting at stream sample {self.n_seen}")
            if self._takes_pair:
                f, x = columns[self._module.INPUT], columns[self._module.OUTPUT]
            else:
                signals = columns
        sample = float_sample(t, f, x)
        result = None if sample is None else self._update_sample(*sample)
        if result is not None:
            return result
        if signals is not None or not self._takes_pair or f is None or x is None:
            return self._update_signals(t, f, x, signals)
        t, f, x, dt = check_chunk(t, f, x, n=self._n, t_last=self._t_last, dt=self._dt,
                                  scan=self._scan)
        half, scale = self._half_of(dt), self._scale_of((f, x))
        module = self._module
        check_amplitudes(module, (module.INPUT, module.OUTPUT), (f, x),
                         self._limits if scale == self._scale else self._pair_limits(scale),
                         self._pair_divisors, n=self._n, within=self._within,
                         new_scale=scale != self._scale, scale=scale)
        self._take_step(dt, half, scale)  # checks done: from here on the state changes
        m = t.size
        f, x = (f, x) if scale is None or scale == 1.0 else (f * scale, x * scale)
        channels = (f, x) if self._channel_order == (0, 1) else \
            tuple((f, x)[i] for i in self._channel_order)
        out = np.empty((self._n_parameters, m))
        error = np.empty(m)
        if m:
            if self._n == 0:
                self._origins[0] = float(t[0])
            self._t_last = float(t[-1])
        self._advance_checked(t, channels, half, out, error)
        self._n += m
        estimates = dict(zip(module.PARAMETERS, out))
        if self.mass is not None:
            with_mass_scaled(module, estimates, self.mass)
        return EstimationResult(t=t, estimates=estimates, model=self.model,
                                filter_order=self.filter_order,
                                quadrature_points=self.quadrature_points, mass=self.mass,
                                mass_scaled=self._mass_scaled, numerical_error=error)

    def _update_sample(self, t, f, x):
        """:meth:`update` of one sample given as floats, where it continues a stream past
        the start-up with no restart or identifiability check due: the estimators'
        one-sample steps (:func:`algid.estimation._numerical_error.sample_stepper`; one compiled
        call each with numba), the same numbers.  None elsewhere, and for a sample that
        needs the full checks: nothing has changed then, and :meth:`update` takes its
        general path."""
        dt, t_last = self._dt, self._t_last
        if t_last is None or dt is None or not self._sample_path:
            return None
        step = t - t_last  # a good step also means that t is finite
        if not (step > 0.0 and abs(step - dt) <= UNIFORM_RTOL * dt and math.isfinite(f)
                and math.isfinite(x)):
            return None
        scale, (limit_f, limit_x) = self._scale, self._limits
        if (scale is None and self._scalable) or not (abs(f) <= limit_f and abs(x) <= limit_x):
            return None  # no scale yet (:meth:`_scale_of`), or update() says why it refuses
        if scale is not None and scale != 1.0:
            f, x = f * scale, x * scale
        values = (f, x) if self._channel_order == (0, 1) else (x, f)
        steppers = self._steppers
        if steppers is None:
            steppers = self._steppers = [sample_stepper(state, self.engine)
                                         for state in self._states]
        out = np.empty((self._n_parameters, 1))
        error = np.empty(1)
        half = self._half
        k, phase = (0, 1) if half is None else divmod(self._n, half)
        if phase == 0:  # an estimator restarts here
            return None
        if k == 0:  # one estimator (re-anchoring: the second has not started)
            ready, advance, _ = steppers[0]
            if not ready():
                return None
            advance(values, out, error)
            self._reported = 0
        else:  # two, one reported: the older (estimator 0 in half periods 1, 3, ...)
            reported = 0 if k % 2 else 1
            ready, advance, _ = steppers[reported]
            ready_1, advance_1, buffer_1 = steppers[1 - reported]  # restarted later
            if not ready():
                return None
            if not buffer_1(values, *self._discard_sample):  # in its start-up, or:
                if not ready_1():
                    return None
                advance_1(values, *self._discard_sample)
            advance(values, out, error)
            self._reported = reported
        self._n += 1
        self._t_last = t
        estimates = dict(zip(self._module.PARAMETERS, out))
        if self.mass is not None:
            with_mass_scaled(self._module, estimates, self.mass)
        return self._result.with_samples(t=np.array((t,)), estimates=estimates,
                                         numerical_error=error)

    def _half_of(self, dt):
        """The half period (in samples) that the step ``dt`` of a checked chunk implies."""
        if self._half is None and self._requested_period is not None and dt is not None:
            return half_period(self._requested_period, dt, self.quadrature_points)
        return self._half

    def _take_step(self, dt, half, scale):
        """Take the step, half period and scale of a chunk that passed every check."""
        self._dt, self._half = dt, half
        if dt is not None and dt != self._states[0].dt:
            for state in self._states:
                state.dt = dt
            self._steppers = None  # they hold the step
        if scale != self._scale:
            self._scale, self._limits = scale, self._pair_limits(scale)

    def _scale_of(self, samples):
        """The stream's power of two, from its first nonzero chunk (:mod:`algid._scaling`)."""
        if self._scale is None and samples[0].size and self._scalable:
            return amplitude_scale(samples)
        return self._scale

    def _pair_limits(self, scale):
        """The largest absolute ``f`` and ``x`` (:func:`~algid.estimation._stream_checks.amplitude_limits`)."""
        limits = amplitude_limits(self._module, self._states[0].divisors, scale)
        return limits if self._channel_order == (0, 1) else limits[::-1]

    def _update_signals(self, t, f, x, signals):
        """:meth:`update` with ``signals=`` (any model)."""
        check_signals_call(self.model, f, x, signals, takes_pair=self._takes_pair,
                           names=self.signals, missing=self._channel_stream.missing)
        t, checked, dt = check_signals_chunk(t, signals, self.signals, n=self.n_seen,
                                             t_last=self._t_last, dt=self._dt, scan=self._scan)
        half, scale = self._half_of(dt), self._scale_of(tuple(checked.values()))
        m = t.size
        saved, unit = self._channel_stream.state(), 1.0 if scale is None else scale
        channels = self._channel_stream.update(checked if unit == 1.0 else {
            name: values * unit for name, values in checked.items()}, t)
        # the differentiator's warm-up: no channel yet, no estimate
        skip = min(max(self._channel_stream.warmup - self._warmed, 0), m)
        try:
            check_channels(self._module, tuple(c[skip:] for c in channels), self._unit_limits,
                           n=self.n_seen, signals=checked, first=skip, scale=scale)
        except InputDataError:
            self._channel_stream.restore(saved)
            raise
        self._take_step(dt, half, scale)  # checks done: from here on the state changes
        out = np.empty((self._n_parameters, m))
        error = np.empty(m)
        rest, rest_error = out, error
        if skip:
            out[:, :skip] = np.nan
            error[:skip] = np.nan
            self._warmed += skip
            rest, rest_error = out[:, skip:], error[skip:]
            channels = tuple(c[skip:] for c in channels)
        if m:
            self._t_last = float(t[-1])
        if skip < m:
            if self._n == 0:
                self._origins[0] = float(t[skip])
            self._advance_checked(t[skip:], channels, half, rest, rest_error)
            self._n += m - skip
        estimates = dict(zip(self._module.PARAMETERS, out))
        if self.mass is not None:
            with_mass_scaled(self._module, estimates, self.mass)
        return EstimationResult(t=t, estimates=estimates, model=self.model,
                                filter_order=self.filter_order,
                                quadrature_points=self.quadrature_points, mass=self.mass,
                                mass_scaled=self._mass_scaled, numerical_error=error)

    def _advance_checked(self, t, channels, half, out, error):
        """Estimates of a checked chunk into ``out``, their numerical error into
        ``error``: with the late twin, from the origin, or re-anchored."""
        if self._twin is not None:  # no re-anchoring
            advance_best(self._states[0], self._twin, channels, backend=self.engine,
                         out=out, error_out=error)
        elif half is None:  # no re-anchoring, or only the first sample so far
            advance_rows_with_error(self._states[0], channels, out, error, self.engine)
        else:
            self._advance_anchored(t, channels, half, out, error)

    def _advance_anchored(self, t, channels, half, out, error):
        """Estimates of a checked chunk with re-anchoring, into ``out`` (their numerical
        error into ``error``)."""
        if self._discard_error.size < t.size:  # the unreported estimates go there
            self._discard = np.empty((out.shape[0], max(t.size, 64)))
            self._discard_error = np.empty(self._discard.shape[1])
        k, phase = divmod(self._n, half)
        if phase and phase + t.size <= half:  # within one half period: one segment,
            # with nothing restarting (what anchor_plan says, without building it)
            self._reported = reported = 0 if k == 0 or k % 2 else 1
            for i in ((0,) if k == 0 else (0, 1)):
                if i == reported:
                    advance_rows_with_error(self._states[i], channels, out, error, self.engine)
                else:
                    advance_rows_with_error(self._states[i], channels, self._discard[:, :t.size],
                                            self._discard_error[:t.size], self.engine)
            return
        # every estimator runs from one restart to its next in one call (estimator 0
        # straight into out, estimator 1 aside); then the segments it reports are copied
        plan = anchor_plan(self._n, t.size, half)
        for i, (target, target_error) in enumerate(((out, error),
                                                    (self._discard, self._discard_error))):
            begin = None
            for segment in plan:
                if i not in segment.running:
                    continue
                if segment.restart == i:
                    if begin is not None:
                        self._advance_run(i, channels, begin, segment.start, target,
                                          target_error)
                    self._states[i].restart(early=self._n + segment.start == 0)  # unreported
                    self._origins[i] = float(t[segment.start])
                    begin = segment.start
                elif begin is None:
                    begin = segment.start
            if begin is not None:
                self._advance_run(i, channels, begin, t.size, target, target_error)
        for segment in plan:
            if segment.reported == 1:
                out[:, segment.start:segment.stop] = \
                    self._discard[:, segment.start:segment.stop]
                error[segment.start:segment.stop] = \
                    self._discard_error[segment.start:segment.stop]
        self._reported = plan[-1].reported

    def _advance_run(self, i, channels, start, stop, target, target_error):
        """Advance estimator ``i`` over samples ``start .. stop - 1`` of the chunk."""
        advance_rows_with_error(self._states[i], tuple(c[start:stop] for c in channels),
                                target[:, start:stop], target_error[start:stop], self.engine)
