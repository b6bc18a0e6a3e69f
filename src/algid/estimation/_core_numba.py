"""The compiled backend of the estimator core (:mod:`algid.estimation._core`); needs numba.

Runs the loop generated for the model at derivation time
(``algid/_generated/<model>_numba.py``, written by ``python -m derivation``; numba
caches its machine code beside it), or, for a model compiled in memory
(:func:`algid.symbolic._codegen.compile_model`), the loop built from its
``NUMBA_SOURCE``.  The loop performs the operations of the NumPy backend in the same
order (see :mod:`algid.symbolic._codegen_numba`).

Compiling the loop of a user model takes numba many seconds, so its source and that
of its algebra are written once to files named by a hash of their text, in
:func:`user_cache_dir`, and numba caches the machine code beside them: the next
process that uses the same model loads it instead of compiling.  Where no cache
directory is usable the loop is compiled in memory.  A compilation to come is announced
by one line on standard error.

numba's cache files are pickles, and loading one runs what it says: a cache that another
user could write (the directory, its ``__pycache__``, a file there, numba's place for it
under ``$NUMBA_CACHE_DIR``, or a parent that lets others rename them) is not read, the
loop is compiled in memory and one line on standard error says why; the default
directory is created private (0700).  The same check guards numba's cache of the built-in
models' loops (``__pycache__`` beside ``algid/_generated``, or numba's user-wide cache),
unless the package's own folder is as writable.  A cache file that cannot be loaded (cut
short, damaged) is compiled anew instead of raising.  Not covered: the other functions
algid compiles with ``cache=True`` (tracker kernels, signal checks, numerical error),
which numba caches beside the installed package (writable by whoever can change its
code) or under ``$NUMBA_CACHE_DIR``: keep that directory private.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import os
import stat
import sys
from functools import cache, lru_cache

import numba  # noqa: F401 - ImportError here: the backend is not available
import numpy as np

from algid._compile_notice import mark_said, watch
from algid._generated import MODULES, NUMBA_MODULES
from algid.models._registry import module_from_source
from algid.signals._quadrature import integrator_weights

watch()   # a line on stderr while numba compiles these for more than a second

__all__ = ["advance", "bound_sample", "bound_sample_pair", "pack_pair", "PAIR_ARRAYS",
           "user_cache_dir", "machine_code_cached"]


def _cache_base():
    base = os.environ.get("ALGID_CACHE_DIR")
    if base is None:
        numba_dir = os.environ.get("NUMBA_CACHE_DIR")
        base = os.path.join(numba_dir, "algid") if numba_dir else os.path.join(
            os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"),
                                                             ".cache"), "algid")
    return base


def _shared(path, entries=False):
    """Why another user could change ``path`` (a directory, or with ``entries`` also
    the files in it), or None: it, or they, must be ours and writable by us only."""
    try:
        names = [""] + (sorted(os.listdir(path)) if entries else [])
    except OSError:
        return None   # (not there yet: numba creates it, with our umask)
    private = False
    for name in names:
        place = os.path.join(path, name) if name else path
        try:
            st = os.lstat(place) if name else os.stat(place)
        except OSError:
            continue
        if st.st_uid != os.geteuid():
            return f"{place} belongs to another user (uid {st.st_uid})"
        # (the modes of files in a directory others cannot enter do not matter)
        if st.st_mode & 0o022 and not private:
            return f"{place} is writable by others (mode {stat.S_IMODE(st.st_mode):04o})"
        private = private or not (name or st.st_mode & 0o011)
    return None


def _ancestors_shared(path):
    """Why another user could rename ``path`` away (a parent writable by others without
    the sticky bit of ``/tmp``, or owned by another user but root), or None."""
    parent = os.path.dirname(os.path.realpath(path))
    while True:
        try:
            st = os.stat(parent)
        except OSError:
            return None
        if st.st_mode & 0o022 and not st.st_mode & stat.S_ISVTX:
            return f"{parent} is writable by others (mode {stat.S_IMODE(st.st_mode):04o})"
        if st.st_uid not in (0, os.geteuid()):
            return f"{parent} belongs to another user (uid {st.st_uid})"
        if parent == os.path.dirname(parent):
            return None
        parent = os.path.dirname(parent)


def _unsafe_reason(base, directory):
    """Why the cache in ``directory`` (under ``base``) could hold files written by
    someone else, or None.

    numba's cache index is a pickle, loaded (code run) when the loop is first called:
    the directory, its ``__pycache__`` and their files must be ours and writable by us
    only, and the parents of ``base`` must not let others rename it.
    """
    real = os.path.realpath(directory)
    return (_shared(os.path.realpath(base)) or _shared(real, entries=True)
            or _shared(os.path.join(real, "__pycache__"), entries=True)
            or _ancestors_shared(base))


def _machine_code_unsafe(module):
    """Why numba's cache of the functions of ``module`` (``__pycache__`` beside the file,
    or under ``$NUMBA_CACHE_DIR``) could hold files written by someone else, or None."""
    for path in sorted({function._cache.cache_path for function in vars(module).values()
                        if hasattr(getattr(function, "_cache", None), "cache_path")}):
        reason = _shared(path, entries=True) or _ancestors_shared(path)
        if reason:
            return reason
    return None


def _cache_dir_and_reason():
    """The cache directory of user models, or None and why none is used."""
    base = _cache_base()
    if not base:
        return None, "the cache is turned off (ALGID_CACHE_DIR is empty)"
    directory = os.path.join(base, "user_models")
    try:   # private when we create them (the parents above: the user's umask)
        os.makedirs(base, mode=0o700, exist_ok=True)
        if not os.path.isdir(directory):
            os.mkdir(directory, mode=0o700)
    except OSError as exc:
        return None, f"{directory} cannot be created ({exc.strerror or exc})"
    if not os.access(directory, os.W_OK | os.X_OK):
        return None, f"{directory} is not writable"
    reason = _unsafe_reason(base, directory)
    if reason:
        return None, f"{reason}: the cache is not used"
    return directory, None


def user_cache_dir():
    """Directory where the compiled loops of user models are cached, or None.

    ``$ALGID_CACHE_DIR`` if it is set (set to an empty string, it turns the cache off);
    else ``algid`` under ``$NUMBA_CACHE_DIR`` if that is set; else
    ``$XDG_CACHE_HOME/algid`` (default ``~/.cache/algid``).  Created private (mode
    0700).  None if the directory cannot be created or written, or if another user
    could write into it (it, a parent or a file there belongs to another user or is
    writable by others): numba's cache holds pickles that run code when loaded.

    Returns
    -------
    str or None
        The directory of the cached sources (numba keeps its machine code beside them,
        or under ``$NUMBA_CACHE_DIR``).
    """
    return _cache_dir_and_reason()[0]


def _digest(text):
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _write_once(path, text):
    """Write ``text`` to ``path`` unless it already holds it (its date then stays, and
    with it numba's cache of the functions it defines)."""
    try:
        with open(path, encoding="utf-8") as held:
            if held.read() == text:
                return
    except FileNotFoundError:
        pass
    temporary = f"{path}.{os.getpid()}.tmp"
    with open(temporary, "w", encoding="utf-8") as new:
        new.write(text)
    os.replace(temporary, path)  # atomic: a concurrent reader sees one text or the other


def _module_from_file(name, path, generated):
    """The module of the file at ``path``, None unless it holds exactly ``generated``.

    Only text the code generator has just produced is executed: the file is read back
    and compared with it (a file replaced after it was written is never run), then made
    a module through module_from_source (its functions defined in the file, for numba).
    """
    with open(path, encoding="utf-8") as held:
        text = held.read()
    if text != generated:
        return None
    return module_from_source(generated, name, filename=path)


def _cached_loop(module, directory):
    """The loops of a model compiled in memory, loaded from files in ``directory`` so
    that numba caches its machine code; None if its texts are not as generated, or why
    numba's cache of them is not used (a str)."""
    source = getattr(module, "GENERATED_SOURCE", None)
    loop_source = module.NUMBA_SOURCE
    algebra_import = f"from {module.__name__} import cramer, regressors_packed\n"
    if source is None or loop_source.count(algebra_import) != 1 or \
            loop_source.count("\nCACHE = False\n") != 1:
        return None
    algebra = f"algid_user_{module.MODEL}_{_digest(source)}"
    loop_source = loop_source.replace(algebra_import,
                                      f"from {algebra} import cramer, regressors_packed\n")
    loop_source = loop_source.replace("\nCACHE = False\n", "\nCACHE = True\n")
    loop_name = f"{algebra}_numba_{_digest(loop_source)}"
    with contextlib.suppress(OSError):   # private before numba makes it (with the umask)
        os.mkdir(os.path.join(directory, "__pycache__"), mode=0o700)
    _write_once(os.path.join(directory, algebra + ".py"), source)
    _write_once(os.path.join(directory, loop_name + ".py"), loop_source)
    if algebra not in sys.modules and _module_from_file(
            algebra, os.path.join(directory, algebra + ".py"), source) is None:
        return None
    loops = _module_from_file(loop_name, os.path.join(directory, loop_name + ".py"),
                              loop_source)
    if loops is None:
        return None
    # (numba reads its cache at the first call only: the modules made, nothing loaded)
    reason = _machine_code_unsafe(sys.modules[algebra]) or _machine_code_unsafe(loops)
    if reason:
        return reason
    if not machine_code_cached(directory, loop_name):
        _announce_compilation(module, f"once: numba caches it in {directory}")
    _recompile_if_damaged(sys.modules[algebra])
    return _recompile_if_damaged(loops)


def machine_code_cached(directory, loop_name):
    """Whether numba holds cached machine code of a user model's loop module.

    It looks for numba's index files ``<loop_name>.*.nbi``, in ``__pycache__`` beside the
    module or under ``$NUMBA_CACHE_DIR``.

    Parameters
    ----------
    directory : str
        The cache directory of user models (:func:`user_cache_dir`).
    loop_name : str
        Name of the loop module written there.

    Returns
    -------
    bool
    """
    places = [os.path.join(directory, "__pycache__")]
    if os.environ.get("NUMBA_CACHE_DIR"):  # numba's place there: <folder>_<sha1 of path>
        source = os.path.abspath(directory)
        places.append(os.path.join(os.environ["NUMBA_CACHE_DIR"], os.path.basename(source)
                                   + "_" + hashlib.sha1(source.encode()).hexdigest()))
    for place in places:
        try:
            names = os.listdir(place)
        except OSError:
            continue
        if any(n.startswith(loop_name + ".") and n.endswith(".nbi") for n in names):
            return True
    return False


def _announce_compilation(module, how):
    # numba compiles a user model's loop at its first call, silently, for tens of
    # seconds to minutes: say so on stderr, so that it is not taken for a hang
    mark_said()   # (the compile-event listener need not say it again)
    print(f"algid: compiling the numba loop of model {module.MODEL!r} at its first use "
          f"({how}); this takes ten to twenty seconds; engine='numpy' starts at once",
          file=sys.stderr, flush=True)


def _recompile_if_damaged(module):
    """Make the compiled functions of ``module`` compile anew where numba's cache file
    of them cannot be loaded (cut short, damaged), instead of raising from its
    unpickling; the index is removed so that numba writes a fresh one."""
    for function in list(vars(module).values()):
        functions_cache = getattr(function, "_cache", None)
        load = getattr(functions_cache, "load_overload", None)
        index = getattr(getattr(functions_cache, "_cache_file", None), "_index_path", None)
        if load is None or index is None or getattr(load, "_algid_guarded", False):
            continue

        def guarded(signature, target_context, _load=load, _index=index, _name=module.__name__):
            try:
                return _load(signature, target_context)
            except Exception as exc:  # noqa: BLE001 - anything unpickling damaged bytes raises
                print(f"algid: numba's cache file {_index} cannot be loaded "
                      f"({type(exc).__name__}); compiling {_name} again", file=sys.stderr,
                      flush=True)
                with contextlib.suppress(OSError):
                    os.unlink(_index)
                return None

        guarded._algid_guarded = True
        functions_cache.load_overload = guarded
    return module


def _built_in_loops(name):
    """The loops of a model generated at derivation time; numba's cache of them (in
    ``__pycache__`` beside the package's file, else numba's user-wide cache or
    ``$NUMBA_CACHE_DIR``) is not read where others could have written it."""
    loops = importlib.import_module(name)
    reason = _machine_code_unsafe(loops)
    # a cache as writable as the package's own code (a group-writable install) is no
    # way in that the code is not
    if reason is None or _shared(os.path.dirname(os.path.abspath(loops.__file__))):
        return _recompile_if_damaged(loops)
    from numba.core.caching import NullCache

    for function in vars(loops).values():   # before their first call: nothing read
        if hasattr(getattr(function, "_cache", None), "cache_path"):
            function._cache = NullCache()
    print(f"algid: numba's cache of {name} is not used ({reason}); compiling it in memory",
          file=sys.stderr, flush=True)
    return loops


@cache
def _loops_of(module):
    """The module of the compiled loops of a generated module."""
    if MODULES.get(module.MODEL) == module.__name__:
        return _built_in_loops(NUMBA_MODULES[module.MODEL])
    directory, reason = _cache_dir_and_reason()
    if directory is not None:
        try:
            loops = _cached_loop(module, directory)
        except OSError:  # the directory went away or is full: compile in memory
            loops, reason = None, f"{directory} cannot be written"
        if isinstance(loops, str):
            loops, reason = None, f"{loops}: numba's cache is not used"
        if loops is not None:
            return loops
        reason = reason or "its source is not as generated"
    _announce_compilation(module, f"in memory: {reason}")
    return module_from_source(module.NUMBA_SOURCE, module.__name__ + "_numba")


#: The arguments of the error propagation where it is not active.
_NOT_PROPAGATED = (np.zeros(1), np.zeros((1, 1)), 0, np.zeros(1), np.zeros((0, 1)),
                   np.zeros((0, 1)), np.zeros(0), np.zeros(0))


@lru_cache(maxsize=64)
def _weights(points, dt):
    return integrator_weights(points, dt)


def _fixed(state):
    """The loop and the weights of ``state`` (kept with it while its step and model
    stay)."""
    fixed = state.__dict__.get("_numba_fixed")
    if fixed is None or fixed[0] != state.dt or fixed[1] is not state.model:
        fixed = state._numba_fixed = (state.dt, state.model, _loops_of(state.model).advance,
                                      *_weights(state.points, state.dt))
    return fixed


def bound_sample_pair(state):
    """One sample of a state and its companion, with the numerical error, in one call.

    The generated ``advance_sample_pair`` and its bound arguments (the arrays of both
    estimators in one buffer, :func:`pack_pair`), for a stream fed one sample at a
    time: the same numbers as :func:`advance` of the estimator and of its companion
    followed by :func:`algid.estimation._numerical_error_numba.block_error`, with the channels'
    extent tracked (:mod:`algid.estimation._numerical_error`).

    Parameters
    ----------
    state : EstimatorState
        Past its start-up, with its companion
        (:func:`algid.estimation._numerical_error.with_companion`).  The arguments hold their
        arrays and
        ``dt``: make a new one if ``state.dt`` changes.

    Returns
    -------
    pair : callable
        The compiled ``advance_sample_pair(*values, n_seen, dt, *arguments, out,
        error_out)``: ``values`` the sample of every channel as floats, in the model's
        ``CHANNELS`` order; ``out`` a float64 array of shape ``(n_parameters, 1)`` and
        ``error_out`` one of shape ``(1,)`` receive the estimates and their numerical
        error.  The caller adds one to ``n_seen`` of the state and of its companion.
    arguments : tuple
        The bound arguments.
    """
    companion = state.companion
    buffer, offsets = pack_pair(state, _fixed(state)[3], _fixed(companion)[3])
    return (_loops_of(state.model).advance_sample_pair,
            (buffer, offsets, state.filter_order, companion.filter_order))


def bound_sample(state):
    """One sample of a state alone (no companion), as a function of the sample's values.

    Parameters
    ----------
    state : EstimatorState
        Past its start-up.  Bound to its arrays and ``dt``: make a new one if they
        change (:func:`pack_pair` replaces the arrays).

    Returns
    -------
    callable
        ``sample(*values, out, n_seen)``: the generated ``advance_sample`` of the values
        (floats, in the model's ``CHANNELS`` order) into ``out`` (shape
        ``(n_parameters, 1)``); the caller adds one to ``state.n_seen``.
    """
    _, _, _, weights, _ = _fixed(state)
    loop = _loops_of(state.model).advance_sample
    integrals, history, dt = state.integrals, state.history, state.dt
    divisors, filter_order = state.divisors, state.filter_order

    def sample(*arguments):
        *values, out, n_seen = arguments
        loop(*values, out, integrals, history, n_seen, dt, divisors, weights, filter_order)
    return sample


#: The arrays of an estimator and its companion that the one-sample step reads and
#: writes, in the order they sit in one buffer (:func:`pack_pair`): passed as one array,
#: they cost numba's dispatch one argument instead of eleven.
PAIR_ARRAYS = ("integrals", "history", "companion.integrals", "companion.history",
               "weights", "companion weights", "divisors", "scratch of the companion's estimates",
               "recent_errors", "channel_max", "channel_last")


def pack_pair(state, weights, companion_weights):
    """Put the arrays of a state and its companion into one buffer (:data:`PAIR_ARRAYS`).

    The state's arrays become views into it, holding the same values (the state works
    as before); a state already packed keeps its buffer.  The weights are written in.

    Parameters
    ----------
    state : EstimatorState
        With its companion (:func:`algid.estimation._numerical_error.with_companion`).
    weights, companion_weights : ndarray
        The quadrature weights of the state and of its companion.

    Returns
    -------
    buffer : ndarray
        Float64, 1-D.
    offsets : ndarray
        Int64: array ``i`` of :data:`PAIR_ARRAYS` is ``buffer[offsets[i]:offsets[i + 1]]``.
    """
    companion = state.companion
    arrays = [state.integrals, state.history, companion.integrals, companion.history,
              weights, companion_weights, state.divisors,
              np.empty(len(state.model.PARAMETERS)), state.recent_errors,
              state.channel_max, state.channel_last]
    offsets = np.cumsum([0] + [a.size for a in arrays])
    packed = state.__dict__.get("_pair_buffer")
    if packed is None or packed.size != offsets[-1] or any(
            a.base is not packed for a in arrays[:4] + arrays[6:7] + arrays[8:]):
        packed = np.empty(offsets[-1])
        views = [packed[a:b].reshape(array.shape) for a, b, array in
                 zip(offsets[:-1], offsets[1:], arrays)]
        for view, array in zip(views, arrays):
            view[...] = array
        (state.integrals, state.history, companion.integrals, companion.history, _, _,
         state.divisors, _, state.recent_errors, state.channel_max, state.channel_last) = views
        companion.divisors = state.divisors
        for cache in ("_pair_buffer", "_sample_step", "_numpy_sample"):  # bound to the old
            for holder in (state, companion):
                holder.__dict__.pop(cache, None)
        state._pair_buffer = packed
    packed[offsets[4]:offsets[5]] = weights
    packed[offsets[5]:offsets[6]] = companion_weights
    return packed, offsets


def advance(state, layout, channels, out, *, from_origin=False, error_out=None):
    """Estimates of a chunk into ``out``, in one compiled pass.

    The chunk continues the stream, or with ``from_origin`` it holds the first samples
    after the time origin (at least ``points`` of them; the estimates of samples
    ``0 .. points - 2`` are NaN).

    Parameters
    ----------
    state : EstimatorState
        The state (:func:`algid.estimation._core.new_state`); advanced in place.
    layout : IntegratorLayout
        Layout of the state's model (:func:`algid.estimation._core.integrator_layout`).
    channels : tuple of ndarray
        The chunk: one float64 1-D array per channel, all of length ``m``, in the
        model's ``CHANNELS`` order.
    out : ndarray, shape (n_parameters, m)
        Float64 array the estimates are written into.
    from_origin : bool, optional
        The chunk starts at the time origin (the state holds no sample yet).
    error_out : ndarray, shape (m,), optional
        With the state's error propagation active
        (:mod:`algid.estimation._error_propagation`): receives the numerical error
        (``state.recent_errors`` is advanced), formed from the companion's estimates at
        the grid samples, for which the estimates stand elsewhere.
    """
    _, _, loop, weights, startup = _fixed(state)
    if from_origin:
        state.n_seen = 0
    propagation = state.propagation
    if error_out is not None:
        arguments = (propagation.taps, propagation.residuals, propagation.switch,
                     propagation.lanes, propagation.levels, propagation.telescoped,
                     state.recent_errors, error_out)
    else:
        arguments = _NOT_PROPAGATED
    # one machine code for every call: numba compiles the loop again (seconds) for an
    # output that is not C-contiguous (a column block of a larger array)
    target = out if out.flags.c_contiguous else np.empty(out.shape)
    loop(*channels, target, state.integrals, state.history, state.n_seen, state.dt,
         state.divisors, weights, startup, state.filter_order, bool(from_origin), *arguments)
    if target is not out:
        out[...] = target
    if from_origin:
        out[:, :state.points - 1] = np.nan
    state.n_seen += channels[0].size
