"""The first compilation of a user model's numba loop is announced on stderr (it takes
numba tens of seconds to minutes), and not when its machine code is cached."""

from __future__ import annotations

import pytest

pytest.importorskip("numba")
pytest.importorskip("sympy")

from algid.estimation import _core_numba as core_numba  # noqa: E402
from algid.models._compiled import compile_equation  # noqa: E402


def test_compilation_is_announced_unless_the_machine_code_is_cached(tmp_path, monkeypatch,
                                                                   capfd):
    monkeypatch.setenv("ALGID_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    model = compile_equation("y'' + a*y' + b*y = u", "a b", name="notice")
    core_numba._loops_of.cache_clear()
    core_numba._loops_of(model)  # imports the loop; numba compiles at the first call
    err = capfd.readouterr().err
    assert err.count("\n") == 1 and "compiling the numba loop of model 'notice'" in err
    directory = tmp_path / "user_models"
    assert str(directory) in err
    (loop,) = [p.stem for p in directory.glob("*_numba_*.py")]
    assert not core_numba.machine_code_cached(str(directory), loop)
    (directory / "__pycache__").mkdir(exist_ok=True)
    (directory / "__pycache__" / f"{loop}.advance-10.py311.nbi").write_bytes(b"")
    assert core_numba.machine_code_cached(str(directory), loop)
    core_numba._loops_of.cache_clear()
    core_numba._loops_of(model)
    assert capfd.readouterr().err == ""
    core_numba._loops_of.cache_clear()
