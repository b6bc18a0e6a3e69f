"""Cumulative quadrature for uniformly sampled signals, usable on-line.

The algebraic estimate is exact in continuous time, but ``det P(t)`` grows from zero
like a high power of ``t``, so at early times the estimate amplifies the error of the
numerical integrals enormously.  The plain trapezoid (order 2) needs about half a second
at 1 kHz to bring the paper's system within 0.1 %; the Adams-Moulton rules below reach
the same accuracy within a few samples.

Rule of ``q`` points (``order=q``, the default 6): the integral over
``[t[n-1], t[n]]`` is that of the polynomial interpolating ``y[n-q+1], ..., y[n]``, so it
uses the current and past samples only (causal).  For the first ``q - 2`` intervals
there are not enough past samples; they use the polynomial through ``y[0], ...,
y[q-1]`` instead.  That start-up is the only look-ahead: every value from sample
``q - 1`` on is causal, and an on-line estimator reports its first value once sample
``q - 1`` has arrived (:data:`startup_samples`).  ``order=2`` is the trapezoid rule.

The rules are exact for polynomials of degree ``q - 1``; the error of the cumulative
integral of a smooth signal is ``O(h**q)``.
"""

from __future__ import annotations

from fractions import Fraction
from functools import lru_cache

import numpy as np

__all__ = ["cumulative_integral", "iterated_integrals", "startup_samples", "rule_weights",
           "QUADRATURE_ORDERS"]

#: Orders (number of points of the rule) that are offered.
QUADRATURE_ORDERS = (2, 3, 4, 5, 6, 7, 8)


def _check_order(order):
    if order not in QUADRATURE_ORDERS:
        raise ValueError(f"quadrature order {order!r} is not one of {QUADRATURE_ORDERS}")


def startup_samples(order: int) -> int:
    """Number of samples the rule of ``order`` points needs before it is causal.

    The estimate at sample ``n`` can be reported once sample ``max(n, order - 1)`` has
    arrived; samples ``0 .. order - 2`` are the start-up.
    """
    _check_order(order)
    return order - 1


def _poly_mul(a, b):
    out = [Fraction(0)] * (len(a) + len(b) - 1)
    for i, ai in enumerate(a):
        for j, bj in enumerate(b):
            out[i + j] += ai * bj
    return out


@lru_cache(maxsize=None)
def _interval_weights(nodes: tuple, lo: int, hi: int) -> tuple:
    """Exact weights ``w`` with ``int_lo^hi p(u) du = sum w_i p(nodes_i)`` for polynomials
    ``p`` of degree ``len(nodes) - 1`` (integration of the Lagrange basis)."""
    weights = []
    for i, ui in enumerate(nodes):
        poly = [Fraction(1)]  # coefficients, lowest degree first
        for j, uj in enumerate(nodes):
            if j != i:
                poly = _poly_mul(poly, [Fraction(-uj, ui - uj), Fraction(1, ui - uj)])
        weights.append(sum(c * (Fraction(hi) ** (d + 1) - Fraction(lo) ** (d + 1)) / (d + 1)
                           for d, c in enumerate(poly)))
    return tuple(weights)


def rule_weights(order: int):
    """Weights of the rule of ``order`` points, in units of the step ``h``.

    Returns
    -------
    regular : ndarray, shape (order,)
        ``int_{t[n-1]}^{t[n]} y = h * regular @ y[n-order+1 : n+1]`` for ``n >= order - 1``.
    startup : ndarray, shape (order - 2, order)
        Row ``j - 1`` integrates over ``[t[j-1], t[j]]`` from ``y[0 : order]``, for
        ``j = 1 .. order - 2``.
    """
    _check_order(order)
    nodes = tuple(range(order))
    regular = np.array([float(w) for w in _interval_weights(nodes, order - 2, order - 1)])
    startup = np.array([[float(w) for w in _interval_weights(nodes, j - 1, j)]
                        for j in range(1, order - 1)]).reshape(order - 2, order)
    return regular, startup


def cumulative_integral(y, h: float, *, order: int = 6) -> np.ndarray:
    """Cumulative integral ``I[n] = int_{t[0]}^{t[n]} y``, with ``I[0] = 0``.

    Parameters
    ----------
    y : array_like, shape (n,)
        Samples on a uniform grid of step ``h``; ``n >= order``.
    h : float
        Sampling step.
    order : int, optional
        Number of points of the rule (2 = trapezoid).  Default 6.

    Returns
    -------
    ndarray, shape (n,)
    """
    y = np.asarray(y, dtype=float)
    n = y.shape[-1]
    regular, startup = rule_weights(order)
    if n < order:
        raise ValueError(f"{n} samples are too few for a rule of {order} points")
    increments = np.empty(n - 1)
    # increments[j-1] is the integral over [t[j-1], t[j]].
    increments[order - 2:] = np.correlate(y, regular, mode="valid")
    if order > 2:
        increments[: order - 2] = startup @ y[:order]
    out = np.empty(n)
    out[0] = 0.0
    np.cumsum(increments, out=out[1:])
    out[1:] *= h
    return out


def iterated_integrals(y, h: float, depth: int, *, order: int = 6) -> list:
    """``[y, int y, int int y, ...]``: the iterated integrals of ``y`` up to ``depth``.

    Each level integrates the previous one with :func:`cumulative_integral`, as the
    integrator chain of the time-varying state-space realisation does.
    """
    levels = [np.asarray(y, dtype=float)]
    for _ in range(depth):
        levels.append(cumulative_integral(levels[-1], h, order=order))
    return levels
