"""Output-error refinement of identify's estimate, for models linear in their signals.

The algebraic estimate weights the data by its kernels and windows, so its variance
stays above the Cramér–Rao bound.  The output-error (prediction-error) fit

    min over theta and x0_s of  sum over segments s and samples k of
        (y_k - yhat_k(theta, x0_s))**2

where ``yhat`` is the model's output simulated from the measured inputs, is the
maximum-likelihood estimate under white Gaussian output noise, asymptotically
efficient.  The algebraic estimate, which needs no initial state, starts it.

Simulation (:class:`LinearSimulation`): the model's terms give
``A(s) Y = sum_j B_j(s) U_j`` with the inputs, the constant 1 (an offset) and time
(a drift) as input channels.  An observable canonical realisation is discretised
exactly for inputs linear between samples (first-order hold: one matrix exponential
per step length) and run in the complex Schur basis of the transition matrix, one
first-order recursion per mode (:func:`scipy.signal.lfilter`), which stays accurate at
any sampling rate (a transfer function in ``z`` loses digits as its poles approach 1).
The initial state of each segment (each record, and each run between gaps) is a
nuisance parameter: the output is linear in it, so it is solved for by least squares
inside every evaluation (variable projection), and the parameters alone are iterated
(Levenberg–Marquardt, :func:`scipy.optimize.least_squares`, on parameters scaled by
the algebraic standard errors).

Covariance (:func:`sandwich_covariance`): the Jacobian with the initial states
projected out, and the residuals' own correlation from an autoregressive model of
them (order by BIC): ``(J'J)^-1 J' S J (J'J)^-1`` with ``S`` the residuals'
covariance.  With white residuals it is ``sigma^2 (J'J)^-1``, the Cramér–Rao bound at
the estimate; with coloured ones (AR output noise, a slowly varying misfit) it stays
honest where ``sigma^2 (J'J)^-1`` would not.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from algid.errors import InputDataError, ModelError
from algid.models._expression import Constant, Signal, Time

__all__ = ["LinearSimulation", "Refinement", "OutputErrorData", "refinement_unavailable",
           "refine_linear", "refine_result", "check_refine", "stabilised",
           "simulates_stably",
           "sandwich_covariance", "jacobian", "projected_jacobian", "prepare",
           "channel_samples", "REFINE_CHOICES", "MAX_AR_ORDER"]

#: Largest order of the autoregressive model of the residuals (the covariance's).
MAX_AR_ORDER = 40

#: Finite-difference step of the Jacobian, in algebraic standard errors.
_JACOBIAN_STEP = 1e-3


def refinement_unavailable(model):
    """Why a model cannot be refined by :func:`refine_linear` (None if it can).

    Parameters
    ----------
    model : algid.models._model.Model

    Returns
    -------
    str or None
        One line, or None.
    """
    if not model.is_linear:
        return "the output-error refinement needs a model linear in its signals"
    output = model.output
    order = max((t.derivative for t in model.terms
                 if isinstance(t.factor, Signal) and t.factor.name == output), default=0)
    if order == 0:
        return f"the output {output!r} is not differentiated: nothing to simulate"
    for term in model.terms:
        if isinstance(term.factor, Signal) and term.factor.name != output \
                and term.derivative > order:
            return (f"the term {term} differentiates an input more often than the "
                    f"output ({order}): the model is not proper")
    return None


def _coefficients(model, values):
    """``A`` (output, by derivative order) and ``B`` (input channel -> by order)."""
    den, num = {}, {}
    for term in model.terms:
        value = term.coefficient * (1.0 if term.parameter is None
                                    else float(values[term.parameter]))
        factor, k = term.factor, term.derivative
        if isinstance(factor, Signal) and factor.name == model.output:
            den[k] = den.get(k, 0.0) + value
            continue
        if isinstance(factor, Constant):
            if k > 0:
                continue                        # D^k 1 = 0
            channel = "__one__"
        elif isinstance(factor, Time):
            if k > 1:
                continue                        # D^k t = 0 from k = 2
            channel, k = ("__one__", 0) if k == 1 else ("__time__", 0)
        else:
            channel = factor.name
        num.setdefault(channel, {})
        num[channel][k] = num[channel].get(k, 0.0) - value   # moved to the right
    return den, num


class LinearSimulation:
    """The output of a linear model on uniformly sampled segments, and its free
    responses, for one parameter set.

    Parameters
    ----------
    model : algid.models._model.Model
        A model for which :func:`refinement_unavailable` is None.
    values : mapping
        Parameter name -> value.
    step : float
        Sampling step (s).
    upsampling : int, optional
        The inputs are given at this many points per sampling step (linear between
        them): 1 for the samples alone, :data:`algid.simulation._interpolation.UPSAMPLING`
        for a band-limited interpolation (:func:`channel_samples`).

    Attributes
    ----------
    channels : tuple of str
        The input channels (signal names, ``"__one__"``, ``"__time__"``).
    poles : numpy.ndarray
        The continuous-time poles.
    """

    def __init__(self, model, values, step, upsampling=1):
        self._setup(*_coefficients(model, values), step, upsampling)

    @classmethod
    def of_polynomials(cls, den, num, step, upsampling=1):
        """The simulation of ``A(D) y = sum_j B_j(D) u_j``.

        Parameters
        ----------
        den : dict
            Derivative order -> coefficient of ``A``.
        num : dict
            Channel name -> {derivative order -> coefficient of ``B_j``}.
        step, upsampling
            As for the constructor.

        Returns
        -------
        LinearSimulation
        """
        sim = cls.__new__(cls)
        sim._setup(den, num, step, upsampling)
        return sim

    def _setup(self, den, num, step, upsampling):
        from scipy.linalg import expm, schur

        n = max(den)
        lead = den[n]
        if not (np.isfinite(lead) and lead != 0.0):
            raise ModelError("the output's highest derivative has a zero coefficient")
        alpha = np.array([den.get(k, 0.0) / lead for k in range(n)])        # alpha_0..
        self.channels = tuple(num)
        m = len(self.channels)
        beta = np.zeros((m, n + 1))
        for j, channel in enumerate(self.channels):
            for k, value in num[channel].items():
                beta[j, k] = value / lead
        # observable canonical form: x_0 = y - D u, x_i' = x_{i+1} - alpha_{n-1-i} y + ..
        A = np.zeros((n, n))
        A[:, 0] = -alpha[::-1]
        A[:-1, 1:] = np.eye(n - 1)
        B = (beta[:, n - 1::-1][:, :n] - np.outer(beta[:, n], alpha[::-1])).T  # (n, m)
        self.D = beta[:, n]
        self.order = n
        self.poles = np.linalg.eigvals(A) if n else np.zeros(0)
        # exact discretisation of a fine step for inputs linear between its points
        # (first-order hold): x+ = phi x + gamma1 v_l + gamma2 (v_{l+1} - v_l)
        L = int(upsampling)
        M = np.zeros((n + 2 * m, n + 2 * m))
        M[:n, :n] = A * (step / L)
        M[:n, n:n + m] = B * (step / L)
        M[n:n + m, n + m:] = np.eye(m)
        E = expm(M)
        phi, gamma1, gamma2 = E[:n, :n], E[:n, n:n + m], E[:n, n + m:]
        # over one sampling step: x_{k+1} = phi**L x_k + sum_l weights[l] v_l over its
        # L + 1 points
        weights = np.zeros((L + 1, n, m))
        power = np.eye(n)
        for q in range(L - 1, -1, -1):        # power = phi**(L - 1 - q)
            weights[q] += power @ (gamma1 - gamma2)
            weights[q + 1] += power @ gamma2
            power = phi @ power
        self._weights = weights
        self.upsampling = L
        T, Z = schur(power.astype(complex), output="complex")   # power = phi**L
        self._T, self._Z = T, Z
        self._finite = bool(np.all(np.isfinite(E)) and np.all(np.isfinite(power)))

    def run(self, inputs):
        """The forced output and the free responses of one segment.

        Parameters
        ----------
        inputs : numpy.ndarray, shape (m, (N - 1) * upsampling + 1)
            The input channels at the points of every step (:func:`channel_samples`),
            in :attr:`channels` order.

        Returns
        -------
        forced : numpy.ndarray, shape (N,)
            The output from a zero initial state.
        free : numpy.ndarray, shape (N, n)
            The output from the unit initial states, without input.
        """
        from numpy.lib.stride_tricks import sliding_window_view
        from scipy.signal import lfilter

        L = self.upsampling
        n, N = self.order, (inputs.shape[1] - 1) // L + 1
        if not self._finite:
            return np.full(N, np.nan), np.full((N, n), np.nan)
        points = sliding_window_view(inputs, L + 1, axis=1)[:, ::L]   # (m, N - 1, L + 1)
        g = np.einsum("lnm,mkl->nk", self._weights, points)
        forcing = np.zeros((n + 1, n, N - 1), complex)   # forced, then free from e_j
        forcing[0] = self._Z.conj().T @ g
        start = np.zeros((n + 1, n), complex)
        start[1:] = self._Z.conj()                       # row j: Z^H e_j
        w = np.empty((n + 1, n, N), complex)
        w[:, :, 0] = start
        T = self._T
        with np.errstate(over="ignore", invalid="ignore"):
            for i in range(n - 1, -1, -1):   # triangular: the later modes drive the earlier
                f = forcing[:, i] + np.einsum("j,rjk->rk", T[i, i + 1:], w[:, i + 1:, :-1])
                lam = T[i, i]
                w[:, i, 1:] = lfilter([1.0], [1.0, -lam], f, axis=1,
                                      zi=(lam * w[:, i, :1]))[0]
            states0 = np.real(np.einsum("j,rjk->rk", self._Z[0], w))
        forced = states0[0] + self.D @ inputs[:, ::L]
        return forced, states0[1:].T

    def is_stable(self):
        """True when every pole has a negative real part."""
        return bool(np.all(self.poles.real < 0))


def simulates_stably(model, values):
    """True when the output's polynomial has its roots in the left half-plane, apart
    from the integrators the model has by structure (no term in the output itself, as
    a mass with friction and no spring): those keep a bounded input's response
    bounded over a record, and the initial state absorbs their constant.

    Parameters
    ----------
    model : algid.models._model.Model
    values : mapping

    Returns
    -------
    bool
    """
    den, _ = _coefficients(model, values)
    lowest = min((k for k, v in den.items() if v != 0.0), default=max(den))
    structural = all(not (isinstance(t.factor, Signal) and t.factor.name == model.output
                          and t.derivative < lowest) for t in model.terms)
    start = lowest if structural else 0
    coefficients = [den.get(k, 0.0) for k in range(max(den), start - 1, -1)]
    roots = np.roots(coefficients) if len(coefficients) > 1 else np.zeros(0)
    return bool(np.all(np.isfinite(roots)) and np.all(roots.real < 0))


def channel_samples(channels, segment, upsampling=1):
    """The input channels of a segment at ``upsampling`` points per sampling step.

    Parameters
    ----------
    channels : tuple of str
        :attr:`LinearSimulation.channels`.
    segment : Segment
        Uniformly sampled.
    upsampling : int
        1: the samples; :data:`~algid.simulation._interpolation.UPSAMPLING`: the
        measured signals interpolated as band-limited signals
        (:func:`~algid.simulation._interpolation.bandlimited_samples`, as the simulator
        does), the constant and time exactly.

    Returns
    -------
    numpy.ndarray, shape (m, (N - 1) * upsampling + 1)
    """
    from algid.simulation._interpolation import bandlimited_samples

    t = np.asarray(segment.t, dtype=float)
    fine = np.linspace(t[0], t[-1], (len(t) - 1) * upsampling + 1)
    rows = []
    for channel in channels:
        if channel == "__one__":
            rows.append(np.ones(len(fine)))
        elif channel == "__time__":
            rows.append(fine)
        else:
            values = np.asarray(segment.values[channel], dtype=float)
            rows.append(values if upsampling == 1 else bandlimited_samples(values))
    return np.array(rows).reshape(len(channels), len(fine))


@dataclass
class OutputErrorData:
    """The records as the refinement simulates them (built once by :func:`prepare`).

    Attributes
    ----------
    model : algid.models._model.Model
    step : float
        Sampling step (s).
    upsampling : int
        Points per sampling step of the inputs.
    inputs : list of numpy.ndarray
        Per segment, the input channels (:func:`channel_samples`).
    outputs : list of numpy.ndarray
        Per segment, the measured output.
    """

    model: object
    step: float
    upsampling: int
    inputs: list
    outputs: list


def prepare(model, segments, step, interpolation="bandlimited"):
    """:class:`OutputErrorData` of the segments.

    Parameters
    ----------
    model : algid.models._model.Model
    segments : list of Segment
        Uniformly sampled runs.
    step : float
        Sampling step (s).
    interpolation : {"bandlimited", "linear"}
        The inputs between samples: as band-limited signals (as
        :func:`algid.simulate_model` does by default; the choice that does not bias
        the estimate at few samples per period), or linear.

    Returns
    -------
    OutputErrorData
    """
    from algid.simulation._interpolation import UPSAMPLING

    upsampling = UPSAMPLING if interpolation == "bandlimited" else 1
    channels = LinearSimulation(model, dict.fromkeys(model.parameters, 1.0), step).channels
    return OutputErrorData(
        model, step, upsampling,
        [channel_samples(channels, seg, upsampling) for seg in segments],
        [np.asarray(seg.values[model.output], dtype=float) for seg in segments])


@dataclass
class _Evaluation:
    residual: np.ndarray                 # all segments, stacked
    free: list                           # per segment: (N_s, n)
    initial: list                        # per segment: the fitted initial state


def _evaluate(data, theta):
    model = data.model
    sim = LinearSimulation(model, dict(zip(model.parameters, theta)), data.step,
                           data.upsampling)
    residual, free, initial = [], [], []
    for inputs, y in zip(data.inputs, data.outputs):
        forced, F = sim.run(inputs)
        if not (np.all(np.isfinite(forced)) and np.all(np.isfinite(F))):
            return _Evaluation(np.full(sum(len(y) for y in data.outputs), np.inf), [], [])
        x0 = np.linalg.lstsq(F, y - forced, rcond=None)[0] if F.shape[1] else np.zeros(0)
        residual.append(y - forced - F @ x0)
        free.append(F)
        initial.append(x0)
    return _Evaluation(np.concatenate(residual), free, initial)


def jacobian(data, theta, scale):
    """The residuals' Jacobian in the parameters, initial states projected out.

    Central differences of steps ``scale * 1e-3`` of the residuals, the initial states
    refitted at each (variable projection).

    Parameters
    ----------
    data : OutputErrorData
    theta : numpy.ndarray
        The parameters.
    scale : numpy.ndarray
        Per parameter, its typical uncertainty.

    Returns
    -------
    numpy.ndarray, shape (N, p)
    """
    columns = []
    for i in range(len(theta)):
        h = scale[i] * _JACOBIAN_STEP
        up, down = np.array(theta, float), np.array(theta, float)
        up[i] += h
        down[i] -= h
        columns.append((_evaluate(data, up).residual
                        - _evaluate(data, down).residual) / (2 * h))
    return np.array(columns).T


def _ar_fit(residuals, max_order):
    """Autoregressive model of residual runs by Yule–Walker (pooled autocovariances),
    its order by BIC: the coefficients ``a`` (``a[0] = 1``) and the innovation
    variance."""
    from scipy.linalg import solve_toeplitz

    n_total = sum(len(r) for r in residuals)
    gamma = np.zeros(max_order + 1)
    for r in residuals:
        for lag in range(min(max_order, len(r) - 1) + 1):
            gamma[lag] += r[lag:] @ r[:len(r) - lag]
    gamma /= n_total
    best = (np.log(gamma[0]) if gamma[0] > 0 else -np.inf, np.ones(1), gamma[0])
    if not gamma[0] > 0:
        return best[1], gamma[0]
    for order in range(1, max_order + 1):
        try:
            phi = solve_toeplitz(gamma[:order], gamma[1:order + 1])
        except np.linalg.LinAlgError:
            break
        variance = gamma[0] - phi @ gamma[1:order + 1]
        if not variance > 0:
            break
        bic = np.log(variance) + order * np.log(n_total) / n_total
        if bic < best[0]:
            best = (bic, np.concatenate([[1.0], -phi]), variance)
    return best[1], best[2]


def sandwich_covariance(J, residuals, bounds, dof, max_order=MAX_AR_ORDER):
    """Covariance of an output-error estimate, honest under coloured residuals.

    Parameters
    ----------
    J : numpy.ndarray, shape (N, p)
        Jacobian of the residuals (initial states projected out).
    residuals : numpy.ndarray, shape (N,)
    bounds : list of (int, int)
        The segments' rows in ``J`` and ``residuals``.
    dof : int
        Residual degrees of freedom (samples less the parameters and initial states).
    max_order : int
        Largest autoregressive order.

    Returns
    -------
    covariance : numpy.ndarray, shape (p, p)
    ar : numpy.ndarray
        The autoregressive polynomial of the residuals (``[1.0]``: white).
    """
    from scipy.signal import lfilter

    runs = [residuals[a:b] for a, b in bounds]
    order = int(min(max_order, max(0, min(b - a for a, b in bounds) // 20)))
    ar, innovation = _ar_fit(runs, order)
    total = float(residuals @ residuals)
    n = len(residuals)
    bread = np.linalg.pinv(J.T @ J)
    if len(ar) == 1:   # white: the Cramér–Rao form, on the degrees of freedom
        return bread * total / max(dof, 1), ar
    # Cov(r) = s2 H H' with H the AR synthesis filter: J' Cov J = s2 (H'J)'(H'J), H'
    # being the same filter run backwards in time, segment by segment
    whitened = np.concatenate([lfilter([1.0], ar, J[a:b][::-1], axis=0)[::-1]
                               for a, b in bounds])
    innovation *= n / max(dof, 1)
    meat = innovation * (whitened.T @ whitened)
    return bread @ meat @ bread, ar


@dataclass
class Refinement:
    """What the output-error refinement did (:attr:`IdentificationResult.refinement`).

    Attributes
    ----------
    applied : bool
        The result reports the refined estimate (else the algebraic one).
    reason : str
        Why it was applied or not, in one line.
    converged : bool
        The Levenberg–Marquardt iteration met its tolerance.
    evaluations : int
        Simulations of the model on every segment, the Jacobian's included.
    rms_before, rms_after : float
        Root mean square of the simulation residuals at the algebraic and at the
        refined estimate (initial states fitted); NaN where not simulated.
    noise_ar : tuple of float
        The autoregressive polynomial of the residuals that the covariance uses
        (``(1.0,)``: white).
    initial_states : list of numpy.ndarray
        Per segment, the fitted initial state (observable canonical coordinates).
    residual_test : algid.identification._residual_tests.ResidualTest or None
        The tests of the simulation residuals for model errors.
    """

    applied: bool
    reason: str
    converged: bool = False
    evaluations: int = 0
    rms_before: float = float("nan")
    rms_after: float = float("nan")
    noise_ar: tuple = (1.0,)
    initial_states: list = field(default_factory=list)
    residual_test: object = None


def projected_jacobian(data, theta, scale, free=None):
    """:func:`jacobian` with the free responses projected out, segment by segment.

    (The Jacobian of residuals with refitted initial states also has a part in the span
    of the free responses, of the order of the residuals: it is dropped, leaving the
    parameters' block of the Fisher information with the initial states as nuisance.)

    Parameters
    ----------
    data : OutputErrorData
    theta, scale : numpy.ndarray
        As :func:`jacobian`.
    free : list of numpy.ndarray, optional
        The free responses at ``theta`` (computed when not given).

    Returns
    -------
    J : numpy.ndarray, shape (N, p)
    bounds : list of (int, int)
        Each segment's rows.
    """
    J = jacobian(data, theta, scale)
    free = _evaluate(data, theta).free if free is None else free
    bounds, at = [], 0
    for F in free:
        b = at + F.shape[0]
        if F.shape[1]:
            J[at:b] -= F @ np.linalg.lstsq(F, J[at:b], rcond=None)[0]
        bounds.append((at, b))
        at = b
    return J, bounds


def refine_linear(data, theta, scale):
    """The output-error estimate started from ``theta``.

    Parameters
    ----------
    data : OutputErrorData
        The records (:func:`prepare`) of a model for which
        :func:`refinement_unavailable` is None.
    theta : numpy.ndarray
        The starting estimate (identify's), in ``model.parameters`` order.
    scale : numpy.ndarray
        Per parameter, a positive typical uncertainty (the algebraic standard errors).

    Returns
    -------
    theta : numpy.ndarray
    covariance : numpy.ndarray
    refinement : Refinement
    """
    from scipy.optimize import least_squares

    theta0 = np.asarray(theta, dtype=float)
    scale = np.asarray(scale, dtype=float)
    count = [0]

    def residual(z):
        count[0] += 1
        r = _evaluate(data, theta0 + z * scale).residual
        return np.where(np.isfinite(r), r, 1e150)

    start = _evaluate(data, theta0)
    rms_before = float(np.sqrt(np.mean(start.residual ** 2)))
    fit = least_squares(residual, np.zeros(len(theta0)), method="lm", x_scale=1.0,
                        diff_step=_JACOBIAN_STEP, xtol=1e-10, ftol=1e-12, gtol=1e-12,
                        max_nfev=100 * (len(theta0) + 1))
    theta_hat = theta0 + fit.x * scale
    final = _evaluate(data, theta_hat)
    J, bounds = projected_jacobian(data, theta_hat, scale, final.free)
    count[0] += 2 * len(theta0)
    dof = len(final.residual) - len(theta0) - sum(F.shape[1] for F in final.free)
    covariance, ar = sandwich_covariance(J, final.residual, bounds, dof)
    rms_after = float(np.sqrt(np.mean(final.residual ** 2)))
    test = None
    if np.all(np.isfinite(final.residual)) and np.all(np.isfinite(J)):
        from algid.identification._residual_tests import residual_test

        test = residual_test(data, theta_hat, final.residual, final.free, J, bounds, ar, dof)
    return theta_hat, covariance, Refinement(
        applied=True, reason="", converged=bool(fit.success), evaluations=count[0],
        rms_before=rms_before, rms_after=rms_after, noise_ar=tuple(float(a) for a in ar),
        initial_states=final.initial, residual_test=test)


#: Values of ``refine`` that :func:`algid.identify` takes.
REFINE_CHOICES = ("auto", True, False)


def check_refine(refine):
    """``refine`` as one of :data:`REFINE_CHOICES`, else an InputDataError."""
    if isinstance(refine, (bool, np.bool_)):
        return bool(refine)
    if isinstance(refine, str) and refine == "auto":
        return refine
    raise InputDataError(f"refine must be True, False or 'auto', got {refine!r:.40}")


def stabilised(model, values):
    """The parameters with the unstable roots of the output's polynomial reflected into
    the left half-plane, the same leading coefficient (None where the parameters
    cannot set that polynomial, or a root stays on the imaginary axis).

    Parameters
    ----------
    model : algid.models._model.Model
    values : mapping
        Parameter name -> value.

    Returns
    -------
    dict or None
    """
    den, _ = _coefficients(model, values)
    n = max(den)
    coefficients = np.array([den.get(k, 0.0) for k in range(n, -1, -1)])
    roots = np.roots(coefficients)
    if np.any(roots.real == 0):
        return None
    target = np.real(np.poly(np.where(roots.real > 0, -roots.conj(), roots)))
    target = target[::-1] * coefficients[0]                  # by derivative order
    names = [p for p in model.parameters
             if any(t.parameter == p and isinstance(t.factor, Signal)
                    and t.factor.name == model.output for t in model.terms)]
    A, known = np.zeros((n + 1, len(names))), np.zeros(n + 1)
    for term in model.terms:
        if isinstance(term.factor, Signal) and term.factor.name == model.output:
            if term.parameter is None:
                known[term.derivative] += term.coefficient
            else:
                A[term.derivative, names.index(term.parameter)] += term.coefficient
    solution = np.linalg.lstsq(A, target - known, rcond=None)[0]
    if not np.allclose(A @ solution + known, target, rtol=1e-9, atol=1e-12 * np.max(
            np.abs(target))):
        return None
    return dict(values, **dict(zip(names, solution.tolist())))


def _typical_uncertainty(result):
    """Per parameter, the algebraic standard error, or where it is not a positive
    number a small part of the value (the scale of the refinement's steps)."""
    theta = np.array([result.values[p] for p in result.model.parameters], dtype=float)
    se = np.array([result.stderr[p] for p in result.model.parameters], dtype=float)
    fallback = np.maximum(1e-3 * np.abs(theta), 1e-12)
    return np.where(np.isfinite(se) & (se > 0), se, fallback)


def refine_result(result, segments, step, refine, data_warnings=()):
    """``result`` refined by output error (:func:`refine_linear`) where ``refine`` asks.

    Parameters
    ----------
    result : IdentificationResult
        The algebraic result.
    segments : list of Segment
        The records' runs of contiguous samples.
    step : float
        Sampling step (s).
    refine : {"auto", True, False}
        ``"auto"``: refine where it is safe (the algebraic model is stable and the
        refined one too, and the simulation error drops), else keep the algebraic
        estimate and say why in :attr:`Refinement.reason`; True: refine, refusing a
        model that cannot be, with a warning where the fit does not lower the
        simulation error; False: keep the algebraic estimate.
    data_warnings : sequence of str
        The result's warnings about the records (not about the algebraic estimate):
        kept in a refined result, whose other warnings are those of its residual test
        (the algebraic ones stay in ``algebraic["warnings"]``).

    Returns
    -------
    IdentificationResult
        With ``estimate`` ``"refined"`` or ``"algebraic"``, ``algebraic`` (the algebraic
        values and covariance) and ``refinement``.

    Raises
    ------
    ModelError
        ``refine=True`` on a model that cannot be simulated by the linear simulator.
    """
    from dataclasses import replace

    refine = check_refine(refine)
    algebraic = {"values": dict(result.values), "covariance": result.covariance.copy(),
                 "numerical_error": dict(result.numerical_error),
                 "warnings": list(result.warnings)}
    if refine is False:
        return replace(result, algebraic=algebraic, refinement=Refinement(
            applied=False, reason="not asked (refine=False)"))
    why = refinement_unavailable(result.model)
    if why is None and any(seg.step is None or abs(seg.step - step) > 1e-6 * step
                           for seg in segments):
        why = "the output-error refinement needs uniformly sampled records"
    if why is not None:
        if refine is True:
            raise ModelError(f"refine: {why}")
        return replace(result, algebraic=algebraic,
                       refinement=Refinement(applied=False, reason=why))
    model = result.model
    theta0 = np.array([result.values[p] for p in model.parameters], dtype=float)
    started = ""
    if not np.all(np.isfinite(theta0)):
        why = "the algebraic estimate is not finite"
    elif refine == "auto" and not simulates_stably(model, result.values):
        # (a wrong model's algebraic estimate often is: its fit then starts from the
        # same model with its unstable poles reflected, and must end stable)
        reflected = stabilised(model, result.values)
        if reflected is None:
            why = ("the algebraic estimate's model is not stable: an output-error fit "
                   "could diverge (refine=True tries it)")
        else:
            theta0 = np.array([reflected[p] for p in model.parameters])
            started = "; started from the algebraic model with its unstable poles reflected"
    if why is not None:
        if refine is True:
            raise ModelError(f"refine: {why}")
        return replace(result, algebraic=algebraic,
                       refinement=Refinement(applied=False, reason=why))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        data = prepare(model, segments, step)
        theta, covariance, info = refine_linear(data, theta0, _typical_uncertainty(result))
    values = dict(zip(model.parameters, theta.tolist()))
    if not (np.all(np.isfinite(theta)) and np.all(np.isfinite(covariance))
            and info.rms_after <= info.rms_before):
        why = "the output-error fit did not lower the simulation error"
    elif refine == "auto" and not simulates_stably(model, values):
        why = "the output-error fit gives a model that is not stable"
    if why is not None:   # (a warning where asked for: "auto" says so in the reason)
        info.applied, info.reason = False, why
        notes = [f"not refined: {why}; the algebraic estimate is reported"] \
            if refine is True else []
        return replace(result, algebraic=algebraic, refinement=info,
                       warnings=result.warnings + notes)
    info.reason = (f"output error {info.rms_after:.3g} rms (algebraic "
                   f"{info.rms_before:.3g}){started}")
    found = [] if info.residual_test is None else info.residual_test.warnings()
    # (the simulation is exact for inputs linear between samples: no quadrature error)
    return replace(result, values=values, covariance=covariance, estimate="refined",
                   numerical_error={}, algebraic=algebraic, refinement=info,
                   warnings=[w for w in result.warnings if w in data_warnings] + found)
