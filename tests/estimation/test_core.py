"""The estimator core (algid.estimation._core): one state, the NumPy and numba backends, chunking.

The numba-specific tests are skipped when numba is not installed; the option handling
of ``estimate(engine=...)`` is tested either way.
"""

import sys

import numpy as np
import pytest

from algid.estimation import _backends as backends

from algid.estimation import _core as core
from algid.errors import InputDataError
from algid.estimation._batch import estimate
from algid.models._registry import load_model
from algid._signal_checks import check_experiment

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


def _state(model, points, filter_order, dt, **kw):
    return core.new_state(load_model(model), points=points, filter_order=filter_order, dt=dt,
                          **kw)


def _run_chunked(state, f, x, sizes, backend):
    pieces, start = [], 0
    for size in sizes:
        est, state = core.advance(state, (f[start:start + size], x[start:start + size]),
                                  backend=backend)
        pieces.append(est)
        start += size
    assert start == f.size
    return np.concatenate(pieces, axis=1)


def _random_sizes(n, rng, high):
    sizes = []
    while sum(sizes) < n:
        sizes.append(int(min(rng.integers(0, high), n - sum(sizes))))
    return sizes


# --------------------------------------------------------------------------------------
# numba backend = numpy backend
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("points", [2, 4, 6])
@pytest.mark.parametrize("model", MODELS)
def test_numba_backend_equals_numpy_backend(data, model, points):
    """Same operations in the same order: equal to round-off (in practice bit for bit)
    for every filter order, including the first estimates, which amplify any
    difference in the start-up by many orders of magnitude."""
    _numba()
    t, f, x = data
    for filter_order in range(4):
        opts = dict(model=model, filter_order=filter_order, quadrature_points=points)
        fast = estimate(t, f, x, engine="numba", **opts)
        slow = estimate(t, f, x, engine="numpy", **opts)
        assert fast.parameters == slow.parameters
        for name in slow.parameters:
            _assert_same(fast.estimates[name], slow.estimates[name], 1e-10)
        assert fast.valid_index == slow.valid_index == points - 1
        # the estimates are those of the method, not just equal to each other
        final = fast.final()
        assert final["K" if model == "msd" else "k"] == pytest.approx(3.0, rel=1e-4)


def test_numba_backend_with_known_mass(data):
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
    original = core.advance_rows  # every call of the core goes through it

    def spy(state, rows, out, backend="numpy"):
        calls.append(backend)
        return original(state, rows, out, backend)

    monkeypatch.setattr(core, "advance_rows", spy)
    estimate(t, f, x, numerical_error=False)  # the estimator alone: one call
    assert calls == ["numpy"]  # 1501 samples: NumPy
    monkeypatch.setattr(backends, "AUTO_ENGINE_MIN_SAMPLES", t.size)
    auto = estimate(t, f, x, numerical_error=False)
    assert calls == ["numpy", "numba"]
    _assert_same(auto.B, estimate(t, f, x, engine="numpy", numerical_error=False).B, 1e-10)
    estimate(t, f, x, lowpass=([100.0], [1.0, 20.0, 100.0]))  # not through the core
    assert calls == ["numpy", "numba", "numpy"]
    estimate(t, f, x)  # with the numerical error: companion and twin on the same engine
    assert set(calls[3:]) == {"numba"} and len(calls) > 4
    with pytest.raises(InputDataError, match="lowpass"):
        estimate(t, f, x, engine="numba", lowpass=([100.0], [1.0, 20.0, 100.0]))


# --------------------------------------------------------------------------------------
# streaming: advance with carried state
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("backend", ["numpy", "numba"])
@pytest.mark.parametrize("model", MODELS)
def test_random_chunks_equal_one_chunk(data, model, backend):
    """Chunk (and block) boundaries do not change a single operation."""
    if backend == "numba":
        _numba()
    t, f, x = data
    dt = t[1] - t[0]
    rng = np.random.default_rng(7)
    for filter_order, q in ((2, 6), (0, 4), (3, 2)):
        whole, _ = core.advance(_state(model, q, filter_order, dt), (f, x), backend=backend)
        for high in (4, 40, 700):  # chunks smaller than q, around a block, larger
            sizes = _random_sizes(f.size, rng, high)
            state = _state(model, q, filter_order, dt)
            np.testing.assert_array_equal(_run_chunked(state, f, x, sizes, backend), whole)
            assert state.n_seen == f.size


def test_numpy_blocks_do_not_change_the_numbers(data, monkeypatch):
    from algid.estimation import _core_numpy as core_numpy
    t, f, x = data
    dt = t[1] - t[0]
    whole, _ = core.advance(_state("msd", 6, 2, dt), (f, x))
    monkeypatch.setattr(core_numpy, "BLOCK", 97)
    np.testing.assert_array_equal(core.advance(_state("msd", 6, 2, dt), (f, x))[0], whole)


def _wild_signals(rng, n):
    """Signals spanning many magnitudes, with runs of (signed) zeros."""
    f = rng.standard_normal(n) * 10.0 ** rng.integers(-12, 12, n)
    x = rng.standard_normal(n) * 10.0 ** rng.integers(-12, 12, n)
    f[50:60] = -0.0
    x[55:70] = 0.0
    x[70:75] = -0.0
    return f, x


@pytest.mark.parametrize("on_floats", [True, False])
def test_numpy_small_chunks_are_bit_identical(monkeypatch, on_floats):
    """Chunks of 1 to 3 samples take the per-sample step of the NumPy backend: it
    performs correlate's and cumsum's operations in the same order, so any mixture of
    tiny and large chunks gives the numbers of one chunk, bit for bit, on random
    signals over 24 orders of magnitude (also with the model algebra on arrays)."""
    from algid.estimation import _core_numpy as core_numpy
    if not on_floats:
        monkeypatch.setattr(core_numpy, "_algebra_on_floats", lambda module: False)
    rng = np.random.default_rng(11)
    for model, q, filter_order in (("msd", 6, 2), ("msd_mass", 3, 1), ("msd", 2, 0),
                                   ("msd", 8, 3)):
        f, x = _wild_signals(rng, 300)
        whole, _ = core.advance(_state(model, q, filter_order, 1e-3), (f, x))
        for high in (4, 6, 30):
            sizes = _random_sizes(f.size, rng, high)
            state = _state(model, q, filter_order, 1e-3)
            got = _run_chunked(state, f, x, sizes, "numpy")
            np.testing.assert_array_equal(got, whole)
            assert np.signbit(got).tolist() == np.signbit(whole).tolist()


def test_numpy_sample_step_matches_correlate_here():
    """The per-sample step is exact on this platform (else the backend would not use
    it, and the test above would still pass through the block path)."""
    from algid.estimation import _core_numpy as core_numpy
    assert core_numpy.sample_step_is_exact()


def test_chunk_at_the_origin_is_integrated_at_once(data):
    """A chunk that starts at the time origin is integrated in one call, from the
    origin: the same numbers as buffering the start-up first, on both backends."""
    t, f, x = data
    dt = t[1] - t[0]
    for backend in ("numpy",) + (("numba",) if backends.numba_available() else ()):
        whole, _ = core.advance(_state("msd", 6, 2, dt), (f[:400], x[:400]), backend=backend)
        state = _state("msd", 6, 2, dt)
        pieces = _run_chunked(state, f[:400], x[:400], [3, 3, 394], backend)
        np.testing.assert_array_equal(pieces, whole)
        state.restart()
        again, _ = core.advance(state, (f[:400], x[:400]), backend=backend)
        np.testing.assert_array_equal(again, whole)


@pytest.mark.parametrize("q", [2, 6])
def test_startup_with_chunks_smaller_than_q(data, q):
    """Samples 0 .. q-2 are NaN whatever the chunking; sample q-1 is the first estimate,
    returned by the call that delivers it, and it is the batch value."""
    t, f, x = data
    dt = t[1] - t[0]
    whole, _ = core.advance(_state("msd", q, 2, dt), (f[:50], x[:50]))
    assert np.isnan(whole[:, : q - 1]).all() and np.isfinite(whole[:, q - 1:]).all()
    for sizes in ([1] * 50, [q - 1, 1, 50 - q], [q - 2, 0, 2, 50 - q] if q > 2 else [1, 0, 1, 48]):
        state = _state("msd", q, 2, dt)
        np.testing.assert_array_equal(_run_chunked(state, f[:50], x[:50], sizes, "numpy"),
                                      whole)
    state = _state("msd", q, 2, dt)
    first, _ = core.advance(state, (f[:q - 1], x[:q - 1]))
    assert first.shape == (2, q - 1) and np.isnan(first).all()
    assert state.n_seen == q - 1 and not state.integrals.any()  # only buffered so far
    np.testing.assert_array_equal(core.advance(state, (f[q - 1:q], x[q - 1:q]))[0],
                                  whole[:, q - 1:q])


@pytest.mark.parametrize("q", [7, 8])
def test_rules_of_more_points_report_as_early_as_six(data, q):
    """With more than 6 points, samples 5 .. q-2 are estimated by the rules of 6, 7, ...
    points over the samples so far (the same numbers as those rules' first estimates),
    in any chunking and on both backends; from sample q-1 on by the rule's own start-up."""
    t, f, x = data
    dt = t[1] - t[0]
    assert core.first_estimate(q) == 5 and core.first_estimate(4) == 3
    for backend in ("numpy",) + (("numba",) if backends.numba_available() else ()):
        whole, _ = core.advance(_state("msd", q, 2, dt), (f[:60], x[:60]), backend=backend)
        assert np.isnan(whole[:, :5]).all() and np.isfinite(whole[:, 5:]).all()
        for n in range(5, q - 1):
            fewer, _ = core.advance(_state("msd", n + 1, 2, dt), (f[:60], x[:60]),
                                    backend=backend)
            np.testing.assert_array_equal(whole[:, n], fewer[:, n])
        # from sample q - 1 on it is not the 6-point estimator: its start-up is its own
        six, _ = core.advance(_state("msd", 6, 2, dt), (f[:60], x[:60]), backend=backend)
        assert (whole[:, q - 1:] != six[:, q - 1:]).any(axis=0).all()
        for sizes in ([1] * 60, [4, 1, 1, 1, 53], [6, 54], [5, 0, 2, 53]):
            state = _state("msd", q, 2, dt)
            np.testing.assert_array_equal(_run_chunked(state, f[:60], x[:60], sizes, backend),
                                          whole)
            assert state.n_seen == 60


def test_copy_and_restart(data):
    t, f, x = data
    dt = t[1] - t[0]
    state = _state("msd_mass", 6, 2, dt)
    head, _ = core.advance(state, (f[:300], x[:300]))
    twin = state.copy()
    a, _ = core.advance(state, (f[300:], x[300:]))
    b, _ = core.advance(twin, (f[300:], x[300:]))
    np.testing.assert_array_equal(a, b)
    state.restart()
    assert state.n_seen == 0
    np.testing.assert_array_equal(core.advance(state, (f[:300], x[:300]))[0], head)
    # re-anchoring: a state started at sample 700 is the batch estimator on x[700:]
    late, _ = core.advance(_state("msd_mass", 6, 2, dt), (f[700:], x[700:]))
    batch = estimate(t[700:], f[700:], x[700:], model="msd_mass", engine="numpy",
                     quadrature_points=6)
    _assert_same(late[2], batch.k, 1e-10)


def test_out_argument_and_bad_shapes(data):
    t, f, x = data
    dt = t[1] - t[0]
    whole, _ = core.advance(_state("msd", 6, 2, dt), (f, x))
    big = np.full((2, f.size + 10), -1.0)
    state = _state("msd", 6, 2, dt)
    core.advance(state, (f[:500], x[:500]), out=big[:, 5:505])
    core.advance(state, np.stack((f[500:], x[500:])), out=big[:, 505:-5])  # a 2-D array
    np.testing.assert_array_equal(big[:, 5:-5], whole)
    assert (big[:, :5] == -1).all() and (big[:, -5:] == -1).all()
    with pytest.raises(InputDataError, match="equally long"):
        core.advance(state, (f[:3], x[:4]))
    with pytest.raises(InputDataError, match="2 equally long"):
        core.advance(state, (f[:3],))
    with pytest.raises(InputDataError, match="out must be"):
        core.advance(state, (f[:3], x[:3]), out=np.empty((3, 3)))
    with pytest.raises(InputDataError, match="dt"):
        _state("msd", 6, 2, 0.0)
    with pytest.raises(InputDataError, match="quadrature_points"):
        _state("msd", 10, 2, dt)
    with pytest.raises(InputDataError, match="divisors"):
        _state("msd", 6, 2, dt, divisors=(1.0, -2.0))
    with pytest.raises(InputDataError, match="backend"):
        core.advance(state, (f[:3], x[:3]), backend="fortran")


# --------------------------------------------------------------------------------------
# the compiled check of the signals
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


def test_compiled_check_agrees_with_check_experiment(data):
    _numba()
    from algid._signal_checks_numba import check_experiment_compiled
    t, f, x = data
    ok = check_experiment_compiled(t, f, x, min_samples=12)
    assert ok[0] is t and ok[1] is f and ok[2] is x
    assert ok[3] == check_experiment(t, f, x, min_samples=12)[3]
    for what, args in _bad_experiments(t, f, x):
        try:
            expected = check_experiment(*args, min_samples=12)
        except InputDataError as err:
            with pytest.raises(InputDataError) as got:
                check_experiment_compiled(*args, min_samples=12)
            assert str(got.value) == str(err), what
        else:  # accepted by both (e.g. integer input converted)
            got = check_experiment_compiled(*args, min_samples=12)
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
    assert not backends.numba_available()
    with pytest.raises(InputDataError, match=r"needs numba.*pip install"):
        estimate(t, f, x, engine="numba")
    monkeypatch.setattr(backends, "AUTO_ENGINE_MIN_SAMPLES", 0)
    r = estimate(t, f, x)  # auto -> numpy
    assert r.final()["B"] == pytest.approx(2.0, rel=1e-6)

