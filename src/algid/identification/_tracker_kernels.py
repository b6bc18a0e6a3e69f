"""The per-window loops of :class:`algid.Tracker`: one implementation, compiled by numba
when installed, run as Python otherwise.

:class:`~algid.Tracker` gathers a chunk's new windows and hands them to loops that run
window after window in a fixed order, so that the results do not depend on how the
stream is cut into chunks:

- here, the accumulation: :func:`window_sums` (the forgetting factor of each window, the
  Givens update of the triangular factors ``R`` of ``[A | b]``, one per kernel
  multiplicity, the noise sums ``G``, the weight sums and the sums of squared output
  differences of the noise bound, with a copy of each after every window) and
  :func:`window_scores` (the lagged products of the windows' scores and, at each window
  to be reported, their contraction with the estimate there: the HAC middle of the
  standard errors);
- in :mod:`algid.identification._tracker_solve`, the window equations, the noise bound
  and the per-window solve and covariance.

The loops use scalars, fixed-size arrays and ``math`` only, so that they compile (numba
today, C99 later) and run unchanged as Python.  :func:`kernels` gives the compiled ones
when numba is used (:mod:`algid.identification._tracker_jit`), else the Python
functions: the same operations in the same order, the same results bit for bit (but for
the forgetting factors ``2**x``, where numba's ``pow`` and the C library's can differ in
the last bit), tens to hundreds of times slower (360 times on the EMPS record with every
window end reported: ``python -m benchmarks.tracking``, section ``python_loops``).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from functools import cache
from typing import NamedTuple

import numpy as np

from algid.identification._tracker_jit import USE_NUMBA, compile_marked, compiled, declined

__all__ = ["Kernels", "window_sums", "window_scores", "compile_loops", "kernels"]


class Kernels(NamedTuple):
    """The tracker's per-window loops (compiled, or the Python functions)."""

    window_sums: Callable
    window_scores: Callable
    window_rows: Callable
    step_integrals: Callable
    difference_squares: Callable
    noise_bounds: Callable
    solve_windows: Callable
    window_stderr: Callable


def window_sums(rows, grams, ends, last_end, half_life, squares, ranges, R, G, W, bound,
                out_R, out_G, out_W, out_bound, out_decay):
    """Accumulate ``n`` windows; the state (``R``, ``G``, ``W``, ``bound``) in place.

    Parameters
    ----------
    rows : numpy.ndarray, shape (m, n, p + 1)
        ``[A | b]`` of each window, per multiplicity.
    grams : numpy.ndarray, shape (m, n, p + 1, p + 1)
        The noise covariance each window adds.
    ends : numpy.ndarray, shape (n,)
        Times of the windows' last samples.
    last_end : float
        The end of the window before (NaN: none).
    half_life : float
        Of the forgetting (inf: none).
    squares : numpy.ndarray, shape (k, 8)
        Squared output differences of orders 1 to 8 at the new samples.
    ranges : numpy.ndarray of int64, shape (n, 2)
        The rows of ``squares`` each window adds to the noise bound.
    R, G : numpy.ndarray, shape (m, p + 1, p + 1)
        Triangular factors and noise sums.
    W : numpy.ndarray, shape (2,)
        Sums of the weights and of their squares.
    bound : numpy.ndarray, shape (2, 8)
        Sums of the squared differences and their counts.
    out_R, out_G, out_W, out_bound : numpy.ndarray
        The state after each window (leading axis ``n``).
    out_decay : numpy.ndarray, shape (n,)
        Each window's forgetting factor.
    """
    m, n, q1 = rows.shape
    x = np.empty(q1)
    previous = last_end
    for w in range(n):
        decay = 1.0
        if not math.isinf(half_life) and not math.isnan(previous):
            decay = 2.0 ** (-(ends[w] - previous) / half_life)
        previous = ends[w]
        out_decay[w] = decay
        for k in range(8):
            bound[0, k] *= decay
            bound[1, k] *= decay
        for i in range(ranges[w, 0], ranges[w, 1]):
            for k in range(8):
                bound[0, k] += squares[i, k]
        added = float(ranges[w, 1] - ranges[w, 0])
        for k in range(8):
            bound[1, k] += added
        root = math.sqrt(decay)
        for a in range(m):
            for i in range(q1):
                x[i] = rows[a, w, i]
                for j in range(q1):
                    R[a, i, j] *= root
                    G[a, i, j] = decay * G[a, i, j] + grams[a, w, i, j]
            for i in range(q1):       # Givens rotations: the new row into R
                if x[i] == 0.0:
                    continue
                r = np.hypot(R[a, i, i], x[i])
                c = R[a, i, i] / r
                s = x[i] / r
                R[a, i, i] = r
                x[i] = 0.0
                for j in range(i + 1, q1):
                    rij = R[a, i, j]
                    R[a, i, j] = c * rij + s * x[j]
                    x[j] = c * x[j] - s * rij
            for i in range(q1):
                for j in range(q1):
                    out_R[w, a, i, j] = R[a, i, j]
                    out_G[w, a, i, j] = G[a, i, j]
        W[0] = decay * W[0] + 1.0
        W[1] = decay * decay * W[1] + 1.0
        out_W[w, 0] = W[0]
        out_W[w, 1] = W[1]
        for k in range(8):
            out_bound[w, 0, k] = bound[0, k]
            out_bound[w, 1, k] = bound[1, k]


def window_scores(rows, ends, decays, half_life, bars, lag_weights, U, ring_rows,
                  ring_times, count, out_hac, out_trace):
    """Lagged products of the scores; their HAC contraction where ``bars`` is finite.

    The score of a window is ``a_j [A | b]_j`` (the outer product, flattened), and
    ``U[l]`` sums, with the forgetting, the products of each score with the one ``l``
    windows before it in the same segment; at ``theta_bar`` they give the lagged
    products ``sum_j w_j (a_j r_j)(a_{j-l} r_{j-l})^T`` of the estimating equations.

    Parameters
    ----------
    rows : numpy.ndarray, shape (n, p + 1)
        ``[A | b]`` of each window (top multiplicity).
    ends, decays : numpy.ndarray, shape (n,)
        Window ends and forgetting factors (from :func:`window_sums`).
    half_life : float
        Of the forgetting (inf: none).
    bars : numpy.ndarray, shape (n, p + 1)
        ``(theta, -1)`` where the HAC middle is wanted, NaN elsewhere.
    lag_weights : numpy.ndarray, shape (lags + 1,)
        identify's flat-top weights.
    U : numpy.ndarray, shape (lags + 1, q, q)
        The lagged products (in place).
    ring_rows, ring_times : numpy.ndarray, shapes (lags, q), (lags,)
        The last scores and their window ends (in place).
    count : numpy.ndarray of int64, shape (1,)
        Scores in the ring since the segment's start (in place).
    out_hac : numpy.ndarray, shape (n, p, p)
        The HAC sum ``lagged_0 + sum_l k_l (lagged_l + lagged_l^T)``.
    out_trace : numpy.ndarray, shape (n,)
        The trace of ``lagged_0``.
    """
    n, q1 = rows.shape
    p = q1 - 1
    q = p * q1
    lags = ring_rows.shape[0]
    score = np.empty(q)
    contracted = np.empty((lags + 1, p, p))
    for w in range(n):
        for i in range(p):
            for j in range(q1):
                score[i * q1 + j] = rows[w, i] * rows[w, j]
        decay2 = decays[w] * decays[w]
        used = min(count[0], lags)
        for i in range(q):
            for j in range(q):
                U[0, i, j] = decay2 * U[0, i, j] + score[i] * score[j]
        for back in range(1, lags + 1):
            if back > used:
                for i in range(q):
                    for j in range(q):
                        U[back, i, j] *= decay2
                continue
            slot = (count[0] - back) % lags
            weight = 1.0
            if not math.isinf(half_life):
                weight = 2.0 ** (-(ends[w] - ring_times[slot]) / half_life)
            for i in range(q):
                old = weight * ring_rows[slot, i]
                for j in range(q):
                    U[back, i, j] = decay2 * U[back, i, j] + old * score[j]
        slot = count[0] % lags
        for i in range(q):
            ring_rows[slot, i] = score[i]
        ring_times[slot] = ends[w]
        count[0] += 1
        if math.isnan(bars[w, 0]):
            continue
        for lag in range(lags + 1):
            for a in range(p):
                for b in range(p):
                    total = 0.0
                    for c in range(q1):
                        inner = 0.0
                        for d in range(q1):
                            inner += U[lag, a * q1 + c, b * q1 + d] * bars[w, d]
                        total += bars[w, c] * inner
                    contracted[lag, a, b] = total
        trace = 0.0
        for a in range(p):
            trace += contracted[0, a, a]
            for b in range(p):
                hac = contracted[0, a, b]
                for lag in range(1, lags + 1):
                    hac += lag_weights[lag] * (contracted[lag, a, b] + contracted[lag, b, a])
                out_hac[w, a, b] = hac
        out_trace[w] = trace


def compile_loops():
    """Compile the loops of :mod:`algid.identification._tracker_solve` (when numba is
    used): from then on, in this process, identify's bias compensation
    (:func:`~algid.identification._tracker_solve.koopmans`) runs compiled too."""
    import algid.identification._tracker_solve  # noqa: F401  (defines and marks the loops)

    compile_marked()


@cache
def kernels():
    """The tracker's per-window loops, compiled when numba is used.

    Returns
    -------
    Kernels
        The functions of this module and of
        :mod:`algid.identification._tracker_solve`.
    """
    compile_loops()   # from here, the module's names are the compiled loops
    from algid.identification._tracker_solve import (
        difference_squares,
        noise_bounds,
        solve_windows,
        step_integrals,
        window_rows,
        window_stderr,
    )

    if not USE_NUMBA and not declined():
        print("algid: numba is not installed, so the Tracker's loops run as Python, tens to "
              "hundreds of times slower than compiled (pip install 'algid[fast]' compiles "
              "them)", file=sys.stderr, flush=True)
    return Kernels(compiled(window_sums), compiled(window_scores), window_rows,
                   step_integrals, difference_squares, noise_bounds, solve_windows,
                   window_stderr)
