"""Times at which a velocity inside ``sign()`` changes sign, from the position itself.

In a model such as ``M*q'' + Fv*q' + Fc*sign(q') + off = F`` the factor ``sign(q')``
needs the times at which ``q'`` crosses zero.  The numerical derivative of ``q``
(:func:`algid.signals.algebraic_derivative`) is a weighted average of ``q'`` over its
window, and at a crossing ``q'`` has a kink (the Coulomb term flips, so ``q''`` jumps by
``J = -2 Fc / M``): the average crosses zero late, by the same sign at every crossing,
which biases ``M``.  A shorter window shrinks the shift and multiplies the noise.

So the position itself is fitted around each crossing with the motion the model gives
it there.  Written ``L q'' + a q' + S sign(q') + sum_k w_k z_k = 0`` (:func:`crossing_motion`),
near a crossing at ``tc`` the model says

    q(t) = c0 (1 + (a/L) s) + int_tc^t int_tc^tau g - (a/L) int_tc^t q + (J/4) sign(s) s^2,

with ``s = t - tc``, ``g = -sum_k w_k z_k / L`` the forcing from the measured signals and
``J = -2 S / L`` (:func:`crossing_jumps`), all from an estimate of the parameters.  For
a given ``tc`` this is linear in ``c0``; ``tc`` minimises the residual sum of squares
(coarse and fine grids, then a parabola).  Without forcing, or where the mass sticks
(``|g(tc)| <= |J| / 2``), a stationary point whose curvature jumps by ``J`` is fitted
instead.  A crossing is refined only where the fit can describe it (:data:`FIT_HALF_WIDTH`
samples clear of the ends and of other sign changes, the best time within
:data:`SEARCH_SPAN`, an acceleration that agrees with the crossing's direction);
:func:`refine_crossings` also gives how each time moves with the position samples, which
the covariance of the estimate carries.

The user guide, "How identify works", has the derivation and the fallbacks in full.
"""

from __future__ import annotations

import numpy as np

from algid.identification._window_kernels import sign_changes, sign_samples
from algid.models._expression import Call, Power, Product, Signal, Sum
from algid.signals._differentiation import DEFAULT_WINDOW_STEPS

__all__ = ["refine_crossings", "crossing_jumps", "crossing_motion", "sign_factor", "term_weight",
           "FIT_HALF_WIDTH", "SEARCH_SPAN"]

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


def term_weight(term, values):
    """A term's coefficient times its parameter's value (1 for a known term).

    Parameters
    ----------
    term : Term
    values : mapping
        Parameter name -> value.

    Returns
    -------
    float
    """
    return term.coefficient * (1.0 if term.parameter is None
                               else float(values[term.parameter]))


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

    leading = sum(term_weight(term, values) for term in model.terms
                  if term.factor == plain and term.derivative == 2)
    coulomb = sum(term_weight(term, values) for term, _ in discontinuous)
    jump = -2.0 * coulomb / leading if leading != 0 else np.nan
    return {factor: jump} if np.isfinite(jump) else {}


def crossing_motion(model, values, signals, t):
    """The model's acceleration of its output, without the ``q'`` and ``sign(q')`` terms.

    For a model accepted by :func:`crossing_jumps`, written ``L q'' + a q' + S sign(q')
    + sum_k w_k z_k = 0`` (every other term without a derivative), this gives the
    samples of ``-sum_k w_k z_k / L`` and ``a / L``: near a crossing the output then
    moves as ``q'' = forcing - (a / L) q' - (S / L) sign(q')``, whatever drives it (a
    feedback loop acts through the measured force).

    Parameters
    ----------
    model : Model
        The model, of the form :func:`crossing_jumps` accepts.
    values : mapping
        Parameter name -> value (the previous estimate).
    signals : mapping
        Signal name (or ``(name, k)`` for a derivative estimate) -> samples.
    t : array_like
        Sample times.

    Returns
    -------
    tuple of (numpy.ndarray, float) or None
        ``(forcing, damping)``; None when the model is not of that form.
    """
    jumps = crossing_jumps(model, values)
    if not jumps:
        return None
    (factor, _), = jumps.items()
    plain = Signal(model.output)

    leading = damping = 0.0
    forcing = np.zeros(len(t))
    for term in model.terms:
        if term.factor == plain and term.derivative in (1, 2):
            if term.derivative == 2:
                leading += term_weight(term, values)
            else:
                damping += term_weight(term, values)
        elif term.derivative != 0:
            return None
        elif term.factor != factor:
            samples = np.asarray(term.factor.evaluate(signals, t), dtype=float)
            forcing -= term_weight(term, values) * samples
    return forcing / leading, damping / leading


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
    return np.einsum("gi,gi->g", residual, residual), coef, residual


def _refine_one(residuals, guess, upwards, scale):
    """Refined crossing time near ``guess``, or None where the fit cannot place it.

    ``residuals(times)`` gives the residual sums of squares of the local fit at every
    candidate time, the acceleration just before each and the residuals themselves."""
    coarse = guess + np.arange(-SEARCH_SPAN, SEARCH_SPAN + _COARSE / 2, _COARSE) * scale
    rss = residuals(coarse)[0]
    m = int(np.argmin(rss))
    if m == 0 or m == len(coarse) - 1:
        return None   # the best time is at the edge of the search: no clear minimum
    times = coarse[m] + np.linspace(-_COARSE, _COARSE, _FINE) * scale
    rss = residuals(times)[0]
    m = min(max(int(np.argmin(rss)), 1), _FINE - 2)
    below, at, above = rss[m - 1:m + 2]
    curvature = below - 2.0 * at + above
    if not curvature > 0:
        return None
    spacing = times[1] - times[0]
    best = times[m] + np.clip(0.5 * (below - above) / curvature, -1.0, 1.0) * spacing
    before = residuals(np.array([best]))[1]
    # the acceleration just before the crossing must point the way the velocity crosses
    # (after it, near sticking, it may be about zero or even point back a little)
    if not (before[0] > 0 if upwards else before[0] < 0):
        return None
    return float(best)


def _motion_residuals(position, t, jump, forcing, damping):
    """Residual function of the fit by the model's own motion (see the module notes).

    The running integrals are those of cubic Hermite interpolants (with the samples'
    ``numpy.gradient`` as slopes for the forcing and the position; the trapezoid rule
    with its end correction), and are interpolated at ``tc`` the same way."""
    from scipy.interpolate import CubicHermiteSpline

    forced = CubicHermiteSpline(t, forcing, np.gradient(forcing, t)).antiderivative()(t)
    once = CubicHermiteSpline(t, forced, forcing)           # int g
    twice = once.antiderivative()(t)
    twice_at = CubicHermiteSpline(t, twice, forced)        # int int g
    moved = CubicHermiteSpline(t, position, np.gradient(position, t)).antiderivative()(t)
    moved_at = CubicHermiteSpline(t, moved, position)      # int q

    def residuals(times):
        s = t[None, :] - times[:, None]
        target = (position[None, :]
                  - (twice[None, :] - twice_at(times)[:, None] - once(times)[:, None] * s)
                  + damping * (moved[None, :] - moved_at(times)[:, None])
                  - 0.25 * jump * np.sign(s) * s ** 2)
        basis = 1.0 + damping * s
        c0 = np.einsum("gi,gi->g", basis, target) / np.einsum("gi,gi->g", basis, basis)
        residual = target - c0[:, None] * basis
        before = np.interp(times, t, forcing) - 0.5 * jump
        return np.einsum("gi,gi->g", residual, residual), before, residual

    return residuals


def _polynomial_residuals(position, t, jump, scale):
    """Residual function of the kinked stationary-point polynomial fit."""
    def residuals(times):
        rss, coef, residual = _residuals(position, t, times, jump, scale)
        return rss, 2.0 * coef[:, 1] / scale ** 2, residual
    return residuals


def _time_sensitivity(residuals, best, scale):
    """Derivative of the refined time with respect to each fitted sample.

    The time minimises the residual sum of squares ``R(tc, q)``, so ``dR/dtc = 0`` and
    ``dtc/dq = -(d2R/dtc dq) / (d2R/dtc2)``, with ``dR/dq = 2 r`` (the residuals): exact
    for the polynomial fit; the motion fit's other terms that read the position (its
    ``q'`` term: a few per cent on the friction loop) are left out."""
    delta = 0.01 * scale
    rss, _, r = residuals(best + np.array([-delta, 0.0, delta]))
    curvature = (rss[0] - 2.0 * rss[1] + rss[2]) / delta ** 2
    return -(r[2] - r[0]) / (delta * curvature)


def refine_crossings(position, t, velocity, jump, half_width=FIT_HALF_WIDTH, *,
                     forcing=None, damping=0.0, sensitivity=False):
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
    forcing : array_like, optional
        The model's acceleration without its ``q'`` and ``sign(q')`` terms, at the
        same times (:func:`crossing_motion`).  When given, each crossing is fitted by
        the model's own motion through it; otherwise by the kinked polynomial.
    damping : float
        Coefficient of ``q'`` in the model's acceleration, with the sign that slows it
        (``Fv / M`` for ``M*q'' + Fv*q' + ...``); used with ``forcing``.
    sensitivity : bool
        Also return, per crossing, how its time moves with the position samples.

    Returns
    -------
    times : numpy.ndarray
        One time per change of sign of ``velocity`` (in order): the refined time, or
        where a crossing cannot be refined, the zero of ``velocity`` interpolated
        linearly between its two samples.
    sensitivities : list
        With ``sensitivity=True``: per crossing, ``(first, weights)``, the derivative
        of its time with respect to the samples ``first, first + 1, ...`` of
        ``position`` (to first order in their noise), or None where it was not refined.
    """
    q = np.asarray(position, dtype=float)
    t = np.asarray(t, dtype=float)
    v = np.asarray(velocity, dtype=float)
    if forcing is not None:
        forcing = np.asarray(forcing, dtype=float) * np.ones(len(t))
    z = np.sign(v)
    index, fraction = sign_changes(v)
    times = t[index] + fraction * (t[index + 1] - t[index])
    sensitivities = [None] * index.size
    if index.size == 0:
        return (times, sensitivities) if sensitivity else times
    gaps = np.diff(index)
    isolated = np.ones(index.size, dtype=bool)
    isolated[1:] &= gaps > 2 * half_width
    isolated[:-1] &= gaps > 2 * half_width
    inside = (index - half_width + 1 >= 0) & (index + half_width < len(t))
    for j in np.flatnonzero(isolated & inside):
        window = slice(index[j] - half_width + 1, index[j] + half_width + 1)
        tw = t[window]
        upwards = z[index[j] + 1] > 0
        signed = jump if upwards else -jump
        scale = float(np.median(np.diff(tw)))
        refined = None
        if forcing is not None:
            residuals = _motion_residuals(q[window] - q[index[j]], tw, signed,
                                          forcing[window], damping)
            refined = _refine_one(residuals, times[j], upwards, scale)
            # where the forcing cannot overcome the Coulomb term, the model has the mass
            # stick at the crossing: a motion the fit by the model's does not describe
            if refined is not None and not \
                    abs(np.interp(refined, t, forcing)) > abs(jump) / 2:
                refined = None
        if refined is None:
            residuals = _polynomial_residuals(q[window] - q[index[j]], tw, signed, scale)
            refined = _refine_one(residuals, times[j], upwards, scale)
        if refined is not None:
            times[j] = refined
            if sensitivity:
                sensitivities[j] = (window.start,
                                    _time_sensitivity(residuals, refined, scale))
    return (times, sensitivities) if sensitivity else times


def sign_factor(argument, t, *, position=None, jump=None, motion=None):
    """Samples and steps of ``sign(v)`` for the window integrals of :func:`algid.identify`.

    Parameters
    ----------
    argument : array_like
        Samples of ``v`` (an estimate of ``q'``).
    t : array_like
        Their times.
    position : array_like, optional
        Samples of ``q``: when given (with ``jump``), the steps are placed at the
        crossings refined by :func:`refine_crossings`, else where linear interpolation
        of ``v`` puts them.
    jump : float, optional
        As in :func:`refine_crossings`.
    motion : tuple, optional
        ``(forcing, damping)`` from :func:`crossing_motion`: the refinement fits the
        model's motion (else the kinked polynomial).

    Returns
    -------
    samples : numpy.ndarray
        :func:`algid.identification._window_kernels.sign_samples` at the steps.
    steps : tuple or None
        ``(first value, step times, step sizes)`` for
        :func:`algid.identification._window_kernels.step_window_integrals`; None where a sample of
        ``v`` is exactly zero (the trapezoid sum of the samples is used there).
    crossings : list
        Per refined crossing, ``(time, step size, first sample of the fit, derivative of
        the time with respect to the fitted samples of q)``.
    """
    t = np.asarray(t, dtype=float)
    v = np.asarray(argument, dtype=float) * np.ones(len(t))
    index, fraction = sign_changes(v)
    sizes = np.sign(v[index + 1]) - np.sign(v[index])
    times, refined = t[index] + fraction * np.diff(t)[index], []
    if position is not None and jump is not None:
        forcing, damping = motion if motion else (None, 0.0)
        times, moves = refine_crossings(position, t, v, jump, forcing=forcing,
                                        damping=damping, sensitivity=True)
        refined = [(tc, size, *move) for tc, size, move in zip(times, sizes, moves)
                   if move is not None]
        samples = sign_samples(v, t, times)
    else:
        samples = sign_samples(v, t)
    steps = (np.sign(v[0]), times, sizes) if np.all(v != 0) else None
    return samples, steps, refined
