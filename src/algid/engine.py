"""Compiled estimation engine: one fused pass over the samples (optional, needs numba).

The NumPy estimator (:func:`algid.estimate` with ``engine="numpy"``) computes every
kernel, every entry of ``P`` and ``Q``, every numerator and every filter level as a
full-length array: some twenty passes over memory and a working set of dozens of
arrays.  This engine computes the same numbers in a single loop over the samples,
compiled with numba, that keeps only the state of the estimator between samples and
writes only the estimates.

Realisation
-----------
The generated module of a model (:mod:`algid.generated`) lists in ``CHAINS`` the
integrator chains ``(signal, power, depth)``: level ``l`` of a chain is the ``l``-fold
cumulative integral of ``tau**power * signal`` (``tau = n * h``, the time since the
first sample, computed as ``n * h`` at each sample, never accumulated).  The kernels
``KERNELS`` are levels of these chains.  Per sample the engine

1. steps every chain with the causal ``q``-point Adams-Moulton rule of
   :mod:`algid.quadrature` (``q = quadrature_order``; same weights, same arithmetic:
   the unscaled increments are summed and the sum is multiplied by ``h``);
2. evaluates the generated ``regressors_packed`` (``P``, ``Q``) and ``cramer``
   (numerators, denominator), compiled with numba: the model algebra comes from the
   generated code only;
3. steps ``p = filter_order`` more integrators on every numerator and on the
   denominator (the invariant filter ``1/s**p``);
4. writes ``numerator / denominator``, or NaN where the denominator is zero or not
   finite.

Each integrator keeps its running sum and, in a ring buffer, the last ``q - 1``
values of its integrand.  The rule of ``q`` points integrates the first ``q - 2``
intervals with the polynomial through samples ``0 .. q - 1``, so the first ``q - 1``
samples of the inputs are buffered; when sample ``q - 1`` arrives, samples
``0 .. q - 1`` are processed with the start-up rule exactly as
:func:`algid.quadrature.cumulative_integral` does.  The estimates of samples
``0 .. q - 2`` are NaN, as in the NumPy estimator.  The results equal those of the
NumPy estimator to round-off (the order of the sums of the rule may differ).

State-carrying API
------------------
The whole past is summarised by an :class:`EngineState` (a few small arrays, whose
size does not depend on the number of samples seen), so a batch is one chunk and a
stream is many chunks, with identical results however the stream is cut::

    from algid import engine
    from algid.estimator import load_model

    state = engine.make_state(load_model("msd"), quadrature_order=6, filter_order=2,
                              step=1e-3)
    est = engine.run_chunk(state, f_chunk, x_chunk)     # shape (n_parameters, n)
    est = engine.run_chunk(state, f_next, x_next)       # continues where it stopped
    state.reset()                                       # new time origin (re-anchoring)

``run_chunk`` takes the input and output samples of the chunk (time is implied by
the sample count and the step: the sampling must be uniform, which the caller checks),
returns the estimates of exactly the samples given (row ``i`` is parameter
``state.parameters[i]``), and advances the state.  ``out=`` lets the caller supply the
result array (for example a view into a larger array).  Copies of a state
(:meth:`EngineState.copy`) continue independently.  The compiled function is built
once per model and cached (also on disk, by numba); the first call in a process pays
the compile time (or the cache load).

Functions
---------
:func:`available` tells whether numba can be imported; :func:`make_state`,
:func:`run_chunk` and :func:`estimate_arrays` (batch helper) raise
:class:`~algid.errors.InputDataError` with an install hint when it cannot.
"""

from __future__ import annotations

import importlib.util
import math
from functools import lru_cache

import numpy as np

from algid.errors import InputDataError
from algid.quadrature import rule_weights

__all__ = ["available", "EngineState", "make_state", "run_chunk", "estimate_arrays",
           "INSTALL_HINT"]

#: How to install the optional dependency of this engine.
INSTALL_HINT = 'pip install "algid[fast]"  (or: pip install "numba>=0.59")'


def available() -> bool:
    """Whether numba can be imported, i.e. whether this engine can run."""
    return importlib.util.find_spec("numba") is not None


def _require_numba():
    try:
        import numba  # noqa: F401
    except ImportError:
        raise InputDataError(
            f"engine='numba' needs numba, which is not installed: {INSTALL_HINT}") from None
    return numba


# --------------------------------------------------------------------------------------
# compiled kernels
# --------------------------------------------------------------------------------------


@lru_cache(maxsize=None)
def _kernels():
    """The generic compiled loops (built on first use, so that importing this module
    does not import numba)."""
    numba = _require_numba()
    njit = numba.njit(cache=True, nogil=True, error_model="numpy")

    @njit
    def start_integrator(y, out, k, sums, ring, W, WS, h):
        """Integrate the first ``q`` samples ``y`` of integrator ``k`` into ``out``
        (start-up rule for the first ``q - 2`` intervals, then the regular rule), and
        set its running sum and ring buffer as after sample ``q - 1``."""
        q = W.shape[0]
        m = q - 1
        s = 0.0
        out[0] = 0.0
        for j in range(1, q - 1):
            inc = 0.0
            for i in range(q):
                inc += WS[j - 1, i] * y[i]
            s += inc
            out[j] = s * h
        inc = 0.0
        for i in range(q):
            inc += W[i] * y[i]
        s += inc
        out[q - 1] = s * h
        sums[k] = s
        for j in range(q):
            pos = j % m
            ring[k, pos] = y[j]
            ring[k, pos + m] = y[j]

    @njit
    def advance(u, x, out, sums, ring, startbuf, count, h, divisor, sig, power, depth, slot,
                W, WS, p, regressors_packed, cramer):
        """Process one chunk of samples; see :func:`run_chunk`."""
        q = W.shape[0]
        m = q - 1
        n_chains = sig.shape[0]
        n_par = out.shape[0]
        n_kern = 0
        for c in range(n_chains):
            for lev in range(depth[c] + 1):
                if slot[c, lev] >= 0:
                    n_kern += 1
        kv = np.empty(n_kern)
        filt = np.empty(n_par + 1)
        nan = np.nan
        n0 = count[0]
        size = u.shape[0]
        i = 0
        # ---- start-up: buffer samples 0 .. q-2, process 0 .. q-1 at sample q-1
        while i < size and n0 + i < m:
            startbuf[0, n0 + i] = u[i] / divisor
            startbuf[1, n0 + i] = x[i]
            for r in range(n_par):
                out[r, i] = nan
            i += 1
        if i < size and n0 + i == m:
            startbuf[0, m] = u[i] / divisor
            startbuf[1, m] = x[i]
            cur = np.empty(q)
            nxt = np.empty(q)
            kvs = np.empty((n_kern, q))
            k = 0
            for c in range(n_chains):
                for j in range(q):
                    tau = j * h
                    w = 1.0
                    for _ in range(power[c]):
                        w *= tau
                    cur[j] = w * startbuf[sig[c], j]
                if slot[c, 0] >= 0:
                    kvs[slot[c, 0], :] = cur
                for lev in range(1, depth[c] + 1):
                    start_integrator(cur, nxt, k, sums, ring, W, WS, h)
                    cur[:] = nxt
                    if slot[c, lev] >= 0:
                        kvs[slot[c, lev], :] = cur
                    k += 1
            fin = np.empty((n_par + 1, q))
            for j in range(q):
                P, Q = regressors_packed(kvs[:, j])
                nums, den = cramer(P, Q)
                for r in range(n_par):
                    fin[r, j] = nums[r]
                fin[n_par, j] = den
            for r in range(n_par + 1):
                cur[:] = fin[r]
                for _ in range(p):
                    start_integrator(cur, nxt, k, sums, ring, W, WS, h)
                    cur[:] = nxt
                    k += 1
                filt[r] = cur[q - 1]
            d = filt[n_par]
            if d == 0.0 or not math.isfinite(d):
                for r in range(n_par):
                    out[r, i] = nan
            else:
                for r in range(n_par):
                    out[r, i] = filt[r] / d
            i += 1
        # ---- regular samples
        if i < size:
            pos = (n0 + i) % m  # the ring of every integrator holds its last m
            # integrand values at pos .. pos + m - 1, oldest first
            for i in range(i, size):
                n = n0 + i
                tau = n * h
                uval = u[i] / divisor
                xval = x[i]
                k = 0
                for c in range(n_chains):
                    w = 1.0
                    for _ in range(power[c]):
                        w *= tau
                    y = w * (uval if sig[c] == 0 else xval)
                    if slot[c, 0] >= 0:
                        kv[slot[c, 0]] = y
                    for lev in range(1, depth[c] + 1):
                        inc = 0.0
                        for j in range(m):
                            inc += W[j] * ring[k, pos + j]
                        inc += W[m] * y
                        s = sums[k] + inc
                        sums[k] = s
                        ring[k, pos] = y
                        ring[k, pos + m] = y
                        y = s * h
                        if slot[c, lev] >= 0:
                            kv[slot[c, lev]] = y
                        k += 1
                P, Q = regressors_packed(kv)
                nums, den = cramer(P, Q)
                for r in range(n_par + 1):
                    y = nums[r] if r < n_par else den
                    for _ in range(p):
                        inc = 0.0
                        for j in range(m):
                            inc += W[j] * ring[k, pos + j]
                        inc += W[m] * y
                        s = sums[k] + inc
                        sums[k] = s
                        ring[k, pos] = y
                        ring[k, pos + m] = y
                        y = s * h
                        k += 1
                    filt[r] = y
                d = filt[n_par]
                if d == 0.0 or not math.isfinite(d):
                    for r in range(n_par):
                        out[r, i] = nan
                else:
                    for r in range(n_par):
                        out[r, i] = filt[r] / d
                pos += 1
                if pos == m:
                    pos = 0
        count[0] = n0 + size

    return advance


@lru_cache(maxsize=None)
def _model_functions(module_name):
    """The generated ``regressors_packed`` and ``cramer`` of a model, compiled."""
    numba = _require_numba()
    module = importlib.import_module(module_name)
    njit = numba.njit(cache=True, nogil=True, inline="always")
    return njit(module.regressors_packed), njit(module.cramer)


@lru_cache(maxsize=None)
def _layout(module_name):
    """Integer arrays that drive the generic loop from ``CHAINS`` and ``KERNELS``."""
    module = importlib.import_module(module_name)
    signals = {module.INPUT: 0, module.OUTPUT: 1}
    chains = module.CHAINS
    max_depth = max(depth for _, _, depth in chains)
    sig = np.array([signals[s] for s, _, _ in chains], dtype=np.int64)
    power = np.array([pw for _, pw, _ in chains], dtype=np.int64)
    depth = np.array([d for _, _, d in chains], dtype=np.int64)
    slot = np.full((len(chains), max_depth + 1), -1, dtype=np.int64)
    index = {(s, pw): c for c, (s, pw, _) in enumerate(chains)}
    for position, (s, pw, order) in enumerate(module.KERNELS):
        c = index[(s, pw)]
        if order > depth[c]:
            raise InputDataError(f"kernel {module.kernel_name(s, pw, order)} of model "
                                 f"{module.MODEL!r} is deeper than its chain")
        slot[c, order] = position
    for arr in (sig, power, depth, slot):
        arr.setflags(write=False)
    return sig, power, depth, slot


# --------------------------------------------------------------------------------------
# state and public functions
# --------------------------------------------------------------------------------------


class EngineState:
    """Everything the engine remembers between chunks (see :func:`make_state`).

    Attributes
    ----------
    model : str
    parameters : tuple of str
        Names of the rows of the estimates returned by :func:`run_chunk`.
    quadrature_order, filter_order : int
    step : float
        Sampling step ``h``.
    input_divisor : float
        The input samples are divided by it (the known mass of model ``"msd"``).
    n_seen : int
        Samples processed since the time origin.
    """

    def __init__(self, module, quadrature_order, filter_order, step, input_divisor):
        self._module_name = module.__name__
        self.model = module.MODEL
        self.parameters = tuple(module.PARAMETERS)
        self.quadrature_order = int(quadrature_order)
        self.filter_order = int(filter_order)
        self.step = float(step)
        self.input_divisor = float(input_divisor)
        regular, startup = rule_weights(self.quadrature_order)
        self._weights = np.ascontiguousarray(regular)
        self._startup_weights = np.ascontiguousarray(startup.reshape(-1, regular.size))
        if self._startup_weights.shape[0] == 0:
            self._startup_weights = np.zeros((1, regular.size))
        self._layout = _layout(self._module_name)
        n_int = int(self._layout[2].sum()) + (len(self.parameters) + 1) * self.filter_order
        q = self.quadrature_order
        self.sums = np.zeros(n_int)
        self.ring = np.zeros((n_int, 2 * (q - 1)))
        self.startup_buffer = np.zeros((2, q))
        self.count = np.zeros(1, dtype=np.int64)

    @property
    def n_seen(self) -> int:
        return int(self.count[0])

    def reset(self):
        """Move the time origin to the next sample: forget everything seen."""
        self.sums.fill(0.0)
        self.ring.fill(0.0)
        self.startup_buffer.fill(0.0)
        self.count[0] = 0

    def copy(self):
        """An independent copy that continues from the same point."""
        new = object.__new__(EngineState)
        new.__dict__.update(self.__dict__)
        for name in ("sums", "ring", "startup_buffer", "count"):
            setattr(new, name, getattr(self, name).copy())
        return new

    def __repr__(self):
        return (f"EngineState(model={self.model!r}, quadrature_order={self.quadrature_order}, "
                f"filter_order={self.filter_order}, step={self.step!r}, "
                f"n_seen={self.n_seen})")


def make_state(module, quadrature_order, filter_order, *, step, input_divisor=1.0):
    """A fresh engine state (time origin at the next sample).

    Parameters
    ----------
    module : module
        Generated estimator module (:func:`algid.estimator.load_model`).
    quadrature_order : int
        Points of the cumulative quadrature rule (see :mod:`algid.quadrature`).
    filter_order : int
        Order ``p`` of the invariant filter ``1/s**p``.
    step : float
        Sampling step ``h`` [s].
    input_divisor : float, optional
        The input samples are divided by it before use (the known mass, when the
        input of model ``"msd"`` is a force).  Default 1.

    Returns
    -------
    EngineState

    Raises
    ------
    InputDataError
        If numba is not installed, or ``step`` / ``input_divisor`` is not a positive
        finite number.
    """
    _require_numba()
    for name, value in (("step", step), ("input_divisor", input_divisor)):
        if not (np.isfinite(value) and value > 0):
            raise InputDataError(f"{name} must be a positive number, got {value!r}")
    return EngineState(module, quadrature_order, filter_order, step, input_divisor)


def run_chunk(state, f, x, *, out=None):
    """Estimates over one chunk of samples, advancing ``state``.

    Parameters
    ----------
    state : EngineState
        From :func:`make_state`; updated in place.
    f, x : ndarray, shape (n,)
        Input and output samples (float64; uniformly sampled with the state's step,
        continuing the samples seen before).
    out : ndarray, shape (n_parameters, n), optional
        Where to write the estimates (float64, rows contiguous).

    Returns
    -------
    ndarray, shape (n_parameters, n)
        Row ``i`` holds the estimates of ``state.parameters[i]``; NaN for the first
        ``quadrature_order - 1`` samples after the time origin and where the
        denominator is zero or not finite.
    """
    f = np.ascontiguousarray(f, dtype=np.float64)
    x = np.ascontiguousarray(x, dtype=np.float64)
    if f.ndim != 1 or f.shape != x.shape:
        raise InputDataError(f"f and x must be 1-D of equal length, got shapes {f.shape} "
                             f"and {x.shape}")
    if out is None:
        out = np.empty((len(state.parameters), f.size))
    elif out.shape != (len(state.parameters), f.size) or out.dtype != np.float64:
        raise InputDataError(f"out must be a float64 array of shape "
                             f"{(len(state.parameters), f.size)}, got {out.shape} {out.dtype}")
    advance = _kernels()
    regressors_packed, cramer = _model_functions(state._module_name)
    sig, power, depth, slot = state._layout
    advance(f, x, out, state.sums, state.ring, state.startup_buffer, state.count,
            state.step, state.input_divisor, sig, power, depth, slot, state._weights,
            state._startup_weights, state.filter_order, regressors_packed, cramer)
    return out


def estimate_arrays(module, f, x, *, step, quadrature_order, filter_order, input_divisor=1.0):
    """Batch estimation with this engine: one chunk from a fresh state.

    Parameters are those of :func:`make_state` and :func:`run_chunk`; the signals are
    assumed checked (see :func:`algid.validation.check_experiment`).

    Returns
    -------
    ndarray, shape (n_parameters, n)
    """
    state = make_state(module, quadrature_order, filter_order, step=step,
                       input_divisor=input_divisor)
    return run_chunk(state, f, x)
