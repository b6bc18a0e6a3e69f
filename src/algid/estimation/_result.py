"""The result of an estimation: estimates over time, named after the parameters."""

from __future__ import annotations

from functools import cached_property

import numpy as np

from algid.errors import InputDataError

__all__ = ["EstimationResult", "convergence_time"]


def convergence_time(t, estimate, true_value, rtol):
    """First instant from which ``estimate`` stays within ``rtol`` of ``true_value``.

    Parameters
    ----------
    t, estimate : ndarray
        Times and estimates (NaN counts as outside).
    true_value : float
        Nonzero reference value.
    rtol : float
        Relative tolerance.

    Returns
    -------
    float
        The time, or NaN if the estimate is outside the band at the last sample.

    Examples
    --------
    >>> import numpy as np
    >>> from algid.estimation import convergence_time
    >>> t = np.linspace(0.0, 1.0, 11)
    >>> convergence_time(t, 2.0 + np.exp(-10.0 * t), true_value=2.0, rtol=0.01)
    0.4
    """
    err = np.abs(np.asarray(estimate) / true_value - 1.0)
    bad = ~(err <= rtol)
    if bad[-1]:
        return float("nan")
    idx = np.flatnonzero(bad)
    return float(t[0] if idx.size == 0 else t[idx[-1] + 1])


class EstimationResult:
    """Estimates of a model's parameters over time.

    Made by :func:`algid.estimate` and :class:`algid.OnlineEstimator`; every parameter
    below is also an attribute of the same name.

    Parameters
    ----------
    t : ndarray
        Sample times (as given).
    estimates : dict
        Parameter name -> ndarray of estimates over ``t``; NaN where not yet defined.
        Each is also an attribute: ``r.B``, ``r.K``, ...
    model : str
        The model's name.
    filter_order : int
        ``p`` of the invariant low-pass filter ``1/s**p``.
    quadrature_points : int, optional
        Points of the quadrature rule.
    mass : float or None, optional
        The known mass, when given.
    mass_scaled : tuple of str, optional
        The estimates that are a model parameter times the known mass (``c``, ``k``).
    numerical_error : ndarray or None, optional
        Estimated relative error of the estimates at every sample of ``t``, the largest
        over the parameters (:mod:`algid.estimation._numerical_error`): NaN where the estimates
        are NaN, inf where the data do not determine them (those estimates are then
        NaN).  None if not computed.

    Attributes
    ----------
    parameters : tuple of str
        Names of the estimated quantities, in order (model parameters, then ``c``, ``k``
        when the mass was given).
    t_valid : float
        First instant with a defined estimate (NaN if none).
    n_samples : int
        Samples of ``t``.

    Examples
    --------
    >>> from algid.estimation import estimate
    >>> from algid.simulation import simulate
    >>> result = estimate(*simulate("step", duration=1.0), engine="numpy")
    >>> result
    <EstimationResult model='msd' n_samples=1001 t_valid=0.005 final: B=2, K=3>
    >>> result.parameters, result.B.shape
    (('B', 'K'), (1001,))
    >>> {name: round(value, 6) for name, value in result.final().items()}
    {'B': 2.0, 'K': 3.0}
    """

    def __init__(self, *, t, estimates, model, filter_order, quadrature_points=None,
                 mass=None, mass_scaled=(), numerical_error=None):
        self.t = t
        self.estimates = dict(estimates)
        self.parameters = tuple(self.estimates)
        self.model = model
        self.filter_order = filter_order
        self.quadrature_points = quadrature_points
        self.mass = mass
        self.mass_scaled = tuple(mass_scaled)
        self.numerical_error = numerical_error

    @cached_property
    def valid_index(self):
        """Index of the first sample where every estimate is defined (None if none)."""
        defined = None
        for values in self.estimates.values():
            finite = np.isfinite(values)
            defined = finite if defined is None else defined & finite
        if defined is None or defined.size == 0:
            return None
        i = int(np.argmax(defined))  # first True, without materialising all indices
        return i if defined[i] else None

    @property
    def t_valid(self) -> float:
        """First instant with a defined estimate (NaN if none)."""
        i = self.valid_index
        return float("nan") if i is None else float(self.t[i])

    @property
    def n_samples(self) -> int:
        """Number of samples (the size of :attr:`t`)."""
        return int(self.t.size)

    def __getattr__(self, name):
        estimates = self.__dict__.get("estimates", {})
        if name in estimates:
            return estimates[name]
        raise AttributeError(f"{type(self).__name__} has no attribute {name!r} "
                             f"(parameters: {', '.join(estimates)})")

    def __dir__(self):
        return sorted(set(super().__dir__()) | set(self.estimates))

    def with_samples(self, *, t, estimates, numerical_error=None) -> EstimationResult:
        """A result of the same model, options and parameters for other samples.

        Cheaper than the constructor (for a stream fed one sample at a time): nothing is
        copied or checked.

        Parameters
        ----------
        t : ndarray
            Sample times.
        estimates : dict
            Parameter name -> ndarray over ``t``, with the keys of :attr:`parameters` in
            their order; kept, not copied.
        numerical_error : ndarray, optional
            Over ``t``.

        Returns
        -------
        EstimationResult
        """
        new = object.__new__(type(self))
        new.__dict__ = {"t": t, "estimates": estimates, "parameters": self.parameters,
                        "model": self.model, "filter_order": self.filter_order,
                        "quadrature_points": self.quadrature_points, "mass": self.mass,
                        "mass_scaled": self.mass_scaled, "numerical_error": numerical_error}
        return new

    def final(self) -> dict:
        """Estimates at the last sample.

        Returns
        -------
        dict
            ``{name: float}``, one entry per estimated quantity.

        Raises
        ------
        InputDataError
            If the result holds no sample (e.g. the result of an empty chunk given to
            :meth:`algid.OnlineEstimator.update`).
        """
        if self.n_samples == 0:
            raise InputDataError("the result holds no sample: there is no final estimate "
                                 "(an empty chunk gives an empty result)")
        return {k: float(v[-1]) for k, v in self.estimates.items()}

    def final_numerical_error(self) -> float:
        """Estimated relative error of the final estimates (:attr:`numerical_error`).

        Returns
        -------
        float
            The last value of :attr:`numerical_error`; NaN if it was not computed or
            there is no sample.
        """
        error = self.numerical_error
        if error is None or len(error) == 0:
            return float("nan")
        return float(error[-1])

    def at(self, time) -> dict:
        """Estimates at the last sample at or before ``time``.

        Parameters
        ----------
        time : float
            Instant, on the scale of :attr:`t`.

        Returns
        -------
        dict
            ``{name: float}``, one entry per estimated quantity.

        Raises
        ------
        ValueError
            If ``time`` is before the first sample.
        """
        i = int(np.searchsorted(self.t, time, side="right")) - 1
        if i < 0:
            raise ValueError(f"time {time} is before the first sample {self.t[0]}")
        return {k: float(v[i]) for k, v in self.estimates.items()}

    def convergence_times(self, true_values: dict, rtol: float) -> dict:
        """Convergence time of each parameter in ``true_values``.

        The convergence time is the first instant from which the estimate stays within
        ``rtol`` of the true value (see :func:`convergence_time`).

        Parameters
        ----------
        true_values : dict
            Parameter name -> nonzero reference value.
        rtol : float
            Relative tolerance.

        Returns
        -------
        dict
            Parameter name -> time (NaN if the estimate is outside the band at the last
            sample).
        """
        return {k: convergence_time(self.t, self.estimates[k], v, rtol)
                for k, v in true_values.items()}

    def to_dict(self) -> dict:
        """Final estimates plus ``t_valid`` and ``n_samples``, JSON-ready.

        Returns
        -------
        dict
            ``{name: float or None}`` of the final estimates, plus ``"t_valid"``,
            ``"n_samples"`` and ``"numerical_error"`` (of the final estimates); NaN
            becomes None, an infinite numerical error the string ``"inf"``.
        """
        out = {k: (v if np.isfinite(v) else None) for k, v in self.final().items()}
        out["t_valid"] = self.t_valid if np.isfinite(self.t_valid) else None
        out["n_samples"] = self.n_samples
        error = self.final_numerical_error()
        out["numerical_error"] = error if np.isfinite(error) else \
            "inf" if np.isinf(error) else None
        return out

    def plot(self, *, true_values=None, ax=None, parameters=None, ylim=None):
        """Plot the estimates over time (needs matplotlib).

        Parameters
        ----------
        true_values : dict, optional
            Reference values drawn as dashed lines.
        ax : matplotlib Axes, optional
        parameters : sequence of str, optional
            Which estimates to draw (default: the model's parameters).
        ylim : (float, float), optional
            View limits; default: the range of the settled estimates and the true
            values (:func:`algid.plotting.estimate_ylim`), the ill-conditioned start-up
            clipped.  ``ax.autoscale()`` shows everything.

        Returns
        -------
        matplotlib Axes
        """
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(7, 4))
        # by default the model's own parameters, not the quantities a known mass scales
        names = parameters or [p for p in self.parameters if p not in self.mass_scaled]
        for name in names:
            line, = ax.plot(self.t, self.estimates[name], label=f"{name} (estimate)")
            if true_values and name in true_values:
                ax.axhline(true_values[name], color=line.get_color(), ls="--", lw=1,
                           label=f"{name} = {true_values[name]:g}")
        if ylim is None:
            from algid.plotting import estimate_ylim

            ylim = estimate_ylim(self.t, {name: self.estimates[name] for name in names},
                                 true_values=true_values)
        if ylim is not None:
            ax.set_ylim(*ylim)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("estimate")
        ax.set_title(f"algebraic estimates, model {self.model!r}, filter 1/s^{self.filter_order}")
        ax.legend(loc="best")
        ax.grid(True, alpha=0.3)
        return ax

    def __repr__(self):
        if self.n_samples == 0:
            return f"<EstimationResult model={self.model!r} n_samples=0 (no estimate)>"
        final = ", ".join(f"{k}={v:.6g}" for k, v in self.final().items())
        return (f"<EstimationResult model={self.model!r} n_samples={self.n_samples} "
                f"t_valid={self.t_valid:.6g} final: {final}>")
