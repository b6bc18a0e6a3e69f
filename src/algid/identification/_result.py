"""The result of :func:`algid.identify`: parameters, uncertainty, validation, export."""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from algid.errors import InputDataError, ModelError
from algid.identification._records import estimate_derivative, prepare_records
from algid.models._expression import Constant, Signal, Time
from algid.simulation._model import fit_initial_state, simulate_model
from algid.simulation._output_equation import OutputEquation

__all__ = ["IdentificationResult", "ResultRow", "Validation", "ROW_KEYS", "WARNING_SEPARATOR",
           "check_fit_samples",
           "check_row_names"]

#: Keys of :meth:`IdentificationResult.to_dict` besides the parameters and their errors.
ROW_KEYS = ("window", "n_samples", "estimate", "warnings")

#: What joins the warnings of a result into the one string of its row.
WARNING_SEPARATOR = " | "


def check_row_names(parameters, reserved=()):
    """Refuse parameter names that would collide with another key of a result's row.

    Parameters
    ----------
    parameters : sequence of str
        The model's parameters.
    reserved : sequence of str, optional
        Further keys of the table the rows go into (``error``, the id column).

    Raises
    ------
    ModelError
        A parameter named like a key of the row.
    """
    taken = set(ROW_KEYS) | set(reserved)
    taken |= {f"{kind}_{p}" for p in parameters for kind in ("stderr", "numerical_error")}
    clash = [p for p in parameters if p in taken]
    if clash:
        raise ModelError(f"parameter name {clash[0]!r} is also a column of the results "
                         f"table ({', '.join(ROW_KEYS + tuple(reserved))}, stderr_<p>, "
                         f"numerical_error_<p>); rename it")


@dataclass
class Validation:
    """A simulation of the identified model on one record.

    Attributes
    ----------
    t, measured, simulated : numpy.ndarray
        Times, measured and simulated output.
    initial_state : numpy.ndarray
        Fitted initial state (output and its derivatives).
    skip : int
        Samples used to fit the initial state, left out of the error.

    Examples
    --------
    >>> from algid.identification import identify
    >>> from algid.simulation import simulate
    >>> sim = simulate("sine", frequency=3.0, duration=10.0, rate=100.0, noise_std=1e-4, seed=0)
    >>> record = {"t": sim.t, "f": sim.f, "x": sim.x}
    >>> result = identify(record, "x'' + B*x' + K*x = f", "B K")
    >>> validation = result.simulate(record, method="RK4")
    >>> validation.skip, validation.simulated.shape, round(validation.fit_percent)
    (50, (1001,), 100)
    """

    t: np.ndarray
    measured: np.ndarray
    simulated: np.ndarray
    initial_state: np.ndarray
    skip: int

    @property
    def residuals(self):
        """Measured minus simulated output."""
        return self.measured - self.simulated

    @property
    def rmse(self):
        """Root-mean-square simulation error after the first ``skip`` samples."""
        return float(np.sqrt(np.mean(self.residuals[self.skip:] ** 2)))

    @property
    def fit_percent(self):
        """``100 (1 - |y - y_sim| / |y - mean(y)|)`` after the first ``skip`` samples."""
        y = self.measured[self.skip:]
        return float(100.0 * (1.0 - np.linalg.norm(self.residuals[self.skip:])
                              / np.linalg.norm(y - y.mean())))


class ResultRow:
    """What every result of identify holds: its values as attributes, standard errors, and
    the flat row of a results table (:class:`IdentificationResult` and
    :class:`algid.identification.SystemResult`; they name ``parameter_names`` and hold
    ``values``, ``covariance``, ``numerical_error``, ``window``, ``n_samples``,
    ``estimate`` and ``warnings``)."""

    def __getattr__(self, name):
        values = self.__dict__.get("values", {})
        if name in values:
            return values[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def parameters(self):
        """Parameter name -> estimate."""
        return dict(self.values)

    @property
    def stderr(self):
        """Parameter name -> standard error."""
        se = np.sqrt(np.maximum(np.diag(self.covariance), 0.0))
        return dict(zip(self.parameter_names, se.tolist()))

    def fit_percent(self, data, **kwargs):
        """Fit (%) of the simulated output on a record (of each output, for a system).

        Parameters
        ----------
        data : mapping
            One record.
        **kwargs
            Options of ``simulate``.

        Returns
        -------
        float or dict
            The fit; for a system, output name -> fit.
        """
        return self.simulate(data, **kwargs).fit_percent

    def to_dict(self):
        """The result as one flat row: a value per parameter, its errors, the window.

        The row of a table of results (:func:`algid.identify_many` makes one of a
        fleet): every value a plain Python scalar, so that it goes as it is into JSON,
        a pandas ``DataFrame``, a CSV or a Parquet file.

        Returns
        -------
        dict
            In this order: each parameter's value (under its own name); each one's
            standard error ``stderr_<p>``; each one's numerical error
            ``numerical_error_<p>`` (NaN where none was estimated); ``window`` (s),
            ``n_samples``, ``estimate`` (``"refined"`` or ``"algebraic"``) and
            ``warnings``: the warnings joined by ``" | "`` in one string (``""`` when
            there are none; a warning is one line without ``|``, and
            ``row["warnings"].split(" | ")`` gives ``result.warnings`` back), so that the
            row holds only scalars.

        Raises
        ------
        ModelError
            A parameter named like another key of the row (``window``,
            ``stderr_K``...).

        Examples
        --------
        >>> from algid.identification import identify
        >>> from algid.simulation import simulate
        >>> sim = simulate("sine", frequency=3.0, duration=10.0, rate=100.0, noise_std=1e-4, seed=0)
        >>> record = {"t": sim.t, "f": sim.f, "x": sim.x}
        >>> row = identify(record, "x'' + B*x' + K*x = f", "B K").to_dict()
        >>> list(row)  # doctest: +NORMALIZE_WHITESPACE
        ['B', 'K', 'stderr_B', 'stderr_K', 'numerical_error_B', 'numerical_error_K',
         'window', 'n_samples', 'estimate', 'warnings']
        >>> round(row["K"], 2), row["n_samples"], row["estimate"], row["warnings"]
        (3.0, 1001, 'refined', '')
        """
        parameters = self.parameter_names
        check_row_names(parameters)
        stderr = self.stderr
        row = {p: float(self.values[p]) for p in parameters}
        row.update({f"stderr_{p}": float(stderr[p]) for p in parameters})
        row.update({f"numerical_error_{p}": float(self.numerical_error.get(p, math.nan))
                    for p in parameters})
        row["window"] = float(self.window)
        row["n_samples"] = int(self.n_samples)
        row["estimate"] = str(self.estimate)
        row["warnings"] = WARNING_SEPARATOR.join(str(w) for w in self.warnings)
        return row

    def to_pandas(self):
        """The result as a pandas ``DataFrame`` of one row (:meth:`to_dict`).

        Concatenate the rows of several results (``pandas.concat``) to compare them,
        or let :func:`algid.identify_many` make the table of a fleet.

        Returns
        -------
        pandas.DataFrame
            One row (index 0), the columns of :meth:`to_dict` in its order.

        Examples
        --------
        >>> from algid.identification import identify
        >>> from algid.simulation import simulate
        >>> sim = simulate("sine", frequency=3.0, duration=10.0, rate=100.0, noise_std=1e-4, seed=0)
        >>> record = {"t": sim.t, "f": sim.f, "x": sim.x}
        >>> table = identify(record, "x'' + B*x' + K*x = f", "B K").to_pandas()
        >>> table.shape, table.loc[0, "estimate"], round(float(table.loc[0, "B"]), 3)
        ((1, 10), 'refined', 2.0)
        """
        import pandas as pd

        return pd.DataFrame([self.to_dict()])




@dataclass
class IdentificationResult(ResultRow):
    """Parameters identified on records, their uncertainty and validation helpers.

    Made by :func:`algid.identify` (or :meth:`from_values`); every parameter below is
    also an attribute of the same name.

    Parameters
    ----------
    model : Model
        The parsed model.
    values : dict
        Parameter name -> estimate (also readable as attributes: ``result.M``).
    covariance : numpy.ndarray
        Covariance of the estimates, in ``model.parameters`` order (see
        :mod:`algid.identification._identify`: that of the output noise through the kernels, or
        HAC).
    window : float
        Window length used (s).
    n_samples : int
        Samples used.
    n_windows : int
        Windows stacked (per multiplicity).
    method : str
        ``"bc"``, ``"ls"`` or ``"iv"``.
    multiplicities : tuple
        Kernel multiplicities stacked.
    time : str or None
        Time column of the records (as given to :func:`algid.identify`).
    rate : float or None
        Sampling rate of the records (as given to :func:`algid.identify`).
    window_scores : dict or None
        Window length (samples) -> criterion, when the window was chosen automatically.
    separate : dict
        Multiplicity -> estimate with that multiplicity alone.
    numerical_error : dict
        Parameter name -> estimated quadrature error (absolute): the difference between
        the estimates of the lowest and highest multiplicity (as an embedded
        Runge-Kutta pair estimates its step error).  Not part of the covariance; report
        it beside the standard error (on noisy records it also holds the part of the
        noise in which the two estimates differ).
    adequacy : algid.identification._adequacy.Adequacy or None
        The test of whether the model explains the data within the noise.
    warnings : list of str
        One-line warnings about the result (an inadequate model, poorly separated or
        strongly correlated parameters).
    estimate : {"algebraic", "refined"}
        Which estimate ``values`` and ``covariance`` hold: the algebraic one, or the
        output-error refinement started from it (:meth:`refine`).
    algebraic : dict or None
        The algebraic estimate: ``{"values": ..., "covariance": ...,
        "numerical_error": ..., "warnings": ...}`` (a refined estimate's numerical
        error is that of its simulation, its warnings those of the test of its
        simulation residuals).
    refinement : algid.identification._refinement.Refinement or None
        Whether the refinement was applied, why, and its figures.

    Examples
    --------
    >>> from algid.identification import identify
    >>> from algid.simulation import simulate
    >>> sim = simulate("sine", frequency=3.0, duration=10.0, rate=100.0, noise_std=1e-4, seed=0)
    >>> record = {"t": sim.t, "f": sim.f, "x": sim.x}
    >>> result = identify(record, "x'' + B*x' + K*x = f", "B K")
    >>> result.model.parameters, result.method, result.n_samples
    (('B', 'K'), 'bc', 1001)
    >>> round(result.values["K"], 2), result.stderr["K"] < 0.01
    (3.0, True)
    """

    model: object
    values: dict
    covariance: np.ndarray
    window: float
    n_samples: int
    n_windows: int
    method: str
    multiplicities: tuple
    time: str | None = None
    rate: float | None = None
    window_scores: dict | None = None
    separate: dict = field(default_factory=dict)
    numerical_error: dict = field(default_factory=dict)
    adequacy: object = None
    warnings: list = field(default_factory=list)
    estimate: str = "algebraic"
    algebraic: dict | None = None
    refinement: object = None

    @property
    def parameter_names(self):
        """The parameters, in the order of ``covariance``."""
        return self.model.parameters

    @property
    def equation(self):
        """The model equation as written."""
        return self.model.equation

    def __repr__(self):
        def piece(p, v):
            numerical = self.numerical_error.get(p)
            extra = "" if numerical is None else f" (numerical {numerical:.2g})"
            return f"{p}={v:.6g} ± {self.stderr[p]:.2g}{extra}"

        if self.method == "given" and self.estimate != "refined":  # nothing was measured
            pieces = ", ".join(f"{p}={v:.6g}" for p, v in self.values.items())
            return f"IdentificationResult({self.model.equation!r}: {pieces}; given)"
        pieces = ", ".join(piece(p, v) for p, v in self.values.items())
        warned = "".join(f"; warning: {w}" for w in self.warnings)
        if self.method == "given":   # refined from values of the user's choosing
            return (f"IdentificationResult({self.model.equation!r}: {pieces}; "
                    f"{self.n_samples} samples, refined by output error from given "
                    f"values{warned})")
        refined = "; refined by output error" if self.estimate == "refined" else ""
        return (f"IdentificationResult({self.model.equation!r}: {pieces}; window "
                f"{self.window:.4g} s, {self.n_samples} samples, {self.method}{refined}"
                f"{warned})")

    @classmethod
    def from_values(cls, equation, values, *, parameters=None, output=None, time=None,
                    rate=None):
        """A result holding parameter values of your choosing, to simulate and validate.

        Everything a result of :func:`algid.identify` offers for validation
        (:meth:`simulate`, :meth:`fit_percent`, :meth:`residuals`, :meth:`plot`,
        :meth:`to_control`, :meth:`to_nlsys`) then works on any values: published ones,
        a colleague's, a design target.  No uncertainty is known (NaN covariance).

        Parameters
        ----------
        equation : str or Model
            The model, as for :func:`algid.identify`; its parameters are the keys of
            ``values`` (its other names are signals, read from the records).
        values : mapping
            Parameter name -> value, for every parameter of the model.
        parameters : str or sequence of str, optional
            The model's parameters, when they must be stated: by default the keys of
            ``values``, and a name left out of them that multiplies a signal as a
            parameter would (``k*y``) is refused as a value missing.
        output : str, optional
            The output signal (default: the signal of highest derivative order).
        time : str, optional
            Time column of the records it will be given.
        rate : float, optional
            Sampling rate of the records it will be given, without a time column.

        Returns
        -------
        IdentificationResult
            ``method`` is ``"given"``; ``window`` NaN, ``n_samples`` 0.

        Raises
        ------
        ModelError
            A bad equation.
        InputDataError
            Values missing, unknown or not finite real numbers.
        """
        from algid.models._grammar import parse_equation
        from algid.models._model import Model

        if not isinstance(values, Mapping):
            raise InputDataError(f"values must be a mapping of parameter name -> value, "
                                 f"got {type(values).__name__}")
        if isinstance(equation, Model):
            model = equation
        else:
            model = parse_equation(equation, list(values) if parameters is None else
                                   parameters, output=output)
            if parameters is None:
                _refuse_unvalued(model)
        n = len(model.parameters)
        blank = cls(model=model, values=dict.fromkeys(model.parameters, math.nan),
                    covariance=np.full((n, n), np.nan), window=math.nan, n_samples=0,
                    n_windows=0, method="given", multiplicities=(), time=time, rate=rate)
        return blank.with_parameters(values)

    def with_parameters(self, values):
        """Return a copy with other parameter values (e.g. published ones).

        The covariance is kept as it is; use it to validate other values the same way.
        The adequacy test, made for the identified values, is not carried over.

        Parameters
        ----------
        values : mapping
            Parameter name -> value, for every parameter of the model.

        Returns
        -------
        IdentificationResult
        """
        if not isinstance(values, Mapping):
            raise InputDataError(f"with_parameters needs a mapping of parameter name -> "
                                 f"value, got {type(values).__name__}")
        missing = [p for p in self.model.parameters if p not in values]
        if missing:
            raise InputDataError(f"no value for parameter {missing[0]}")
        unknown = [p for p in values if p not in self.model.parameters]
        if unknown:
            raise InputDataError(f"{unknown[0]!r:.40} is not a parameter of the model "
                                 f"(its parameters: {', '.join(self.model.parameters)})")
        for p in self.model.parameters:
            v = values[p]
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real) \
                    or not math.isfinite(v):
                raise InputDataError(f"parameter {p} must be a finite real number, got "
                                     f"{v!r:.40}")
        return replace(self, values={p: float(values[p]) for p in self.model.parameters},
                       adequacy=None, warnings=[])

    def refine(self, data, *, time=None, rate=None):
        """The output-error refinement of this estimate on records.

        A prediction-error fit of the model's simulated output to the measured one,
        started from this estimate, with the initial state of every record (and of every
        run between gaps) as a nuisance parameter: the maximum-likelihood estimate under
        white output noise, whose standard errors reach the Cramér–Rao bound.  Its
        covariance counts coloured residuals (an autoregressive model of them), so it
        stays honest under coloured noise.  Models linear in their signals, sampled
        uniformly (see the user guide, "How good is my estimate").

        Parameters
        ----------
        data : record or list of records
            The records the estimate came from (or others of the same system).
        time, rate
            Time axis, as for :func:`algid.identify` (default: those of the fit).

        Returns
        -------
        IdentificationResult
            ``estimate == "refined"`` with the refined values and covariance, the
            algebraic ones in ``algebraic``; or, where the fit does not lower the
            simulation error, this estimate with a warning saying so.

        Raises
        ------
        ModelError
            A model the refinement cannot simulate (not proper, a ``sign()`` of an
            expression of the output rather than of one of its derivatives, or numba not
            installed for a model nonlinear in its signals).
        """
        from algid.identification._output_error import refine_result

        if self.method == "given" or not np.all(np.isfinite(self.covariance)):
            base = self
        else:
            base = self if self.estimate == "algebraic" else replace(
                self, values=dict(self.algebraic["values"]),
                covariance=self.algebraic["covariance"], estimate="algebraic",
                numerical_error=dict(self.algebraic["numerical_error"]),
                warnings=list(self.algebraic["warnings"]))
        time = self.time if time is None and rate is None else time
        rate = self.rate if time is None and rate is None else rate
        segments, step, n_samples = prepare_records(
            data, self.model.signals, time=time, rate=rate,
            min_length=2 * max(self.model.order, 1) + 2)
        if self.method == "given":   # its samples are now these records'
            base = replace(base, n_samples=n_samples)
        return refine_result(base, segments, step, True)

    # validation -------------------------------------------------------------------------

    def _record(self, data, time, rate):
        time = self.time if time is None and rate is None else time
        rate = self.rate if time is None and rate is None else rate
        segments, _, _ = prepare_records(data, self.model.signals, time=time, rate=rate,
                                         min_length=2)
        if len(segments) != 1:
            raise InputDataError("simulate needs one record without gaps or NaN")
        return segments[0]

    def simulate(self, data, *, time=None, rate=None, fit_samples=None, method="DOP853",
                 interpolation="bandlimited", substeps=4):
        """Simulate the identified model on a record, driven by its measured inputs.

        The simulator is :func:`algid.simulation.simulate_model`: by default
        DOP853 (relative tolerance 1e-8) with the inputs interpolated as band-limited
        signals (a cubic spline on a non-uniform grid).  ``method="RK4"`` (4 steps per
        sample on the same interpolant) is about ten times faster: within 9 uV rms of
        DOP853 on the Silverbox arrow part (9 samples per period), 2e-4 of the output's
        spread on a synthetic record at 8 samples per period (DOP853: 5e-8).  The
        initial state is fitted on the first ``fit_samples`` samples, which are left
        out of the error.

        Parameters
        ----------
        data : mapping
            One record (column name -> samples).
        time, rate
            Time axis, as for :func:`algid.identify` (default: those of the fit).
        fit_samples : int, optional
            Samples used to fit the initial state (and left out of the error): from the
            model order + 1 to half the record's samples (the rest measure the fit);
            default 50, or half the record if it is shorter than 100 samples.
        method : str
            Integrator: a :func:`scipy.integrate.solve_ivp` method (default
            ``"DOP853"``) or ``"RK4"`` with ``substeps`` fixed steps per sample.
        interpolation : {"bandlimited", "cubic"}
            Input between samples: band-limited (uniform grids) or cubic spline.
        substeps : int
            Steps per sampling interval of ``method="RK4"``.

        Returns
        -------
        Validation

        Raises
        ------
        ModelError
            Where the simulated output diverges (is not finite from some time on).
        """
        seg = self._record(data, time, rate)
        fit_samples = check_fit_samples(fit_samples, self.model.order, len(seg))
        inputs = {name: seg.values[name] for name in self.model.inputs}
        y = seg.values[self.model.output]
        options = {"output": self.model.output, "method": method,
                   "interpolation": interpolation, "substeps": substeps}
        with np.errstate(over="ignore", invalid="ignore"):   # a diverging model: refused
            x0 = fit_initial_state(self.model, self.values, seg.t, inputs, y, fit_samples,
                                   **options)
            simulated = simulate_model(self.model, self.values, seg.t, inputs,
                                       initial_state=x0, **options)
        bad = np.flatnonzero(~np.isfinite(simulated))
        if bad.size or not np.all(np.isfinite(x0)):
            start = seg.t[bad[0]] if bad.size else seg.t[0]
            raise ModelError(f"the simulated output diverges: it is not finite from "
                             f"t = {start:.6g} s on with parameters "
                             f"{', '.join(f'{p}={v:.6g}' for p, v in self.values.items())}")
        return Validation(seg.t, y, simulated, x0, fit_samples)

    def residuals(self, data, **kwargs):
        """Measured minus simulated output on a record.

        Parameters
        ----------
        data : mapping
            One record.
        **kwargs
            Options of :meth:`simulate`.

        Returns
        -------
        numpy.ndarray
        """
        return self.simulate(data, **kwargs).residuals

    def equation_error(self, data, *, time=None, rate=None, span=None):
        """Relative error of the equation on a record, as for an inverse model.

        Every term is evaluated on the record (derivatives by a local polynomial
        derivative); the result is ``|sum of all terms| / |known terms|``: for
        ``M*q'' + ... = F`` the relative error of the predicted force.

        Parameters
        ----------
        data : mapping
            One record.
        time, rate
            Time axis, as for :func:`algid.identify` (default: those of the fit).
        span : int, optional
            Samples of the local polynomial derivative (default: 2k + 7).

        Returns
        -------
        float
        """
        seg = self._record(data, time, rate)
        values = dict(seg.values)
        for term in self.model.terms:
            if term.derivative and isinstance(term.factor, Signal):
                key = (term.factor.name, term.derivative)
                values[key] = estimate_derivative(values[term.factor.name], seg.t,
                                                  term.derivative, seg.step, span)
        for name, k in self.model.needs_derivatives:
            values[(name, k)] = estimate_derivative(values[name], seg.t, k, seg.step, span)
        total, known = 0.0, 0.0
        for term in self.model.terms:
            factor = (Signal(term.factor.name, term.derivative)
                      if term.derivative else term.factor)
            z = factor.evaluate(values, seg.t) * term.coefficient
            if term.parameter is None:
                known = known + z
                total = total + z
            else:
                total = total + self.values[term.parameter] * z
        return float(np.linalg.norm(total) / np.linalg.norm(known))

    def plot(self, data, ax=None, **kwargs):
        """Plot measured against simulated output on a record (matplotlib).

        Parameters
        ----------
        data : mapping
            One record.
        ax : matplotlib.axes.Axes, optional
            Axes to draw on (a new figure by default).
        **kwargs
            Options of :meth:`simulate`.

        Returns
        -------
        matplotlib.axes.Axes
        """
        import matplotlib.pyplot as plt

        v = self.simulate(data, **kwargs)
        if ax is None:
            _, ax = plt.subplots(figsize=(8, 3.5))
        ax.plot(v.t, v.measured, lw=0.8, label="measured")
        ax.plot(v.t, v.simulated, lw=0.8, label=f"model (fit {v.fit_percent:.1f} %)")
        ax.plot(v.t, v.residuals, lw=0.6, label="error")
        ax.set_xlabel("t (s)")
        ax.set_ylabel(self.model.output)
        ax.legend(loc="upper right")
        return ax

    # export -----------------------------------------------------------------------------

    def to_control(self, kind="tf"):
        """Export the identified linear model to python-control.

        Offset (constant) terms are left out: they are not part of the dynamics.

        Parameters
        ----------
        kind : {"tf", "ss"}
            A ``TransferFunction`` or a ``StateSpace``, from the inputs to the output.

        Returns
        -------
        control.TransferFunction or control.StateSpace

        Raises
        ------
        ModelError
            For a nonlinear model, a model without input, or one with a term in time
            (``d*t``: not an offset, and no transfer function has it).
        """
        import control as ct

        if kind not in ("tf", "ss"):
            raise ModelError(f"to_control: kind must be 'tf' or 'ss', got {kind!r:.40}")
        model = self.model
        if not model.is_linear:
            raise ModelError("to_control needs a linear model; use to_nlsys()")
        ramps = [str(t) for t in model.terms if isinstance(t.factor, Time)]
        if ramps:
            raise ModelError(f"to_control: the term {ramps[0]} in time is not an offset "
                             f"and has no transfer function; identify without it to export")
        if not model.inputs:
            raise ModelError("to_control: the model has no input, so no transfer function "
                             "(its output is driven by its initial state only)")
        output = model.output
        den, nums = {}, {}
        for term in model.terms:
            value = term.coefficient * (1.0 if term.parameter is None
                                        else self.values[term.parameter])
            if isinstance(term.factor, (Constant, Time)):
                continue
            name = term.factor.name
            if name == output:
                den[term.derivative] = den.get(term.derivative, 0.0) + value
            else:
                nums.setdefault(name, {})
                nums[name][term.derivative] = nums[name].get(term.derivative, 0.0) - value
        order = max(den)
        den_coeffs = [den.get(k, 0.0) for k in range(order, -1, -1)]
        inputs = list(nums)
        num_coeffs = [[[nums[u].get(k, 0.0) for k in range(max(nums[u]), -1, -1)]
                       for u in inputs]]
        if len(inputs) == 1:
            system = ct.tf(num_coeffs[0][0], den_coeffs, inputs=inputs, outputs=[output])
        else:
            system = ct.tf(num_coeffs, [[den_coeffs] * len(inputs)], inputs=inputs,
                           outputs=[output])
        return ct.ss(system) if kind == "ss" else system

    def to_nlsys(self):
        """The identified model as a python-control nonlinear I/O system.

        States: the output and its derivatives below the model order; inputs: the
        other measured signals (derivatives of inputs are not available).

        Returns
        -------
        control.NonlinearIOSystem
        """
        import control as ct

        equation = OutputEquation(self.model, self.values)
        names = [name for name, _ in equation.inputs]
        if any(k for _, k in equation.inputs):
            raise ModelError("to_nlsys: the model reads a derivative of an input")

        def update(t, x, u, params):
            return np.array(equation.derivative(t, [float(v) for v in x],
                                                [float(v) for v in np.atleast_1d(u)]))

        def output(t, x, u, params):
            return np.array([x[0]])

        out = self.model.output
        states = [out + "'" * k for k in range(equation.order)]
        return ct.nlsys(update, output, inputs=names, outputs=[out], states=states,
                        name=self.model.name)


def check_fit_samples(fit_samples, order, n):
    """``fit_samples`` of :meth:`IdentificationResult.simulate`, checked (default: 50,
    or half a record shorter than 100 samples)."""
    if fit_samples is None:
        fit_samples = min(50, n // 2)
    if isinstance(fit_samples, (bool, np.bool_)) or not isinstance(fit_samples,
                                                                   (int, np.integer)):
        raise InputDataError(f"fit_samples must be an integer, got {fit_samples!r:.40}")
    if not order + 1 <= fit_samples <= n // 2:
        raise InputDataError(f"fit_samples must be in {order + 1}..{n // 2} (at most half "
                             f"the record's {n} samples), got {fit_samples}")
    return int(fit_samples)


def _refuse_unvalued(model):
    """Refuse a name that appears nowhere else and multiplies a signal that does (``k*y``),
    as a parameter would: a parameter whose value was left out (read as a signal)."""
    from algid.models._expression import Product, Signal

    for term in model.terms:
        if term.parameter is not None or not isinstance(term.factor, Product):
            continue
        for factor in term.factor.factors:
            if not isinstance(factor, Signal) or factor.derivative or \
                    factor.name == model.output:
                continue
            others = {name for f in term.factor.factors if f is not factor
                      for name in f.signals()}
            elsewhere = {name for other in model.terms if other is not term
                         for name in other.factor.signals()} | {model.output}
            if factor.name not in elsewhere and others & elsewhere:
                raise InputDataError(
                    f"no value for {factor.name!r}, which multiplies {term.factor} as a "
                    f"parameter would; give its value, or parameters= naming the "
                    f"parameters if {factor.name!r} is a signal")
