"""The result of :func:`algid.identify` on a system of equations: the shared parameters,
their joint covariance, the coupled system's simulation and export."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from algid.errors import InputDataError, ModelError
from algid.identification._records import prepare_records
from algid.identification._result import ResultRow, check_fit_samples

__all__ = ["SystemResult", "SystemValidation", "WEAK_RELATIVE_ERROR"]

#: A parameter whose standard error exceeds this fraction of its value is warned of as
#: poorly determined (and no output-error fit is started from it automatically).
WEAK_RELATIVE_ERROR = 0.25


@dataclass
class SystemValidation:
    """A simulation of an identified system on one record.

    Attributes
    ----------
    t : numpy.ndarray
        Times.
    measured, simulated : dict
        Output name -> samples.
    initial_state : numpy.ndarray
        The fitted initial state (each output and its derivatives).
    skip : int
        Samples used to fit the initial state, left out of the errors.

    Examples
    --------
    >>> import numpy as np
    >>> from algid.identification import SystemValidation
    >>> t = np.arange(4.0)
    >>> v = SystemValidation(t, {"y": np.array([0.0, 1, 2, 3])},
    ...                      {"y": np.array([0.0, 1, 2, 2.5])}, np.zeros(1), 1)
    >>> v.rmse["y"] == float(np.sqrt(0.25 / 3)), round(v.fit_percent["y"], 1)
    (True, 64.6)
    """

    t: np.ndarray
    measured: dict
    simulated: dict
    initial_state: np.ndarray
    skip: int

    @property
    def residuals(self):
        """Output name -> measured minus simulated samples."""
        return {y: self.measured[y] - self.simulated[y] for y in self.measured}

    @property
    def rmse(self):
        """Output name -> root-mean-square simulation error after ``skip`` samples."""
        return {y: float(np.sqrt(np.mean(r[self.skip:] ** 2)))
                for y, r in self.residuals.items()}

    @property
    def fit_percent(self):
        """Output name -> ``100 (1 - |y - y_sim| / |y - mean(y)|)`` after ``skip``."""
        fits = {}
        for y, r in self.residuals.items():
            v = self.measured[y][self.skip:]
            fits[y] = float(100.0 * (1.0 - np.linalg.norm(r[self.skip:])
                                     / np.linalg.norm(v - v.mean())))
        return fits


@dataclass
class SystemResult(ResultRow):
    """Shared parameters of a system of equations identified on records.

    Made by :func:`algid.identify` given a list of equations; every parameter is also
    an attribute of the same name.

    Parameters
    ----------
    system : algid.models.SystemModel
        The equations.
    values : dict
        Parameter name -> estimate.
    covariance : numpy.ndarray
        Joint covariance of the estimates, in ``system.parameters`` order: it counts the
        correlation between equations that share a noisy signal.
    window : float
        Window length (s).
    n_samples, n_windows : int
        Samples used; windows stacked per equation.
    method : str
        ``"bc"`` or ``"ls"``.
    multiplicities : tuple
        Kernel multiplicities.
    time, rate : optional
        As given to :func:`algid.identify`.
    numerical_error : dict
        Parameter name -> the difference of the two multiplicities' estimates.
    misfits : dict
        Output name (one per equation) -> its equation's residual energy over what the
        noise of its signals puts there (about 1 or less for an equation that holds).
    window_scores : dict or None
        The window rule's criterion per length (samples), when it chose the window.
    warnings : list of str
        One-line warnings.
    estimate : {"algebraic", "refined"}
        Which estimate ``values`` and ``covariance`` hold: the algebraic one (the
        stacked window equations) or its output-error refinement on every output.
    algebraic : dict or None
        The algebraic estimate: ``{"values", "covariance", "numerical_error",
        "warnings"}``.
    refinement : algid.identification._refinement.Refinement or None
        Whether the refinement was applied, why, and its figures.
    noise_rms : dict
        Output name -> rms of the refined simulation's residuals (the output noise, for
        a model that holds); empty where not refined.
    hidden : tuple of str
        Outputs of the equations that are not measured (eliminated for the algebraic
        estimate, simulated by the refinement).
    elimination : algid.identification._hidden.Elimination or None
        With hidden signals: the input–output equations identified, and their
        coefficients as functions of the parameters.

    Examples
    --------
    >>> import numpy as np
    >>> from algid.identification import identify
    >>> from algid.simulation import simulate_system
    >>> t = np.arange(0, 20, 1e-3)
    >>> u = np.sin(2.1 * t) + np.sin(5.3 * t) + np.sin(11.7 * t)
    >>> true = {"L": 0.5, "R": 2.0, "K": 0.8, "J": 0.2, "b": 0.1}
    >>> equations = ["L*i' + R*i + K*w = u", "J*w' + b*w = K*i"]
    >>> outputs = simulate_system(equations, true, t, {"u": u})
    >>> result = identify({"t": t, "u": u, **outputs}, equations, "L R K J b")
    >>> {p: round(v, 3) for p, v in result.values.items()}
    {'L': 0.5, 'R': 2.0, 'K': 0.8, 'J': 0.2, 'b': 0.1}
    """

    system: object
    values: dict
    covariance: np.ndarray
    window: float
    n_samples: int
    n_windows: int
    method: str
    multiplicities: tuple
    time: str | None = None
    rate: float | None = None
    numerical_error: dict = field(default_factory=dict)
    misfits: dict = field(default_factory=dict)
    window_scores: dict | None = None
    warnings: list = field(default_factory=list)
    estimate: str = "algebraic"
    algebraic: dict | None = None
    refinement: object = None
    noise_rms: dict = field(default_factory=dict)
    hidden: tuple = ()
    elimination: object = None

    @property
    def parameter_names(self):
        """The parameters, in the order of ``covariance``."""
        return self.system.parameters

    @property
    def equations(self):
        """The equations as written."""
        return [model.equation for model in self.system.equations]

    @property
    def outputs(self):
        """The output of each equation."""
        return self.system.outputs

    @property
    def measured(self):
        """The outputs that are measured (not hidden)."""
        return tuple(y for y in self.system.outputs if y not in self.hidden)

    @property
    def correlation(self):
        """The correlation matrix of the estimates (``system.parameters`` order)."""
        se = np.sqrt(np.maximum(np.diag(self.covariance), 0.0))
        se[se == 0] = 1.0
        return self.covariance / se[:, None] / se[None, :]

    def __repr__(self):
        pieces = ", ".join(f"{p}={v:.6g} ± {self.stderr[p]:.2g}"
                           for p, v in self.values.items())
        warned = "".join(f"; warning: {w}" for w in self.warnings)
        refined = "; refined by output error" if self.estimate == "refined" else ""
        return (f"SystemResult({self.system.equation!r}: {pieces}; window "
                f"{self.window:.4g} s, {self.n_samples} samples, {self.method}{refined}"
                f"{warned})")

    # validation ---------------------------------------------------------------------

    def simulate(self, data, *, time=None, rate=None, fit_samples=None):
        """Simulate the coupled system on a record, driven by its measured inputs.

        A linear system is simulated exactly for inputs linear between samples
        (:mod:`algid.simulation._system`), a nonlinear one by DOP853 on interpolated
        inputs (:func:`algid.simulation.simulate_system`); the initial state is fitted
        on the first ``fit_samples`` samples of every output, which are left out of the
        errors.

        Parameters
        ----------
        data : mapping
            One record holding the inputs and the outputs.
        time, rate
            Time axis, as for :func:`algid.identify` (default: those of the fit).
        fit_samples : int, optional
            Samples for the initial state (default 50, or half a short record; with
            hidden signals, half the record: their initial state is read from the
            measured outputs, which need a long stretch to show it).

        Returns
        -------
        SystemValidation

        Raises
        ------
        ModelError
            A system that cannot be simulated (a top derivative inside a nonlinear
            factor), or a simulation that diverges.
        """
        from algid.simulation._system import fit_initial_state, state_space
        from algid.simulation._system_equations import (
            SystemEquations,
            fit_nonlinear_initial_state,
            simulate_nonlinear_system,
        )

        time = self.time if time is None and rate is None else time
        rate = self.rate if time is None and rate is None else rate
        signals = [s for s in self.system.signals if s not in self.hidden]
        segments, _, _ = prepare_records(data, signals, time=time, rate=rate, min_length=2)
        if len(segments) != 1:
            raise InputDataError("simulate needs one record without gaps or NaN")
        seg = segments[0]
        linear = self.system.is_linear
        space = state_space(self.system, self.values) if linear else \
            SystemEquations(self.system, self.values)
        order = max(k for _, k in space.states) + 1
        if fit_samples is None and self.hidden:
            fit_samples = len(seg) // 2
        fit_samples = check_fit_samples(fit_samples, order, len(seg))
        measured = {y: seg.values[y] for y in self.measured}
        inputs = {u: seg.values[u] for u in self.system.inputs}
        with np.errstate(over="ignore", invalid="ignore"):
            if linear:
                x0, forced, free = fit_initial_state(space, seg.t, inputs, measured,
                                                     fit_samples)
                simulated = forced + np.tensordot(x0, free, axes=1)
            else:
                x0 = fit_nonlinear_initial_state(space, seg.t, inputs, measured,
                                                 fit_samples)
                simulated = simulate_nonlinear_system(space, seg.t, inputs, x0)
        if not np.all(np.isfinite(simulated)):
            raise ModelError("the simulated outputs are not finite (the system diverges, or "
                             "leaves a function's domain) with parameters "
                             + ", ".join(f"{p}={v:.6g}" for p, v in self.values.items()))
        simulated = dict(zip(self.outputs, simulated))
        return SystemValidation(seg.t, measured, {y: simulated[y] for y in measured}, x0,
                                fit_samples)

    # export -------------------------------------------------------------------------

    def to_control(self):
        """The identified linear system as a python-control ``StateSpace`` (MIMO).

        States: each output and its derivatives below its order; inputs: the measured
        inputs, then ``one`` (offsets) and ``time`` (drifts) where the equations have
        them.

        Returns
        -------
        control.StateSpace

        Raises
        ------
        ModelError
            A nonlinear system (no state-space form: :meth:`to_nlsys` exports it).
        """
        import control as ct

        from algid.simulation._system import ONE, TIME, state_space

        if not self.system.is_linear:
            raise ModelError("to_control: this system is not linear in its signals, so it "
                             "has no state-space form; to_nlsys() exports it")
        space = state_space(self.system, self.values)
        names = {ONE: "one", TIME: "time"}
        states = [y if k == 0 else f"{y}{chr(39) * k}" for y, k in space.states]
        return ct.ss(space.A, space.B, space.C, np.zeros((len(space.outputs),
                                                          len(space.channels))),
                     inputs=[names.get(c, c) for c in space.channels],
                     outputs=list(space.outputs), states=states)

    def to_nlsys(self):
        """The identified system as a python-control nonlinear I/O system (MIMO).

        Linear or not in its signals.  States: each output and its derivatives below its
        order; inputs: the measured inputs; outputs: every equation's output.

        Returns
        -------
        control.NonlinearIOSystem

        Raises
        ------
        ModelError
            A system that cannot be simulated (a top derivative inside a nonlinear
            factor, a derivative of an input).
        """
        import control as ct

        from algid.simulation._system_equations import SystemEquations

        equations = SystemEquations(self.system, self.values)
        rows = [equations.states.index((y, 0)) for y in equations.outputs]

        def update(t, x, u, params):
            return np.array(equations.derivative(t, [float(v) for v in x],
                                                 [float(v) for v in np.atleast_1d(u)]))

        def output(t, x, u, params):
            return np.asarray(x, dtype=float)[rows]

        states = [y if k == 0 else f"{y}{chr(39) * k}" for y, k in equations.states]
        return ct.nlsys(update, output, inputs=list(equations.inputs),
                        outputs=list(equations.outputs), states=states,
                        name="identified_system")
