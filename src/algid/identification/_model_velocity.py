"""The velocity a friction model gives its output, driven by the measured signals.

A model ``L q'' + a q' + S sign(q') + sum_k w_k z_k = 0`` (every other term without a
derivative: inputs, offsets, springs of ``q`` itself) is, for its velocity ``v = q'``,
the first-order equation

    v' = g(t) - alpha v - c sign(v),   g = -sum_k w_k z_k / L,  alpha = a / L,  c = S / L,

whose forcing ``g`` comes from the measured signals and an estimate of the parameters.
With ``alpha >= 0`` and ``c > 0`` it forgets its initial velocity, so it gives, without
differentiating the noisy position, where the velocity crosses zero and where the mass
sticks: where ``v`` reaches zero and ``|g| <= c``, the Coulomb force holds it
(Filippov's solution, ``v = 0``), until ``|g|`` exceeds ``c``.  While it sticks, the
model's ``S sign(q')`` is the force that holds it, ``-L g``: the *effective sign*
``g / c``, in ``[-1, 1]``; with it the equation holds on the stuck stretches too.

:func:`simulate_velocity` integrates it exactly for a forcing linear between the
samples, moved to have the smooth forcing's interval means (each sample interval in
closed form, the crossings by regula falsi on that form, the releases where the linear
forcing reaches ``c``), and returns the effective sign as steps (``sign(v)``, zero
where the mass sticks) and samples of the rest, whose trapezoid sums integrate it
exactly over every interval.  :func:`velocity_equation` reads ``g``, ``alpha`` and
``c`` from a model and an estimate; :func:`initial_velocity` fits the start to the
position; :func:`settle_crossings` finds the estimate that places its own steps.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from algid.errors import InputDataError, ModelError
from algid.identification._sign_crossings import crossing_jumps, crossing_motion, term_weight
from algid.models._expression import Signal

__all__ = ["VelocityPath", "SettledFit", "simulate_velocity", "velocity_equation",
           "has_velocity",
           "initial_velocity", "settle_crossings", "BLOCK", "START_SAMPLES",
           "FIXED_POINT_ITERATIONS", "COULOMB_STARTS", "PICARD_GAP",
           "FIXED_POINT_TOLERANCE", "JACOBIAN_STEP",
           "JACOBIAN_REUSE"]

#: Samples of the sliding motion advanced at once between two events (the recursion is
#: vectorized over a block; an event ends it early).
BLOCK = 512

#: Samples fitted at least by :func:`initial_velocity`.
START_SAMPLES = 64

#: A block's span times ``alpha`` stays below this (the recursion's factors stay in range).
_DECAY_SPAN = 30.0


class VelocityPath(NamedTuple):
    """The model's velocity on one record segment (:func:`simulate_velocity`).

    The effective sign is ``steps`` (``sign(v)``, zero where the mass sticks: a step
    function, integrated exactly) plus ``rest`` (``g / c`` where it sticks, else zero).
    """

    velocity: np.ndarray    # v at the samples
    sign: np.ndarray        # the effective sign, as trapezoid-exact samples
    steps: tuple            # (value at t[0], step times, step sizes) of sign(v)
    rest: np.ndarray        # the stuck stretches' g / c, as trapezoid-exact samples
    crossings: np.ndarray   # times at which v changes sign without sticking
    stuck: list             # (start, end) of every stretch where the mass sticks


def velocity_equation(model, values, signals, t):
    """Forcing, damping and Coulomb level of a friction model's velocity equation.

    Parameters
    ----------
    model : Model
        A model accepted by :func:`algid.identification._sign_crossings.crossing_jumps`.
    values : mapping
        Parameter name -> value (an estimate).
    signals : mapping
        Signal name -> samples (the measured records).
    t : array_like
        Sample times.

    Returns
    -------
    tuple of (numpy.ndarray, float, float) or None
        ``(g, alpha, c)`` as in the module notes, or None where the model is not of
        that form or its estimate has no stable, dissipative velocity (``alpha < 0``
        or ``c <= 0``, or not finite) or one that forgets its start within a sample.
    """
    jumps = crossing_jumps(model, values)
    motion = crossing_motion(model, values, signals, t)
    if not jumps or motion is None:
        return None
    forcing, alpha = motion
    coulomb = -0.5 * next(iter(jumps.values()))
    steps = np.diff(np.asarray(t, dtype=float))
    if not (np.isfinite(alpha) and 0 <= alpha * np.max(steps, initial=0.0) <= _DECAY_SPAN
            and np.isfinite(coulomb) and coulomb > 0 and np.all(np.isfinite(forcing))):
        return None   # (nor one that forgets its start within a sample)
    return np.asarray(forcing, dtype=float), float(alpha), float(coulomb)


def _coefficients(h, alpha):
    """``(e, b0, b1, bc)`` of the exact step ``v1 = e v0 + b0 g0 + b1 g1 - bc c s`` over
    intervals ``h`` with a forcing linear from ``g0`` to ``g1``."""
    x = alpha * h
    small = x < 1e-3
    xs = np.where(small, 1.0, x)
    e = np.exp(-x)
    lost = -np.expm1(-xs) / xs                                    # (1 - e) / x
    late = (xs + np.expm1(-xs)) / xs ** 2                         # (x - 1 + e) / x**2
    lost = np.where(small, 1 - x / 2 + x ** 2 / 6 - x ** 3 / 24, lost)
    late = np.where(small, 0.5 - x / 6 + x ** 2 / 24 - x ** 3 / 120, late)
    return e, h * (lost - late), h * late, h * lost


def _scalar_coefficients(h, alpha):
    """:func:`_coefficients` of one interval, in floats."""
    x = alpha * h
    if x < 1e-3:
        lost = 1 - x / 2 + x * x / 6 - x ** 3 / 24
        late = 0.5 - x / 6 + x * x / 24 - x ** 3 / 120
    else:
        lost = -math.expm1(-x) / x
        late = (x + math.expm1(-x)) / (x * x)
    return math.exp(-x), h * (lost - late), h * late, h * lost


def _advance(v0, g0, g1, h, alpha, c, s, tau):
    """``v`` at ``tau`` into an interval of length ``h`` (forcing from ``g0`` to ``g1``
    over it) sliding with sign ``s`` from ``v0``."""
    g_tau = g0 + (g1 - g0) * (tau / h if h > 0 else 0.0)
    e, b0, b1, bc = _scalar_coefficients(tau, alpha)
    return e * v0 + b0 * g0 + b1 * g_tau - bc * c * s


def _crossing(v0, g0, g1, h, alpha, c, s):
    """Where in ``(0, h]`` the sliding velocity from ``v0`` (sign ``s``) first reaches
    zero (it changes sign at ``h``): regula falsi (Illinois) on its closed form."""
    lo, hi = 0.0, h
    f_lo, f_hi = s * v0, s * _advance(v0, g0, g1, h, alpha, c, s, h)
    if f_lo <= 0:
        return 0.0
    side = 0
    for _ in range(100):
        mid = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
        if not lo < mid < hi:
            mid = 0.5 * (lo + hi)
        f_mid = s * _advance(v0, g0, g1, h, alpha, c, s, mid)
        if f_mid > 0:
            lo, f_lo = mid, f_mid
            if side == 1:
                f_hi /= 2
            side = 1
        else:
            hi, f_hi = mid, f_mid
            if side == -1:
                f_lo /= 2
            side = -1
        if hi - lo <= 1e-13 * h or f_mid == 0:
            break
    return mid


def _release(g0, g1, h, c, start):
    """The first time in ``[start, h]`` of an interval at which ``|g| > c`` (the forcing
    linear from ``g0`` to ``g1``), or None."""
    g_start = g0 + (g1 - g0) * start / h
    if abs(g_start) > c:
        return start
    if abs(g1) <= c:
        return None
    level = c if g1 > 0 else -c
    return start + (h - start) * (level - g_start) / (g1 - g_start)


class _Pieces:
    """The effective sign over every sample interval that holds an event: its exact
    integral, to correct the trapezoid sum of the samples there."""

    def __init__(self):
        self.intervals = {}   # interval -> list of (from, to, regime) in its own time

    def add(self, k, start, end, regime):
        if end > start:
            self.intervals.setdefault(k, []).append((start, end, regime))


def simulate_velocity(t, forcing, alpha, c, v0=0.0):
    """The velocity of ``v' = g - alpha v - c sign(v)`` with sticking, and its effective
    sign.

    Parameters
    ----------
    t : array_like
        Increasing sample times of one segment.
    forcing : array_like
        ``g`` at those times (linear between them, after :func:`_interval_means`).
    alpha : float
        Damping, ``>= 0``.
    c : float
        Coulomb level, ``> 0``.
    v0 : float
        Velocity at ``t[0]``.

    Returns
    -------
    VelocityPath
        ``sign`` holds ``sign(v)`` where the mass slides and ``g / c`` where it sticks,
        each sample moved where an interval holds an event so that the trapezoid sum
        over that interval is the exact integral of the effective sign.
    """
    t = np.asarray(t, dtype=float)
    g = _interval_means(t, np.asarray(forcing, dtype=float) * np.ones(t.size))
    n = t.size
    h = np.diff(t)
    v = np.zeros(n)
    regime = np.zeros(n)          # +1 / -1 sliding, 0 stuck (at every sample)
    crossings, stuck = [], []
    pieces = _Pieces()
    i, x = 0, float(v0)
    if x != 0:
        s = 1.0 if x > 0 else -1.0
    elif abs(g[0]) > c:
        s = 1.0 if g[0] > 0 else -1.0
    else:
        s = 0.0
    stuck_from = t[0] if s == 0 else None
    v[0], regime[0] = x, s
    first, step_times, step_sizes = s, [], []
    while i < n - 1:
        if s == 0:   # stuck at sample i: the first interval where |g| exceeds c
            free = np.flatnonzero(np.abs(g[i + 1:]) > c)
            if free.size == 0:
                regime[i + 1:] = 0.0
                v[i + 1:] = 0.0
                i = n - 1
                break
            k = i + int(free[0])          # released within [t_k, t_k+1]
            regime[i + 1:k + 1] = 0.0
            v[i + 1:k + 1] = 0.0
            tau = _release(g[k], g[k + 1], h[k], c, 0.0)
            s = 1.0 if g[k + 1] > 0 else -1.0
            stuck.append((stuck_from, t[k] + tau))
            stuck_from = None
            step_times.append(t[k] + tau)
            step_sizes.append(s)
            pieces.add(k, 0.0, tau, 0.0)
            pieces.add(k, tau, h[k], s)
            x = float(_advance(0.0, g[k] + (g[k + 1] - g[k]) * tau / h[k], g[k + 1],
                               h[k] - tau, alpha, c, s, h[k] - tau))
            if s * x <= 0:   # (round-off at a release on the interval's end)
                x = 0.0
            i = k + 1
            v[i], regime[i] = x, s
            continue
        # sliding with sign s from sample i: the recursion over a block
        stop = min(n - 1, i + BLOCK)
        if alpha > 0:
            span = np.searchsorted(t, t[i] + _DECAY_SPAN / alpha, side="right")
            stop = max(i + 1, min(stop, span - 1))
        e, b0, b1, bc = _coefficients(h[i:stop], alpha)
        u = b0 * g[i:stop] + b1 * g[i + 1:stop + 1] - bc * c * s
        decay = np.concatenate(([1.0], np.cumprod(e)))
        path = decay * (x + np.concatenate(([0.0], np.cumsum(u / decay[1:]))))
        out = np.flatnonzero(s * path[1:] <= 0)
        if out.size == 0:
            v[i + 1:stop + 1] = path[1:]
            regime[i + 1:stop + 1] = s
            x, i = float(path[-1]), stop
            continue
        k = i + int(out[0])               # v reaches zero within [t_k, t_k+1]
        v[i + 1:k + 1] = path[1:k - i + 1]
        regime[i + 1:k + 1] = s
        x = float(path[k - i])
        tau = _crossing(x, g[k], g[k + 1], h[k], alpha, c, s)
        pieces.add(k, 0.0, tau, s)
        g_tau = g[k] + (g[k + 1] - g[k]) * tau / h[k]
        step_times.append(t[k] + tau)
        if -s * g_tau > c:   # the forcing carries it through: a reversal
            step_sizes.append(-2 * s)
            s = -s
            crossings.append(t[k] + tau)
            pieces.add(k, tau, h[k], s)
            x = float(_advance(0.0, g_tau, g[k + 1], h[k] - tau, alpha, c, s, h[k] - tau))
            if s * x <= 0:
                x = 0.0
        else:                # it sticks; perhaps released within the same interval
            step_sizes.append(-s)
            stuck_from = t[k] + tau
            free = _release(g[k], g[k + 1], h[k], c, tau)
            if free is None:
                s, x = 0.0, 0.0
                pieces.add(k, tau, h[k], 0.0)
            else:
                pieces.add(k, tau, free, 0.0)
                s = 1.0 if g[k + 1] > 0 else -1.0
                stuck.append((stuck_from, t[k] + free))
                stuck_from = None
                step_times.append(t[k] + free)
                step_sizes.append(s)
                pieces.add(k, free, h[k], s)
                x = float(_advance(0.0, g[k] + (g[k + 1] - g[k]) * free / h[k], g[k + 1],
                                   h[k] - free, alpha, c, s, h[k] - free))
                if s * x <= 0:
                    x = 0.0
        i = k + 1
        v[i], regime[i] = x, s
    if stuck_from is not None:
        stuck.append((stuck_from, t[-1]))
    held = np.where(regime == 0, np.clip(g / c, -1.0, 1.0), 0.0)
    sign = held + regime
    _correct(sign, t, h, g, c, pieces, sliding=True)
    _correct(held, t, h, g, c, pieces, sliding=False)
    return VelocityPath(v, sign, (first, np.asarray(step_times), np.asarray(step_sizes)),
                        held, np.asarray(crossings), stuck)


def _interval_means(t, g):
    """Samples of ``g`` whose linear interpolant has the interval means of the smooth
    ``g`` to fourth order: the interpolant's mean over an interval misses
    ``-h**2 g'' / 12``, which the velocity integrates (on the noise-free friction loop,
    the offset's error 1.5e-5 without this, 1.8e-6 with it)."""
    if t.size < 3:
        return g
    h = np.diff(t)
    curvature = 2 * np.diff(np.diff(g) / h) / (h[:-1] + h[1:])
    out = g.copy()
    out[1:-1] -= h[:-1] * h[1:] * curvature / 12
    return out


def _correct(sign, t, h, g, c, pieces, sliding):
    """Move the two samples of every interval with an event so that its trapezoid sum
    is the exact integral over it (in place) of the effective sign, or with
    ``sliding=False`` of its part where the mass sticks."""
    if not pieces.intervals:
        return
    weight = np.empty(t.size)   # trapezoid weight of every sample
    weight[1:-1] = (h[:-1] + h[1:]) / 2
    weight[0], weight[-1] = h[0] / 2, h[-1] / 2
    defects = np.zeros(t.size - 1)
    for k, parts in pieces.intervals.items():
        exact = 0.0
        for start, end, regime in parts:
            if regime != 0:
                exact += regime * (end - start) if sliding else 0.0
            else:   # g / c, linear over the interval
                g_start = g[k] + (g[k + 1] - g[k]) * start / h[k]
                g_end = g[k] + (g[k + 1] - g[k]) * end / h[k]
                exact += 0.5 * (g_start + g_end) / c * (end - start)
        defects[k] = exact - 0.5 * h[k] * (sign[k] + sign[k + 1])
    ks = np.flatnonzero(defects)
    delta = defects[ks] / (weight[ks] + weight[ks + 1])
    np.add.at(sign, ks, delta)
    np.add.at(sign, ks + 1, delta)



#: Gauss-Newton iterations of :func:`initial_velocity`.
_START_ITERATIONS = 6


def initial_velocity(t, position, forcing, alpha, c, guess=None):
    """The velocity at ``t[0]`` whose motion best fits the measured position.

    The model's velocity forgets its start at the rate ``alpha`` (and at a sticking);
    until then the start matters.  It is fitted to the position samples of that
    stretch (at least :data:`START_SAMPLES`, at most three decay times), with an
    unknown position offset: a least-squares fit of the running integral of the
    velocity, by Gauss-Newton with a difference derivative (the position where the
    mass first sticks, say, moves with the start).

    Parameters
    ----------
    t, position, forcing : array_like
        The segment's times, measured position and the velocity equation's forcing.
    alpha, c : float
        As in :func:`simulate_velocity`.
    guess : float, optional
        The first guess (by default the slope of a parabola fitted to the first
        :data:`START_SAMPLES` samples).

    Returns
    -------
    float
    """
    t = np.asarray(t, dtype=float)
    q = np.asarray(position, dtype=float)
    g = np.asarray(forcing, dtype=float) * np.ones(t.size)
    end = t.size if alpha <= 0 else int(np.searchsorted(t, t[0] + 3.0 / alpha))
    end = min(t.size, max(end, START_SAMPLES))
    t, q, g = t[:end], q[:end], g[:end]
    if end < 3:
        return 0.0 if guess is None else float(guess)
    if guess is None:   # the slope of a parabola through the first samples
        first = min(end, START_SAMPLES)
        guess = np.polynomial.polynomial.polyfit(t[:first] - t[0], q[:first], 2)[1]
    v0 = float(guess)
    h = np.diff(t)

    def moved(start):   # the position the velocity from start gives, from zero
        v = simulate_velocity(t, g, alpha, c, start).velocity
        return np.concatenate(([0.0], np.cumsum(0.5 * h * (v[:-1] + v[1:]))))

    scale = max(float(np.max(np.abs(g))), c) * (t[-1] - t[0])
    for _ in range(_START_ITERATIONS):
        delta = 1e-3 * max(abs(v0), scale, 1e-300)
        base = moved(v0)
        basis = np.column_stack([np.ones(end), (moved(v0 + delta) - base) / delta])
        if not (np.all(np.isfinite(basis)) and np.all(np.isfinite(base))):
            break   # (an estimate far from any motion of these records)
        coef, *_ = np.linalg.lstsq(basis, q - base, rcond=None)
        if not np.isfinite(coef[1]):
            break
        # (a step no larger than the speeds the forcing reaches over the stretch: where
        # the start sticks, the derivative is about zero)
        v0 += float(np.clip(coef[1], -scale, scale))
        if abs(coef[1]) <= 1e-6 * max(abs(v0), scale):
            break
    return v0

#: Newton iterations of the fixed point at most (:func:`settle_crossings`).
FIXED_POINT_ITERATIONS = 20

#: The fixed point is reached when no parameter moves by more than this many of its
#: standard errors.
FIXED_POINT_TOLERANCE = 1e-3

#: Coulomb levels (times the rms of the velocity equation's forcing) the fixed point
#: starts from where the first estimate has no dissipative velocity.
COULOMB_STARTS = (0.03, 0.1, 0.3, 1.0)

#: A Jacobian of the iteration serves the covariance where it was made within this
#: many standard errors of the fixed point.
JACOBIAN_REUSE = 3.0

#: Over this many standard errors between ``theta`` and ``G(theta)``, the fixed point
#: is approached by plain steps ``theta <- G(theta)``.
PICARD_GAP = 10.0

#: Difference step of the fixed point's Jacobian, in standard errors of each parameter.
JACOBIAN_STEP = 0.5


class SettledFit(NamedTuple):
    """The fit at the fixed point of :func:`settle_crossings`."""

    fit: object              # the WindowFit, its covariance through the placement
    iterations: int
    contraction: object      # the map's Jacobian at the fixed point (None: not made)


def has_velocity(problem, theta):
    """Whether an estimate gives a stable, dissipative velocity on every segment.

    Parameters
    ----------
    problem : WindowProblem
        The problem (its model and segments).
    theta : array_like
        The estimate, in the order of the model's parameters.

    Returns
    -------
    bool
        Whether :func:`velocity_equation` has one on every segment.
    """
    model = problem.model
    values = dict(zip(model.parameters, np.asarray(theta, dtype=float).tolist()))
    return bool(crossing_jumps(model, values)) and all(
        velocity_equation(model, values, seg.values, seg.t) is not None
        for seg in problem.user_segments)


def settle_crossings(problem, fit, solve, *, final=True, chord=None):
    """The estimate that places the steps of its own ``sign(q')``: a fixed point.

    With the steps placed by the model's velocity at ``theta``, the window equations
    give ``G(theta)``; the estimate is the ``theta`` with ``G(theta) = theta``: plain
    steps ``theta <- G(theta)`` while far from it, then Newton's method on
    ``theta - G(theta)`` (its Jacobian ``I - D`` by central differences of ``G``,
    renewed where progress is slow).  Its covariance carries the placement:
    ``(I - D)^-1 C (I - D)^-T``, ``C`` the covariance of ``G`` at the fixed point (the
    steps held).  Where the first estimate has no dissipative velocity (on a noisy
    position the signs of its derivative scatter, and the Coulomb term comes out about
    zero or negative) or the iteration from it does not settle, it starts again from
    that estimate with the Coulomb level set to each of :data:`COULOMB_STARTS` times
    the forcing's rms, from the one whose image is nearest.

    Parameters
    ----------
    problem : WindowProblem
        The problem; its :attr:`first_values`, :attr:`sign_jumps` and
        :attr:`velocity_crossings` are set here.
    fit : WindowFit
        A first estimate (steps placed by the derivative estimate of ``q``).
    solve : callable
        ``solve()`` -> WindowFit of ``problem`` as it stands (one window, one method).
    final : bool
        Carry the placement into the covariance; else the covariance is that of ``G``
        (a start for another window).
    chord : numpy.ndarray, optional
        A Jacobian of ``G`` to start the iteration with (another window's).

    Returns
    -------
    SettledFit or None
        None where no start has a stable, dissipative velocity, or the iteration does
        not settle from the first estimate nor from the Coulomb starts (the caller
        keeps its own placement).
    """
    problem.velocity_crossings = True
    point = _FixedPoint(problem, solve, final)
    theta = np.asarray(fit.theta, dtype=float)
    image = point.image(theta)
    settled = None if image is None else point.newton(theta, image, chord)
    if settled is None:
        start, image = point.coulomb_start(theta)
        settled = None if image is None else point.newton(start, image)
    return settled


class _FixedPoint:
    """The map ``G`` of :func:`settle_crossings` and Newton's method on it."""

    def __init__(self, problem, solve, final):
        self.problem, self.solve, self.final = problem, solve, final
        self.model = problem.model

    def image(self, theta):
        """``G(theta)`` (a WindowFit), or None where ``theta`` has no dissipative
        velocity or its steps leave the equations unsolvable."""
        problem, model = self.problem, self.model
        if not self.usable(theta):
            return None
        values = dict(zip(model.parameters, theta.tolist()))
        jumps = crossing_jumps(model, values)
        problem.first_values, problem.sign_jumps = values, jumps
        problem.cache.forget_factors(jumps)
        try:
            return self.solve()
        except (ModelError, InputDataError, np.linalg.LinAlgError):
            return None   # (a trial whose steps leave a column empty or proportional)

    def usable(self, theta):
        """Whether ``theta`` gives a stable, dissipative velocity on every segment."""
        return has_velocity(self.problem, theta)

    def jacobian(self, theta, se):
        """``dG/dtheta`` by central differences (None where a side has no image)."""
        steps = np.maximum(JACOBIAN_STEP * se, 1e-7 * np.maximum(np.abs(theta), 1e-300))
        columns = []
        for j, h in enumerate(steps):
            up, down = theta.copy(), theta.copy()
            up[j] += h
            down[j] -= h
            above, below = self.image(up), self.image(down)
            if above is None or below is None:
                return None
            columns.append((above.theta - below.theta) / (2 * h))
        return np.column_stack(columns)

    def coulomb_start(self, theta):
        """A start with the Coulomb level set to each of :data:`COULOMB_STARTS` times
        the forcing's rms: the one whose image is nearest, and its image (None: no
        start has one)."""
        best = (np.inf, theta, None)
        for level in COULOMB_STARTS:
            trial = _with_coulomb(self.model, theta, level, self.problem.user_segments[0])
            image = None if trial is None else self.image(trial)
            if image is None:
                continue
            se = np.maximum(np.sqrt(np.diag(image.covariance)), 1e-300)
            gap = float(np.max(np.abs(image.theta - trial) / se))
            if gap < best[0]:
                best = (gap, trial, image)
        return best[1], best[2]

    def newton(self, theta, current, chord=None):
        """Newton's (chord) iteration from ``theta`` and its image ``current``; a plain
        step ``theta <- G(theta)`` where the gap is over :data:`PICARD_GAP` standard
        errors or Newton's step does not shrink it (the map contracts near the fixed
        point: its Jacobian's eigenvalues were 0 to 0.5 on the friction records)."""
        D, settled, iteration, where = chord, False, 0, None
        while iteration < FIXED_POINT_ITERATIONS:
            iteration += 1
            se = np.maximum(np.sqrt(np.diag(current.covariance)), 1e-300)
            gap = current.theta - theta
            size = float(np.max(np.abs(gap) / se))
            if size <= FIXED_POINT_TOLERANCE:
                settled = True
                break
            after = None
            if size <= PICARD_GAP:
                if D is None:   # a chord method: a new Jacobian where progress is slow
                    D, where = self.jacobian(theta, se), theta
                after, trial = self._newton_step(theta, gap, size, se, D)
            if after is None:   # the plain step
                trial = current.theta
                after = self.image(trial)
                if after is None:
                    return None
            new_size = float(np.max(np.abs(after.theta - trial) / se))
            theta, current = trial, after
            if new_size > 0.5 * size:
                D = None
        if not settled or not self.usable(current.theta):
            return None   # (its image, within the tolerance, has no velocity)
        if not self.final:
            return SettledFit(current, iteration, D)
        se = np.maximum(np.sqrt(np.diag(current.covariance)), 1e-300)
        if D is None or where is None or np.max(np.abs(theta - where) / se) > JACOBIAN_REUSE:
            D = self.jacobian(theta, se)
            if D is None:
                return None
        current = self.image(theta)   # (the placement at the fixed point, for the rows)
        A = np.linalg.inv(np.eye(len(theta)) - D)
        current.covariance = A @ current.covariance @ A.T
        return SettledFit(current, iteration, D)

    def _newton_step(self, theta, gap, size, se, D):
        """``(image, theta)`` after Newton's step, halved until the gap shrinks, or
        ``(None, None)``."""
        if D is None:
            return None, None
        step = np.linalg.solve(np.eye(len(theta)) - D, gap)
        for _ in range(4):
            trial = theta + step
            after = self.image(trial)
            if after is not None and float(np.max(np.abs(after.theta - trial) / se)) < size:
                return after, trial
            step = step / 2
        return None, None


def _with_coulomb(model, theta, level, segment):
    """``theta`` with the one parameter of the ``sign(q')`` terms set so that the
    Coulomb level ``c`` is ``level`` times the rms of the velocity equation's forcing
    on ``segment``, and a damping below zero set to zero; None where the model has
    another form (the sign terms with several parameters or none)."""
    names = model.parameters
    values = dict(zip(names, theta.tolist()))
    jumps = crossing_jumps(model, values)
    motion = crossing_motion(model, values, segment.values, segment.t)
    if not jumps or motion is None:
        return None
    factor = next(iter(jumps))
    plain = Signal(model.output)
    signed = [t for t in model.terms if t.factor == factor]
    free = {t.parameter for t in signed if t.parameter is not None}
    if len(free) != 1:
        return None
    name = free.pop()
    leading = sum(term_weight(t, values)
                  for t in model.terms if t.factor == plain and t.derivative == 2)
    known = sum(t.coefficient for t in signed if t.parameter is None)
    per_unit = sum(t.coefficient for t in signed if t.parameter == name)
    forcing_rms = float(np.sqrt(np.mean(np.square(motion[0]))))
    if not (per_unit != 0 and forcing_rms > 0 and np.isfinite(leading)):
        return None
    out = dict(values)
    out[name] = (level * forcing_rms * leading - known) / per_unit
    if motion[1] < 0:   # no damping rather than a negative one
        for t in model.terms:
            if t.factor == plain and t.derivative == 1 and t.parameter is not None:
                out[t.parameter] = 0.0
    return np.array([out[p] for p in names])
