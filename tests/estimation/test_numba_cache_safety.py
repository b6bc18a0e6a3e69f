"""numba's cache of user models: never read from a directory others can write, created
private, and a damaged cache file compiled anew instead of a traceback."""

from __future__ import annotations

import os
import pickle
import stat

import numpy as np
import pytest

pytest.importorskip("numba")
pytest.importorskip("sympy")

import numba  # noqa: E402

from algid.estimation import _core_numba as core_numba  # noqa: E402
from algid.models._compiled import compile_equation  # noqa: E402


@pytest.fixture
def cache_env(tmp_path, monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.delenv("ALGID_CACHE_DIR", raising=False)
    core_numba._loops_of.cache_clear()
    yield tmp_path
    core_numba._loops_of.cache_clear()


def test_directory_others_can_write_is_not_used(cache_env, monkeypatch, capfd):
    shared = cache_env / "shared"
    (shared / "user_models").mkdir(parents=True)
    monkeypatch.setenv("ALGID_CACHE_DIR", str(shared))
    for target, mode in ((shared, 0o777), (shared / "user_models", 0o775)):
        os.chmod(shared, 0o700)
        os.chmod(shared / "user_models", 0o700)
        os.chmod(target, mode)
        assert core_numba.user_cache_dir() is None
    os.chmod(shared / "user_models", 0o755)
    (shared / "user_models" / "planted.nbi").write_bytes(b"")
    os.chmod(shared / "user_models" / "planted.nbi", 0o666)   # a file others can replace
    assert core_numba.user_cache_dir() is None
    os.chmod(shared / "user_models", 0o700)   # ... unless they cannot enter the directory
    assert core_numba.user_cache_dir() == str(shared / "user_models")
    os.chmod(shared / "user_models", 0o755)
    os.chmod(shared / "user_models" / "planted.nbi", 0o644)
    assert core_numba.user_cache_dir() == str(shared / "user_models")
    os.chmod(shared, 0o777)
    model = compile_equation("y' + a*y = u", "a", name="shared_dir")
    core_numba._loops_of(model)   # (numba compiles at the first call only)
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "in memory" in err and "writable by others" in err \
        and "mode 0777" in err
    assert not list((shared / "user_models").glob("algid_user_*"))   # nothing written


def test_default_directory_is_created_private(cache_env, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(cache_env / "xdg"))
    directory = core_numba.user_cache_dir()
    assert directory == str(cache_env / "xdg" / "algid" / "user_models")
    for path in (cache_env / "xdg" / "algid", cache_env / "xdg" / "algid" / "user_models"):
        assert stat.S_IMODE(os.stat(path).st_mode) == 0o700


def test_machine_code_in_a_pycache_others_can_write_is_not_used(cache_env, monkeypatch,
                                                                 capfd):
    monkeypatch.setenv("ALGID_CACHE_DIR", str(cache_env / "mine"))
    model = compile_equation("y' + a*y = u", "a", name="shared_pycache")
    pycache = cache_env / "mine" / "user_models" / "__pycache__"
    pycache.mkdir(parents=True)
    os.chmod(pycache, 0o777)
    core_numba._loops_of(model)
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "in memory" in err and "__pycache__" in err


def test_damaged_cache_index_is_compiled_again(cache_env, monkeypatch, capfd):
    """One compilation: the index files are damaged before the first call."""
    monkeypatch.setenv("ALGID_CACHE_DIR", str(cache_env / "cache"))
    model = compile_equation("y' + a*y = u", "a", name="damaged_index")
    loops = core_numba._loops_of(model)
    damaged = []
    for name in dir(loops):
        functions_cache = getattr(getattr(loops, name), "_cache", None)
        if functions_cache is not None and hasattr(functions_cache, "_cache_file"):
            path = functions_cache._cache_file._index_path
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "wb") as f:   # numba's version, then a cut-short pickle
                pickle.dump(numba.__version__, f, protocol=-1)
                f.write(pickle.dumps(("stamp", {"k": "v"}), protocol=-1)[:9])
            damaged.append(path)
    assert damaged
    capfd.readouterr()
    from algid.estimation._batch import estimate

    t = np.arange(300) * 1e-2
    u = np.sin(3 * t)
    y = np.sin(3 * t - np.arctan(1.5)) / np.hypot(2, 3)
    fast = estimate(t, u, y, model=model, engine="numba")
    slow = estimate(t, u, y, model=model, engine="numpy")
    np.testing.assert_array_equal(fast.a, slow.a)
    err = capfd.readouterr().err
    assert "cannot be loaded" in err and "Traceback" not in err
    fresh = 0
    for path in damaged:   # the called function's: a fresh index that loads (the others
        with open(path, "rb") as f:   # stay as they are until their first call)
            assert pickle.load(f) == numba.__version__
            try:
                pickle.loads(f.read())
                fresh += 1
            except pickle.UnpicklingError:
                pass
    assert fresh >= 1


def test_built_in_loops_skip_a_cache_others_can_write(monkeypatch, capfd):
    """The built-in loops' cache is checked as well (the reason forced: the package's
    own ``__pycache__`` is not touched); nothing compiles until a first call."""
    from numba.core.caching import NullCache

    from algid._generated import NUMBA_MODULES

    name = NUMBA_MODULES["msd"]
    loops = __import__(name, fromlist=["advance"])
    held = {key: f._cache for key, f in vars(loops).items()
            if hasattr(getattr(f, "_cache", None), "cache_path")}
    assert held
    monkeypatch.setattr(core_numba, "_machine_code_unsafe",
                        lambda module: "/x/__pycache__ is writable by others (mode 0777)")
    capfd.readouterr()
    try:
        assert core_numba._built_in_loops(name) is loops
        assert all(isinstance(getattr(loops, key)._cache, NullCache) for key in held)
        err = capfd.readouterr().err
        assert err.count("\n") == 1 and "not used" in err and "in memory" in err
    finally:
        for key, functions_cache in held.items():
            getattr(loops, key)._cache = functions_cache


def test_a_cached_source_replaced_after_it_was_written_is_never_run(cache_env,
                                                                    monkeypatch):
    """The file read back must hold exactly the generated text: one changed between
    writing and reading (here by the writer itself) is not executed; the loops are
    compiled in memory from the generated text instead."""
    monkeypatch.setenv("ALGID_CACHE_DIR", str(cache_env / "private"))
    written = core_numba._write_once

    def tampered(path, text):
        written(path, text.replace("import numpy", "import numpy  # planted", 1))

    monkeypatch.setattr(core_numba, "_write_once", tampered)
    run = []
    monkeypatch.setattr(core_numba, "module_from_source",
                        lambda source, name, **kw: run.append(source) or None)
    model = compile_equation("y' + a*y = u", "a", name="replaced_file")
    core_numba._loops_of(model)
    assert run and not any("# planted" in source for source in run)
    assert run[-1] == model.NUMBA_SOURCE   # the loops: compiled in memory, as generated
