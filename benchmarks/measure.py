"""Measuring helpers: wall time, peak memory, convergence, stream generation.

The machine the benchmark runs on is shared and noisy, so times are the minimum over
repeats (the least disturbed run) and every speed is reported as a ratio to a
baseline measured in the same run.
"""

from __future__ import annotations

import gc
import math
import time
import tracemalloc

import numpy as np

from algid.estimation._result import convergence_time
from algid.simulation import simulate

__all__ = ["sine_record", "best_time", "peak_memory", "both_converged", "relative_errors",
           "piecewise_stream", "sine_stream"]


def sine_record(n, h=1e-3):
    """The speed benchmarks' record: ``n`` samples ``h`` apart of two sines through a
    mass-spring-damper-like response (the same samples in every speed section).

    Parameters
    ----------
    n : int
    h : float, optional

    Returns
    -------
    t, f, x : ndarray
    """
    t = np.arange(n) * h
    f = np.sin(1.3 * t) + 0.5 * np.sin(0.37 * t)
    x = 0.4 * np.sin(1.3 * t - 0.8) + 0.2 * np.sin(0.37 * t - 0.1)
    return t, f, x


def best_time(func, repeats):
    """Smallest wall time of ``repeats`` calls of ``func()`` [s].

    Parameters
    ----------
    func : callable
        Called without arguments; its result is discarded.
    repeats : int
        Number of calls (at least 1).

    Returns
    -------
    float
    """
    best = math.inf
    for _ in range(max(1, int(repeats))):
        gc.collect()
        start = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - start)
    return best


def peak_memory(func):
    """Peak of the memory traced by :mod:`tracemalloc` during ``func()`` [bytes].

    NumPy reports its array buffers to :mod:`tracemalloc`, so the figure covers the
    arrays an estimator allocates (not the inputs, which exist before the call).

    Parameters
    ----------
    func : callable

    Returns
    -------
    int
    """
    gc.collect()
    tracemalloc.start()
    try:
        base, _ = tracemalloc.get_traced_memory()
        tracemalloc.reset_peak()
        func()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return int(peak - base)


def both_converged(t, estimates, true_values, rtol):
    """First instant from which every estimate stays within ``rtol`` of its value.

    Parameters
    ----------
    t : ndarray
    estimates : dict
        Name -> array over ``t``.
    true_values : dict
        Name -> true value.
    rtol : float

    Returns
    -------
    float
        The latest of the convergence times of the parameters, NaN if one of them is
        outside the band at the last sample.
    """
    times = [convergence_time(t, estimates[k], v, rtol) for k, v in true_values.items()]
    return float("nan") if any(math.isnan(x) for x in times) else float(max(times))


def relative_errors(values, true_values):
    """``{name: |value / true - 1|}`` for the names in ``true_values``."""
    return {k: float(abs(values[k] / v - 1.0)) for k, v in true_values.items()}


def piecewise_stream(kind, segments, *, rate=1000.0, block=100_000, chunk=1000):
    """Noise-free stream of the plant whose parameters change at given times.

    The response is computed block by block with :func:`algid.simulate` (exact for the
    built-in inputs, whose time origin is absolute), each block starting from the
    state where the previous one ended, so memory does not grow with the stream.

    Parameters
    ----------
    kind : {"step", "sine"}
        Input.
    segments : sequence of (n_samples, B, K)
        Consecutive segments of the stream (mass 1); the first starts at rest at
        ``t = 0``.
    rate : float, optional
        Sampling rate [Hz].
    block : int, optional
        Samples simulated at once (at most; the memory of the generator is that of
        one block).
    chunk : int, optional
        Samples per yielded chunk.

    Yields
    ------
    t, f, x : ndarray
        Consecutive chunks (at most ``chunk`` samples; a chunk never spans a change).
    """
    state = (0.0, 0.0)
    index = 0  # stream index of the next sample
    for n_seg, B, K in segments:
        done = 0
        while done < n_seg:
            m = min(block, n_seg - done)
            first = index == 0
            # a block starts at the last sample already produced (its state is known)
            idx = np.arange(index if first else index - 1, index + m)
            sim = simulate(kind, m=1.0, c=B, k=K, timepts=idx / rate, initial_state=state)
            state = (float(sim.x_true[-1]), float(sim.v_true[-1]))
            sl = slice(0 if first else 1, None)
            t, f, x = sim.t[sl], sim.f[sl], sim.x[sl]
            del sim
            for i in range(0, m, chunk):
                # copies: a chunk the consumer keeps must not keep the block alive
                yield t[i:i + chunk].copy(), f[i:i + chunk].copy(), x[i:i + chunk].copy()
            del t, f, x  # freed before the next block is simulated
            done += m
            index += m


def sine_stream(n, *, B=2.0, K=3.0, rate=1000.0, block=100_000, chunk=1000):
    """``n`` samples of the noise-free sine experiment, chunk by chunk.

    See :func:`piecewise_stream`.
    """
    return piecewise_stream("sine", [(n, B, K)], rate=rate, block=block, chunk=chunk)
