"""Closed-form responses of the underdamped x'' + B x' + K x = f, for test references.

Independent of algid's simulators: the particular solution of a constant or sinusoidal
input plus the homogeneous solution fitted to the initial state.  Exact up to
round-off (absolute error a few eps times the size of the response).
"""

import numpy as np


def analytic_response(kind, *, B=2.0, K=3.0, x0=0.0, v0=0.0, duration=2.0, rate=1000.0,
                      amplitude=1.0, omega=1.0):
    """``t, f, x`` for ``f = amplitude`` (``"step"``) or ``amplitude sin(omega t)``."""
    t = np.arange(int(round(duration * rate)) + 1) / rate
    sig = -B / 2.0
    w = np.sqrt(K - B * B / 4.0)  # underdamped: K > B**2 / 4
    if kind == "step":
        f = np.full_like(t, amplitude)
        xp, xp0, vp0 = amplitude / K, amplitude / K, 0.0
    elif kind == "sine":
        f = amplitude * np.sin(omega * t)
        G = amplitude / ((K - omega**2) + 1j * B * omega)
        xp = np.imag(G * np.exp(1j * omega * t))
        xp0, vp0 = G.imag, omega * G.real
    else:
        raise ValueError(kind)
    a = x0 - xp0
    b = (v0 - vp0 - sig * a) / w
    x = xp + np.exp(sig * t) * (a * np.cos(w * t) + b * np.sin(w * t))
    return t, f, x
