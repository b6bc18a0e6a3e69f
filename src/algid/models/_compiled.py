"""User equations in the algebraic estimator: from text to a generated estimator.

:func:`compile_equation` reads an equation with the restricted grammar of
:mod:`algid.models._grammar`, derives its estimator with the symbolic engine (the same
derivation and generator as the built-in models, run in memory) and returns the
generated module, which :func:`algid.estimate` takes as ``model``.  Its channels are the
model's factors: measured signals, the constant 1 of an offset, time, and nonlinear
factors such as ``V2**3`` or ``sign(q')``.  :class:`ChannelStream` computes their
samples from the measured signals, chunk by chunk; a derivative inside a nonlinear
factor is estimated by the algebraic differentiator
(:func:`algid.signals.algebraic_derivative`), centred on each sample (it looks ahead
by half its window; a whole record in one call) or causal (for
:class:`algid.OnlineEstimator`).

Compiling needs SymPy (``algid[derive]``); estimating with the result needs NumPy only.
"""

from __future__ import annotations

import numpy as np

from algid._signal_checks import positive_number
from algid.errors import InputDataError, ModelError
from algid.models._grammar import LIMITS, parse_equation
from algid.models._model import channel_names
from algid.models._system import SystemModel, is_system, parse_system

__all__ = ["compile_equation", "channel_stream", "ChannelStream", "model_of"]


def compile_equation(equation, parameters, *, output=None, name="custom"):
    """The generated estimator of a user equation or system of equations, built in memory.

    A system (a list of equations sharing parameters, :func:`algid.models.parse_system`)
    gives one estimator of the stacked rows of every equation's ``P theta = Q``
    (:class:`algid.symbolic.SystemDerivation`), in the channels of all the equations;
    where they outnumber the parameters, it solves the normal equations ``P^T P theta =
    P^T Q`` at every instant by Cramer's rule, as one equation's estimator solves its
    own.  Equations without parameters are left out.

    Parameters
    ----------
    equation : str or list of str
        The model, e.g. ``"y'' + B*y' + K*y + K3*y**3 = G*u + d"``; see
        :func:`algid.models.parse_equation`.  A list (or a
        :class:`~algid.models.SystemModel`): a system of equations.
    parameters : str or sequence of str
        The unknown parameters (of the whole system).
    output : str or list of str, optional
        The output signal (default: the signal of highest derivative order); for a
        system, one per equation.
    name : str, optional
        Label of the model (an identifier).

    Returns
    -------
    module
        The generated estimator (``CHANNELS``, ``FACTORS``, ``PARAMETERS``, the algebra;
        for a system also ``EQUATIONS``, ``OUTPUTS`` and ``ROWS``, the equation of every
        row); pass it as ``model`` to :func:`algid.estimate` (``signals=`` or a record)
        or :class:`algid.OnlineEstimator`.

    Raises
    ------
    ModelError
        A bad equation or system (also: parameters that no data can separate), or SymPy
        is missing.

    Examples
    --------
    >>> from algid.models import compile_equation
    >>> module = compile_equation("y'' + B*y' + K*y + K3*y**3 = G*u + d", "B K K3 G d")
    >>> module.CHANNELS, module.FACTORS
    (('y', 'z1', 'u', 'one'), {'z1': 'y**3', 'one': '1'})

    A DC motor, whose two equations share the torque constant ``K``:

    >>> import numpy as np
    >>> import algid
    >>> motor = ["L*i' + R*i + K*w = u", "J*w' + b*w = K*i"]
    >>> module = compile_equation(motor, "L R K J b")
    >>> module.CHANNELS, module.N_EQUATIONS, module.ROWS
    (('i', 'w', 'u'), 6, (1, 1, 1, 2, 2, 2))
    >>> t = np.arange(0, 10, 1e-3)
    >>> u = np.sin(2 * t) + np.sin(7.1 * t)
    >>> true = {"L": 0.5, "R": 2.0, "K": 0.8, "J": 0.2, "b": 0.1}
    >>> record = {"t": t, "u": u, **algid.simulate_system(motor, true, t, {"u": u})}
    >>> r = algid.estimate(record, module)
    >>> {p: round(v, 4) for p, v in r.final().items()}
    {'L': 0.5, 'R': 2.0, 'K': 0.8, 'J': 0.2, 'b': 0.1}
    """
    if is_system(equation):
        model = parse_system(equation, parameters, outputs=output, name=name)
        if len(model.parameters) > LIMITS["parameters"]:
            # (Cramer's rule on the normal equations: its code grows as 2^n)
            raise ModelError(f"a system of {len(model.parameters)} parameters: its generated "
                             f"estimator solves at most {LIMITS['parameters']} at once "
                             f"(algid.identify and algid.Tracker take up to "
                             f"{LIMITS['system_parameters']})")
    else:
        model = parse_equation(equation, parameters, output=output, name=name)
    try:
        from algid.symbolic._channels import ChannelModel
        from algid.symbolic._codegen import compile_model
        from algid.symbolic._derivation import derive
    except ImportError:
        raise ModelError("compiling an equation needs SymPy: pip install 'algid[derive]'") \
            from None
    if isinstance(model, SystemModel):
        derivation = derive(model)
        named = derivation.inseparable()
        if named:
            raise ModelError(f"no data can separate {', '.join(named)}: only a combination "
                             f"of them is determined (their terms are proportional in "
                             f"every equation; keep one of them)")
        return compile_model(derivation)
    return compile_model(derive(ChannelModel(model)))


def model_of(module):
    """The user :class:`~algid.models.Model` behind a generated estimator module.

    Parameters
    ----------
    module : module
        A generated estimator (built-in or from :func:`compile_equation`).

    Returns
    -------
    Model or SystemModel
        Read again from the module's equation and parameters (the generated text is
        self-describing); a :class:`~algid.models.SystemModel` of the equations it
        estimates from for a system's module.
    """
    if hasattr(module, "EQUATIONS"):
        return parse_system(module.EQUATIONS, module.PARAMETERS, outputs=module.OUTPUTS,
                            name=module.MODEL)
    return parse_equation(module.EQUATION, module.PARAMETERS, output=module.OUTPUT,
                          name=module.MODEL)


def channel_stream(module, dt, *, differentiator="centred", derivative_window=None,
                   derivative_extra_orders=0):
    """A fresh :class:`ChannelStream` of a generated estimator, its options checked.

    Parameters
    ----------
    module : module
        A generated estimator.
    dt : float
        Sampling step.
    differentiator : {"centred", "causal"}, optional
        How a derivative inside a nonlinear factor is estimated
        (:func:`algid.signals.algebraic_derivative`): with the window centred on each
        sample (default; it looks ahead by about half the window), or causal (the
        window ``[t - T, t]``, as :class:`algid.OnlineEstimator` does; it lags by
        :attr:`ChannelStream.delay` and the first :attr:`ChannelStream.warmup` samples
        of such channels are NaN).
    derivative_window : float, optional
        The differentiator's window ``T`` [s]; default ``DEFAULT_WINDOW_STEPS * dt``.
    derivative_extra_orders : int, optional
        See :class:`ChannelStream`.

    Returns
    -------
    ChannelStream

    Raises
    ------
    InputDataError
        A bad differentiator option.
    """
    if differentiator not in ("centred", "causal"):
        raise InputDataError(f"differentiator must be 'centred' or 'causal', got "
                             f"{differentiator!r}")
    return ChannelStream(module, dt, derivative_window=derivative_window,
                         derivative_extra_orders=derivative_extra_orders,
                         centred=differentiator == "centred")


class ChannelStream:
    """The channels of a generated estimator, computed chunk by chunk from its signals.

    A channel that is a function of the current samples (a signal, ``y**3``, ``1``,
    ``t``, ``y*u``) is computed sample by sample, so its values do not depend on how the
    stream is cut.  A derivative inside a nonlinear factor (``sign(q')``) is estimated by
    the causal algebraic differentiator
    (:class:`algid.signals.CausalDifferentiator`), whose state is carried from
    one chunk to the next: its estimates, and the channels, are the same in any
    chunking, and the first :attr:`warmup` samples of the stream have none (NaN).

    Parameters
    ----------
    module : module
        A generated estimator (built-in or from :func:`compile_equation`).
    dt : float or None
        Sampling step [s]; needed only by a model with derivatives inside factors.
    derivative_window : float, optional
        The differentiator's window ``T`` [s]; default ``DEFAULT_WINDOW_STEPS * dt``.
    derivative_extra_orders : {0, 1, 2}, optional
        Taylor orders beyond the derivative's order ``k`` that the differentiator is
        exact for (its ``truncation`` is ``k + derivative_extra_orders``).  0 (default):
        the minimal estimator, the least noisy, delayed by half the window (default
        kernel).  1 or 2: exact at the sample for polynomials of degree ``k + 1`` or
        ``k + 2``, hence no delay on smooth signals, at the price of more noise.
    centred : bool, optional
        Estimate the derivatives with the window centred on each sample instead (a
        whole record in one call: :func:`channel_stream` with ``"centred"``).

    Attributes
    ----------
    signals : tuple of str
        The measured signals the channels are computed from.
    needs_derivatives : tuple of (str, int)
        The derivatives estimated numerically.
    warmup : int
        Samples at the start of the stream without a derivative estimate (0 when none
        is needed, or ``centred``).
    delay : float
        Delay [s] of the derivative estimates (0 when none is needed, or ``centred``):
        the causal minimal estimator returns the derivative delayed by half its window
        for the default kernel (:func:`algid.signals._differentiation.differentiator_delay`).

    Raises
    ------
    InputDataError
        A derivative is needed and ``dt`` is missing, or a bad window.
    """

    def __init__(self, module, dt, *, derivative_window=None, derivative_extra_orders=0,
                 centred=False):
        if derivative_extra_orders not in (0, 1, 2) or isinstance(derivative_extra_orders,
                                                                   bool):
            raise InputDataError(f"derivative_extra_orders must be 0, 1 or 2, got "
                                 f"{derivative_extra_orders!r}")
        self._extra = int(derivative_extra_orders)
        if derivative_window is not None:
            positive_number(derivative_window, name="derivative_window")
        self.module = module
        self._factors = factors = getattr(module, "FACTORS", {})
        self._centred = centred
        self._dt = dt
        self._window = derivative_window
        if not factors:
            self.signals = tuple(module.CHANNELS)
            self.needs_derivatives = ()
            self._factor_of = {}
        else:
            model = model_of(module)
            self.signals = tuple(model.signals)
            self.needs_derivatives = tuple(model.needs_derivatives)
            self._factor_of = {channel: factor
                               for factor, channel in channel_names(model).items()}
        self._differentiators = {}
        if self.needs_derivatives and not centred:
            from algid.signals._differentiation import CausalDifferentiator

            if dt is None:
                raise InputDataError(
                    f"model {module.MODEL!r} estimates "
                    f"{', '.join(n + chr(39) * k for n, k in self.needs_derivatives)} with "
                    "the causal differentiator, which needs the sampling step: give dt or rate")
            try:
                self._differentiators = {
                    pair: CausalDifferentiator(dt, derivative=pair[1], window=derivative_window,
                                               truncation=pair[1] + self._extra)
                    for pair in self.needs_derivatives}
            except InputDataError as exc:
                raise InputDataError(f"derivative_window: {exc}") from None
        self.warmup = max((d.steps for d in self._differentiators.values()), default=0)
        self.delay = max((d.delay for d in self._differentiators.values()), default=0.0)

    def reset(self):
        """Forget the stream (the differentiators' past samples)."""
        for differentiator in self._differentiators.values():
            differentiator.reset()

    def state(self):
        """What the stream carries from one chunk to the next, for :meth:`restore`.

        Returns
        -------
        tuple
            The differentiators' states.
        """
        return tuple(d.state() for d in self._differentiators.values())

    def restore(self, state):
        """Go back to a :meth:`state` taken before: the samples since are forgotten.

        Parameters
        ----------
        state : tuple
            From :meth:`state`.
        """
        for differentiator, saved in zip(self._differentiators.values(), state):
            differentiator.restore(saved)

    def missing(self, signals):
        """The first signal the channels need that ``signals`` lacks, or None.

        Parameters
        ----------
        signals : mapping or collection of str
            The signal names given.

        Returns
        -------
        str or None
        """
        return next((name for name in self.signals if name not in signals), None)

    def update(self, signals, time):
        """The channels at the next samples, in ``CHANNELS`` order.

        Parameters
        ----------
        signals : mapping
            Measured signal name -> samples (1-D float arrays, checked, of the length of
            ``time``); other names are ignored.
        time : numpy.ndarray
            Sample times.

        Returns
        -------
        tuple of numpy.ndarray
            One array per channel, as long as ``time``.

        Raises
        ------
        InputDataError
            A signal the model needs is missing.
        """
        module = self.module
        missing = self.missing(signals)
        if missing is not None:
            raise InputDataError(f"model {module.MODEL!r} needs the signal {missing!r} "
                                 f"(given: {', '.join(map(str, signals)) or 'none'})")
        factors = self._factors
        if not factors:
            return tuple(np.asarray(signals[name], dtype=float) for name in module.CHANNELS)
        values = {name: np.asarray(signals[name], dtype=float) for name in self.signals}
        for name, k in self.needs_derivatives:
            if self._centred:
                from algid.signals._differentiation import algebraic_derivative
                values[(name, k)] = algebraic_derivative(values[name], self._dt, derivative=k,
                                                         window=self._window,
                                                         truncation=k + self._extra)
            else:
                values[(name, k)] = self._differentiators[(name, k)].update(values[name])
        shape = np.shape(time)
        channels = []
        for name in module.CHANNELS:
            if name in factors:
                with np.errstate(all="ignore"):  # NaN and inf are refused by the callers
                    samples = self._factor_of[name].evaluate(values, time)
                channels.append(samples if np.shape(samples) == shape
                                else np.broadcast_to(samples, shape))
            else:
                channels.append(values[name])
        return tuple(channels)
