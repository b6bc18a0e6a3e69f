"""The compiled engine (algid.engine) against the NumPy estimator, and its streaming API.

The numba-specific tests are skipped when numba is not installed; the option handling
of ``estimate(engine=...)`` is tested either way.
"""

import sys

import numpy as np
import pytest

from algid import engine as compiled
from algid import estimator
from algid.errors import InputDataError
from algid.estimator import estimate, load_model
from algid.validation import check_experiment

from conftest import exact_response

MODELS = ("msd", "msd_mass")


def _numba():
    return pytest.importorskip("numba")


@pytest.fixture(scope="module")
def data():
    """1.5 s of the paper's system driven by a sine, from rest, at 1 kHz (with m = 1 the
    force per unit mass of "msd" is the force of "msd_mass")."""
    return exact_response("sine", duration=1.5, omega=2.0)


def _assert_same(a, b, rtol):
    """Same NaN pattern; equal within ``rtol`` where defined."""
    assert a.shape == b.shape
    nan_a, nan_b = np.isnan(a), np.isnan(b)
    assert np.array_equal(nan_a, nan_b)
    ok = ~nan_a
    assert ok.any()
    np.testing.assert_allclose(a[ok], b[ok], rtol=rtol, atol=0)


# --------------------------------------------------------------------------------------
# numba engine = numpy engine
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("quadrature_order", [2, 4, 6])
@pytest.mark.parametrize("model", MODELS)
def test_numba_engine_equals_numpy_engine(data, model, quadrature_order):
    """Same operations in the same order: equal to round-off (in practice bit for bit)
    for every filter order, including the first estimates, which amplify any
    difference in the start-up by many orders of magnitude."""
    _numba()
    t, f, x = data
    for filter_order in range(4):
        opts = dict(model=model, filter_order=filter_order, quadrature_order=quadrature_order)
        fast = estimate(t, f, x, engine="numba", **opts)
        slow = estimate(t, f, x, engine="numpy", **opts)
        assert fast.parameters == slow.parameters
        for name in slow.parameters:
            _assert_same(fast.estimates[name], slow.estimates[name], 1e-10)
        assert fast.valid_index == slow.valid_index == quadrature_order - 1
        # the estimates are those of the method, not just equal to each other
        final = fast.final()
        assert final["K" if model == "msd" else "k"] == pytest.approx(3.0, rel=1e-4)


def test_numba_engine_with_known_mass(data):
    _numba()
    t, f, x = data
    mass = 2.5
    fast = estimate(t, f * mass, x, mass=mass, engine="numba")
    slow = estimate(t, f * mass, x, mass=mass, engine="numpy")
    assert fast.parameters == slow.parameters == ("B", "K", "c", "k")
    for name in slow.parameters:
        _assert_same(fast.estimates[name], slow.estimates[name], 1e-10)
    assert fast.final()["c"] == pytest.approx(2.0 * mass, rel=1e-6)


def test_auto_engine_chooses_by_size(data, monkeypatch):
    """auto: numba from AUTO_ENGINE_MIN_SAMPLES samples on, numpy below and with lowpass."""
    _numba()
    t, f, x = data
    calls = []
    original = compiled.estimate_arrays

    def spy(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(compiled, "estimate_arrays", spy)
    estimate(t, f, x)
    assert calls == []  # 1501 samples: NumPy
    monkeypatch.setattr(estimator, "AUTO_ENGINE_MIN_SAMPLES", t.size)
    auto = estimate(t, f, x)
    assert calls == [1]
    _assert_same(auto.B, estimate(t, f, x, engine="numpy").B, 1e-10)
    estimate(t, f, x, lowpass=([100.0], [1.0, 20.0, 100.0]))
    assert calls == [1]
    with pytest.raises(InputDataError, match="lowpass"):
        estimate(t, f, x, engine="numba", lowpass=([100.0], [1.0, 20.0, 100.0]))


# --------------------------------------------------------------------------------------
# streaming: run_chunk with carried state
# --------------------------------------------------------------------------------------


def _run_chunked(state, f, x, sizes):
    pieces, start = [], 0
    for size in sizes:
        pieces.append(compiled.run_chunk(state, f[start:start + size], x[start:start + size]))
        start += size
    assert start == f.size
    return np.concatenate(pieces, axis=1)


def _random_sizes(n, rng, high):
    sizes = []
    while sum(sizes) < n:
        sizes.append(int(min(rng.integers(0, high), n - sum(sizes))))
    return sizes


@pytest.mark.parametrize("model", MODELS)
def test_random_chunks_equal_one_chunk(data, model):
    """The block boundaries and chunk boundaries do not change a single operation."""
    _numba()
    t, f, x = data
    h = t[1] - t[0]
    gen = load_model(model)
    rng = np.random.default_rng(7)
    for filter_order, q in ((2, 6), (0, 4), (3, 2)):
        whole = compiled.run_chunk(compiled.make_state(gen, q, filter_order, step=h), f, x)
        for high in (4, 40, 700):  # chunks smaller than q, around a block, larger
            sizes = _random_sizes(f.size, rng, high)
            state = compiled.make_state(gen, q, filter_order, step=h)
            np.testing.assert_array_equal(_run_chunked(state, f, x, sizes), whole)
            assert state.n_seen == f.size


@pytest.mark.parametrize("q", [2, 6])
def test_startup_with_chunks_smaller_than_q(data, q):
    """Samples 0 .. q-2 are NaN whatever the chunking; sample q-1 is the first estimate,
    returned by the call that delivers it, and it is the batch value."""
    _numba()
    t, f, x = data
    h = t[1] - t[0]
    gen = load_model("msd")
    whole = compiled.run_chunk(compiled.make_state(gen, q, 2, step=h), f[:50], x[:50])
    assert np.isnan(whole[:, : q - 1]).all() and np.isfinite(whole[:, q - 1:]).all()
    for sizes in ([1] * 50, [q - 1, 1, 50 - q], [q - 2, 0, 2, 50 - q] if q > 2 else [1, 0, 1, 48]):
        state = compiled.make_state(gen, q, 2, step=h)
        np.testing.assert_array_equal(_run_chunked(state, f[:50], x[:50], sizes), whole)
    state = compiled.make_state(gen, q, 2, step=h)
    first = compiled.run_chunk(state, f[:q - 1], x[:q - 1])
    assert first.shape == (2, q - 1) and np.isnan(first).all()
    assert state.n_seen == q - 1 and not state.sums.any()  # only buffered so far
    np.testing.assert_array_equal(compiled.run_chunk(state, f[q - 1:q], x[q - 1:q]),
                                  whole[:, q - 1:q])


def test_copy_and_reset(data):
    _numba()
    t, f, x = data
    h = t[1] - t[0]
    gen = load_model("msd_mass")
    state = compiled.make_state(gen, 6, 2, step=h)
    head = compiled.run_chunk(state, f[:300], x[:300])
    twin = state.copy()
    a = compiled.run_chunk(state, f[300:], x[300:])
    b = compiled.run_chunk(twin, f[300:], x[300:])
    np.testing.assert_array_equal(a, b)
    state.reset()
    assert state.n_seen == 0
    np.testing.assert_array_equal(compiled.run_chunk(state, f[:300], x[:300]), head)
    # re-anchoring: a state started at sample 700 is the batch estimator on x[700:]
    late = compiled.run_chunk(compiled.make_state(gen, 6, 2, step=h), f[700:], x[700:])
    batch = estimate(t[700:], f[700:], x[700:], model="msd_mass", engine="numpy")
    _assert_same(late[2], batch.k, 1e-10)


def test_out_argument_and_bad_shapes(data):
    _numba()
    t, f, x = data
    h = t[1] - t[0]
    gen = load_model("msd")
    whole = compiled.run_chunk(compiled.make_state(gen, 6, 2, step=h), f, x)
    big = np.full((2, f.size + 10), -1.0)
    state = compiled.make_state(gen, 6, 2, step=h)
    compiled.run_chunk(state, f[:500], x[:500], out=big[:, 5:505])
    compiled.run_chunk(state, f[500:], x[500:], out=big[:, 505:-5])
    np.testing.assert_array_equal(big[:, 5:-5], whole)
    assert (big[:, :5] == -1).all() and (big[:, -5:] == -1).all()
    with pytest.raises(InputDataError, match="shape"):
        compiled.run_chunk(state, f[:3], x[:4])
    with pytest.raises(InputDataError, match="out must be"):
        compiled.run_chunk(state, f[:3], x[:3], out=np.empty((3, 3)))
    with pytest.raises(InputDataError, match="step"):
        compiled.make_state(gen, 6, 2, step=0.0)
    with pytest.raises(InputDataError, match="quadrature_order"):
        compiled.make_state(gen, 9, 2, step=h)


# --------------------------------------------------------------------------------------
# the one-pass check of the signals
# --------------------------------------------------------------------------------------


def _bad_experiments(t, f, x):
    def edit(arr, i, value):
        arr = arr.copy()
        arr[i] = value
        return arr

    late = t.copy()
    late[100:] += 0.3 * (t[1] - t[0])
    yield "NaN in f", (t, edit(f, 17, np.nan), x)
    yield "inf in x", (t, f, edit(x, 5, np.inf))
    yield "inf in t", (edit(t, 40, -np.inf), f, x)
    yield "time goes back", (edit(t, 30, t[28]), f, x)
    yield "a late sample", (late, f, x)
    yield "no excitation", (t, np.zeros_like(f), np.zeros_like(x))
    yield "too few samples", (t[:5], f[:5], x[:5])
    yield "lengths differ", (t, f[:-1], x)
    yield "integers", (t, np.ones(t.size, dtype=int), x)
    yield "2-D", (t, f[None, :], x)


def test_one_pass_check_agrees_with_check_experiment(data):
    _numba()
    t, f, x = data
    ok = compiled.check_experiment(t, f, x, min_samples=12)
    assert ok[0] is t and ok[1] is f and ok[2] is x
    assert ok[3] == check_experiment(t, f, x, min_samples=12)[3]
    for what, args in _bad_experiments(t, f, x):
        try:
            expected = check_experiment(*args, min_samples=12)
        except InputDataError as err:
            with pytest.raises(InputDataError) as got:
                compiled.check_experiment(*args, min_samples=12)
            assert str(got.value) == str(err), what
        else:  # accepted by both (e.g. integer input converted)
            got = compiled.check_experiment(*args, min_samples=12)
            assert got[3] == expected[3], what


# --------------------------------------------------------------------------------------
# option handling (no numba needed)
# --------------------------------------------------------------------------------------


def test_bad_engine_option(data):
    t, f, x = data
    with pytest.raises(InputDataError, match="engine must be one of"):
        estimate(t, f, x, engine="fortran")


def test_numba_engine_without_numba(data, monkeypatch):
    """Without numba: engine='numba' says how to install it; 'auto' falls back."""
    t, f, x = data
    monkeypatch.setitem(sys.modules, "numba", None)  # import numba -> ImportError
    assert not compiled.available()
    with pytest.raises(InputDataError, match=r"needs numba.*pip install"):
        estimate(t, f, x, engine="numba")
    monkeypatch.setattr(estimator, "AUTO_ENGINE_MIN_SAMPLES", 0)
    r = estimate(t, f, x)  # auto -> numpy
    assert r.final()["B"] == pytest.approx(2.0, rel=1e-6)
    with pytest.raises(InputDataError, match="pip install"):
        compiled._require_numba()


def test_compiled_in_memory_when_the_cache_cannot_be_written(data, monkeypatch, tmp_path):
    """An unwritable cache directory: the loop is compiled in memory, same numbers."""
    _numba()
    t, f, x = data
    h = t[1] - t[0]
    gen = load_model("msd")
    reference = compiled.run_chunk(compiled.make_state(gen, 2, 1, step=h), f, x)
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setattr(compiled, "CACHE_DIR", str(blocker / "engine"))  # not a directory
    assert compiled._load_cached(gen, 2) is None
    compiled._compiled.cache_clear()
    try:
        state = compiled.make_state(gen, 2, 1, step=h)
        assert state._advance.__module__ == "_algid_engine_msd_q2"  # built by exec
        np.testing.assert_array_equal(compiled.run_chunk(state, f, x), reference)
    finally:
        compiled._compiled.cache_clear()  # later tests load the cached loops again
