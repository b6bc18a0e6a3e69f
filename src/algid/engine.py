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
The loop is written out per model and rule (straight-line code for the chains, whose
window values stay in registers; a small ring buffer per filter integrator, so that
``p`` is a run-time value) from ``CHAINS`` and ``KERNELS``, compiled once per model
and rule, and cached on disk (see :data:`CACHE_DIR`).

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
           "estimate_arrays", "INSTALL_HINT", "CACHE_DIR"]

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

# u, x, out, sums, windows, n0, h, divisor, p
_SIGNATURE = ("void(float64[::1], float64[::1], float64[:, :], float64[::1], "
              "float64[:, ::1], int64, float64, float64, int64)")


def available() -> bool:
    """Whether numba can be imported, i.e. whether this engine can run."""
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


def _kernel_source(module, q, *, embed):
    """Python source of the module that holds the compiled loop of ``module`` with the
    ``q``-point rule.  With ``embed`` the generated ``regressors_packed`` and ``cramer``
    are copied in (a self-contained, cacheable file); otherwise the namespace must
    provide them."""
    regular, _ = rule_weights(q)
    w = [repr(float(v)) for v in regular]
    m = q - 1
    names = {module.INPUT: "uval", module.OUTPUT: "xval"}
    n_par = len(module.PARAMETERS)
    lanes = n_par + 1  # numerators and denominator
    chain_ints = _chain_integrators(module)
    n_chain = len(chain_ints)

    body = []  # the loop body, one indentation level inside the loop
    level_value = {}
    for c, (signal, power, depth) in enumerate(module.CHAINS):
        body.append(f"# chain {c}: integrals of t**{power} * {signal}")
        factor = "1.0"
        for _ in range(power):  # tau**power as in NumPy: ((1 * tau) * tau) ...
            factor = f"({factor} * tau)"
        value = names[signal] if power == 0 else f"{factor} * {names[signal]}"
        body.append(f"v{c}_0 = {value}")
        level_value[(signal, power, 0)] = f"v{c}_0"
        for level in range(1, depth + 1):
            y = f"v{c}_{level - 1}"
            win = [f"w{c}_{level}_{j}" for j in range(m)] + [y]
            increment = " + ".join(f"{w[j]} * {win[j]}" for j in range(q))
            body.append(f"s{c}_{level} = s{c}_{level} + ({increment})")
            body.append(f"{', '.join(win[:m])} = {', '.join(win[1:])}"
                        if m > 1 else f"{win[0]} = {y}")
            body.append(f"v{c}_{level} = s{c}_{level} * h")
            level_value[(signal, power, level)] = f"v{c}_{level}"
    kernels = [level_value[kernel] for kernel in module.KERNELS]
    body.append(f"kv = ({', '.join(kernels)},)")
    body.append("P, Q = _regressors_packed(kv)")
    body.append("nums, den = _cramer(P, Q)")
    for r in range(lanes):
        body.append(f"y{r} = {f'nums[{r}]' if r < n_par else 'den'}")
    body.append("k = 0")
    body.append("for _ in range(p):  # filter integrators, ring buffers fr[k, pos:pos + m]")
    for r in range(lanes):
        increment = " + ".join([f"{w[j]} * fr[k, pos + {j}]" for j in range(m)]
                               + [f"{w[m]} * y{r}"])
        body += [f"    s = fs[k] + ({increment})", "    fs[k] = s",
                 f"    fr[k, pos] = y{r}", f"    fr[k, pos + {m}] = y{r}",
                 f"    y{r} = s * h", "    k += 1"]
    body.append(f"if y{n_par} == 0.0 or not math.isfinite(y{n_par}):")
    body += [f"    out[{r}, i] = nan" for r in range(n_par)]
    body.append("else:")
    body += [f"    out[{r}, i] = y{r} / y{n_par}" for r in range(n_par)]
    body += ["pos += 1", f"if pos == {m}:", "    pos = 0"]

    src = [f'"""Compiled estimation loop of model {module.MODEL!r}, {q}-point rule.',
           "",
           "Written by algid.engine from the generated module "
           f"{module.__name__}; do not edit.",
           '"""', "", "import math", "", "import numba", "import numpy as np", ""]
    if embed:
        src += ["CACHE = True", "", "# ---- from the generated module, verbatim", ""]
        src += [inspect.getsource(module.regressors_packed),
                inspect.getsource(module.cramer), "# ----", ""]
    else:
        src += ["CACHE = False", ""]
    src += ["_regressors_packed = numba.njit(cache=CACHE, nogil=True)(regressors_packed)",
            "_cramer = numba.njit(cache=CACHE, nogil=True)(cramer)", "",
            f"SIGNATURE = {_SIGNATURE!r}", "",
            "",
            "@numba.njit(SIGNATURE, cache=CACHE, nogil=True)",
            "def advance(u, x, out, sums, windows, n0, h, divisor, p):",
            "    nan = np.nan"]
    for k, (c, level) in enumerate(chain_ints):
        src.append(f"    s{c}_{level} = sums[{k}]")
        src += [f"    w{c}_{level}_{j} = windows[{k}, {j}]" for j in range(m)]
    src += [f"    nf = {lanes} * p",
            "    fs = sums[" + str(n_chain) + ":].copy()",
            f"    fr = np.empty((nf, {2 * m}))",
            "    for k in range(nf):",
            f"        for j in range({m}):",
            f"            fr[k, j] = windows[{n_chain} + k, j]",
            f"            fr[k, j + {m}] = windows[{n_chain} + k, j]",
            "    pos = 0",
            "    for i in range(u.shape[0]):",
            "        tau = (n0 + i) * h",
            "        uval = u[i] / divisor",
            "        xval = x[i]"]
    src += ["        " + line for line in body]
    for k, (c, level) in enumerate(chain_ints):
        src.append(f"    sums[{k}] = s{c}_{level}")
        src += [f"    windows[{k}, {j}] = w{c}_{level}_{j}" for j in range(m)]
    src += ["    for k in range(nf):",
            f"        sums[{n_chain} + k] = fs[k]",
            f"        for j in range({m}):",
            f"            windows[{n_chain} + k, j] = fr[k, pos + j]", ""]
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
        lanes = [np.asarray(v, dtype=float) for v in (*numerators, denominator)]
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
                       state.step, state.input_divisor, state.filter_order)
        state.n_seen += n - i
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
