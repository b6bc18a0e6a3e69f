"""The output of a model linear in its signals, simulated exactly on sampled inputs.

The model's terms give ``A(D) y = sum_j B_j(D) u_j`` (:func:`output_polynomials`), with
the inputs, the constant 1 (an offset) and time (a drift) as input channels.  An
observable canonical realisation is discretised exactly for inputs linear between the
points of a step (:func:`channel_samples`: the samples, or 16 points per sample of a
band-limited or cubic interpolation; first-order hold between them, one matrix
exponential per parameter set) and run in the complex Schur basis of the transition
matrix, one first-order recursion per mode (:func:`scipy.signal.lfilter`), which stays
accurate at any sampling rate (a transfer function in ``z`` loses digits as its poles
approach 1).  :class:`LinearSimulation` gives the forced output and the free responses
of a run of samples; the output-error refinement
(:mod:`algid.identification._output_error`) and its residual test
(:mod:`algid.identification._residual_tests`) simulate with it.
"""

from __future__ import annotations

import numpy as np

from algid.errors import ModelError
from algid.models._expression import Constant, Signal, Time

__all__ = ["LinearSimulation", "output_polynomials", "simulates_stably", "step_points",
           "channel_samples"]


def output_polynomials(model, values):
    """The model as ``A(D) y = sum_j B_j(D) u_j`` at parameter ``values``.

    Parameters
    ----------
    model : algid.models._model.Model
        A model linear in its signals.
    values : mapping
        Parameter name -> value.

    Returns
    -------
    den : dict
        Derivative order -> coefficient of ``A`` (the output's).
    num : dict
        Input channel (a signal, ``"__one__"`` for a constant, ``"__time__"``) ->
        {derivative order -> coefficient of ``B_j``}.
    """
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
        self._setup(*output_polynomials(model, values), step, upsampling)

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
        # in the time unit of one step (tau = t / step): coefficient k times
        # step**(n - k), about (omega step)**(n - k) whatever the unit of t, so that the
        # realisation and its matrix exponential are as well scaled in any unit
        alpha = np.array([den.get(k, 0.0) / lead * step ** (n - k) for k in range(n)])
        self.channels = tuple(num)
        m = len(self.channels)
        beta = np.zeros((m, n + 1))
        for j, channel in enumerate(self.channels):
            for k, value in num[channel].items():
                beta[j, k] = value / lead * step ** (n - k)
        # observable canonical form: x_0 = y - D u, x_i' = x_{i+1} - alpha_{n-1-i} y + ..
        A = np.zeros((n, n))
        A[:, 0] = -alpha[::-1]
        A[:-1, 1:] = np.eye(n - 1)
        B = (beta[:, n - 1::-1][:, :n] - np.outer(beta[:, n], alpha[::-1])).T  # (n, m)
        self.D = beta[:, n]
        self.order = n
        self.poles = np.linalg.eigvals(A) / step if n else np.zeros(0)
        # exact discretisation of a fine step for inputs linear between its points
        # (first-order hold): x+ = phi x + gamma1 v_l + gamma2 (v_{l+1} - v_l)
        L = int(upsampling)
        M = np.zeros((n + 2 * m, n + 2 * m))
        M[:n, :n] = A / L
        M[:n, n:n + m] = B / L
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

    def run(self, inputs, points=None, gains=None):
        """The forced output and the free responses of one segment.

        Parameters
        ----------
        inputs : numpy.ndarray, shape (m, (N - 1) * upsampling + 1)
            The input channels at the points of every step (:func:`channel_samples`),
            in :attr:`channels` order.
        points : numpy.ndarray, optional
            :func:`step_points` of ``inputs`` (given when simulating many times).
        gains : numpy.ndarray, optional
            Per channel, a factor its input was divided by, over the one the output
            was (powers of two: the records scaled to unit size, exactly).

        Returns
        -------
        forced : numpy.ndarray, shape (N,)
            The output from a zero initial state.
        free : numpy.ndarray, shape (N, n)
            The output from the unit initial states, without input.
        """
        from scipy.signal import lfilter

        L = self.upsampling
        n, N = self.order, (inputs.shape[1] - 1) // L + 1
        if not self._finite:
            return np.full(N, np.nan), np.full((N, n), np.nan)
        points = step_points(inputs, L) if points is None else points
        m = inputs.shape[0]
        weights, D = self._weights, self.D
        if gains is not None:
            weights, D = weights * gains, D * gains
        g = weights.transpose(1, 0, 2).reshape(n, (L + 1) * m) @ points
        forcing = np.zeros((n + 1, n, N - 1), complex)   # forced, then free from e_j
        forcing[0] = self._Z.conj().T @ g
        start = np.zeros((n + 1, n), complex)
        start[1:] = self._Z.conj()                       # row j: Z^H e_j
        w = np.empty((n + 1, n, N), complex)
        w[:, :, 0] = start
        T = self._T
        with np.errstate(over="ignore", invalid="ignore"):
            for i in range(n - 1, -1, -1):   # triangular: the later modes drive the earlier
                f = forcing[:, i].copy()
                for j in range(i + 1, n):
                    f += T[i, j] * w[:, j, :-1]
                lam = T[i, i]
                w[:, i, 1:] = lfilter([1.0], [1.0, -lam], f, axis=1,
                                      zi=(lam * w[:, i, :1]))[0]
            states0 = np.zeros((n + 1, N))
            for j in range(n):
                states0 += np.real(self._Z[0, j] * w[:, j])
        forced = states0[0] + D @ inputs[:, ::L]
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
    den, _ = output_polynomials(model, values)
    lowest = min((k for k, v in den.items() if v != 0.0), default=max(den))
    structural = all(not (isinstance(t.factor, Signal) and t.factor.name == model.output
                          and t.derivative < lowest) for t in model.terms)
    start = lowest if structural else 0
    coefficients = [den.get(k, 0.0) for k in range(max(den), start - 1, -1)]
    roots = np.roots(coefficients) if len(coefficients) > 1 else np.zeros(0)
    return bool(np.all(np.isfinite(roots)) and np.all(roots.real < 0))


def step_points(inputs, upsampling):
    """The inputs at the points of every sampling step, stacked for one product.

    Parameters
    ----------
    inputs : numpy.ndarray, shape (m, (N - 1) * upsampling + 1)
    upsampling : int

    Returns
    -------
    numpy.ndarray, shape ((upsampling + 1) * m, N - 1)
        Row ``q * m + j``: channel ``j`` at point ``q`` of each step.
    """
    L = upsampling
    steps = (inputs.shape[1] - 1) // L
    return np.concatenate([inputs[:, q:q + (steps - 1) * L + 1:L] for q in range(L + 1)])


def channel_samples(channels, segment, upsampling=1, interpolation="bandlimited"):
    """The input channels of a segment at ``upsampling`` points per sampling step.

    Parameters
    ----------
    channels : tuple of str
        :attr:`LinearSimulation.channels`.
    segment : Segment
        Uniformly sampled.
    upsampling : int
        1: the samples; :data:`~algid.simulation._interpolation.UPSAMPLING`: the
        measured signals interpolated (the constant and time exactly).
    interpolation : {"bandlimited", "cubic"}
        As band-limited signals
        (:func:`~algid.simulation._interpolation.bandlimited_samples`, as the simulator
        does by default) or by a cubic spline.

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
            if upsampling == 1:
                rows.append(values)
            elif interpolation == "cubic":
                from scipy.interpolate import CubicSpline

                rows.append(CubicSpline(t, values)(fine))
            else:
                rows.append(bandlimited_samples(values))
    return np.array(rows).reshape(len(channels), len(fine))
