"""Batch algebraic estimation: ``algid.estimate``.

A thin layer over the estimator core (:mod:`algid.estimation._core`): the checks of the signals and
options, a fresh state and one chunk, the known mass, the result.  Also the extra
low-pass filter ``lowpass``, which needs the whole record (NumPy only).
"""

from __future__ import annotations

import numpy as np

import algid.estimation._backends as backends
import algid.estimation._core as core
from algid._record_input import (
    TIME_COLUMNS,
    as_record,
    is_record,
    is_timeresponse,
    record_columns,
    refuse_nonfinite,
    refuse_unequal_lengths,
    timeresponse_pair,
)
from algid._scaling import amplitude_scale, check_amplitude_range, scalable
from algid._signal_checks import as_signal, check_experiment, positive_number
from algid.errors import InputDataError
from algid.estimation._identifiability import check_identifiable
from algid.estimation._late_origin import advance_best, late_twin
from algid.estimation._numerical_error import (
    advance_with_error,
    relative_difference,
    with_companion,
)
from algid.estimation._options import (
    DEFAULT_FILTER_ORDER,
    DEFAULT_QUADRATURE_POINTS,
    channel_divisors,
    check_filter_order,
    known_mass,
    quadrature_points_option,
    with_mass_scaled,
)
from algid.estimation._result import EstimationResult
from algid.models._argument import estimator_module, measured_signals, takes_pair
from algid.models._registry import available_models, load_model
from algid.signals._filters import as_lowpass
from algid.signals._quadrature import iterated_integrals, startup_samples

#: The model of ``estimate(t, f, x)`` when none is named: the paper's.
DEFAULT_MODEL = "msd"

__all__ = ["estimate", "available_models", "load_model", "kernel_values",
           "DEFAULT_FILTER_ORDER", "DEFAULT_QUADRATURE_POINTS",
           "ENGINES", "AUTO_ENGINE_MIN_SAMPLES"]  # noqa: F822 - served by __getattr__

#: Values of the ``engine`` option (see :mod:`algid.estimation._backends`).
ENGINES = backends.ENGINES


def __getattr__(name):
    # read at call time from algid.estimation._backends, where it can be changed
    if name == "AUTO_ENGINE_MIN_SAMPLES":
        return backends.AUTO_ENGINE_MIN_SAMPLES
    raise AttributeError(f"module 'algid.estimation._batch' has no attribute {name!r}")


def kernel_values(module, signals, tau, dt, *, points=DEFAULT_QUADRATURE_POINTS):
    """Values of every kernel of a generated model on uniformly sampled signals.

    Parameters
    ----------
    module : module
        Generated estimator (see :func:`load_model`).
    signals : dict
        Signal name -> samples.
    tau : ndarray
        Time since the first sample.
    dt : float
        Sampling step.
    points : int, optional
        Points of the quadrature rule.  Default :data:`DEFAULT_QUADRATURE_POINTS` (8).

    Returns
    -------
    dict
        Kernel name -> array.
    """
    values = {}
    for signal, power, depth in module.CHAINS:
        weighted = signals[signal] if power == 0 else tau**power * signals[signal]
        for level, arr in enumerate(iterated_integrals(weighted, dt, depth, points=points)):
            values[module.kernel_name(signal, power, level)] = arr
    return values


def estimate(t, f=None, x=None, *, model=None, filter_order=DEFAULT_FILTER_ORDER, mass=None,
             quadrature_points=None, lowpass=None, engine="auto",
             signals=None, differentiator="centred", derivative_window=None,
             derivative_extra_orders=0, numerical_error=True, late_origin=False,
             time=None, rate=None, output=None):
    """Estimate the parameters of a model from its input and output, algebraically.

    The estimate at each instant uses only the data up to that instant and does not
    depend on the initial conditions.  Two call forms:

    - ``estimate(record, model, parameters=None, *, time=None, rate=None, ...)``, as
      :func:`algid.identify` and :class:`algid.OnlineEstimator` take it: ``record`` a
      mapping of named columns (a time column ``t``/``time`` or ``time=``, else
      ``rate=``), ``model`` a built-in model's name, equation text with its
      ``parameters``, or a compiled model;
    - ``estimate(t, f, x, model=...)``: arrays, the paper's form.

    Parameters
    ----------
    t : array_like or control.TimeResponseData
        Sample times [s], strictly increasing and uniformly spaced.  May be a
        python-control ``TimeResponseData``, whose input and output are then used and
        ``f``, ``x`` must be omitted.  In the record form, any record type of
        :func:`algid.identify` (a mapping, a pandas ``DataFrame``, an xarray
        ``Dataset``, a ``TimeResponseData`` read by its labels).
    f : array_like
        Model input.  For ``model="msd"`` this is the force per unit mass ``F/m``,
        unless ``mass`` is given, in which case it is the force ``F`` [N].  For
        ``model="msd_mass"`` it is the force ``F``.
    x : array_like
        Measured displacement [m] (the model's output).
    model : str or module, optional
        ``"msd"`` (``x'' + B x' + K x = f``, default) or ``"msd_mass"``
        (``m x'' + c x' + k x = F``); see :func:`available_models`.  Also a generated
        module (:func:`algid.symbolic._codegen.compile_model`).  In the record form
        the model is the argument after the record; ``model=`` names it only when that
        argument is omitted (both are refused).
    filter_order : int, optional
        ``p`` of the invariant low-pass filter ``1/s**p`` applied to numerators and
        denominator alike (0 = none).  Default 2.
    mass : float, optional
        Known mass [kg] (models that declare it, e.g. ``"msd"``): ``f`` is then the
        force, and the result also holds the quantities it scales (``c = B m`` and
        ``k = K m``).
    quadrature_points : int, optional
        Points of the cumulative quadrature rule (2 = trapezoid).  Default
        :data:`DEFAULT_QUADRATURE_POINTS` (8).
    lowpass : tuple, scipy.signal.lti or python-control system, optional
        A strictly proper, stable, continuous-time SISO filter (e.g. ``([100], [1, 20,
        100])`` for ``100/(s + 10)**2``; see :func:`algid.signals._filters.as_lowpass`) applied,
        with zero initial state at the first sample, to the numerators and the
        denominator alike after ``1/s**filter_order``; the estimate stays exact.  Use
        ``filter_order=0`` for this filter alone.  Default: none.
    engine : {"auto", "numpy", "numba"}, optional
        The backend of the estimator core (:mod:`algid.estimation._core`): ``"numpy"``, NumPy and
        SciPy only; ``"numba"``, the compiled loop generated for the model (needs
        ``algid[fast]``; several times faster; no ``lowpass``).  Both give the same
        numbers (bit for bit on the platforms tested).  ``"auto"`` (default):
        ``"numba"`` if numba is installed, there are at least
        :data:`~algid.estimation._backends.AUTO_ENGINE_MIN_SAMPLES` samples and no ``lowpass``,
        else ``"numpy"``.
    time : str, optional
        With a record: the name of its time column (default ``t`` or ``time``).
    rate : float, optional
        With a record without a time column: the sampling rate [Hz].
    output : str, optional
        With equation text: the output signal (default: the signal of highest
        derivative order).
    signals : mapping, optional
        For a model of several signals or nonlinear factors (a module from
        :func:`algid.models.compile_equation`): measured signal name -> samples
        at ``t``, given instead of ``f`` and ``x``.  Nonlinear factors (``y**3``,
        ``sign(q')``) are computed from them; a derivative inside a factor is
        estimated by :func:`algid.signals.algebraic_derivative`.
    differentiator : {"centred", "causal"}, optional
        With ``signals=``, how a derivative inside a nonlinear factor is estimated: with
        the window centred on each sample (default; the estimate at an instant then uses
        data up to half a window after it), or ``"causal"``, from the past window only,
        as :class:`algid.OnlineEstimator` does (the same numbers, bit for bit with the
        same step): the estimator's time origin is then the first sample with a
        derivative estimate, ``derivative_window`` after the first sample, and earlier
        estimates are NaN.
    derivative_window : float, optional
        With ``signals=``, the differentiator's window [s]; default 20 sampling steps.
    derivative_extra_orders : {0, 1, 2}, optional
        With ``signals=``: 0 (default), the minimal differentiator (the least noisy;
        causal, it lags by half its window); 1 or 2, exact for polynomials of 1 or 2
        more degrees (no lag on smooth signals, more noise).  See
        :class:`algid.models._compiled.ChannelStream`.
    numerical_error : bool, optional
        Estimate the numerical error of every estimate (default True): a companion
        estimator with another quadrature rule and filter order runs beside the
        estimator (:mod:`algid.estimation._numerical_error`; in full over the first 1024
        samples, then propagated from the estimator's integrals), which adds a third to
        a half of the estimator's time on long records; the estimates are the same,
        except where a check finds that the samples so far do not determine a parameter
        (NaN there, with an infinite error).  ``False`` skips both (``r.numerical_error`` is then
        None).
    late_origin : bool, optional
        Also run a twin from a time origin 64 samples later and report its estimate
        wherever its numerical error is three times smaller (:mod:`algid.estimation._late_origin`):
        a transient faster than the sampling just after the first sample then no longer
        spoils the record.  Doubles the cost again.  Default False (the estimate is
        that of the method from the first sample, as the generated C computes it).
        Needs ``numerical_error``; not with ``lowpass``.

    Returns
    -------
    EstimationResult
        Estimates over ``r.t`` as attributes named after the parameters (``r.B``,
        ``r.K``, ...), NaN where not yet defined; ``r.t_valid`` is the first instant
        with an estimate; ``r.numerical_error`` the estimated relative error of the
        estimates at every sample (the largest over the parameters; NaN where they
        are NaN, inf where the data do not determine them).

    Raises
    ------
    InputDataError
        Bad signals: NaN or inf, masked samples, booleans, different lengths, time not
        strictly increasing or not uniform, too few samples, no excitation, or a record
        that cannot determine a parameter (:mod:`algid.estimation._identifiability`: the message
        names it); or a bad option (also a ``lowpass``
        filter that is not strictly proper, not stable or not continuous-time;
        ``engine="numba"`` without numba installed or with ``lowpass``).
    ModelError
        Unknown model, or ``mass`` given for a model that takes none.

    Examples
    --------
    >>> import algid
    >>> r = algid.estimate(algid.simulate("step", m=1, c=2, k=3).to_timeresponse())
    >>> round(r.final()["B"], 6), round(r.final()["K"], 6)
    (2.0, 3.0)
    """
    # a TimeResponseData alone is the paper's form (its input and output); with a model,
    # a record of its labelled signals
    time_name, signal_names = "t", ("t", "f", "x")   # (in messages)
    if is_record(t) and not (is_timeresponse(t) and f is None and x is None):
        if is_timeresponse(t) and any(_samples_given(v) for v in (f, x)):
            raise InputDataError("give either a TimeResponseData or the arrays t, f, x, not both")
        if signals is not None:
            raise InputDataError("give a record or signals=, not both")
        if f is not None and model is not None:
            raise InputDataError(f"the model is given twice: {f!r} (after the record) and "
                                 f"model={model!r}; give it once")
        module = estimator_module(DEFAULT_MODEL if f is None and model is None else
                                  model if f is None else f, x, output=output)
        record = t
        t, columns = record_columns(record, measured_signals(module), time=time, rate=rate,
                                    min_samples=core.shortest_record(
                                        quadrature_points_option(quadrature_points)),
                                    every_sample=True)
        refuse_nonfinite(columns, "record 0")
        time_name = time or next((c for c in TIME_COLUMNS if c in as_record(record)), "t")
        if takes_pair(module):
            signal_names = (time_name, module.INPUT, module.OUTPUT)
        model, f, x = module, None, None
        if takes_pair(module):
            f, x = columns[module.INPUT], columns[module.OUTPUT]
        else:
            signals = columns
    elif time is not None or rate is not None or output is not None:
        raise InputDataError("time=, rate= and output= go with a record (a mapping of "
                             "named columns)")
    if model is None:
        model = DEFAULT_MODEL
    if signals is not None:
        return _estimate_signals(t, signals, time_name=time_name, model=model,
                                 filter_order=filter_order,
                                 quadrature_points=quadrature_points, engine=engine,
                                 given=(f, x, mass, lowpass), differentiator=differentiator,
                                 derivative_window=derivative_window,
                                 derivative_extra_orders=derivative_extra_orders,
                                 with_error=numerical_error, late_origin=late_origin)
    if differentiator != "centred" or derivative_window is not None or derivative_extra_orders:
        raise InputDataError("differentiator, derivative_window and derivative_extra_orders "
                             "apply to models given signals= (derivatives inside factors)")
    if is_timeresponse(t):
        t, f, x = timeresponse_pair(t)
    elif f is None or x is None:
        raise InputDataError("estimate needs the input f and the output x")
    module = load_model(model)
    _check_takes_pair(module)
    filter_order = check_filter_order(filter_order)
    points = quadrature_points_option(quadrature_points)
    _check_late_origin(late_origin, numerical_error, lowpass)
    lowpass_filter = None if lowpass is None else as_lowpass(lowpass)
    backends.choose_engine(engine, 0, lowpass_filter)  # refuse a bad option before the data
    mass = known_mass(module, mass)
    min_samples = core.shortest_record(points)
    try:
        n = len(t)
    except TypeError:
        n = 0  # not a sequence: check_experiment says what is wrong
    backend = backends.choose_engine(engine, n, lowpass_filter)
    if backend == "numba":
        from algid._signal_checks_numba import check_experiment_compiled
        t, f, x, dt = check_experiment_compiled(t, f, x, min_samples=min_samples,
                                                names=signal_names)
    else:
        t, f, x, dt = check_experiment(t, f, x, min_samples=min_samples, names=signal_names)
    state = core.new_state(module, points=points, filter_order=filter_order, dt=dt,
                           divisors=channel_divisors(module, mass))
    signals = _rescaled(module, {module.INPUT: f, module.OUTPUT: x},
                        dict(zip(module.CHANNELS, channel_divisors(module, mass) or
                                 (1.0,) * len(module.CHANNELS))))
    channels = tuple(signals[name] for name in module.CHANNELS)
    error = None
    if lowpass_filter is None:
        with np.errstate(over="ignore", under="ignore", invalid="ignore", divide="ignore"):
            values, error = _advance(state, channels, backend, numerical_error,
                                     late_origin)  # extremes: below
        check_identifiable(module, channels, dt, state=state)
    else:
        check_identifiable(module, channels, dt)
        values = np.array(_with_lowpass(state, channels, lowpass_filter))
        if numerical_error:
            with_companion(state)
            error = relative_difference(
                values, np.array(_with_lowpass(state.companion, channels, lowpass_filter)))
    estimates = with_mass_scaled(module, dict(zip(module.PARAMETERS, values)), mass)
    return EstimationResult(t=t, estimates=estimates, model=module.MODEL,
                            filter_order=filter_order, quadrature_points=points, mass=mass,
                            mass_scaled=tuple(estimates)[len(module.PARAMETERS):],
                            numerical_error=error)


def _samples_given(value):
    """Whether an argument in the place of ``f`` or ``x`` holds samples (not a model's
    name, equation or parameter names)."""
    if isinstance(value, np.ndarray):
        return True
    return isinstance(value, (list, tuple)) and bool(value) and not isinstance(value[0], str)


def _check_takes_pair(module):
    """Refuse ``estimate(t, f, x)`` for a model that reads other signals."""
    if getattr(module, "FACTORS", None) or \
            set(module.CHANNELS) != {module.INPUT, module.OUTPUT}:
        from algid.models._compiled import ChannelStream
        names = ChannelStream(module, None, centred=True).signals
        raise InputDataError(
            f"model {module.MODEL!r} reads the signals {', '.join(names)}: give them as "
            f"estimate(t, signals={{name: samples, ...}}) instead of f and x")


def _check_late_origin(late_origin, numerical_error, lowpass):
    if numerical_error not in (True, False):
        raise InputDataError(f"numerical_error must be True or False, got {numerical_error!r}")
    if late_origin not in (True, False):
        raise InputDataError(f"late_origin must be True or False, got {late_origin!r}")
    if late_origin and (not numerical_error or lowpass is not None):
        raise InputDataError("late_origin needs numerical_error=True and no lowpass: the "
                             "twin is chosen by its numerical error")


def _advance(state, channels, backend, with_error, late_origin):
    """Estimates of a fresh state over the whole record, and their numerical error
    (None without ``with_error``); with ``late_origin``, from a later origin where that
    is clearly more accurate (:mod:`algid.estimation._late_origin`)."""
    if not with_error:
        return core.advance(state, channels, backend=backend)[0], None
    with_companion(state)
    if late_origin:
        return advance_best(state, late_twin(state), channels, backend=backend)
    return advance_with_error(state, channels, backend=backend)[:2]


def _rescaled(module, signals, divisors=None):
    """The signals times a common power of two against overflow and underflow, when
    the model's parameters do not depend on it (:mod:`algid._scaling`); refused where
    their amplitudes, divided by ``divisors`` (name -> divisor, default 1), do not fit
    together in floating point (:func:`algid._scaling.check_amplitude_range`)."""
    if not scalable(module):
        return signals
    scale = amplitude_scale(tuple(signals.values()))
    divisors = divisors or {}
    check_amplitude_range(tuple(signals), tuple(signals.values()),
                          tuple(divisors.get(name, 1.0) for name in signals), scale,
                          len(module.PARAMETERS))
    if scale is None or scale == 1.0:
        return signals
    return {name: values * scale for name, values in signals.items()}


def _with_lowpass(state, channels, lowpass, points=None):
    """Estimates with the extra filter ``lowpass`` applied after ``1/s**p`` to the
    numerators and the denominator alike.  It needs them over the whole record: the
    kernels, the algebra and ``1/s**p`` are formed here from the same integrators
    (:mod:`algid.signals._quadrature`) as in the core, then filtered and divided; the first
    estimates come from rules of fewer points, as in the core
    (:func:`algid.estimation._core.first_estimate`)."""
    module, dt = state.model, state.dt
    points = state.points if points is None else points
    scaled = [c / d for c, d in zip(channels, state.divisors)]
    tau = np.arange(scaled[0].size) * dt
    kern = kernel_values(module, dict(zip(module.CHANNELS, scaled)), tau, dt, points=points)
    numerators, denominator = module.cramer(*module.regressors(kern))
    lanes = [np.broadcast_to(np.asarray(v, dtype=float), tau.shape)
             for v in (*numerators, denominator)]
    if state.filter_order:
        lanes = [iterated_integrals(v, dt, state.filter_order, points=points)[-1]
                 for v in lanes]
    lanes = [lowpass.apply(v, dt, points=points) for v in lanes]
    denominator = lanes[-1]
    undefined = ~np.isfinite(denominator) | (denominator == 0)
    undefined[:startup_samples(points)] = True
    with np.errstate(divide="ignore", invalid="ignore"):
        values = [np.where(undefined, np.nan, num / denominator) for num in lanes[:-1]]
    for n in range(core.first_estimate(points), min(startup_samples(points), tau.size)):
        early = _with_lowpass(state, [c[:n + 1] for c in channels], lowpass, points=n + 1)
        for row, first in zip(values, early):
            row[n] = first[n]
    return values


def _check_channels_finite(module, channels, start, signals):
    """Refuse a channel of a user model that is NaN or infinite from sample ``start`` on
    (a function outside its domain, ``log(y)`` of ``y <= 0``, or an overflow)."""
    factors = getattr(module, "FACTORS", {})
    for name, values in zip(module.CHANNELS, channels):
        bad = ~np.isfinite(values[start:])
        if bad.any():
            i = start + int(np.argmax(bad))
            what = (f"channel {name!r} = {factors[name]}" if name in factors
                    else f"signal {name!r}")
            at = ", ".join(f"{s} = {float(v[i]):.10g}" for s, v in signals.items())
            kind = "NaN" if np.isnan(values[i]) else "infinite"
            raise InputDataError(f"{what} is {kind} at row {i} ({at}): outside the domain "
                                 f"of its function, or an overflow")


def _estimate_signals(t, signals, *, time_name, model, filter_order, quadrature_points,
                      engine, given, differentiator, derivative_window,
                      derivative_extra_orders, with_error, late_origin):
    """:func:`estimate` for a model of several signals or nonlinear factors (``signals=``)."""
    from algid.models._compiled import channel_stream

    if any(v is not None for v in given):
        raise InputDataError("with signals= give no f, x, mass or lowpass: the signals "
                             "mapping holds every measured signal")
    if not hasattr(signals, "items") or not signals:
        raise InputDataError("signals must be a non-empty mapping of signal name -> samples")
    module = load_model(model)
    filter_order = check_filter_order(filter_order)
    points = quadrature_points_option(quadrature_points)
    _check_late_origin(late_origin, with_error, None)
    # the time axis once (passed as its own companions: t is never identically zero,
    # so only the checks of the time axis can fail), then every signal
    t_checked, _, _, dt = check_experiment(t, t, t, names=(time_name,) * 3,
                                           min_samples=core.shortest_record(points))
    checked = {name: as_signal(samples, name=str(name)) for name, samples in signals.items()}
    refuse_unequal_lengths({time_name: t_checked, **{str(k): v for k, v in checked.items()}})
    if not any(values.any() for values in checked.values()):
        raise InputDataError("no excitation: every signal is identically zero")
    span = t_checked[-1] - t_checked[0]
    if derivative_window is not None and positive_number(
            derivative_window, name="derivative_window") > span:
        raise InputDataError(f"derivative_window {derivative_window:g} s is longer than "
                             f"the record ({span:g} s)")
    stream = channel_stream(module, dt, differentiator=differentiator,
                            derivative_window=derivative_window,
                            derivative_extra_orders=derivative_extra_orders)
    channels = stream.update(_rescaled(module, checked), t_checked)
    # causal derivatives: the time origin is the first sample that has one
    start = stream.warmup
    _check_channels_finite(module, channels, start, checked)
    if t_checked.size - start < core.shortest_record(points):
        raise InputDataError(f"too few samples: {t_checked.size}, of which the first {start} "
                             "have no causal derivative estimate")
    backend = backends.choose_engine(engine, t_checked.size - start, None)
    state = core.new_state(module, points=points, filter_order=filter_order, dt=dt,
                           divisors=np.ones(len(module.CHANNELS)))
    values = np.full((len(module.PARAMETERS), t_checked.size), np.nan)
    error = np.full(t_checked.size, np.nan) if with_error else None
    channels = tuple(c[start:] for c in channels)
    values[:, start:], part_error = _advance(state, channels, backend, with_error, late_origin)
    if error is not None:
        error[start:] = part_error
    check_identifiable(module, channels, dt, state=state)
    return EstimationResult(t=t_checked, estimates=dict(zip(module.PARAMETERS, values)),
                            model=module.MODEL, filter_order=filter_order,
                            quadrature_points=points, numerical_error=error)
