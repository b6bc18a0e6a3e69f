"""The result of :func:`algid.simulate`: a ``control.TimeResponseData`` with the
experiment's names.

The data live in a python-control ``TimeResponseData`` (:attr:`SimulationResult.response`:
input ``F``, measured output ``x``, noise-free states ``x``, ``v``, the parameters in
``params``), which provides labels, plotting and conversion to pandas.  This class adds
what an identification experiment needs on top: unpacking as ``t, f, x``, the
normalised parameters ``B``, ``K``, the noise settings and an exact CSV file.
"""

from __future__ import annotations

import os
import pathlib
from collections.abc import Iterator
from typing import Any

import control
import numpy as np

__all__ = ["SimulationResult"]


class SimulationResult:
    """A simulated experiment on the mass-spring-damper.

    Unpacks as ``t, f, x = result``.

    Parameters
    ----------
    t : numpy.ndarray
        Time points in s.
    f : numpy.ndarray
        Applied force ``F`` in N at the time points.
    x : numpy.ndarray
        Measured displacement in m: ``x_true`` plus measurement noise, if any.
    x_true : numpy.ndarray
        Noise-free displacement in m.
    v_true : numpy.ndarray
        Noise-free velocity ``x'`` in m/s.
    m, c, k : float
        Mass (kg), damping (N s/m) and stiffness (N/m) used.
    noise_std : float, default 0.0
        Standard deviation of the noise added to ``x``, in m.
    seed : object, optional
        Seed passed to :func:`numpy.random.default_rng` (``None`` if not given).

    Attributes
    ----------
    response : control.TimeResponseData
        The experiment as python-control stores it: ``time``, ``inputs`` (``F``),
        ``outputs`` (measured ``x``), ``states`` (noise-free ``x``, ``v``) and
        ``params`` (``m``, ``c``, ``k``).
    t, f, x, x_true, v_true : numpy.ndarray
        Views of the arrays of :attr:`response`.
    m, c, k, noise_std : float
        As given.
    seed : object
        As given.

    Examples
    --------
    >>> import algid
    >>> sim = algid.simulate("step", duration=1.0, rate=100.0)
    >>> t, f, x = sim
    >>> sim.response.output_labels, sim.response.state_labels
    (['x'], ['x', 'v'])
    """

    __slots__ = ("response", "t", "f", "x", "x_true", "v_true", "m", "c", "k",
                 "noise_std", "seed")

    def __init__(self, t, f, x, x_true, v_true, m, c, k, noise_std=0.0, seed=None):
        response = control.TimeResponseData(
            time=t, outputs=x, inputs=f, states=np.stack([x_true, v_true]), issiso=True,
            output_labels=["x"], input_labels=["F"], state_labels=["x", "v"],
            sysname="mass_spring_damper", params={"m": m, "c": c, "k": k})
        values = {"response": response, "t": response.t, "f": response.u[0],
                  "x": response.y[0], "x_true": response.x[0], "v_true": response.x[1],
                  "m": m, "c": c, "k": k, "noise_std": noise_std, "seed": seed}
        for name, value in values.items():
            object.__setattr__(self, name, value)

    def __setattr__(self, name, value):
        raise AttributeError(f"SimulationResult is read-only (cannot set {name!r})")

    def __repr__(self) -> str:
        return (f"SimulationResult(n={self.t.size}, m={self.m!r}, c={self.c!r}, k={self.k!r}, "
                f"noise_std={self.noise_std!r}, seed={self.seed!r})")

    @property
    def B(self) -> float:
        """Normalised damping ``c/m`` in 1/s."""
        return self.c / self.m

    @property
    def K(self) -> float:
        """Normalised stiffness ``k/m`` in 1/s**2."""
        return self.k / self.m

    def __iter__(self) -> Iterator[np.ndarray]:
        """Yield ``t``, ``f`` and ``x`` so that ``t, f, x = result`` works."""
        yield self.t
        yield self.f
        yield self.x

    def to_timeresponse(self) -> control.TimeResponseData:
        """Return the experiment as a :class:`control.TimeResponseData`.

        Returns
        -------
        control.TimeResponseData
            :attr:`response`: ``time = t``, ``outputs = x`` (measured), ``inputs = f``,
            ``states`` the noise-free displacement and velocity.
        """
        return self.response

    def plot(self, *args: Any, **kwargs: Any):
        """Plot the experiment with :meth:`control.TimeResponseData.plot` (needs matplotlib).

        Parameters
        ----------
        *args, **kwargs
            Passed to :meth:`control.TimeResponseData.plot`.

        Returns
        -------
        control.ControlPlot
            What python-control returns.
        """
        return self.response.plot(*args, **kwargs)

    def to_csv(self, path: str | os.PathLike) -> pathlib.Path:
        """Write the columns ``t, f, x`` to a comma-separated file.

        The first line is the header ``t,f,x``.  Every number is written as the
        shortest decimal string that reads back as the same float64 (Python's
        ``repr``), so reading the file recovers the arrays exactly.

        Parameters
        ----------
        path : str or os.PathLike
            File to write (overwritten if it exists).

        Returns
        -------
        pathlib.Path
            The path written.
        """
        p = pathlib.Path(path)
        lines = ["t,f,x"]
        lines.extend(
            f"{a!r},{b!r},{c!r}"
            for a, b, c in zip(self.t.tolist(), self.f.tolist(), self.x.tolist())
        )
        p.write_text("\n".join(lines) + "\n", encoding="utf-8")
        return p
