"""The sections of the benchmark, each a function of a :class:`Config`.

1. :func:`accuracy` - noise-free convergence times and final errors.
2. :func:`efficiency` - RMSE over seeded noisy runs against the Cramér-Rao bound.
3. :func:`performance` - batch throughput, streaming cost per sample, peak memory.
4. :func:`long_stream` - a long noise-free stream with re-anchoring of the origin.
5. :func:`tracking` - a change of the parameters in mid-stream.

Every section returns JSON-ready data (lists of dicts of numbers and strings; NaN is
turned into ``null`` when written).  The paper's system is ``m = 1``, ``c = 2``,
``k = 3`` (``B = 2``, ``K = 3``), sampled at 1 kHz.
"""

from __future__ import annotations

import importlib
import inspect
import math
from dataclasses import dataclass, field

import numpy as np

import algid
from algid.estimation._options import DEFAULT_QUADRATURE_POINTS
from algid.estimation._result import convergence_time
from algid.simulation import simulate
from benchmarks import baselines as bl
from benchmarks.c_speed import c_speed  # section 6, in a module of its own
from benchmarks.error_cost import error_cost  # section 7, likewise
from benchmarks.measure import (
    best_time,
    both_converged,
    peak_memory,
    piecewise_stream,
    relative_errors,
    sine_stream,
)

__all__ = ["Config", "CONFIGS", "TRUE", "RTOL", "accuracy", "efficiency", "performance",
           "long_stream", "tracking", "c_speed", "error_cost", "optional_features"]

#: True parameters of the paper's system.
TRUE = {"B": 2.0, "K": 3.0}
#: Relative band of the convergence times.
RTOL = 1e-3
#: Sampling rate [Hz].
RATE = 1000.0
#: Non-zero initial state of the experiments that test independence of it.
INITIAL_STATE = (0.1, -0.2)


@dataclass(frozen=True)
class Config:
    """Sizes of one benchmark run.

    Attributes
    ----------
    mode : str
        ``"full"``, ``"quick"`` or ``"smoke"``.
    duration : float
        Length of the accuracy and efficiency experiments [s].
    horizons : tuple of float
        Horizons of the efficiency study [s].
    n_runs : int
        Seeded noisy runs per input in the efficiency study.
    n_batch : int
        Samples of the batch throughput and memory measurements.
    n_oe : int
        Samples for the output-error fits (too slow and too large for ``n_batch``).
    n_stream_1 : int
        Samples fed one at a time.
    n_stream_1000 : int
        Samples fed in chunks of 1000.
    repeats : int
        Timed repeats (the minimum is kept).
    n_long : int
        Samples of the long stream.
    tracking_duration : float
        Length of the tracking streams [s]; the change is at the middle.
    """

    mode: str
    duration: float = 5.0
    horizons: tuple = (1.0, 2.5, 5.0)
    n_runs: int = 200
    n_batch: int = 10**7
    n_oe: int = 10**6
    n_stream_1: int = 20_000
    n_stream_1000: int = 10**6
    repeats: int = 3
    n_long: int = 10**7
    tracking_duration: float = 10.0
    noise_std: float = 0.01
    seed: int = 0
    extra: dict = field(default_factory=dict)


#: The three sizes: the full benchmark, a quick look while developing, and the
#: smallest run (seconds) used by the test suite.
CONFIGS = {
    "full": Config(mode="full"),
    "quick": Config(mode="quick", n_runs=10, n_batch=10**6, n_oe=10**5, n_stream_1=5_000,
                    n_stream_1000=200_000, repeats=2, n_long=10**6),
    "smoke": Config(mode="smoke", duration=2.0, horizons=(1.0, 2.0), n_runs=1,
                    n_batch=10_000, n_oe=2_000, n_stream_1=100, n_stream_1000=5_000,
                    repeats=1, n_long=6_000, tracking_duration=1.0),
}


# --------------------------------------------------------------------------------------
# optional parts of the toolkit
# --------------------------------------------------------------------------------------


def _study_function():
    """``crlb_study`` from whichever module of the toolkit holds it (or None)."""
    for name in ("algid.estimation._cramer_rao", "algid.estimation._efficiency"):
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        func = getattr(module, "crlb_study", None)
        if callable(func):
            return func, name
    return None, None


def _online():
    try:
        from algid.estimation import _online as online
    except ImportError:
        return None
    return online if hasattr(online, "OnlineEstimator") else None


def _online_engines(online):
    """Engines to run ``OnlineEstimator`` with: ``[(name, kwargs), ...]``.

    ``[("default", {})]`` if it has no ``engine`` option; otherwise ``"numpy"`` and,
    when numba is installed, ``"numba"``.
    """
    if "engine" not in inspect.signature(online.OnlineEstimator).parameters:
        return [("default", {})]
    engines = [("numpy", {"engine": "numpy"})]
    if _numba_engine()[0]:
        engines.append(("numba", {"engine": "numba"}))
    return engines


def _online_fastest(online):
    """Label suffix and options of the fastest engine of ``OnlineEstimator`` here."""
    name, kwargs = _online_engines(online)[-1]
    return ("" if name == "default" else f", {name} engine"), kwargs


def _numba_engine():
    """Whether ``algid.estimate(..., engine="numba")`` can run here, and why not."""
    if "engine" not in inspect.signature(algid.estimate).parameters:
        return False, "algid.estimate has no engine option"
    from algid.estimation._backends import numba_available
    if not numba_available():
        return False, "numba not installed"
    return True, "available"


def optional_features():
    """Which optional parts of the toolkit this run could use.

    Returns
    -------
    dict
        ``crlb_study`` (module or None), ``online`` (bool), ``numba_engine`` (reason).
    """
    _, study_module = _study_function()
    ok, why = _numba_engine()
    return {"crlb_study": study_module, "online": _online() is not None,
            "numba_engine": why if not ok else "available"}


# --------------------------------------------------------------------------------------
# 1. accuracy and convergence, noise-free
# --------------------------------------------------------------------------------------

#: Methods of the accuracy section: key -> (label, kind), kind "online" (an estimate at
#: every sample) or "batch" (one estimate from the whole record).
ACCURACY_METHODS = {
    "algid": (f"algid default ({DEFAULT_QUADRATURE_POINTS}-point rule, filter 1/s^2)",
              "online"),
    "algid_p0": ("algid, filter_order=0", "online"),
    "algid_trap_p0": ("algid trapezoid (quadrature_points=2), p=0", "online"),
    "algid_trap_p1": ("algid trapezoid (quadrature_points=2), p=1", "online"),
    "naive_numpy": ("naive NumPy, paper's formulas + cumulative_trapezoid", "online"),
    "svf_rls": (f"SVF + RLS (lam={bl.SVF_LAMBDA:g}, forgetting 1)", "online"),
    "svf_ls": (f"SVF + least squares (lam={bl.SVF_LAMBDA:g})", "batch"),
    "oe_nls": ("output-error NLS (scipy least_squares, start B=K=1)", "batch"),
    "algid_refined": ("algid + refine (Gauss-Newton output error)", "batch"),
}


def _experiments(duration):
    return {
        "step": simulate("step", duration=duration, rate=RATE),
        "sine": simulate("sine", duration=duration, rate=RATE),
        "step_ic": simulate("step", duration=duration, rate=RATE, initial_state=INITIAL_STATE),
        "sine_ic": simulate("sine", duration=duration, rate=RATE, initial_state=INITIAL_STATE),
    }


def _trajectory(key, t, f, x):
    """Estimates over time of an on-line method: ``{"B": array, "K": array}``."""
    if key == "algid":
        return algid.estimate(t, f, x).estimates
    if key == "algid_p0":
        return algid.estimate(t, f, x, filter_order=0).estimates
    if key == "algid_trap_p0":
        return algid.estimate(t, f, x, quadrature_points=2, filter_order=0).estimates
    if key == "algid_trap_p1":
        return algid.estimate(t, f, x, quadrature_points=2, filter_order=1).estimates
    if key == "naive_numpy":
        B, K = bl.naive_algebraic(t, f, x)
        return {"B": B, "K": K}
    if key == "svf_rls":
        B, K = bl.svf_rls(t, f, x)
        return {"B": B, "K": K}
    raise KeyError(key)


def _batch_fit(key, t, f, x):
    """Final estimates of a batch method: ``{"B": float, "K": float}``."""
    if key == "svf_ls":
        return bl.svf_least_squares(t, f, x).final()
    if key == "oe_nls":
        return bl.output_error_nls(t, f, x).final()
    if key == "algid_refined":
        from algid.estimation._refinement import refine

        r = refine(t, f, x)
        return {"B": r.B, "K": r.K}
    raise KeyError(key)


def accuracy(config):
    """Noise-free convergence times and final errors on the paper's system.

    Four experiments of ``config.duration`` seconds at 1 kHz: step and sine (1 rad/s)
    inputs, from rest as in the paper (``step``, ``sine``) and from the initial state
    ``(x0, v0) = (0.1, -0.2)`` unknown to the estimators (``step_ic``, ``sine_ic``).

    Returns
    -------
    dict
        ``rows``: one per method and experiment with ``convergence_time`` (on-line
        methods: the instant from which both ``B`` and ``K`` stay within 0.1 %; NaN if
        not at the end) and the final relative errors; ``svf_predicted_bias``: the
        bias of the state-variable-filter least squares predicted from the initial
        state, per experiment; ``naive_vs_algid_trapezoid``: the largest relative
        difference between the from-scratch trapezoid estimator and ``algid``'s after
        the first 10 samples (the same estimator written twice).
    """
    rows = []
    predicted = {}
    agreement = {}
    for name, sim in _experiments(config.duration).items():
        t, f, x = sim.t, sim.f, sim.x
        trajectories = {}
        for key, (label, kind) in ACCURACY_METHODS.items():
            if kind == "online":
                est = _trajectory(key, t, f, x)
                trajectories[key] = est
                final = {k: float(est[k][-1]) for k in TRUE}
                conv = both_converged(t, est, TRUE, RTOL)
            else:
                final = _batch_fit(key, t, f, x)
                conv = float("nan")
            err = relative_errors(final, TRUE)
            rows.append({"method": key, "label": label, "kind": kind, "experiment": name,
                         "convergence_time": conv if kind == "online" else None,
                         "final_B": final["B"], "final_K": final["K"],
                         "error_B": err["B"], "error_K": err["K"]})
        x0, v0 = (0.0, 0.0) if not name.endswith("_ic") else INITIAL_STATE
        predicted[name] = bl.svf_transient_bias(t, f, sim.x_true, B=TRUE["B"], K=TRUE["K"],
                                                x0=x0, v0=v0)
        a, b = trajectories["naive_numpy"], trajectories["algid_trap_p0"]
        agreement[name] = float(max(np.nanmax(np.abs(a[k][10:] / b[k][10:] - 1.0))
                                    for k in TRUE))
    return {"rtol": RTOL, "duration": config.duration, "rate": RATE,
            "initial_state_ic": list(INITIAL_STATE), "rows": rows,
            "svf_predicted_bias": predicted, "naive_vs_algid_trapezoid": agreement}


# --------------------------------------------------------------------------------------
# 2. statistical efficiency
# --------------------------------------------------------------------------------------

#: Baselines of the efficiency section (the algebraic and refined estimates come from
#: the toolkit's study function).
EFFICIENCY_BASELINES = {
    "algid_trap_p0": "algid trapezoid, p=0 (paper-style)",
    "algid_trap_p1": "algid trapezoid, p=1 (paper-style)",
    "svf_ls": f"SVF + least squares (lam={bl.SVF_LAMBDA:g})",
    "svf_rls": f"SVF + RLS (lam={bl.SVF_LAMBDA:g})",
    "oe_nls": "output-error NLS (scipy, start B=K=1)",
}

_INPUTS = ("step", "sine")


def _baseline_final(key, t, f, x):
    if key == "algid_trap_p0":
        return algid.estimate(t, f, x, quadrature_points=2, filter_order=0).final()
    if key == "algid_trap_p1":
        return algid.estimate(t, f, x, quadrature_points=2, filter_order=1).final()
    if key == "svf_rls":
        B, K = bl.svf_rls(t, f, x)
        return {"B": float(B[-1]), "K": float(K[-1])}
    return _batch_fit(key, t, f, x)


def _stats(errors, bound):
    err = np.asarray(errors, dtype=float).reshape(-1, 2)
    ok = np.all(np.isfinite(err), axis=1)
    err = err[ok]
    if err.size:
        rmse = np.sqrt(np.mean(err**2, axis=0))
        bias = np.mean(err, axis=0)
    else:
        rmse = bias = np.full(2, np.nan)
    return {"n_valid": int(ok.sum()), "bias_B": float(bias[0]), "bias_K": float(bias[1]),
            "rmse_B": float(rmse[0]), "rmse_K": float(rmse[1]),
            "crlb_B": bound["B"], "crlb_K": bound["K"],
            "ratio_B": float(rmse[0] / bound["B"]), "ratio_K": float(rmse[1] / bound["K"])}


def efficiency(config):
    """RMSE against the Cramér-Rao bound, toolkit and baselines on the same data.

    The toolkit's study function (``crlb_study``) gives the algebraic and the refined
    estimates; the baselines are run on the very same noisy records, rebuilt as the
    study builds them (noise-free response of ``config.duration`` seconds plus
    ``N(0, noise_std**2)`` noise from ``numpy.random.SeedSequence([seed, i_input,
    run])``; the record of horizon ``T`` is its first ``T * rate + 1`` samples).

    Returns
    -------
    dict
        ``rows`` (one per method, input and horizon), ``noise_std``, ``n_runs``,
        ``study`` (module of the study function, or a reason why it is missing),
        ``same_data_check`` (per input: relative difference between the study's
        algebraic RMSE at the longest horizon and the same RMSE recomputed here from
        the rebuilt records; round-off if the data are the same).
    """
    from algid.estimation._cramer_rao import crlb

    study, module = _study_function()
    horizons = tuple(float(T) for T in config.horizons)
    rows = []
    bounds = {}
    if study is not None:
        for r in study(n_runs=config.n_runs, horizons=horizons, inputs=_INPUTS,
                       noise_std=config.noise_std, seed=config.seed):
            key = (r["input"], float(r["horizon"]))
            bounds[key] = {"B": float(r["crlb_B"]), "K": float(r["crlb_K"])}
            rows.append({"method": r["method"], "label": f"{r['method']} (toolkit study)",
                         "input": r["input"], "horizon": float(r["horizon"]),
                         "n_runs": int(r["n_runs"]), "n_valid": int(r["n_valid"]),
                         **{k: float(r[k]) for k in ("bias_B", "bias_K", "rmse_B", "rmse_K",
                                                     "crlb_B", "crlb_K", "ratio_B",
                                                     "ratio_K")}})
    duration = max(horizons)
    lengths = {T: int(round(T * RATE)) + 1 for T in horizons}
    same_data = {}
    for i_input, name in enumerate(_INPUTS):
        sim = simulate(name, m=1.0, c=TRUE["B"], k=TRUE["K"], duration=duration, rate=RATE)
        for T, n in lengths.items():
            if (name, T) not in bounds:
                bounds[name, T] = {k: v for k, v in crlb(
                    sim.t[:n], sim.f[:n], B=TRUE["B"], K=TRUE["K"],
                    noise_std=config.noise_std).items() if k in TRUE}
        errors = {(key, T): [] for key in EFFICIENCY_BASELINES for T in horizons}
        check = []  # the study's algebraic estimate at the longest horizon, recomputed
        for run in range(config.n_runs):
            rng = np.random.default_rng(np.random.SeedSequence([config.seed, i_input, run]))
            x_run = sim.x_true + rng.normal(0.0, config.noise_std, size=sim.t.size)
            for T, n in lengths.items():
                t, f, x = sim.t[:n], sim.f[:n], x_run[:n]
                for key in EFFICIENCY_BASELINES:
                    est = _baseline_final(key, t, f, x)
                    errors[key, T].append([est["B"] - TRUE["B"], est["K"] - TRUE["K"]])
            final = algid.estimate(sim.t, sim.f, x_run).final()
            check.append([final["B"] - TRUE["B"], final["K"] - TRUE["K"]])
        for key, label in EFFICIENCY_BASELINES.items():
            for T in horizons:
                rows.append({"method": key, "label": label, "input": name, "horizon": T,
                             "n_runs": config.n_runs,
                             **_stats(errors[key, T], bounds[name, T])})
        study_row = next((r for r in rows if r["method"] == "algebraic"
                          and r["input"] == name and r["horizon"] == duration), None)
        if study_row is not None:
            mine = _stats(check, bounds[name, duration])
            same_data[name] = max(abs(mine[k] / study_row[k] - 1.0)
                                  for k in ("rmse_B", "rmse_K"))
    return {"noise_std": config.noise_std, "n_runs": config.n_runs, "seed": config.seed,
            "horizons": list(horizons),
            "study": module or "not available (no crlb_study in algid)",
            "same_data_check": same_data, "rows": rows}


# --------------------------------------------------------------------------------------
# 3. speed and memory
# --------------------------------------------------------------------------------------


def _batch_methods(n_oe):
    """key -> (label, function(t, f, x), samples used)."""
    from algid.estimation._refinement import refine

    numpy_engine = ({"engine": "numpy"}
                    if "engine" in inspect.signature(algid.estimate).parameters else {})
    methods = {
        "naive_numpy": ("naive NumPy (paper's formulas, cumulative_trapezoid), p=0 "
                        "[baseline]", lambda t, f, x: bl.naive_algebraic(t, f, x), None),
        "algid": ("algid default (NumPy engine)",
                  lambda t, f, x: algid.estimate(t, f, x, **numpy_engine), None),
    }
    # the estimator without its companion (numerical_error=False): the work the speed
    # targets of the estimator core were set for, before the numerical error existed
    alone = ({"numerical_error": False}
             if "numerical_error" in inspect.signature(algid.estimate).parameters else None)
    if alone is not None:
        methods["algid_alone"] = (
            "algid, numerical_error=False (NumPy engine)",
            lambda t, f, x: algid.estimate(t, f, x, **alone, **numpy_engine), None)
    ok, _ = _numba_engine()
    if ok:
        methods["algid_numba"] = ("algid default (numba engine)",
                                  lambda t, f, x: algid.estimate(t, f, x, engine="numba"),
                                  None)
        if alone is not None:
            methods["algid_numba_alone"] = (
                "algid, numerical_error=False (numba engine)",
                lambda t, f, x: algid.estimate(t, f, x, engine="numba", **alone), None)
    methods.update({
        "algid_trap_p0": ("algid trapezoid, p=0 (NumPy engine)",
                          lambda t, f, x: algid.estimate(t, f, x, quadrature_points=2,
                                                         filter_order=0, **numpy_engine),
                          None),
        "svf_ls": ("SVF + least squares", bl.svf_least_squares, None),
        "svf_rls": ("SVF + RLS (one chunk)", bl.svf_rls, None),
        "oe_nls": ("output-error NLS (scipy)", bl.output_error_nls, n_oe),
        "algid_refined": ("algid + refine", lambda t, f, x: refine(t, f, x), n_oe),
    })
    return methods


def _streamers(online):
    """key -> (label, factory of an object with update(t, f, x))."""
    out = {}
    if online is not None:
        period = getattr(online, "TRACKING_RESET_PERIOD", 0.05)
        engines = _online_engines(online)
        for name, kw in engines:
            suffix = "" if name == "default" else f", {name} engine"
            tag = "" if name == "default" else f"_{name}"
            out[f"online{tag}"] = (f"OnlineEstimator{suffix}",
                                   lambda kw=kw: online.OnlineEstimator(rate=RATE, **kw))
            out[f"online_reset{tag}"] = (
                f"OnlineEstimator reset_period={period:g}{suffix}",
                lambda kw=kw: online.OnlineEstimator(rate=RATE, reset_period=period, **kw))
        name, kw = engines[0]
        suffix = "" if name == "default" else f", {name} engine"
        out["online_trap_p0"] = (f"OnlineEstimator trapezoid, p=0{suffix}",
                                 lambda: online.OnlineEstimator(rate=RATE, quadrature_points=2,
                                                                filter_order=0, **kw))
        numba_online = any(name == "numba" for name, _ in engines)
    else:
        numba_online = False
    ok, _ = _numba_engine()
    if ok and not numba_online:
        out["engine_numba"] = ("algid.estimation._core state + advance (numba)", _EngineStream)
    out["svf_rls"] = ("SVF + RLS", bl.SVFRecursiveLeastSquares)
    return out


class _EngineStream:
    """The estimator core's streaming interface (numba backend) behind ``update(t, f,
    x)``."""

    def __init__(self):
        from algid.estimation import _core as core
        from algid.models._registry import load_model

        self._core = core
        self._state = core.new_state(load_model("msd"), points=6, filter_order=2,
                                     dt=1.0 / RATE)

    def update(self, t, f, x):
        return self._core.advance(self._state, (np.atleast_1d(f), np.atleast_1d(x)),
                                  backend="numba")[0]


def _feed(factory, t, f, x, chunk):
    est = factory()
    if chunk == 1:
        for i in range(t.size):
            est.update(float(t[i]), float(f[i]), float(x[i]))
    else:
        for i in range(0, t.size, chunk):
            est.update(t[i:i + chunk], f[i:i + chunk], x[i:i + chunk])


def performance(config):
    """Batch throughput, streaming cost per sample and peak memory, as ratios.

    The data are the noise-free sine experiment.  Every method is called once on 2000
    samples first (imports, caches, compilation are not timed).  Batch methods run on
    ``config.n_batch`` samples (the output-error fits on ``config.n_oe``); times are
    the minimum over ``config.repeats`` interleaved repeats; memory is the
    :mod:`tracemalloc` peak of a separate call divided by the bytes of the input
    (``t``, ``f``, ``x``: 24 bytes per sample).  The reference (ratio 1.0) is the
    from-scratch NumPy trapezoid estimator: its throughput for the batch figures, its
    cost per sample for the streaming figures.

    Returns
    -------
    dict
        ``batch`` and ``streaming`` rows, ``reference`` figures, sizes.
    """
    n = config.n_batch
    sim = simulate("sine", duration=(n - 1) / RATE, rate=RATE)
    t, f, x = sim.t, sim.f, sim.x
    del sim
    methods = _batch_methods(config.n_oe)
    for _, func, _ in methods.values():  # warm-up: imports, caches, compilation
        func(t[:2000], f[:2000], x[:2000])
    times = {key: math.inf for key in methods}
    for _ in range(max(1, config.repeats)):  # interleaved: the machine's load varies
        for key, (_, func, m) in methods.items():
            m = n if m is None else min(m, n)
            times[key] = min(times[key], best_time(lambda: func(t[:m], f[:m], x[:m]), 1))
    batch = []
    for key, (label, func, m) in methods.items():
        m = n if m is None else min(m, n)
        peak = peak_memory(lambda: func(t[:m], f[:m], x[:m]))
        batch.append({"method": key, "label": label, "n_samples": m, "time": times[key],
                      "throughput": m / times[key], "peak_bytes": peak,
                      "memory_ratio": peak / (24.0 * m)})
    ref = next(r for r in batch if r["method"] == "naive_numpy")
    for r in batch:
        r["throughput_ratio"] = r["throughput"] / ref["throughput"]
    ok, why = _numba_engine()
    if not ok:
        batch.append({"method": "algid_numba", "label": "algid default (numba engine)",
                      "not_available": why})

    online = _online()
    streaming = []
    ref_cost = 1.0 / ref["throughput"]
    sizes = ((1, config.n_stream_1), (1000, config.n_stream_1000))
    for key, (label, factory) in _streamers(online).items():
        _feed(factory, t[:2000], f[:2000], x[:2000], 1000)  # warm-up
        for chunk, m in sizes:
            m = min(m, n)
            elapsed = best_time(lambda: _feed(factory, t[:m], f[:m], x[:m], chunk),
                                config.repeats if chunk > 1 else 1)
            cost = elapsed / m
            streaming.append({"method": key, "label": label, "chunk": chunk, "n_samples": m,
                              "cost_per_sample": cost, "cost_ratio": cost / ref_cost})
    if online is None:
        streaming.append({"method": "online", "label": "OnlineEstimator",
                          "not_available":
                "algid.estimation._online not available"})
    return {"n_batch": n, "n_oe": config.n_oe, "repeats": config.repeats,
            "reference": {"method": "naive_numpy", "throughput": ref["throughput"],
                          "cost_per_sample": ref_cost},
            "batch": batch, "streaming": streaming}


# --------------------------------------------------------------------------------------
# 4. long stream
# --------------------------------------------------------------------------------------


def _resident_bytes():
    """Resident memory of this process [bytes] (Linux), or None."""
    try:
        with open("/proc/self/statm") as fh:
            pages = int(fh.read().split()[1])
    except (OSError, ValueError, IndexError):
        return None
    import os

    return pages * os.sysconf("SC_PAGE_SIZE")


def _run_stream(factory, chunks, settle_time, *, n_samples):
    """Feed a stream; keep the largest error after ``settle_time`` and the memory.

    Memory is traced (:mod:`tracemalloc`, which slows Python code several times) only
    over the first and the last tenth of the stream: the peak of the allocations made
    in each (estimator and stream generation together; equal peaks mean that the
    cost of a chunk does not grow), and the resident memory of the process after the
    first tenth and at the end (its growth would reveal memory kept from chunk to
    chunk).
    """
    import tracemalloc

    est = factory()
    worst = {k: 0.0 for k in TRUE}
    n_undefined = 0
    n = 0
    max_state = 0.0
    final = {}
    tenth = max(1, n_samples // 10)
    peaks = {}
    rss = {}
    gc_collect = __import__("gc").collect
    gc_collect()
    tracemalloc.start()
    try:
        for t, f, x in chunks:
            if ("first" in peaks and "last" not in peaks
                    and n + t.size > n_samples - tenth):
                tracemalloc.start()
                peaks["last"] = None
            out = est.update(t, f, x)
            values = out.estimates if hasattr(out, "estimates") else dict(zip(("B", "K"), out))
            n += t.size
            if hasattr(est, "state_magnitude"):
                max_state = max(max_state, float(est.state_magnitude))
            keep = t >= settle_time
            if keep.any():
                for k, v in TRUE.items():
                    e = np.abs(np.asarray(values[k])[keep] / v - 1.0)
                    bad = ~np.isfinite(e)
                    n_undefined += int(bad.sum())
                    worst[k] = max(worst[k], math.inf if bad.any() else float(e.max()))
            final = {k: float(np.asarray(values[k])[-1]) for k in TRUE}
            if "first" not in peaks and n >= tenth:
                peaks["first"] = tracemalloc.get_traced_memory()[1]
                tracemalloc.stop()
                gc_collect()
                rss["first"] = _resident_bytes()
        if tracemalloc.is_tracing():
            peaks["last"] = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    del out, values
    gc_collect()
    rss["end"] = _resident_bytes()
    growth = None if None in (rss.get("first"), rss["end"]) else rss["end"] - rss["first"]
    return {"n_samples": n, "max_rel_error": worst, "n_undefined": n_undefined,
            "final": final, "peak_bytes_first_tenth": peaks.get("first"),
            "peak_bytes_last_tenth": peaks.get("last"), "rss_growth_bytes": growth,
            "max_state_magnitude": max_state if max_state else None}


def long_stream(config):
    """The noise-free sine experiment streamed over ``config.n_long`` samples.

    Chunks of 1000 samples, simulated block by block (memory does not grow with the
    stream).  With re-anchoring every ``TRACKING_RESET_PERIOD`` (and every 1 s), the
    error is measured after the first period (from then on every reported window has
    had half a period to converge); without re-anchoring and for the recursive least
    squares, after 1 s.  Memory: the :mod:`tracemalloc` peaks of the first and of the
    last tenth of the stream (estimator and stream generation together) and the
    growth of the resident memory between the end of the first tenth and the end.

    At 1 kHz the sample times ``n / 1000`` are rounded to doubles: the simulated
    samples are the exact response at times off the uniform grid by up to
    ``eps * t`` (about 1e-12 s at ``t = 1e4`` s), which the estimator, assuming a
    uniform step, sees as data error growing with ``t``.  The row
    ``online_reset_1024`` repeats the re-anchored stream at 1024 Hz, where
    ``n / 1024`` is exact, to separate this effect of the synthetic data from the
    estimator.

    Returns
    -------
    dict
        ``rows`` (one per estimator) or ``not_available``.
    """
    import time

    online = _online()
    rows = []
    if online is None:
        return {"n_samples": config.n_long, "not_available": "online estimator not available"}
    period = getattr(online, "TRACKING_RESET_PERIOD", 0.05)
    exact_rate = 1024.0
    eng, kw = _online_fastest(online)
    setups = {
        "online_reset": (f"OnlineEstimator reset_period={period:g}{eng}",
                         lambda: online.OnlineEstimator(rate=RATE, reset_period=period, **kw),
                         period, RATE),
        "online_reset_1024": (f"OnlineEstimator reset_period={period:g}{eng}, "
                              f"{exact_rate:g} Hz (exact sample times)",
                              lambda: online.OnlineEstimator(rate=exact_rate,
                                                             reset_period=period, **kw),
                              period, exact_rate),
        "online_reset_1s": (f"OnlineEstimator reset_period=1{eng}",
                            lambda: online.OnlineEstimator(rate=RATE, reset_period=1.0, **kw),
                            1.0, RATE),
        "online": (f"OnlineEstimator, no re-anchoring{eng}",
                   lambda: online.OnlineEstimator(rate=RATE, **kw), 1.0, RATE),
        "svf_rls": ("SVF + RLS", bl.SVFRecursiveLeastSquares, 1.0, RATE),
    }
    # blocks small enough that the first tenth holds several (steady memory)
    block = max(2000, min(100_000, config.n_long // 20))
    for key, (label, factory, settle, rate) in setups.items():
        start = time.perf_counter()
        out = _run_stream(factory, sine_stream(config.n_long, rate=rate, block=block), settle,
                          n_samples=config.n_long)
        rows.append({"method": key, "label": label, "rate": rate, "settle_time": settle,
                     "elapsed": time.perf_counter() - start, **out})
    return {"n_samples": config.n_long, "input": "sine", "chunk": 1000, "rows": rows}


# --------------------------------------------------------------------------------------
# 5. tracking a change of the parameters
# --------------------------------------------------------------------------------------

#: Changes of the parameters in mid-stream: name -> (B, K) after the change.
CHANGES = {"K 3->5": (2.0, 5.0), "B 2->1": (1.0, 3.0), "both": (1.0, 5.0)}
#: Instants of the change after the middle of the stream [s]: 1 ms after a round time
#: (the worst case for origins re-anchored at multiples of a round period: the window
#: that started just before the change holds both plants) and an irregular offset.
CHANGE_OFFSETS = (0.001, 0.013)


def _tracking_run(factory, kind, n1, n2, after):
    t_all, est_all = [], {k: [] for k in TRUE}
    est = factory()
    for t, f, x in piecewise_stream(kind, [(n1, *TRUE.values()), (n2, *after)], rate=RATE):
        out = est.update(t, f, x)
        values = out.estimates if hasattr(out, "estimates") else dict(zip(("B", "K"), out))
        t_all.append(t)
        for k in TRUE:
            est_all[k].append(np.asarray(values[k]))
    t = np.concatenate(t_all)
    return t, {k: np.concatenate(v) for k, v in est_all.items()}


def tracking(config):
    """Time to follow a change of the parameters, noise-free.

    Each stream lasts ``config.tracking_duration`` seconds; the plant's parameters
    change at ``t_c = t[n1 - 1]``, :data:`CHANGE_OFFSETS` after the middle of the
    stream (the samples from ``n1`` on are responses of the new plant, continuing
    from the state at ``t_c``).  The tracking time is the instant from which both
    estimates stay within 0.1 % of the new values, minus ``t_c`` (NaN: not within the
    band at the end of the stream).

    A change of ``B`` alone while a step response has settled is barely visible: at
    rest the output does not depend on ``B``, and only the remains of the transient
    (``exp(-t)``, below 1 % after 5 s) excite it.  Such rows carry
    ``low_excitation = True`` and are reported but left out of the target.

    Returns
    -------
    dict
        ``rows`` (one per estimator, input, change and offset) or ``not_available``.
    """
    online = _online()
    if online is None:
        return {"not_available": "algid.estimation._online not available"}
    period = getattr(online, "TRACKING_RESET_PERIOD", 0.05)
    eng, kw = _online_fastest(online)
    setups = {
        "online_reset": (f"OnlineEstimator reset_period={period:g}{eng}",
                         lambda: online.OnlineEstimator(rate=RATE, reset_period=period, **kw)),
        "online": (f"OnlineEstimator, no re-anchoring{eng}",
                   lambda: online.OnlineEstimator(rate=RATE, **kw)),
        "svf_rls": ("SVF + RLS (forgetting 1)", bl.SVFRecursiveLeastSquares),
    }
    n_total = int(round(config.tracking_duration * RATE)) + 1
    rows = []
    for kind in _INPUTS:
        for change, after in CHANGES.items():
            for offset in CHANGE_OFFSETS:
                n1 = n_total // 2 + int(round(offset * RATE)) + 1
                for key, (label, factory) in setups.items():
                    t, est = _tracking_run(factory, kind, n1, n_total - n1, after)
                    t_c = float(t[n1 - 1])
                    post = slice(n1, None)
                    truth = dict(zip(TRUE, after))
                    times = [convergence_time(t[post], est[k][post], v, RTOL)
                             for k, v in truth.items()]
                    tt = (float("nan") if any(math.isnan(v) for v in times)
                          else max(times) - t_c)
                    rows.append({"method": key, "label": label, "input": kind,
                                 "change": change, "offset": offset,
                                 "low_excitation": kind == "step" and after[1] == TRUE["K"],
                                 "B_after": after[0],
                                 "K_after": after[1], "t_change": t_c, "tracking_time": tt,
                                 "final_B": float(est["B"][-1]),
                                 "final_K": float(est["K"][-1])})
    return {"duration": config.tracking_duration, "rtol": RTOL,
            "offsets": list(CHANGE_OFFSETS), "rows": rows}
