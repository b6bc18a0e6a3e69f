"""Synthetic records with known truth for :func:`algid.identify`.

Each generator computes the true continuous-time response to an analytic input (a
multisine): exactly for the linear plant and the friction loop (piece by piece between
the zeros of its velocity), by RK4 at 16 steps per sample for the cubic spring; noise
is added to the measured output.  Used by ``tests/identification/test_identify.py`` and
the identify benchmark.

- :func:`linear_offsets`: ``y'' + B y' + K y = G u`` at 8 samples per period of its
  resonance, with DC offsets on both measured channels (the model's ``d`` absorbs them).
- :func:`cubic_spring`: ``y'' + B y' + K y + K3 y^3 = G u``.
- :func:`friction_loop`: ``M q'' + Fv q' + Fc sign(q') + off = F`` under a PD
  position loop following a multisine reference.
- :func:`drop_rows`: remove a fraction of the rows of a record (gaps).
"""

from __future__ import annotations

import numpy as np

__all__ = ["linear_offsets", "linear_gaps", "cubic_spring", "friction_loop", "drop_rows",
           "FrictionLoop",
           "multisine_lines", "INPUT_SEED",
           "LINEAR_EQUATION", "CUBIC_EQUATION", "FRICTION_EQUATION"]

LINEAR_EQUATION = ("y'' + B*y' + K*y = G*u + d", "B K G d")
CUBIC_EQUATION = ("y'' + B*y' + K*y + K3*y**3 = G*u + d", "B K K3 G d")
FRICTION_EQUATION = ("M*q'' + Fv*q' + Fc*sign(q') + off = F", "M Fv Fc off")


def multisine_lines(rng, f_low, f_high, count, rms):
    """Frequencies, random phases and the common amplitude of a multisine of rms ``rms``."""
    freqs = np.linspace(f_low, f_high, count)
    return freqs, rng.uniform(0, 2 * np.pi, count), rms * np.sqrt(2.0 / count)


def _multisine(rng, f_low, f_high, count, rms=1.0):
    freqs, phases, amp = multisine_lines(rng, f_low, f_high, count, rms)

    def u(t):
        t = np.asarray(t, dtype=float)
        return amp * np.sum(np.sin(2 * np.pi * freqs[:, None] * np.atleast_1d(t)[None, :]
                                   + phases[:, None]), axis=0).reshape(np.shape(t))
    return u


def _rk4(rhs, x0, t_end, steps, drive):
    """Classical RK4 with ``steps`` steps; ``drive`` holds the input at every half step.
    Returns the states at every step."""
    h = t_end / steps
    x = [float(v) for v in x0]
    out = np.empty((steps + 1, len(x)))
    out[0] = x
    d = drive.tolist()
    for i in range(steps):
        u0, um, u1 = d[2 * i], d[2 * i + 1], d[2 * i + 2]
        k1 = rhs(x, u0)
        k2 = rhs([a + 0.5 * h * b for a, b in zip(x, k1)], um)
        k3 = rhs([a + 0.5 * h * b for a, b in zip(x, k2)], um)
        k4 = rhs([a + h * b for a, b in zip(x, k3)], u1)
        x = [a + h / 6.0 * (b + 2 * c + 2 * e + f) for a, b, c, e, f in zip(x, k1, k2, k3, k4)]
        out[i + 1] = x
    return out


#: RK4 steps per sample of the generators (step 1/(16 rate): errors below 1e-6).
FINE = 16

#: Seed of the input multisine's phases (the same input in every realisation).
INPUT_SEED = 12345


def _drive(n, rate):
    """The multisine input (0.2-15 Hz, 40 lines) at every half step of the fine grid."""
    u = _multisine(np.random.default_rng(INPUT_SEED), 0.2, 15.0, 40)
    return u, u(np.arange(2 * FINE * (n - 1) + 1) / (2 * FINE * rate))


def _measured(t, u, y, rng, noise, offsets):
    scale = np.std(y)
    return {"t": t, "u": u(t) + offsets[0],
            "y": y + offsets[1] + noise * scale * rng.standard_normal(len(t))}


def linear_offsets(seed=0, *, n=4000, noise=0.01):
    """Linear plant at 8 samples per period of its 10 Hz resonance, in periodic steady
    state (exact: the sum of the multisine lines through the frequency response),
    offsets on both channels, ``noise`` x rms(y) white output noise.

    Returns
    -------
    record : dict
        ``t``, ``u``, ``y``.
    truth : dict
        ``B``, ``K``, ``G`` and the equivalent offset ``d = K c_y - G c_u``.
    """
    f0, rate = 10.0, 80.0
    K = (2 * np.pi * f0) ** 2
    B, G = 2.0 * 0.05 * 2 * np.pi * f0, K
    offsets = (0.1, -0.05)
    freqs, phases, amp = multisine_lines(np.random.default_rng(INPUT_SEED), 0.2, 15.0, 40, 1.0)
    t = np.arange(n) / rate
    w = 2 * np.pi * freqs
    H = G / (K - w ** 2 + 1j * B * w)
    y = np.sum(amp * np.abs(H)[:, None] * np.sin(w[:, None] * t + phases[:, None]
                                                  + np.angle(H)[:, None]), axis=0)
    u = _multisine(np.random.default_rng(INPUT_SEED), 0.2, 15.0, 40)
    record = _measured(t, u, y, np.random.default_rng(seed), noise, offsets)
    return record, {"B": B, "K": K, "G": G, "d": K * offsets[1] - G * offsets[0]}


def linear_gaps(seed=0, *, n=4000, noise=0.01):
    """:func:`linear_offsets` with 5 % of its rows missing (a random choice per seed)."""
    record, truth = linear_offsets(seed, n=n, noise=noise)
    return drop_rows(record, 0.05, seed=seed), truth


#: Amplitude of the cubic spring's input: ``K3 y^2`` reaches about 20 % of ``K`` at the
#: peaks of the response.  (With the unscaled multisine it reached 1.7 ``K``: a mean
#: linearised stiffness of 1.9 ``K``, a resonance near 13.7 Hz, 5.8 samples per period
#: and third harmonics beyond the Nyquist frequency, whose aliasing the window sums
#: cannot undo; :mod:`benchmarks.cubic_study` measures both.)
CUBIC_INPUT_SCALE = 0.25


def cubic_spring(seed=0, *, n=4000, noise=0.01, rate=80.0, input_scale=CUBIC_INPUT_SCALE):
    """Hardening spring ``K3 y^3`` (about 20 % of the linear force at the peaks), at
    8 samples per period of the 10 Hz linear resonance by default; no offsets (``d`` =
    0).  Integrated by RK4 at 16 steps per sample with the analytic input, the multisine
    times ``input_scale`` (:data:`CUBIC_INPUT_SCALE`)."""
    f0 = 10.0
    K = (2 * np.pi * f0) ** 2
    B, G, K3 = 2.0 * 0.05 * 2 * np.pi * f0, K, 0.2 * K / 4.0
    multisine, drive = _drive(n, rate)
    drive = input_scale * drive

    def u(t):
        return input_scale * multisine(t)

    states = _rk4(lambda x, v: [x[1], G * v - B * x[1] - K * x[0] - K3 * x[0] ** 3],
                  [0.0, 0.0], (n - 1) / rate, FINE * (n - 1), drive)
    t = np.arange(n) / rate
    record = _measured(t, u, states[::FINE, 0], np.random.default_rng(seed), noise, (0, 0))
    return record, {"B": B, "K": K, "K3": K3, "G": G, "d": 0.0}


def friction_loop(seed=0, *, n=6000, rate=1000.0, noise=1e-6):
    """Mass with viscous and Coulomb friction and a force offset, under a PD position
    loop following a multisine reference; ``noise`` is the standard deviation of the
    position noise (m).

    Exact (:class:`FrictionLoop`): between two zeros of the velocity the loop is linear,
    its response the multisine's through the loop plus a decaying transient; each zero
    is found to round-off, and there the friction flips or, where the net force is
    within the Coulomb force, the mass sticks until it is not.  (RK4 at 16 steps per
    sample put the flip up to a third of a step away from the zero: the crossings
    moved by about 2 us, M by 4e-6.)"""
    loop = FrictionLoop()
    t = np.arange(n) / rate
    q, v, r = loop.sample(t)
    F = loop.kp * (r - q) - loop.kv * v
    rng = np.random.default_rng(seed)
    return ({"t": t, "q": q + noise * rng.standard_normal(n), "F": F},
            {"M": loop.M, "Fv": loop.Fv, "Fc": loop.Fc, "off": loop.off})


class FrictionLoop:
    """``M q'' + Fv q' + Fc sign(q') + off = kp (r - q) - kv q'`` solved piece by piece.

    With the friction's sign ``m`` fixed the loop is ``M q'' + (kv + Fv) q' + kp q =
    kp r - off - m Fc``: the multisine lines of ``r`` through the loop's frequency
    response, a constant, and a transient from the state where the piece starts.
    After :meth:`sample`, ``events`` holds the times where a piece ended: the velocity
    back at zero, or the mass leaving rest."""

    def __init__(self, M=2.0, Fv=5.0, Fc=1.0, off=-0.2, kp=4000.0, kv=120.0):
        self.M, self.Fv, self.Fc, self.off, self.kp, self.kv = M, Fv, Fc, off, kp, kv
        lines = multisine_lines(np.random.default_rng(777), 0.3, 3.0, 6, 0.02)
        freqs, self.phases, self.amp = lines
        self.omega = 2 * np.pi * freqs
        self.gain = kp / (M * (1j * self.omega) ** 2 + (kv + Fv) * 1j * self.omega + kp)
        self.a = np.array([[0.0, 1.0], [-kp / M, -(kv + Fv) / M]])
        self.roots, self.vectors = np.linalg.eig(self.a)
        self.inverse = np.linalg.inv(self.vectors)

    def reference(self, t):
        t = np.atleast_1d(t)
        return self.amp * np.sin(np.outer(t, self.omega) + self.phases).sum(axis=1)

    def _forced(self, t, mode):
        """Position and velocity of the steady response (the friction's sign ``mode``)."""
        t = np.atleast_1d(t)
        x = self.amp * self.gain * np.exp(1j * (np.outer(t, self.omega) + self.phases))
        q = x.imag.sum(axis=1) - (self.off + mode * self.Fc) / self.kp
        return q, (1j * self.omega * x).imag.sum(axis=1)

    def _state(self, t, start, state, mode):
        """Position and velocity at times ``t`` of the piece from ``state`` at ``start``."""
        q0, v0 = self._forced(start, mode)
        c = self.inverse @ (np.asarray(state) - np.array([q0[0], v0[0]]))
        e = np.exp(np.outer(np.atleast_1d(t) - start, self.roots))
        transient = ((e * c) @ self.vectors.T).real
        q, v = self._forced(t, mode)
        return q + transient[:, 0], v + transient[:, 1]

    def _net(self, t, q):
        """The force on a mass at rest at ``q``, friction aside."""
        return self.kp * (self.reference(t) - q) - self.off

    def sample(self, t, state=None):
        """Position, velocity and reference at the (increasing) times ``t``, from rest at
        the reference or from ``state`` (position, velocity) at ``t[0]``."""
        from scipy.optimize import brentq

        q, v = np.empty(len(t)), np.empty(len(t))
        self.events = []
        start, state = float(t[0]), state or (float(self.reference(t[0])[0]), 0.0)
        moving = np.sign(state[1])
        grid = np.diff(t).min() / 8
        done, released = 0, False
        while done < len(t):
            net = float(self._net(start, state[0])[0])
            # leaving rest, the net force is the Coulomb force itself (to round-off)
            mode = np.sign(net) if released or abs(net) > self.Fc else 0
            mode, moving = (moving, 0) if moving else (mode, 0)
            released = mode == 0
            if mode == 0:   # stuck until the net force exceeds the Coulomb force
                def excess(x):
                    return abs(float(self._net(x, state[0])[0])) - self.Fc
            else:           # moving until the velocity returns to zero
                def excess(x):
                    return -mode * self._state(x, start, state, mode)[1][0]
            probe = start + grid * np.arange(1, 257)
            end = None
            while end is None and probe[0] <= t[-1]:
                values = (np.abs(self._net(probe, state[0])) - self.Fc if mode == 0
                          else -mode * self._state(probe, start, state, mode)[1])
                hit = np.flatnonzero(values > 0)
                if hit.size:
                    hi = probe[hit[0]]
                    lo = probe[hit[0] - 1] if hit[0] > 0 else start + grid / 2
                    while hit[0] == 0 and excess(lo) > 0 and lo - start > 1e-13:
                        hi, lo = lo, start + (lo - start) / 2   # a piece shorter than
                    end = brentq(excess, lo, hi, xtol=1e-15, rtol=1e-15)  # the grid
                probe = probe + 256 * grid
            stop = len(t) if end is None else int(np.searchsorted(t, end, side="right"))
            if mode == 0:
                q[done:stop], v[done:stop] = state[0], 0.0
            else:
                q[done:stop], v[done:stop] = self._state(t[done:stop], start, state, mode)
            done = stop
            if end is not None:
                self.events.append(end)
                position = state[0] if mode == 0 else \
                    float(self._state(end, start, state, mode)[0][0])
                start, state = end, (position, 0.0)
        return q, v, self.reference(t)


def drop_rows(record, fraction, seed=0):
    """A copy of ``record`` with a random ``fraction`` of its rows removed."""
    rng = np.random.default_rng(seed)
    n = len(record["t"])
    keep = np.sort(rng.choice(n, size=n - int(round(fraction * n)), replace=False))
    return {k: np.asarray(v)[keep] for k, v in record.items()}
