"""Generated estimator modules: reproducible byte for byte, and numerically equal to
the SymPy expressions they come from."""

import filecmp
import json
import os
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp

from algid.estimation._batch import load_model
from algid.symbolic import TIME as t
from algid.symbolic import derive, evaluate_kernel
from algid.symbolic._builtin_models import BUILTIN_MODELS, builtin_model

from conftest import ROOT


def test_regeneration_is_byte_identical(tmp_path):
    subprocess.run([sys.executable, "-m", "derivation", "--out", str(tmp_path)], cwd=ROOT,
                   check=True, capture_output=True)
    generated = ROOT / "src" / "algid" / "_generated"
    names = sorted(p.name for p in tmp_path.glob("*.py"))
    assert names == sorted(p.name for p in generated.glob("*.py"))
    for name in names:
        assert filecmp.cmp(tmp_path / name, generated / name, shallow=False), (
            f"src/algid/_generated/{name} differs from the derivation: run `python -m derivation`")


def test_every_builtin_model_is_generated():
    for name in BUILTIN_MODELS:
        module = load_model(name)
        assert module.MODEL == name
        assert "do not edit by hand" in module.__doc__


# closed-form trajectories: x'' + 3x' + 2x = 1 + exp(-3t) (msd) and
# 2x'' + 6x' + 4x = 1 + t (msd_mass), with nonzero initial conditions
def _trajectory(name):
    model = builtin_model(name)
    if name == "msd":
        values = dict(zip(model.parameters, (3, 2)))
        forcing = 1 + sp.exp(-3 * t)
    else:
        values = dict(zip(model.parameters, (2, 6, 4)))
        forcing = 1 + t
    ode = model.ode().subs(values).subs(model.input_function, forcing).doit()
    y = model.output_function
    x = sp.dsolve(ode, y, ics={y.subs(t, 0): sp.Rational(1, 2), y.diff(t).subs(t, 0): -1}).rhs
    return model, values, {model.output: x, model.input: forcing}


@pytest.mark.parametrize("name", ["msd", "msd_mass"])
def test_generated_functions_match_sympy(name):
    model, values, signals = _trajectory(name)
    d = derive(model)
    module = load_model(name)
    times = np.linspace(0.05, 3.0, 7)
    exact = {k: evaluate_kernel(k, signals) for k in d.kernels}
    kern = {k.name: sp.lambdify(t, exact[k], "numpy")(times) * np.ones_like(times)
            for k in d.kernels}
    P_gen, Q_gen = module.regressors(kern)
    subs = {k.expression(): exact[k] for k in d.kernels}
    for i in range(d.P.shape[0]):
        q_sym = sp.lambdify(t, d.Q[i].xreplace(subs), "numpy")(times)
        np.testing.assert_allclose(Q_gen[i], q_sym, rtol=1e-12, atol=1e-14)
        for j in range(d.P.shape[1]):
            p_sym = sp.lambdify(t, d.P[i, j].xreplace(subs), "numpy")(times)
            np.testing.assert_allclose(P_gen[i][j], p_sym, rtol=1e-12, atol=1e-14)
    # and the generated Cramer solution returns the true parameters on this trajectory;
    # det P vanishes like a high power of t, so the float evaluation of the closed forms
    # loses digits at early times: check from t = 0.5 on
    nums, den = module.cramer(P_gen, Q_gen)
    late = times >= 0.5
    for p, num in zip(model.parameters, nums):
        np.testing.assert_allclose((num / den)[late], float(values[p]), rtol=1e-9)


def test_kernel_names_and_chains_are_consistent():
    for name in BUILTIN_MODELS:
        module = load_model(name)
        depth = {(s, p): d for s, p, d in module.CHAINS}
        for signal, power, order in module.KERNELS:
            assert order <= depth[(signal, power)]
        assert set(module.PARAMETERS) == {str(p) for p in builtin_model(name).parameters}


def test_packed_regressors_equal_named_ones():
    rng = np.random.default_rng(3)
    for name in BUILTIN_MODELS:
        module = load_model(name)
        values = rng.standard_normal((len(module.KERNELS), 5))
        named = {module.kernel_name(*k): values[i] for i, k in enumerate(module.KERNELS)}
        P1, Q1 = module.regressors(named)
        P2, Q2 = module.regressors_packed(values)
        np.testing.assert_array_equal(np.array(P1), np.array(P2))
        np.testing.assert_array_equal(np.array(Q1), np.array(Q2))


def test_generated_modules_declare_channels_and_mass_scaling():
    msd, msd_mass = load_model("msd"), load_model("msd_mass")
    assert msd.CHANNELS == ("f", "x") and msd_mass.CHANNELS == ("F", "x")
    assert {s for s, _, _ in msd.CHAINS} <= set(msd.CHANNELS)
    assert msd.MASS_SCALED == {"c": "B", "k": "K"} and msd.MASS_DIVIDED == ("f",)
    assert msd_mass.MASS_SCALED == {} and msd_mass.MASS_DIVIDED == ()


_USER_SCRIPT = """
import json, sys
import numpy as np
from algid.estimation import _core_numba as core_numba
from algid.estimation._batch import estimate
from algid.symbolic import derive
from algid.symbolic._codegen import compile_model
from algid.symbolic._model import LinearODEModel
user = compile_model(derive(LinearODEModel.from_equation(
    "x'' + a*x' + b*x = f", parameters="a b", name="user_msd")))
t = np.arange(800) * 1e-3
fast = estimate(t, np.sin(3 * t), 0.1 * np.sin(3 * t - 0.4), model=user, engine="numba")
loop = core_numba._loops_of(user).advance
print(json.dumps({"hits": sum(loop.stats.cache_hits.values()), "a": fast.a[-1]}))
"""


def test_user_model_compiled_in_memory_runs_on_both_backends(request, monkeypatch):
    """A model given as an equation goes through the same generators, in memory: with
    the equation of "msd" it gives the built-in estimates bit for bit, on either
    backend.  Its compiled loop is cached on disk (here in pytest's cache, so that
    later runs of the suite load it): another process loads it instead of compiling."""
    from algid.estimation._batch import estimate
    from algid.symbolic._codegen import compile_model
    from algid.symbolic._model import LinearODEModel

    user = compile_model(derive(LinearODEModel.from_equation(
        "x'' + a*x' + b*x = f", parameters="a b", name="user_msd")))
    assert user.PARAMETERS == ("a", "b") and "numba" in user.NUMBA_SOURCE
    t = np.arange(800) * 1e-3
    f = np.sin(3 * t)
    x = 0.1 * np.sin(3 * t - 0.4) + 0.05 * np.exp(-t)
    builtin = estimate(t, f, x, engine="numpy")
    mine = estimate(t, f, x, model=user, engine="numpy")
    np.testing.assert_array_equal(mine.a, builtin.B)
    np.testing.assert_array_equal(mine.b, builtin.K)
    pytest.importorskip("numba")
    cache = request.config.cache.mkdir("algid")
    monkeypatch.setenv("ALGID_CACHE_DIR", str(cache))
    fast = estimate(t, f, x, model=user, engine="numba")
    np.testing.assert_array_equal(fast.a, estimate(t, f, x, engine="numba").B)
    # the sources are cached under names that hash their text, and a new process
    # loads the machine code numba cached for them (no compilation)
    cached = sorted(p.name for p in (cache / "user_models").glob("algid_user_user_msd_*.py"))
    assert len(cached) >= 2 and any("_numba_" in name for name in cached)
    run = subprocess.run([sys.executable, "-c", _USER_SCRIPT], capture_output=True,
                         text=True, check=True,
                         env={**os.environ, "ALGID_CACHE_DIR": str(cache)})
    answer = json.loads(run.stdout.strip().splitlines()[-1])
    assert answer["hits"] >= 1
    slow = estimate(t, f, 0.1 * np.sin(3 * t - 0.4), engine="numba")
    assert answer["a"] == slow.B[-1]


def test_user_cache_dir_follows_the_environment(tmp_path, monkeypatch):
    """ALGID_CACHE_DIR, else NUMBA_CACHE_DIR/algid, else the user cache; empty turns
    the cache off, and an unusable directory means no cache (compiled in memory)."""
    from algid.estimation._backends import numba_available
    if not numba_available():
        pytest.skip("numba is not installed")
    from algid.estimation._core_numba import user_cache_dir
    monkeypatch.setenv("ALGID_CACHE_DIR", str(tmp_path / "mine"))
    assert user_cache_dir() == str(tmp_path / "mine" / "user_models")
    monkeypatch.delenv("ALGID_CACHE_DIR")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "numba"))
    assert user_cache_dir() == str(tmp_path / "numba" / "algid" / "user_models")
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert user_cache_dir() == str(tmp_path / "xdg" / "algid" / "user_models")
    monkeypatch.setenv("ALGID_CACHE_DIR", "")
    assert user_cache_dir() is None
    blocker = tmp_path / "a_file"
    blocker.write_text("not a directory")
    monkeypatch.setenv("ALGID_CACHE_DIR", str(blocker))
    assert user_cache_dir() is None
