"""Times at which a velocity inside ``sign()`` changes sign, from the position itself.

In a model such as ``M*q'' + Fv*q' + Fc*sign(q') + off = F`` the factor ``sign(q')``
needs the times at which ``q'`` crosses zero.  The numerical derivative of ``q``
(:func:`algid.differentiation.algebraic_derivative`) is a weighted average of ``q'``
over its window, and at a crossing ``q'`` has a kink: the Coulomb term flips, so ``q''``
jumps by ``J = -2 Fc / M`` (upwards crossing).  The average of a kinked function is not
zero where the function is: on the synthetic friction loop (1 kHz, a 20-sample window)
every crossing of the estimate came 0.1-0.6 ms late (0.37 ms on average), a shift of
the same sign at every crossing that biased ``M`` by 3 standard errors.  A shorter
window shrinks the shift and multiplies the noise.

The refinement fits the position itself around each crossing with the shape it has
there: a stationary point at ``tc`` whose curvature jumps by the known ``J``,

    q(t) = c0 + c2 s^2 + c3 s^3 + (J / 2) max(s, 0)^2,   s = t - tc,

linear in ``c0, c2, c3`` for a given ``tc``, and ``tc`` minimises the residual sum of
squares (a coarse and a fine grid around the first guess, then a parabola through the
best three points).  ``J`` comes from the model and a first estimate of its parameters
(:func:`crossing_jumps`): fitted from the data instead (the median of free fits over
the crossings) it was 3 % off under 1 um noise, an error that moves every crossing the
same way and scattered the offset twice as much.  Measured on the synthetic
friction loop: the mean crossing error falls from 0.37 ms to -0.014 ms, and under
1 um position noise the crossings scatter less than those of the differentiator
(0.010 ms against 0.018 ms per crossing).

A crossing is refined only where the fit can describe it: at least
:data:`FIT_HALF_WIDTH` samples from the record's ends and from any other change of
sign of the estimate (a slow or chattering crossing keeps its first guess), with the
best time inside the searched interval (:data:`SEARCH_SPAN`), and an acceleration
before it that agrees with the direction of the crossing.  On the friction loop with
three times its Coulomb force (crossings close to sticking, the differentiator up to
3.7 ms late), the relative errors of ``M, Fv, Fc, off`` on the noise-free record
fall from ``5.7e-3, 4.2e-3, 3.0e-3, 2.0e-2`` to ``1.5e-4, 3.4e-4, 1.6e-4, 2.3e-3``.
"""

from __future__ import annotations

import numpy as np

from algid.differentiation import DEFAULT_WINDOW_STEPS
from algid.expression import Call, Power, Product, Signal, Sum
from algid.window_kernels import sign_changes

__all__ = ["refine_crossings", "crossing_jumps", "FIT_HALF_WIDTH", "SEARCH_SPAN"]

#: Samples on each side of a crossing that the local fit of the position uses (on the
#: friction loop, 15 scatter the crossings 1.6 times as much, 25 shift them twice as far
#: through the terms the cubic leaves out).
FIT_HALF_WIDTH = 20

#: The refined time is searched within this many samples of the first guess: half the
#: differentiator's window, the farthest a zero of its estimate can be from the true one
#: (an average over the window has the sign of the velocity once the whole window is on
#: one side of the crossing).
SEARCH_SPAN = DEFAULT_WINDOW_STEPS / 2

#: Spacing (samples) of the coarse search grid, and points of the fine one around its
#: best point (whose minimum is then refined by a parabola).
_COARSE = 0.5
_FINE = 21


def _sign_calls(expr):
    """Every ``sign(...)`` call inside an expression."""
    if isinstance(expr, Call):
        found = [expr] if expr.function == "sign" else []
        return found + [c for a in expr.args for c in _sign_calls(a)]
    children = {Sum: "terms", Product: "factors"}.get(type(expr))
    if children is not None:
        return [c for e in getattr(expr, children) for c in _sign_calls(e)]
    if isinstance(expr, Power):
        return _sign_calls(expr.base)
    return []


def crossing_jumps(model, values):
    """Jump of the output's second derivative where ``sign(output')`` steps up.

    For a model of second order in its output ``q`` whose only discontinuous factor is
    ``sign(q')`` (in terms without a derivative), the equation gives, where ``q'``
    crosses zero upwards (the factor steps from -1 to +1), the jump
    ``-2 S / L`` of ``q''``: ``S`` the sum of the sign terms' coefficients, ``L`` that
    of the ``q''`` terms (each coefficient times its parameter's value).

    Parameters
    ----------
    model : Model
        The model.
    values : mapping
        Parameter name -> value (a first estimate).

    Returns
    -------
    dict
        ``{sign factor: jump}``; empty when the model is not of that form.
    """
    output = model.output
    plain = Signal(output)
    discontinuous = [(term, calls) for term in model.terms
                     if (calls := _sign_calls(term.factor))]
    factors = {term.factor for term, _ in discontinuous}
    if len(factors) != 1:
        return {}
    factor = factors.pop()
    if not (isinstance(factor, Call) and factor.function == "sign"
            and factor.args[0] == Signal(output, 1)
            and all(term.derivative == 0 and calls == [factor]
                    for term, calls in discontinuous)):
        return {}
    orders = [term.derivative for term in model.terms if term.factor == plain]
    if max(orders, default=0) != 2:
        return {}

    def weight(term):
        return term.coefficient * (1.0 if term.parameter is None
                                   else float(values[term.parameter]))

    leading = sum(weight(term) for term in model.terms
                  if term.factor == plain and term.derivative == 2)
    coulomb = sum(weight(term) for term, _ in discontinuous)
    jump = -2.0 * coulomb / leading if leading != 0 else np.nan
    return {factor: jump} if np.isfinite(jump) else {}


def _residuals(position, t, times, jump, scale):
    """Residual sums of squares of the kinked stationary-point fit at every time in
    ``times`` (the samples ``position`` at ``t``, offsets in units of ``scale``)."""
    s = (t[None, :] - times[:, None]) / scale
    target = position[None, :] - 0.5 * jump * scale ** 2 * np.maximum(s, 0.0) ** 2
    basis = np.stack([np.ones_like(s), s ** 2, s ** 3], axis=-1)
    normal = np.einsum("gik,gil->gkl", basis, basis)
    right = np.einsum("gik,gi->gk", basis, target)
    coef = np.linalg.solve(normal, right[..., None])[..., 0]
    residual = target - np.einsum("gik,gk->gi", basis, coef)
    return np.einsum("gi,gi->g", residual, residual), coef


def _refine_one(position, t, guess, jump, upwards, scale):
    """Refined crossing time near ``guess``, or None where the fit cannot place it."""
    coarse = guess + np.arange(-SEARCH_SPAN, SEARCH_SPAN + _COARSE / 2, _COARSE) * scale
    rss, _ = _residuals(position, t, coarse, jump, scale)
    m = int(np.argmin(rss))
    if m == 0 or m == len(coarse) - 1:
        return None   # the best time is at the edge of the search: no clear minimum
    times = coarse[m] + np.linspace(-_COARSE, _COARSE, _FINE) * scale
    rss, _ = _residuals(position, t, times, jump, scale)
    m = min(max(int(np.argmin(rss)), 1), _FINE - 2)
    below, at, above = rss[m - 1:m + 2]
    curvature = below - 2.0 * at + above
    if not curvature > 0:
        return None
    spacing = times[1] - times[0]
    best = times[m] + np.clip(0.5 * (below - above) / curvature, -1.0, 1.0) * spacing
    _, coef = _residuals(position, t, np.array([best]), jump, scale)
    # the acceleration just before the crossing must point the way the velocity crosses
    # (after it, near sticking, it may be about zero or even point back a little)
    before = 2.0 * coef[0, 1] / scale ** 2
    if not (before > 0 if upwards else before < 0):
        return None
    return float(best)


def refine_crossings(position, t, velocity, jump, half_width=FIT_HALF_WIDTH):
    """Times at which the velocity changes sign, refined by fits of the position.

    Parameters
    ----------
    position : array_like
        Samples of ``q``.
    t : array_like
        Their (increasing) times.
    velocity : array_like
        An estimate of ``q'`` at the same times (its changes of sign are the crossings).
    jump : float
        Jump of ``q''`` at an upwards crossing (:func:`crossing_jumps`); the opposite
        at a downwards one.
    half_width : int
        Samples on each side of a crossing used by its fit.

    Returns
    -------
    numpy.ndarray
        One time per change of sign of ``velocity`` (in order): the refined time, or
        where a crossing cannot be refined, the zero of ``velocity`` interpolated
        linearly between its two samples.
    """
    q = np.asarray(position, dtype=float)
    t = np.asarray(t, dtype=float)
    v = np.asarray(velocity, dtype=float)
    z = np.sign(v)
    index, fraction = sign_changes(v)
    times = t[index] + fraction * (t[index + 1] - t[index])
    if index.size == 0:
        return times
    gaps = np.diff(index)
    isolated = np.ones(index.size, dtype=bool)
    isolated[1:] &= gaps > 2 * half_width
    isolated[:-1] &= gaps > 2 * half_width
    inside = (index - half_width + 1 >= 0) & (index + half_width < len(t))
    for j in np.flatnonzero(isolated & inside):
        window = slice(index[j] - half_width + 1, index[j] + half_width + 1)
        tw = t[window]
        upwards = z[index[j] + 1] > 0
        refined = _refine_one(q[window] - q[index[j]], tw, times[j],
                              jump if upwards else -jump, upwards,
                              float(np.median(np.diff(tw))))
        if refined is not None:
            times[j] = refined
    return times
