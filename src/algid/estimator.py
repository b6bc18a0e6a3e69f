"""Batch algebraic estimation: ``algid.estimate``.

Runs the generated estimator of a model on measured signals: the kernels (iterated
integrals of ``t**k`` times the signals, see :mod:`algid.quadrature`), the linear system
``P(t) theta = Q(t)``, Cramer's rule, and the invariant filter ``1/s**p`` applied to the
numerators and the common denominator alike before dividing.  NumPy only.
"""

from __future__ import annotations

import importlib

import numpy as np

from algid.errors import InputDataError, ModelError
from algid.filters import as_lowpass
from algid.generated import MODULES
from algid.quadrature import iterated_integrals, startup_samples
from algid.result import EstimationResult
from algid.validation import check_experiment, positive_number

__all__ = ["estimate", "available_models", "load_model", "DEFAULT_FILTER_ORDER",
           "DEFAULT_QUADRATURE_ORDER", "kernel_values", "ENGINES", "AUTO_ENGINE_MIN_SAMPLES"]

#: Default order ``p`` of the invariant filter ``1/s**p``.
DEFAULT_FILTER_ORDER = 2
#: Default number of points of the cumulative quadrature rule.
DEFAULT_QUADRATURE_ORDER = 6
#: Values of the ``engine`` option of :func:`estimate`.
ENGINES = ("auto", "numpy", "numba")
#: ``engine="auto"`` uses the compiled engine (:mod:`algid.engine`) from this many
#: samples on: below it NumPy takes a few tens of milliseconds, less than importing
#: numba (about half a second) and loading the compiled loop.
AUTO_ENGINE_MIN_SAMPLES = 100_000


def available_models():
    """Names of the models that have a generated estimator."""
    return tuple(MODULES)


def load_model(name):
    """The generated estimator module of model ``name``.

    Raises
    ------
    ModelError
        If no estimator was generated for ``name``.
    """
    if not isinstance(name, str) or name not in MODULES:
        raise ModelError(f"unknown model {name!r} (known: {', '.join(MODULES)})")
    return importlib.import_module(MODULES[name])


def _check_options(filter_order, quadrature_order):
    if isinstance(filter_order, bool) or not isinstance(filter_order, (int, np.integer)) \
            or filter_order < 0:
        raise InputDataError(f"filter_order must be an integer >= 0, got {filter_order!r}")
    from algid.quadrature import QUADRATURE_ORDERS
    if quadrature_order not in QUADRATURE_ORDERS:
        raise InputDataError(f"quadrature_order must be one of {QUADRATURE_ORDERS}, "
                             f"got {quadrature_order!r}")


def kernel_values(module, signals, tau, h, *, order):
    """Values of every kernel of a generated model on uniformly sampled signals.

    Parameters
    ----------
    module : module
        Generated estimator (see :func:`load_model`).
    signals : dict
        Signal name -> samples.
    tau : ndarray
        Time since the first sample.
    h : float
        Sampling step.
    order : int
        Quadrature rule (number of points).

    Returns
    -------
    dict
        Kernel name -> array.
    """
    values = {}
    for signal, power, depth in module.CHAINS:
        weighted = signals[signal] if power == 0 else tau**power * signals[signal]
        for level, arr in enumerate(iterated_integrals(weighted, h, depth, order=order)):
            values[module.kernel_name(signal, power, level)] = arr
    return values


def _choose_engine(engine, n, lowpass, *, min_samples=None):
    """``"numpy"`` or ``"numba"`` for an ``engine`` option.

    ``"auto"`` takes numba when it is installed, there is no ``lowpass`` and there are at
    least ``min_samples`` samples (default :data:`AUTO_ENGINE_MIN_SAMPLES`, read at call
    time; a stream passes 0: there the cost per call matters).
    """
    if min_samples is None:
        min_samples = AUTO_ENGINE_MIN_SAMPLES
    if not isinstance(engine, str) or engine not in ENGINES:
        raise InputDataError(f"engine must be one of {', '.join(map(repr, ENGINES))}, "
                             f"got {engine!r}")
    if engine == "numpy":
        return "numpy"
    from algid import engine as compiled
    if engine == "numba":
        if not compiled.available():
            raise InputDataError(f"engine='numba' needs numba, which is not installed: "
                                 f"{compiled.INSTALL_HINT}")
        if lowpass is not None:
            raise InputDataError("engine='numba' does not support lowpass; use "
                                 "engine='numpy' (or 'auto')")
        return "numba"
    use = lowpass is None and n >= min_samples and compiled.available()
    return "numba" if use else "numpy"


def _known_mass(gen, model, mass):
    """The validated known mass, or None; refused for a model that estimates the mass."""
    if mass is None:
        return None
    if "m" in gen.PARAMETERS:
        raise ModelError(f"model {model!r} estimates the mass: do not give mass")
    return positive_number(mass, name="mass")


def _with_physical_parameters(estimates, mass):
    """Add ``c = B m`` and ``k = K m`` to ``estimates`` when the mass is known."""
    if mass is not None:
        estimates["c"] = estimates["B"] * mass
        estimates["k"] = estimates["K"] * mass
    return estimates


def _unpack_timeresponse(data):
    t = np.asarray(data.time, dtype=float)
    u = np.asarray(data.inputs, dtype=float)
    y = np.asarray(data.outputs, dtype=float)
    if u.ndim != 1 or y.ndim != 1:
        raise InputDataError(
            f"TimeResponseData must have one input and one output (got input shape {u.shape}, "
            f"output shape {y.shape}); squeeze it or pick the signals")
    return t, u, y


def estimate(t, f=None, x=None, *, model="msd", filter_order=DEFAULT_FILTER_ORDER, mass=None,
             quadrature_order=DEFAULT_QUADRATURE_ORDER, lowpass=None, engine="auto"):
    """Estimate the parameters of a model from its input and output, algebraically.

    The estimate at each instant uses only the data up to that instant and does not
    depend on the initial conditions.

    Parameters
    ----------
    t : array_like or control.TimeResponseData
        Sample times [s], strictly increasing and uniformly spaced.  May be a
        python-control ``TimeResponseData``, whose input and output are then used and
        ``f``, ``x`` must be omitted.
    f : array_like
        Model input.  For ``model="msd"`` this is the force per unit mass ``F/m``,
        unless ``mass`` is given, in which case it is the force ``F`` [N].  For
        ``model="msd_mass"`` it is the force ``F``.
    x : array_like
        Measured displacement [m].
    model : str, optional
        ``"msd"`` (``x'' + B x' + K x = f``, default) or ``"msd_mass"``
        (``m x'' + c x' + k x = F``); see :func:`available_models`.
    filter_order : int, optional
        ``p`` of the invariant low-pass filter ``1/s**p`` applied to numerators and
        denominator alike (0 = none).  Default 2.
    mass : float, optional
        Known mass [kg] (model ``"msd"`` only): ``f`` is then the force, and the result
        also holds ``c = B m`` and ``k = K m``.
    quadrature_order : int, optional
        Points of the cumulative quadrature rule (2 = trapezoid).  Default 6.
    lowpass : tuple, scipy.signal.lti or python-control system, optional
        A strictly proper, stable, continuous-time SISO filter (e.g. ``([100], [1, 20,
        100])`` for ``100/(s + 10)**2``; see :func:`algid.filters.as_lowpass`) applied,
        with zero initial state at the first sample, to the numerators and the
        denominator alike after ``1/s**filter_order``; the estimate stays exact.  Use
        ``filter_order=0`` for this filter alone.  Default: none.
    engine : {"auto", "numpy", "numba"}, optional
        ``"numpy"``: full-length arrays, NumPy only.  ``"numba"``: the compiled
        single-pass engine of :mod:`algid.engine` (needs ``algid[fast]``; about ten
        times faster and needs memory only for the result; no ``lowpass``).  Both give
        the same numbers (bit for bit on the platforms tested).  ``"auto"`` (default):
        ``"numba"`` if numba is installed, there are at least
        :data:`AUTO_ENGINE_MIN_SAMPLES` samples and no ``lowpass``, else ``"numpy"``.

    Returns
    -------
    EstimationResult
        Estimates over ``r.t`` as attributes named after the parameters (``r.B``,
        ``r.K``, ...), NaN where not yet defined; ``r.t_valid`` is the first instant
        with an estimate.

    Raises
    ------
    InputDataError
        Bad signals: NaN or inf, different lengths, time not strictly increasing or not
        uniform, too few samples, no excitation; or a bad option (also a ``lowpass``
        filter that is not strictly proper, not stable or not continuous-time;
        ``engine="numba"`` without numba installed or with ``lowpass``).
    ModelError
        Unknown model, or ``mass`` given for a model that estimates the mass.

    Examples
    --------
    >>> import algid
    >>> r = algid.estimate(algid.simulate("step", m=1, c=2, k=3).to_timeresponse())
    >>> round(r.final()["B"], 6), round(r.final()["K"], 6)
    (2.0, 3.0)
    """
    if hasattr(t, "time") and hasattr(t, "outputs"):
        if f is not None or x is not None:
            raise InputDataError("give either a TimeResponseData or the arrays t, f, x, not both")
        t, f, x = _unpack_timeresponse(t)
    elif f is None or x is None:
        raise InputDataError("estimate needs the input f and the output x")
    gen = load_model(model)
    _check_options(filter_order, quadrature_order)
    lowpass_filter = None if lowpass is None else as_lowpass(lowpass)
    _choose_engine(engine, 0, lowpass_filter)  # refuse a bad engine option before the data
    mass = _known_mass(gen, model, mass)
    min_samples = max(2 * quadrature_order, 8)
    try:
        n = len(t)
    except TypeError:
        n = 0  # not a sequence: check_experiment says what is wrong
    if _choose_engine(engine, n, lowpass_filter) == "numba":
        from algid import engine as compiled
        t, f, x, h = compiled.check_experiment(t, f, x, min_samples=min_samples)
        values = compiled.estimate_arrays(gen, f, x, step=h, quadrature_order=quadrature_order,
                                          filter_order=int(filter_order),
                                          input_divisor=1.0 if mass is None else mass)
    else:
        t, f, x, h = check_experiment(t, f, x, min_samples=min_samples)
        values = _numpy_estimates(gen, f / mass if mass is not None else f, x, h,
                                  filter_order=int(filter_order),
                                  quadrature_order=quadrature_order, lowpass=lowpass_filter)
    estimates = _with_physical_parameters(dict(zip(gen.PARAMETERS, values)), mass)
    return EstimationResult(t=t, estimates=estimates, model=model, filter_order=int(filter_order),
                            quadrature_order=quadrature_order, mass=mass)


def _numpy_estimates(gen, u, x, h, *, filter_order, quadrature_order, lowpass):
    """The NumPy engine: one array of estimates per parameter, NaN where undefined."""
    tau = np.arange(u.size) * h  # time origin at the first sample: the method allows it
    kern = kernel_values(gen, {gen.INPUT: u, gen.OUTPUT: x}, tau, h, order=quadrature_order)
    numerators, denominator = gen.cramer(*gen.regressors(kern))
    if filter_order:
        numerators = [iterated_integrals(num, h, filter_order, order=quadrature_order)[-1]
                      for num in numerators]
        denominator = iterated_integrals(denominator, h, filter_order,
                                         order=quadrature_order)[-1]
    if lowpass is not None:
        numerators = [lowpass.apply(num, h, order=quadrature_order) for num in numerators]
        denominator = lowpass.apply(denominator, h, order=quadrature_order)
    undefined = ~np.isfinite(denominator) | (denominator == 0)
    undefined[: startup_samples(quadrature_order)] = True
    with np.errstate(divide="ignore", invalid="ignore"):
        return [np.where(undefined, np.nan, num / denominator) for num in numerators]
