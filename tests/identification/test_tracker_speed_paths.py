"""algid.Tracker: the compiled and the NumPy recurrences, and parameters reported as soon
as the equations determine them."""

import numpy as np
import pytest
from benchmarks.synthetic_records import LINEAR_EQUATION, linear_offsets

import algid
from algid.datasets import EMPS_EQUATION, EMPS_PUBLISHED, emps
from algid.identification import _tracker_kernels
from algid.identification._tracker import Tracker

EQUATION, NAMES = LINEAR_EQUATION
PARAMETERS = NAMES.split()
WINDOW = 0.1875


def stream(tracker, record, sizes):
    n = len(next(iter(record.values())))
    outputs, start, k = [], 0, 0
    while start < n:
        size = sizes[k % len(sizes)]
        outputs.append(tracker.update({c: v[start:start + size] for c, v in record.items()}))
        start, k = start + size, k + 1
    return {key: np.concatenate([getattr(o, key) for o in outputs])
            for key in ("t", "values", "stderr", "numerical_error", "alarms")}


@pytest.fixture
def numpy_path(monkeypatch):
    monkeypatch.setattr(_tracker_kernels, "USE_NUMBA", False)


def test_numpy_path_same_whatever_the_chunking_and_as_identify(numpy_path):
    record, _ = linear_offsets(5, n=900)
    outputs = [stream(Tracker(EQUATION, PARAMETERS, time="t", window=WINDOW), record, sizes)
               for sizes in ([1000], [1], [7], [3, 50, 1, 400])]
    for other in outputs[1:]:
        for key, value in outputs[0].items():
            assert np.array_equal(value, other[key], equal_nan=True), key
    reference = algid.identify(record, EQUATION, PARAMETERS, window=WINDOW, refine=False)
    expected = np.array([reference.values[p] for p in PARAMETERS])
    assert np.max(np.abs(outputs[0]["values"][-1] / expected - 1)) < 1e-9


def test_numpy_and_compiled_paths_agree(monkeypatch):
    pytest.importorskip("numba")
    record, _ = linear_offsets(6, n=900)
    results = []
    for compiled in (True, False):
        monkeypatch.setattr(_tracker_kernels, "USE_NUMBA", compiled)
        results.append(Tracker(EQUATION, PARAMETERS, time="t", window=WINDOW,
                               half_life=2.0).update(record))
    # the same recurrences in another order of operations: round-off apart
    finite = np.isfinite(results[0].values)
    assert np.array_equal(finite, np.isfinite(results[1].values))
    np.testing.assert_allclose(results[1].values[finite], results[0].values[finite],
                               rtol=1e-9)
    np.testing.assert_allclose(results[1].stderr[finite], results[0].stderr[finite],
                               rtol=1e-6)


def test_parameters_reported_as_soon_as_determined():
    """EMPS moves one way for its first 3 s: ``sign(qm')`` is the constant 1 there, so Fc
    and off are one parameter, while M and Fv are determined (as by identify on the
    model without the proportional term)."""
    rec = emps()
    n = 2000
    record = {k: np.asarray(rec[k], dtype=float)[:n] for k in ("t", "qm", "F")}
    names = list(EMPS_PUBLISHED)
    out = Tracker(EMPS_EQUATION, names, window=0.03, method="ls").update(record)
    last = out.values[-1]
    assert np.isfinite(last[:2]).all() and np.isnan(last[2:]).all()
    assert np.isfinite(out.stderr[-1, :2]).all() and np.isnan(out.stderr[-1, 2:]).all()
    # as the model without the proportional term (an offset c for Fc + off)
    reduced = Tracker("M*qm'' + Fv*qm' + c = F", "M Fv c", window=0.03,
                      method="ls").update(record)
    same = np.isin(reduced.t, out.t)   # without sign(qm') no causal lag: more windows
    assert np.array_equal(reduced.t[same], out.t)
    np.testing.assert_allclose(out.values[:, :2], reduced.values[same, :2], rtol=1e-9)
    assert abs(last[0] / EMPS_PUBLISHED["M"] - 1) < 0.05


@pytest.fixture
def compiled_path(monkeypatch):
    pytest.importorskip("numba")
    monkeypatch.setattr(_tracker_kernels, "USE_NUMBA", True)


def test_compiled_path_same_whatever_the_chunking_on_irregular_times(compiled_path):
    """Windows whose times are not uniform take the exact weights of their own times
    (outside the compiled loop); the outputs still do not depend on the chunking."""
    record, _ = linear_offsets(7, n=700)
    jitter = np.zeros(700)
    jitter[300:320] = 0.2 / 80.0 * np.sin(np.arange(20))   # irregular windows there
    record = {**record, "t": record["t"] + jitter}
    outputs = [stream(Tracker(EQUATION, PARAMETERS, time="t", window=WINDOW, half_life=2.0),
                      record, sizes) for sizes in ([1000], [1], [7], [3, 50, 1, 400])]
    assert np.isfinite(outputs[0]["values"][-1]).all()
    for other in outputs[1:]:
        for key, value in outputs[0].items():
            assert np.array_equal(value, other[key], equal_nan=True), key


def test_numpy_and_compiled_paths_agree_on_emps(monkeypatch):
    """The sign term's exact integrals, its proportional phase (Fc and off one
    parameter) and the bias compensation, on both paths."""
    pytest.importorskip("numba")
    rec = emps()
    record = {k: np.asarray(rec[k], dtype=float)[:4500] for k in ("t", "qm", "F")}
    results = []
    for compiled in (True, False):
        monkeypatch.setattr(_tracker_kernels, "USE_NUMBA", compiled)
        results.append(Tracker(EMPS_EQUATION, list(EMPS_PUBLISHED), window=0.03,
                               half_life=1.0).update(record))
    finite = np.isfinite(results[0].values)
    assert np.array_equal(finite, np.isfinite(results[1].values))
    assert finite[:, :2].any() and (~finite[:, 2:]).any() and finite.all(axis=1).any()
    # the first windows after the first reversal solve nearly proportional columns
    # (condition ~1e9): compared before them (M and Fv) and from 0.1 s after them
    reversal = results[0].t[finite.all(axis=1)][0]
    settled = results[0].t > reversal + 0.1
    before = (results[0].t < reversal)[:, None] & finite
    for key in ("values", "stderr"):
        first, second = getattr(results[0], key), getattr(results[1], key)
        tolerance = 1e-9 if key == "values" else 1e-6
        np.testing.assert_allclose(second[before], first[before], rtol=tolerance)
        np.testing.assert_allclose(second[settled], first[settled], rtol=tolerance)
