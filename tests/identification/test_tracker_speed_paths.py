"""algid.Tracker: its loops compiled and run as Python, and parameters reported as soon as
the equations determine them."""

import importlib.util
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from benchmarks.synthetic_records import LINEAR_EQUATION, linear_offsets

import algid
from algid.datasets import EMPS_EQUATION, EMPS_PUBLISHED, emps
from algid.identification import _tracker_jit, _tracker_kernels
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


KEYS = ("t", "values", "stderr", "numerical_error", "alarms")

#: Run as Python (``ALGID_TRACKER_PYTHON=1``: the choice is made at import), in a process
#: of its own: the tracker on a record in several chunkings, and identify.
PYTHON_RUN = textwrap.dedent("""
    import sys
    import numpy as np
    import algid
    from algid.identification import _tracker_jit
    sys.path[:0] = sys.argv[2:]
    from test_tracker_speed_paths import RUNS, stream
    assert not _tracker_jit.USE_NUMBA
    out = {}
    for name, (make, settings, sizes) in RUNS.items():
        record = make()
        for k, chunks in enumerate(sizes):
            tracked = stream(algid.Tracker(**settings), record, chunks)
            out.update({f"{name}/{k}/{key}": value for key, value in tracked.items()})
    np.savez(sys.argv[1], **out)
""")


def _jittered(record):
    step = float(record["t"][1] - record["t"][0])
    jitter = np.random.default_rng(3).uniform(-1e-7, 1e-7, len(record["t"])) * step
    return {**record, "t": record["t"] + jitter}


def _emps_start():
    rec = emps()
    return {k: np.asarray(rec[k], dtype=float)[:3400] for k in ("t", "qm", "F")}


RUNS = {   # name: (record, tracker settings, chunkings)
    "linear": (lambda: linear_offsets(5, n=700)[0],
               {"equation": EQUATION, "parameters": PARAMETERS, "time": "t",
                "window": WINDOW}, ([1000], [1], [3, 50, 1, 400])),
    # times off the grid by 1e-7 steps (taken as uniform): the windows' steps vary
    "jitter": (lambda: _jittered(linear_offsets(7, n=700)[0]),
               {"equation": EQUATION, "parameters": PARAMETERS, "time": "t",
                "window": WINDOW}, ([1000],)),
    "forgetting": (lambda: linear_offsets(6, n=700)[0],
                   {"equation": EQUATION, "parameters": PARAMETERS, "time": "t",
                    "window": WINDOW, "half_life": 2.0}, ([1000],)),
    # the sign term's exact integrals, its proportional phase (Fc and off one parameter
    # before the first reversal) and the bias compensation
    "emps": (_emps_start, {"equation": EMPS_EQUATION, "parameters": list(EMPS_PUBLISHED),
                           "window": 0.05, "half_life": 1.0}, ([1000],)),
}


@pytest.fixture(scope="module")
def python_runs(tmp_path_factory):
    """The outputs of :data:`RUNS` with the loops run as Python."""
    path = tmp_path_factory.mktemp("python") / "runs.npz"
    env = {**os.environ, "ALGID_TRACKER_PYTHON": "1"}
    here = Path(__file__).resolve().parent
    subprocess.run([sys.executable, "-c", PYTHON_RUN, str(path), str(here), str(here.parents[1])],
                   env=env, check=True, timeout=600)
    with np.load(path) as data:
        return dict(data)


def test_python_loops_same_whatever_the_chunking_and_as_identify(python_runs):
    make, settings, sizes = RUNS["linear"]
    for k in range(1, len(sizes)):
        for key in KEYS:
            assert np.array_equal(python_runs[f"linear/0/{key}"],
                                  python_runs[f"linear/{k}/{key}"], equal_nan=True), key
    reference = algid.identify(make(), EQUATION, PARAMETERS, window=WINDOW, refine=False)
    expected = np.array([reference.values[p] for p in PARAMETERS])
    assert np.max(np.abs(python_runs["linear/0/values"][-1] / expected - 1)) < 1e-9


@pytest.mark.parametrize("name", list(RUNS))
def test_python_loops_give_the_compiled_numbers(python_runs, name):
    """One implementation: the loops compiled are the loops run as Python, bit for bit
    (both call the C library's ``hypot``, as ``numpy.hypot`` does: CPython's own
    ``math.hypot`` rounds differently; integer powers by repeated squaring, as numba
    computes them), except the forgetting factors ``2**x``: numba's ``pow`` and the C
    library's can differ in the last bit."""
    pytest.importorskip("numba")
    if not _tracker_jit.USE_NUMBA:
        pytest.skip("the loops are not compiled in this process")
    make, settings, sizes = RUNS[name]
    record = make()
    if name == "emps":   # both phases: M and Fv alone, then all four parameters
        finite = np.isfinite(python_runs["emps/0/values"])
        assert (finite[:, :2] & ~finite[:, 2:]).all(axis=1).any() and finite.all(axis=1).any()
    for k, chunks in enumerate(sizes):
        compiled = stream(Tracker(**settings), record, chunks)
        for key in KEYS:
            python = python_runs[f"{name}/{k}/{key}"]
            if "half_life" in settings:   # round-off of the forgetting factors
                assert np.array_equal(np.isfinite(python), np.isfinite(compiled[key]))
                np.testing.assert_allclose(compiled[key], python, rtol=1e-9, atol=0,
                                           equal_nan=True, err_msg=f"{name}/{k}/{key}")
            else:
                assert np.array_equal(compiled[key], python, equal_nan=True), \
                    f"{name}/{k}/{key}"


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


def test_same_whatever_the_chunking_on_irregular_times():
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




@pytest.fixture
def kernels_again():
    _tracker_kernels.kernels.cache_clear()
    yield
    _tracker_kernels.kernels.cache_clear()


def test_loops_as_python_said_once_when_numba_is_missing(monkeypatch, capsys, kernels_again):
    monkeypatch.setattr(_tracker_kernels, "USE_NUMBA", False)
    monkeypatch.delenv("ALGID_TRACKER_PYTHON", raising=False)
    _tracker_kernels.kernels()
    _tracker_kernels.kernels()
    lines = capsys.readouterr().err.splitlines()
    assert len(lines) == 1 and "numba is not installed" in lines[0] and "algid[fast]" in lines[0]
    # asked for: nothing said
    _tracker_kernels.kernels.cache_clear()
    monkeypatch.setenv("ALGID_TRACKER_PYTHON", "1")
    _tracker_kernels.kernels()
    assert capsys.readouterr().err == ""


def test_numba_declined_by_the_environment(monkeypatch):
    monkeypatch.setenv("ALGID_TRACKER_PYTHON", "1")
    assert not _tracker_jit.numba_available()
    monkeypatch.setenv("ALGID_TRACKER_PYTHON", "0")
    assert _tracker_jit.numba_available() == (
        importlib.util.find_spec("numba") is not None)
