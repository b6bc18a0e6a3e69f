"""Simulated experiments on the mass-spring-damper plant.

The plant is

.. math:: m \\ddot x + c \\dot x + k x = F,

with force :math:`F` in N, displacement :math:`x` in m, mass :math:`m` in kg, damping
:math:`c` in N s/m and stiffness :math:`k` in N/m.  Divided by the mass it reads
:math:`\\ddot x + B \\dot x + K x = f` with :math:`B = c/m`, :math:`K = k/m` and
:math:`f = F/m`; the transfer function from :math:`F` to :math:`x` is
:math:`1/(m s^2 + c s + k)`.

:func:`simulate` produces noise-free responses that are exact up to floating-point
round-off for the built-in step and sine inputs (about 1e-16 absolute for the default
plant on the default grid, with no growth over long records), accurate to the
integrator tolerance (about 1e-13 relative) for a callable input, and exact for the
piecewise-linear interpolation of an array of input samples.  Measurement noise, if
requested, is added to the measured displacement only.

This package needs the ``control`` package (``pip install algid[simulate]``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

try:
    import control
except ImportError as exc:  # pragma: no cover - depends on the environment
    raise ImportError(
        "algid.simulation needs the 'control' package; install it with "
        "'pip install algid[simulate]'"
    ) from exc

from algid.errors import InputDataError
from algid.simulation._arguments import (
    array_samples,
    callable_samples,
    check_parameters,
    format_value,
    initial_state_vector,
    real_number,
    seed_generator,
    time_grid,
)
from algid.simulation._responses import (
    callable_response,
    exosystem_response,
    foh_response,
    plant_matrices,
)
from algid.simulation._result import SimulationResult

__all__ = ["plant", "simulate", "SimulationResult", "INPUT_NAMES"]

#: Names of the built-in input signals accepted by :func:`simulate`.
INPUT_NAMES = ("step", "sine")

# --------------------------------------------------------------------------------------
# the plant and its exact responses
# --------------------------------------------------------------------------------------


def plant(*, m: float = 1.0, c: float = 2.0, k: float = 3.0) -> control.StateSpace:
    """State-space model of the mass-spring-damper ``m x'' + c x' + k x = F``.

    Parameters
    ----------
    m : float, default 1.0
        Mass in kg, must be positive.
    c : float, default 2.0
        Viscous damping coefficient in N s/m, must be non-negative.
    k : float, default 3.0
        Spring stiffness in N/m, must be non-negative.

    Returns
    -------
    control.StateSpace
        Continuous-time system with states ``[x, v]`` (displacement in m and velocity
        in m/s), input ``F`` (force in N) and output ``x``:
        ``A = [[0, 1], [-k/m, -c/m]]``, ``B = [[0], [1/m]]``, ``C = [[1, 0]]``,
        ``D = [[0]]``.

    Raises
    ------
    InputDataError
        If a parameter is not a finite real number, ``m <= 0``, ``c < 0`` or ``k < 0``.

    Examples
    --------
    >>> sys = plant(m=2.0, c=4.0, k=6.0)
    >>> sys.A
    array([[ 0.,  1.],
           [-3., -2.]])
    """
    m, c, k = check_parameters(m, c, k)
    with np.errstate(over="ignore"):
        A = np.array([[0.0, 1.0], [-k / m, -c / m]])
        B = np.array([[0.0], [1.0 / m]])
    if not (np.isfinite(A).all() and np.isfinite(B).all()):
        raise InputDataError(
            f"m={m:g}, c={c:g}, k={k:g}: k/m, c/m or 1/m overflows; express the "
            "parameters in other units")
    C = np.array([[1.0, 0.0]])
    D = np.array([[0.0]])
    return control.ss(
        A, B, C, D, inputs=["F"], outputs=["x"], states=["x", "v"],
        name="mass_spring_damper",
    )


# --------------------------------------------------------------------------------------
# the simulator
# --------------------------------------------------------------------------------------


def simulate(
    inputs: str | Callable | Any = "step",
    *,
    m: float = 1.0,
    c: float = 2.0,
    k: float = 3.0,
    duration: float = 5.0,
    rate: float = 1000.0,
    timepts: Any = None,
    amplitude: float = 1.0,
    frequency: float = 1.0,
    initial_state: Any = (0.0, 0.0),
    noise_std: float = 0.0,
    seed: Any = None,
) -> SimulationResult:
    """Simulate an experiment on the mass-spring-damper ``m x'' + c x' + k x = F``.

    Parameters
    ----------
    inputs : {"step", "sine"}, callable or array_like, default "step"
        The applied force ``F`` in N:

        - ``"step"``: ``F = amplitude`` from the first time point on (constant, not a
          ramp over the first interval).
        - ``"sine"``: ``F = amplitude * sin(frequency * t)``.

          For both, the plant and the signal generator (a constant, or an oscillator
          with states ``amplitude sin(frequency t)``, ``amplitude cos(frequency t)``)
          form one autonomous linear system, whose solution is evaluated at every
          time point independently, never by stepping through the grid: the exact
          forced solution (from a Sylvester equation) plus the free response in
          closed form, or, at or near resonance, the matrix exponential of the
          4-state system.  The response is exact up to round-off, also for long
          records and non-uniform grids.
        - a callable ``F(t)``, vectorised: called with a 1-D float array of times it
          must return a float array of the same shape.  The response is integrated
          with ``scipy.integrate.solve_ivp`` (DOP853, ``rtol=1e-13``, ``atol`` 1e-15
          times the size of each state, values at the time points from the dense
          output), accurate to about 1e-13 relative for smooth inputs;
          discontinuities reduce the accuracy locally.
        - an array of samples of ``F`` at the time points: the force is interpolated
          linearly between samples (first-order hold, as ``control.forced_response``
          does) and the response to that piecewise-linear force is exact.  A smooth
          force given this way carries an interpolation error of order ``dt**2``.
    m : float, default 1.0
        Mass in kg, > 0.
    c : float, default 2.0
        Damping in N s/m, >= 0.
    k : float, default 3.0
        Stiffness in N/m, >= 0.
    duration : float, default 5.0
        Length of the experiment in s (ignored if ``timepts`` is given).
    rate : float, default 1000.0
        Sampling rate in Hz (ignored if ``timepts`` is given).  The grid is
        ``np.arange(n) / rate`` with ``n = round(duration * rate) + 1``.
    timepts : array_like, optional
        Time points in s, 1-D and strictly increasing, starting anywhere; uniform
        spacing is not required.
    amplitude : float, default 1.0
        Amplitude of the ``"step"`` and ``"sine"`` inputs in N.
    frequency : float, default 1.0
        Angular frequency of the ``"sine"`` input in rad/s.
    initial_state : (float, float), default (0.0, 0.0)
        Displacement (m) and velocity (m/s) at the first time point.
    noise_std : float, default 0.0
        Standard deviation in m of white Gaussian noise added to the measured
        displacement ``x`` (not to ``x_true``, ``v_true`` or ``f``).
    seed : int, numpy.random.SeedSequence or numpy.random.Generator, optional
        Seed for :func:`numpy.random.default_rng`; the same seed gives the same noise.
        The global random state is never used.

    Returns
    -------
    SimulationResult
        Time points, force, measured and noise-free displacement, noise-free velocity
        and the parameters; unpacks as ``t, f, x``.

    Raises
    ------
    InputDataError
        For a non-finite parameter, ``m <= 0``, ``c < 0``, ``k < 0``,
        ``duration <= 0``, ``rate <= 0``, fewer than 2 time points, ``timepts`` not
        strictly increasing, an unknown input name, a callable returning the wrong
        shape or non-finite values, an input array of the wrong length or with NaN/inf,
        a bad ``initial_state`` or ``noise_std < 0``.

    Examples
    --------
    >>> t, f, x = simulate("sine", frequency=2.0, duration=1.0, rate=100.0)
    >>> t.shape, f.shape, x.shape
    ((101,), (101,), (101,))
    """
    m, c, k = check_parameters(m, c, k)
    noise = real_number("noise_std", noise_std)
    if noise < 0.0:
        raise InputDataError(f"noise_std must be >= 0 m, got {format_value(noise_std)}")
    t = time_grid(timepts, duration, rate)
    x0 = initial_state_vector(initial_state)
    sys = plant(m=m, c=c, k=k)
    A, b = plant_matrices(sys)

    with np.errstate(all="ignore"):  # a response out of range is refused below
        f, states = _response(inputs, sys, A, b, t, x0, amplitude, frequency)
    x_true = np.ascontiguousarray(states[0], dtype=np.float64)
    v_true = np.ascontiguousarray(states[1], dtype=np.float64)
    if noise > 0.0:
        rng = seed_generator(seed)
        with np.errstate(over="ignore"):
            x = x_true + rng.normal(0.0, noise, size=t.size)
    else:
        x = x_true.copy()
    for name, values in (("x_true", x_true), ("v_true", v_true), ("x", x)):
        if not np.isfinite(values).all():
            row = int(np.argmax(~np.isfinite(values)))
            given = [f"m={m:g}", f"c={c:g}", f"k={k:g}", f"initial_state={tuple(x0.tolist())}"]
            if isinstance(inputs, str):
                given += [f"{inputs} amplitude={float(amplitude):g}"] + (
                    [f"frequency={float(frequency):g}"] if inputs == "sine" else [])
            given += [f"noise_std={noise:g}"] if noise else []
            raise InputDataError(
                f"the simulated {name} is not finite in floating point from t = "
                f"{float(t[row]):.6g} s on ({', '.join(given)}): express the quantities in "
                f"other units")
    return SimulationResult(
        t=t, f=np.ascontiguousarray(f, dtype=np.float64), x=x, x_true=x_true,
        v_true=v_true, m=m, c=c, k=k, noise_std=noise, seed=seed,
    )


def _response(inputs, sys, A, b, t, x0, amplitude, frequency):
    """The input samples and the states of :func:`simulate`."""
    if isinstance(inputs, str):
        if inputs == "step":
            amp = real_number("amplitude", amplitude)
            f = np.full(t.size, amp)
            states = exosystem_response(
                A, b, np.zeros((1, 1)), np.array([1.0]), f[None, :], x0, t
            )
        elif inputs == "sine":
            amp = real_number("amplitude", amplitude)
            w = real_number("frequency", frequency)
            f = amp * np.sin(w * t)
            S = np.array([[0.0, w], [-w, 0.0]])
            W = amp * np.stack([np.sin(w * t), np.cos(w * t)])
            states = exosystem_response(A, b, S, np.array([1.0, 0.0]), W, x0, t)
        else:
            valid = ", ".join(repr(name) for name in INPUT_NAMES)
            raise InputDataError(
                f"inputs={inputs!r} is not a known input; valid names are {valid} "
                "(or pass a callable F(t) or an array of force samples)"
            )
    elif callable(inputs):
        f = callable_samples(inputs, t)
        states = callable_response(sys, inputs, f, x0, t)
    else:
        f = array_samples(inputs, t)
        states = foh_response(sys, f, x0, t)
    return f, states


