"""Compiled estimation engine: one fused pass over the samples (optional, needs numba).

The NumPy estimator (:func:`algid.estimate` with ``engine="numpy"``) computes every
kernel, every entry of ``P`` and ``Q``, every numerator and every filter level as a
full-length array: some twenty passes over memory and a working set of dozens of
arrays.  This engine computes the same numbers in a single compiled loop over the
samples that keeps only the state of the estimator between samples and writes only
the estimates.  Install it with ``pip install "algid[fast]"`` (numba).

Realisation
-----------
The generated module of a model (:mod:`algid.generated`) lists in ``CHAINS`` the
integrator chains ``(signal, power, depth)``: level ``l`` of a chain is the ``l``-fold
cumulative integral of ``tau**power * signal``, where ``tau = n * h`` is the time since
the origin, computed as ``n * h`` at every sample (never accumulated).  ``KERNELS`` are
levels of these chains.  For every sample the engine

1. steps every chain with the causal ``q``-point Adams-Moulton rule of
   :mod:`algid.quadrature` (``q = quadrature_order``), with the same weights and the
   same arithmetic as :func:`~algid.quadrature.cumulative_integral`: the increment
   ``w[0] y[n-q+1] + ... + w[q-1] y[n]`` is added to a running sum, which is then
   multiplied by ``h``;
2. evaluates ``P`` and ``Q`` with the generated ``regressors_packed`` and the
   numerators and denominator with the generated ``cramer``, both compiled by numba:
   the model algebra comes from the generated code only;
3. steps ``p = filter_order`` more integrators on every numerator and on the
   denominator (the invariant filter ``1/s**p``);
4. writes ``numerator / denominator``, or NaN where the denominator is zero or not
   finite.

Each integrator keeps its running sum and the last ``q - 1`` values of its integrand.
The loop is written out per model and rule from ``CHAINS`` and ``KERNELS`` (the
weights are literals), compiled once, and cached on disk (see :data:`CACHE_DIR`).  It
works on blocks of :data:`_BLOCK` samples: for each level of the chains, the
increments of all samples of the block are computed first (a loop the compiler
vectorises, each increment summed in the rule's order), then the running sums (one
dependency chain per integrator, interleaved across chains).  The block arrays
(some tens of kilobytes) stay in the cache; the traffic to memory is the reading of
``f``, ``x`` and the writing of the estimates.

The rule of ``q`` points integrates the first ``q - 2`` intervals with the polynomial
through samples ``0 .. q - 1`` (see :mod:`algid.quadrature`), so the first ``q - 1``
samples are only buffered; when sample ``q - 1`` arrives, samples ``0 .. q - 1`` are
processed with NumPy exactly as :func:`algid.estimate` does (start-up rule included),
and the compiled loop continues from the resulting state.  The estimates of samples
``0 .. q - 2`` are NaN, as in the NumPy estimator.  Because every operation is done in
the same order as in the NumPy estimator (no reassociation, no fused multiply-add),
the results equal those of ``engine="numpy"`` bit for bit on the platforms tested,
and in any case to round-off.

State-carrying API
------------------
The whole past is summarised by an :class:`EngineState` (a few small arrays whose size
does not depend on the number of samples seen), so a batch is one chunk and a stream
is many chunks, with identical results however the stream is cut::

    from algid import engine
    from algid.estimator import load_model

    state = engine.make_state(load_model("msd"), quadrature_order=6, filter_order=2,
                              step=1e-3)
    est = engine.run_chunk(state, f_chunk, x_chunk)   # shape (n_parameters, len(chunk))
    est = engine.run_chunk(state, f_next, x_next)     # continues where it stopped
    state.reset()                                     # time origin at the next sample

:func:`run_chunk` takes the input and output samples of a chunk (time is implied by
the sample count and the step: the caller checks that the sampling is uniform),
returns the estimates of exactly the samples given (row ``i`` belongs to
``state.parameters[i]``; ``out=`` may supply the array, e.g. a view into a larger one),
and advances the state.  :meth:`EngineState.copy` gives an independent continuation;
:meth:`EngineState.reset` moves the time origin (re-anchoring, as the method permits
because it does not depend on the initial conditions).  :func:`prepare` compiles (or
loads from the cache) ahead of time; otherwise the first :func:`make_state` of a model
and rule does.  Every function raises :class:`~algid.errors.InputDataError` with an
install hint when numba is missing; :func:`available` tells beforehand.

For samples that arrive one at a time the cost is dominated by the Python call
(a few microseconds per call); chunks of a thousand samples run at nearly the batch
speed.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import inspect
import math
import os
import sys
import tempfile
from functools import lru_cache

import numpy as np

from algid.errors import InputDataError
from algid.quadrature import rule_weights

__all__ = ["available", "prepare", "EngineState", "make_state", "run_chunk",
           "estimate_arrays", "check_experiment", "INSTALL_HINT", "CACHE_DIR"]

#: How to install the optional dependency of this engine.
INSTALL_HINT = 'pip install "algid[fast]" (or: pip install "numba>=0.59")'

#: Directory where the compiled loops are cached: ``$ALGID_CACHE_DIR`` if set, else
#: ``$XDG_CACHE_HOME/algid/engine`` (``~/.cache/algid/engine``).  The source of each
#: loop is written there, named after the hash of its text, and numba keeps the machine
#: code beside it; if the directory cannot be written, the loops are compiled in memory
#: in every process instead.
CACHE_DIR = os.environ.get("ALGID_CACHE_DIR") or os.path.join(
    os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache"),
    "algid", "engine")

#: Samples per block of the compiled loop: every level of every chain is computed for
#: a block at a time (the increments vectorised over the block), in arrays that stay
#: in the first-level cache.
_BLOCK = 256

# u, x, out, sums, windows, n0, h, divisor, p, work
_SIGNATURE = ("void(float64[::1], float64[::1], float64[:, :], float64[::1], "
              "float64[:, ::1], int64, float64, float64, int64, float64[::1])")


def available() -> bool:
    """Whether numba is installed, i.e. whether this engine can run."""
    import importlib.util

    return importlib.util.find_spec("numba") is not None


def _require_numba():
    try:
        import numba
    except ImportError:
        raise InputDataError(
            f"engine='numba' needs numba, which is not installed: {INSTALL_HINT}") from None
    return numba


# --------------------------------------------------------------------------------------
# the compiled loop, written out per model and rule
# --------------------------------------------------------------------------------------


def _chain_integrators(module):
    """``[(chain, level)]`` of the chain integrators in state order."""
    return [(c, level) for c, (_, _, depth) in enumerate(module.CHAINS)
            for level in range(1, depth + 1)]


def _work_size(module, q, p):
    """Length of the scratch array of the compiled loop: every level of every chain
    and ``p + 1`` levels of numerators and denominator over ``q - 1 + BLOCK``
    samples, the increments of a block, and the filter sums."""
    lanes = len(module.PARAMETERS) + 1
    levels = sum(d + 1 for _, _, d in module.CHAINS)
    span = q - 1 + _BLOCK
    return (levels * span + (len(module.CHAINS) + lanes) * _BLOCK
            + (p + 1) * lanes * (span + 1))


def _kernel_source(module, q, *, embed):
    """Python source of the module that holds the compiled loop of ``module`` with the
    ``q``-point rule (see :func:`_compiled`).  With ``embed`` the generated
    ``regressors_packed`` and ``cramer`` are copied in verbatim (a self-contained,
    cacheable file); otherwise the namespace must provide them."""
    regular, _ = rule_weights(q)
    w = [repr(float(v)) for v in regular]
    m = q - 1
    n_par = len(module.PARAMETERS)
    lanes = n_par + 1  # numerators, then the denominator
    chains = module.CHAINS
    chain_ints = _chain_integrators(module)
    n_chain_ints = len(chain_ints)
    depth = max(d for _, _, d in chains)
    value = {module.INPUT: "uval", module.OUTPUT: "xval"}

    def fir(buf):  # the increment w[0] y[b] + ... + w[q-1] y[b+q-1], in this order
        return " + ".join(f"{w[j]} * {buf}[b + {j}]" for j in range(q))

    src = [f'"""Compiled estimation loop of model {module.MODEL!r}, {q}-point rule.',
           "",
           f"Written by algid.engine from {module.__name__}; do not edit.",
           '"""', "", "import math", "", "import numba", "import numpy as np", ""]
    if embed:
        src += ["CACHE = True", "", "# ---- from the generated module, verbatim", "",
                inspect.getsource(module.regressors_packed),
                inspect.getsource(module.cramer), "# ----", ""]
    else:
        src += ["CACHE = False", ""]
    src += ["_regressors_packed = numba.njit(cache=CACHE, nogil=True)(regressors_packed)",
            "_cramer = numba.njit(cache=CACHE, nogil=True)(cramer)", "",
            f"SIGNATURE = {_SIGNATURE!r}", f"BLOCK = {_BLOCK}", f"M = {m}", "", "",
            "@numba.njit(SIGNATURE, cache=CACHE, nogil=True)",
            "def advance(u, x, out, sums, windows, n0, h, divisor, p, work):"]
    a = src.append
    a("    # y<c>_<l>[:M] holds the last M values of level l of chain c before the block,")
    a("    # y<c>_<l>[M + b] its value at sample b of the block; s<c>_<l> is the running")
    a("    # sum of level l.  fb[l, r] and fs[l, r] likewise for filter level l of")
    a("    # numerator r (r = n_parameters: the denominator; level 0: unfiltered).")
    a("    # all of them are views into the scratch array work (see _work_size)")
    offset = 0
    for c, (_, _, d) in enumerate(chains):
        for level in range(d + 1):
            a(f"    y{c}_{level} = work[{offset}:{offset} + M + BLOCK]")
            offset += m + _BLOCK
    for c in range(len(chains)):
        a(f"    i{c} = work[{offset}:{offset + _BLOCK}]")
        offset += _BLOCK
    for r in range(lanes):
        a(f"    j{r} = work[{offset}:{offset + _BLOCK}]")
        offset += _BLOCK
    a(f"    nfb = (p + 1) * {lanes} * (M + BLOCK)")
    a(f"    fb = work[{offset}:{offset} + nfb].reshape((p + 1, {lanes}, M + BLOCK))")
    a(f"    fs = work[{offset} + nfb:{offset} + nfb + (p + 1) * {lanes}]"
      f".reshape((p + 1, {lanes}))")
    for k, (c, level) in enumerate(chain_ints):
        a(f"    s{c}_{level} = sums[{k}]")
    a("    for k in range(M):")
    for i, (c, level) in enumerate(chain_ints):
        a(f"        y{c}_{level - 1}[k] = windows[{i}, k]")
    a("    for lev in range(p):")
    a(f"        for r in range({lanes}):")
    a(f"            fs[lev + 1, r] = sums[{n_chain_ints} + lev * {lanes} + r]")
    a("            for k in range(M):")
    a(f"                fb[lev, r, k] = windows[{n_chain_ints} + lev * {lanes} + r, k]")
    a("    size = u.shape[0]")
    a("    for start in range(0, size, BLOCK):")
    a("        nb = min(BLOCK, size - start)")
    a("        # level 0 of the chains: tau**power * signal")
    a("        for b in range(nb):")
    a("            tau = (n0 + start + b) * h")
    a("            uval = u[start + b] / divisor")
    a("            xval = x[start + b]")
    for c, (signal, power, _) in enumerate(chains):
        factor = "1.0"
        for _ in range(power):  # as NumPy's tau**power: ((1 * tau) * tau) ...
            factor = f"({factor} * tau)"
        rhs = value[signal] if power == 0 else f"{factor} * {value[signal]}"
        a(f"            y{c}_0[M + b] = {rhs}")
    for level in range(1, depth + 1):
        active = [c for c, (_, _, d) in enumerate(chains) if d >= level]
        a(f"        # level {level}: the increments (vectorised), then the running sums")
        a("        for b in range(nb):")
        for c in active:
            a(f"            i{c}[b] = {fir(f'y{c}_{level - 1}')}")
        a("        for b in range(nb):")
        for c in active:
            a(f"            s{c}_{level} = s{c}_{level} + i{c}[b]")
            a(f"            y{c}_{level}[M + b] = s{c}_{level} * h")
    level_of = {}
    for c, (signal, power, d) in enumerate(chains):
        for level in range(d + 1):
            level_of[(signal, power, level)] = f"y{c}_{level}[M + b]"
    for r in range(lanes):
        a(f"        g{r} = fb[0, {r}]")
    a("        # P, Q, Cramer's rule: the generated code")
    a("        for b in range(nb):")
    a(f"            kv = ({', '.join(level_of[kernel] for kernel in module.KERNELS)},)")
    a("            P, Q = _regressors_packed(kv)")
    a("            nums, den = _cramer(P, Q)")
    for r in range(n_par):
        a(f"            g{r}[M + b] = nums[{r}]")
    a(f"            g{n_par}[M + b] = den")
    a("        # the invariant filter 1/s**p on the numerators and the denominator")
    a("        for lev in range(p):")
    for r in range(lanes):
        a(f"            g{r} = fb[lev, {r}]")
        a(f"            e{r} = fb[lev + 1, {r}]")
        a(f"            t{r} = fs[lev + 1, {r}]")
    a("            for b in range(nb):")
    for r in range(lanes):
        a(f"                j{r}[b] = {fir(f'g{r}')}")
    a("            for b in range(nb):")
    for r in range(lanes):
        a(f"                t{r} = t{r} + j{r}[b]")
        a(f"                e{r}[M + b] = t{r} * h")
    for r in range(lanes):
        a(f"            fs[lev + 1, {r}] = t{r}")
    for r in range(lanes):
        a(f"        g{r} = fb[p, {r}]")
    a("        for b in range(nb):")
    a(f"            d = g{n_par}[M + b]")
    a("            if d == 0.0 or not math.isfinite(d):")
    for r in range(n_par):
        a(f"                out[{r}, start + b] = np.nan")
    a("            else:")
    for r in range(n_par):
        a(f"                out[{r}, start + b] = g{r}[M + b] / d")
    a("        # the last M values of every level start the next block")
    a("        for k in range(M):")
    for c, (_, _, d) in enumerate(chains):
        for level in range(d):
            a(f"            y{c}_{level}[k] = y{c}_{level}[nb + k]")
    a("            for lev in range(p):")
    a(f"                for r in range({lanes}):")
    a("                    fb[lev, r, k] = fb[lev, r, nb + k]")
    for k, (c, level) in enumerate(chain_ints):
        a(f"    sums[{k}] = s{c}_{level}")
    a("    for k in range(M):")
    for i, (c, level) in enumerate(chain_ints):
        a(f"        windows[{i}, k] = y{c}_{level - 1}[k]")
    a("    for lev in range(p):")
    a(f"        for r in range({lanes}):")
    a(f"            sums[{n_chain_ints} + lev * {lanes} + r] = fs[lev + 1, r]")
    a("            for k in range(M):")
    a(f"                windows[{n_chain_ints} + lev * {lanes} + r, k] = fb[lev, r, k]")
    a("")
    return "\n".join(src)


def _load_cached(module, q):
    """Write the loop's source into :data:`CACHE_DIR` (if not there yet) and import it,
    so that numba caches the machine code beside it.  ``None`` if that fails."""
    try:
        source = _kernel_source(module, q, embed=True)
    except (OSError, TypeError):  # the generated module's source is not available
        return None
    digest = hashlib.sha256(source.encode()).hexdigest()[:20]
    stem = f"{module.MODEL}_q{q}_{digest}"
    path = os.path.join(CACHE_DIR, stem + ".py")
    try:
        if not os.path.exists(path):
            os.makedirs(CACHE_DIR, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=CACHE_DIR, suffix=".tmp")
            with os.fdopen(fd, "w") as fh:
                fh.write(source)
            os.replace(tmp, path)
        name = f"_algid_engine_{stem}"
        spec = importlib.util.spec_from_file_location(name, path)
        kernel_module = importlib.util.module_from_spec(spec)
        # numba finds the module's globals by name when it loads cached code
        sys.modules[name] = kernel_module
        try:
            spec.loader.exec_module(kernel_module)
        except BaseException:
            del sys.modules[name]
            raise
    except OSError:
        return None
    return kernel_module.advance


@lru_cache(maxsize=None)
def _compiled(module_name, q):
    """The compiled loop of a generated module and rule (built once per process)."""
    _require_numba()
    module = importlib.import_module(module_name)
    advance = _load_cached(module, q)
    if advance is None:
        namespace = {"__name__": f"_algid_engine_{module.MODEL}_q{q}",
                     "regressors_packed": module.regressors_packed,
                     "cramer": module.cramer}
        exec(compile(_kernel_source(module, q, embed=False), namespace["__name__"], "exec"),
             namespace)
        advance = namespace["advance"]
    return advance


def prepare(module, quadrature_order):
    """Compile the loop of a model and rule now (or load it from the cache).

    Parameters
    ----------
    module : module
        Generated estimator module (:func:`algid.estimator.load_model`).
    quadrature_order : int
        Points of the cumulative quadrature rule.
    """
    _compiled(module.__name__, int(quadrature_order))


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
        Sampling step ``h`` [s].
    input_divisor : float
        The input samples are divided by it (the known mass of model ``"msd"``).
    n_seen : int
        Samples processed since the time origin.
    sums : ndarray, shape (n_integrators,)
        Running sum of the unscaled increments of every integrator: the chains in
        ``CHAINS`` order, level by level, then the filter integrators (filter level
        by filter level, numerators in ``PARAMETERS`` order then the denominator).
    windows : ndarray, shape (n_integrators, quadrature_order - 1)
        The last ``q - 1`` integrand values of every integrator, oldest first.
    """

    def __init__(self, module, quadrature_order, filter_order, step, input_divisor):
        self._module = module
        self.model = module.MODEL
        self.parameters = tuple(module.PARAMETERS)
        self.quadrature_order = int(quadrature_order)
        self.filter_order = int(filter_order)
        self.step = float(step)
        self.input_divisor = float(input_divisor)
        self._advance = _compiled(module.__name__, self.quadrature_order)
        q = self.quadrature_order
        n_int = (len(_chain_integrators(module))
                 + (len(self.parameters) + 1) * self.filter_order)
        self.sums = np.zeros(n_int)
        self.windows = np.zeros((n_int, q - 1))
        self._startup = np.zeros((2, q))  # input (divided) and output, samples 0 .. q-1
        self._work = np.empty(_work_size(module, q, self.filter_order))  # scratch
        self.n_seen = 0

    def reset(self):
        """Move the time origin to the next sample: forget everything seen."""
        self.sums.fill(0.0)
        self.windows.fill(0.0)
        self._startup.fill(0.0)
        self.n_seen = 0

    def copy(self):
        """An independent copy that continues from the same point."""
        new = object.__new__(EngineState)
        new.__dict__.update(self.__dict__)
        new.sums = self.sums.copy()
        new.windows = self.windows.copy()
        new._startup = self._startup.copy()
        new._work = np.empty_like(self._work)
        return new

    def __repr__(self):
        return (f"EngineState(model={self.model!r}, quadrature_order={self.quadrature_order}, "
                f"filter_order={self.filter_order}, step={self.step!r}, "
                f"n_seen={self.n_seen})")

    def _start(self):
        """Process the buffered samples ``0 .. q - 1`` with NumPy, as the batch estimator
        does; set the state as after sample ``q - 1`` and return its estimates."""
        module = self._module
        q, h = self.quadrature_order, self.step
        regular, startup = rule_weights(q)

        def integrate(y):
            # cumulative_integral, keeping the running sum of the unscaled increments
            increments = np.empty(q - 1)
            increments[q - 2:] = np.correlate(y, regular, mode="valid")
            if q > 2:
                increments[: q - 2] = startup @ y[:q]
            sums = np.cumsum(increments)
            out = np.empty(q)
            out[0] = 0.0
            out[1:] = sums * h
            return out, sums[-1]

        tau = np.arange(q) * h
        signals = {module.INPUT: self._startup[0], module.OUTPUT: self._startup[1]}
        kernels = {}
        k = 0
        for signal, power, depth in module.CHAINS:
            y = signals[signal] if power == 0 else tau**power * signals[signal]
            kernels[module.kernel_name(signal, power, 0)] = y
            for level in range(1, depth + 1):
                self.windows[k] = y[1:]
                y, self.sums[k] = integrate(y)
                kernels[module.kernel_name(signal, power, level)] = y
                k += 1
        P, Q = module.regressors(kernels)
        numerators, denominator = module.cramer(P, Q)
        lanes = [np.array(np.broadcast_to(v, (q,)), dtype=float)  # constants too
                 for v in (*numerators, denominator)]
        for _ in range(self.filter_order):
            for r, y in enumerate(lanes):
                self.windows[k] = y[1:]
                lanes[r], self.sums[k] = integrate(y)
                k += 1
        den = lanes[-1][q - 1]
        if den == 0.0 or not math.isfinite(den):
            return np.full(len(self.parameters), np.nan)
        with np.errstate(all="ignore"):
            return np.array([num[q - 1] / den for num in lanes[:-1]])


def make_state(module, quadrature_order, filter_order, *, step, input_divisor=1.0):
    """A fresh engine state, with the time origin at the next sample.

    Compiles the loop of the model and rule, or loads it from the cache, on first use
    in a process.

    Parameters
    ----------
    module : module
        Generated estimator module (:func:`algid.estimator.load_model`).
    quadrature_order : int
        Points of the cumulative quadrature rule (see :mod:`algid.quadrature`).
    filter_order : int
        Order ``p >= 0`` of the invariant filter ``1/s**p``.
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
        If numba is not installed, or an option is invalid.
    """
    from algid.estimator import _check_options
    _check_options(filter_order, quadrature_order)
    for name, value in (("step", step), ("input_divisor", input_divisor)):
        if not (isinstance(value, (int, float, np.floating, np.integer))
                and np.isfinite(value) and value > 0):
            raise InputDataError(f"{name} must be a positive number, got {value!r}")
    return EngineState(module, quadrature_order, filter_order, step, input_divisor)


def run_chunk(state, f, x, *, out=None):
    """Estimates over one chunk of samples, advancing ``state``.

    Parameters
    ----------
    state : EngineState
        From :func:`make_state`; updated in place.
    f, x : array_like, shape (n,)
        Input and output samples of the chunk (finite; uniformly sampled with the
        state's step, continuing the samples seen before).  ``n`` may be 0.
    out : ndarray, shape (n_parameters, n), optional
        Float64 array to write the estimates into.

    Returns
    -------
    ndarray, shape (n_parameters, n)
        Row ``i`` holds the estimates of ``state.parameters[i]``; NaN for the first
        ``quadrature_order - 1`` samples after the time origin and where the
        denominator is zero or not finite.

    Raises
    ------
    InputDataError
        If ``f``, ``x`` or ``out`` have the wrong shape.
    """
    f = np.ascontiguousarray(f, dtype=np.float64)
    x = np.ascontiguousarray(x, dtype=np.float64)
    if f.ndim != 1 or f.shape != x.shape:
        raise InputDataError(f"f and x must be 1-D and equally long, got shapes {f.shape} "
                             f"and {x.shape}")
    n = f.size
    shape = (len(state.parameters), n)
    if out is None:
        out = np.empty(shape)
    elif not (isinstance(out, np.ndarray) and out.shape == shape and out.dtype == np.float64):
        raise InputDataError(f"out must be a float64 array of shape {shape}, got "
                             f"{getattr(out, 'shape', None)} {getattr(out, 'dtype', None)}")
    q = state.quadrature_order
    i = 0
    if state.n_seen < q:  # start-up: buffer samples 0 .. q-1
        seen = state.n_seen
        i = min(q - seen, n)
        state._startup[0, seen:seen + i] = f[:i] / state.input_divisor
        state._startup[1, seen:seen + i] = x[:i]
        out[:, :i] = np.nan
        state.n_seen = seen + i
        if state.n_seen == q:
            out[:, i - 1] = state._start()
    if i < n:
        state._advance(f[i:], x[i:], out[:, i:], state.sums, state.windows, state.n_seen,
                       state.step, state.input_divisor, state.filter_order, state._work)
        state.n_seen += n - i
    return out


@lru_cache(maxsize=None)
def _signal_scan():
    """Compiled passes over ``t``, ``f``, ``x``: True when they pass every check of
    :func:`algid.validation.check_experiment` that looks at the values."""
    numba = _require_numba()

    # reductions in any order (vectorised); the result does not depend on the order:
    # a sum of x * 0 is NaN if and only if some x is not finite
    @numba.njit("float64(float64[::1], float64[::1], float64[::1])", cache=True, nogil=True,
                fastmath={"reassoc"})
    def nonfinite_and_excitation(t, f, x):
        nan_if_bad = 0.0
        excitation = 0.0
        for i in range(t.shape[0]):
            nan_if_bad += t[i] * 0.0 + f[i] * 0.0 + x[i] * 0.0
            excitation += abs(f[i]) + abs(x[i])
        return nan_if_bad if excitation > 0.0 else math.nan

    @numba.njit("boolean(float64[::1], float64, float64)", cache=True, nogil=True)
    def uniform(t, h, tolerance):
        violations = 0
        for i in range(t.shape[0] - 1):
            dt = t[i + 1] - t[i]
            violations += (not dt > 0.0) + (abs(dt - h) > tolerance)
        return violations == 0

    def scan(t, f, x, h, tolerance):
        return (math.isfinite(h) and nonfinite_and_excitation(t, f, x) == 0.0
                and uniform(t, h, tolerance))

    return scan


def check_experiment(t, f, x, *, min_samples=16):
    """:func:`algid.validation.check_experiment` in two compiled passes over the data.

    Same arguments, result and errors: for float64 1-D contiguous arrays of equal
    length the values are checked by compiled loops (finite, time strictly increasing and
    uniform within :data:`~algid.validation.UNIFORM_RTOL`, some excitation); anything
    else, and any failure, goes to :func:`algid.validation.check_experiment`, which
    raises the error that names the offending input.
    """
    from algid.validation import UNIFORM_RTOL
    from algid.validation import check_experiment as check_slowly
    arrays = (t, f, x)
    if all(isinstance(a, np.ndarray) and a.dtype == np.float64 and a.ndim == 1
           and a.flags.c_contiguous for a in arrays):
        n = t.size
        if f.size == n and x.size == n and n >= max(int(min_samples), 2):
            h = float((t[-1] - t[0]) / (n - 1))
            if _signal_scan()(t, f, x, h, UNIFORM_RTOL * h):
                return t, f, x, h
    return check_slowly(t, f, x, min_samples=min_samples)


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
