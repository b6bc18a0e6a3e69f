"""Synthetic records whose parameters change mid-record, for :class:`algid.Tracker`.

- :func:`friction_change`: the friction loop of :mod:`benchmarks.synthetic_records`
  (exact between velocity zeros) whose mass changes by ``change`` at ``t_change``; the
  second piece continues from the first's position and velocity.
- :func:`cubic_change`: the cubic spring (RK4 at 16 steps per sample) whose linear
  stiffness ``K`` changes by ``change`` at ``t_change``.
"""

from __future__ import annotations

import numpy as np

from benchmarks.synthetic_records import (
    CUBIC_INPUT_SCALE,
    FINE,
    FrictionLoop,
    _drive,
    _measured,
    _rk4,
)

__all__ = ["friction_change", "cubic_change"]


def friction_change(seed=0, *, duration=20.0, t_change=10.0, change=0.25, rate=1000.0,
                    noise=1e-6):
    """Friction loop whose mass ``M`` becomes ``(1 + change) M`` at ``t_change``.

    Returns
    -------
    record : dict
        ``t``, ``q``, ``F``.
    before, after : dict
        The parameters before and after the change.
    """
    n = int(round(duration * rate)) + 1
    t = np.arange(n) / rate
    first = FrictionLoop()
    cut = int(np.searchsorted(t, t_change))
    q1, v1, r1 = first.sample(t[:cut + 1])
    second = FrictionLoop(M=first.M * (1 + change))
    q2, v2, r2 = second.sample(t[cut:], state=(float(q1[-1]), float(v1[-1])))
    q = np.concatenate([q1[:-1], q2])
    v = np.concatenate([v1[:-1], v2])
    r = np.concatenate([r1[:-1], r2])
    F = first.kp * (r - q) - first.kv * v
    rng = np.random.default_rng(seed)
    before = {"M": first.M, "Fv": first.Fv, "Fc": first.Fc, "off": first.off}
    return ({"t": t, "q": q + noise * rng.standard_normal(n), "F": F}, before,
            {**before, "M": second.M})


def cubic_change(seed=0, *, duration=50.0, t_change=25.0, change=-0.10, rate=80.0,
                 noise=0.01):
    """Cubic spring (as :func:`benchmarks.synthetic_records.cubic_spring`) whose linear
    stiffness ``K`` becomes ``(1 + change) K`` at ``t_change``.

    Returns
    -------
    record : dict
        ``t``, ``u``, ``y``.
    before, after : dict
    """
    f0 = 10.0
    K = (2 * np.pi * f0) ** 2
    B, G, K3 = 2.0 * 0.05 * 2 * np.pi * f0, K, 0.2 * K / 4.0
    n = int(round(duration * rate)) + 1
    multisine, drive = _drive(n, rate)
    drive = CUBIC_INPUT_SCALE * drive
    cut = int(round(t_change * rate))

    def rhs(stiffness):
        return lambda x, v: [x[1], G * v - B * x[1] - stiffness * x[0] - K3 * x[0] ** 3]

    first = _rk4(rhs(K), [0.0, 0.0], cut / rate, FINE * cut, drive[:2 * FINE * cut + 1])
    second = _rk4(rhs(K * (1 + change)), first[-1], (n - 1 - cut) / rate,
                  FINE * (n - 1 - cut), drive[2 * FINE * cut:])
    states = np.concatenate([first[:-1], second])
    t = np.arange(n) / rate

    def u(time):
        return CUBIC_INPUT_SCALE * multisine(time)

    record = _measured(t, u, states[::FINE, 0], np.random.default_rng(seed), noise, (0, 0))
    before = {"B": B, "K": K, "K3": K3, "G": G, "d": 0.0}
    return record, before, {**before, "K": K * (1 + change)}
