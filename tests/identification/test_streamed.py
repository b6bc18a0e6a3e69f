"""identify on a record read in chunks: the same estimate as in memory, from files, Dask
DataFrames and memory maps; refusals of what cannot be streamed."""

import numpy as np
import pytest
from benchmarks.synthetic_records import LINEAR_EQUATION, linear_offsets
from conftest import assert_one_line_error

import algid
from algid.cli import main
from algid.errors import InputDataError, ModelError
from algid.identification import _identify
from algid.identification._window_kernels import (
    block_window_integrals,
    uniform_window_integrals,
)

FIELDS = ("values", "stderr", "numerical_error")


@pytest.fixture(scope="module")
def record():
    data, truth = linear_offsets(3, n=6000)
    return data, truth


def assert_same(streamed, memory, rtol=1e-9):
    """Equal estimates, standard errors, numerical errors, window and samples."""
    assert streamed.window == pytest.approx(memory.window, rel=1e-12)
    assert streamed.n_samples == memory.n_samples
    assert streamed.n_windows == memory.n_windows
    for field in FIELDS:
        a, b = getattr(streamed, field), getattr(memory, field)
        for p in memory.parameters:
            assert a[p] == pytest.approx(b[p], rel=rtol, abs=1e-300), (field, p)
    assert streamed.warnings == memory.warnings


@pytest.mark.parametrize("length", [12, 16, 65, 100, 887])
def test_block_integrals_equal_the_fft_ones(length):
    z = np.random.default_rng(length).normal(size=5003)
    stride = max(1, length // 8)
    for k in (0, 1, 2):
        a = uniform_window_integrals(z, 0.25, length, 12, k, stride)
        b = block_window_integrals(z, 0.25, length, 12, k, stride)
        assert a.shape == b.shape
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-14 * np.max(np.abs(a)))


@pytest.mark.parametrize("method", ["bc", "ls"])
@pytest.mark.parametrize("window", [0.5, None])
def test_chunks_give_the_in_memory_estimate(record, method, window):
    data, _ = record
    memory = algid.identify(data, *LINEAR_EQUATION, window=window, method=method,
                            refine=False)
    streamed = algid.identify(data, *LINEAR_EQUATION, window=window, method=method,
                              refine=False, chunk=700)
    assert_same(streamed, memory)


def test_gaps_nan_rows_and_a_rate_stream_as_in_memory(record):
    data, _ = record
    gappy = {k: np.delete(v, np.s_[2500:2540]) for k, v in data.items()}   # missing rows
    gappy["y"] = gappy["y"].copy()
    gappy["y"][[700, 4100]] = np.nan                                       # NaN samples
    memory = algid.identify(gappy, *LINEAR_EQUATION, window=0.4, refine=False)
    assert_same(algid.identify(gappy, *LINEAR_EQUATION, window=0.4, refine=False,
                               chunk=512), memory)
    no_time = {"u": data["u"], "y": data["y"]}
    memory = algid.identify(no_time, *LINEAR_EQUATION, rate=80.0, window=0.4, refine=False)
    assert_same(algid.identify(no_time, *LINEAR_EQUATION, rate=80.0, window=0.4,
                               refine=False, chunk=999), memory)


def test_files_memory_maps_and_dask_frames_are_read_in_chunks(record, tmp_path):
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    dd = pytest.importorskip("dask.dataframe")
    data, _ = record
    memory = algid.identify(data, *LINEAR_EQUATION, window=0.5, refine=False)
    frame = pd.DataFrame(data)
    frame.to_parquet(tmp_path / "r.parquet", row_group_size=1000)
    frame.to_csv(tmp_path / "r.csv", index=False)
    maps = {}
    for name, values in data.items():
        np.save(tmp_path / f"{name}.npy", values)
        maps[name] = np.load(tmp_path / f"{name}.npy", mmap_mode="r")
    for source in (tmp_path / "r.parquet", str(tmp_path / "r.csv"), maps,
                   dd.from_pandas(frame, npartitions=4)):
        streamed = algid.identify(source, *LINEAR_EQUATION, window=0.5,
                                  chunk=None if not isinstance(source, dict) else 800)
        # a CSV's numbers are printed to 17 digits and read back: the same samples
        assert_same(streamed, memory)
        assert streamed.refinement.reason.startswith("a record read in chunks")


def test_a_long_record_streams_and_says_why_it_is_not_refined(record, monkeypatch):
    data, truth = record
    monkeypatch.setattr(_identify, "STREAM_SAMPLES", 4000)
    monkeypatch.setattr(_identify, "EXCERPT_SAMPLES", 2400)
    result = algid.identify(data, *LINEAR_EQUATION)   # 6000 samples: streamed
    assert result.estimate == "algebraic"
    assert "read in chunks" in result.refinement.reason
    for p, value in truth.items():   # the window from excerpts of 2400 samples
        assert abs(result.values[p] - value) < 4 * result.stderr[p], p
    # what cannot be streamed stays in memory: refinement asked for, a sign()
    assert algid.identify(data, *LINEAR_EQUATION, refine=True).estimate == "refined"
    coulomb = algid.identify(data, "y'' + B*y' + K*y + F*sign(y') = G*u + d", "B K F G d",
                             window=0.5, refine=False)
    assert "chunks" not in coulomb.refinement.reason


@pytest.mark.parametrize("call, kind, fragments", [
    (dict(equation=("y'' + B*y' + K*y + F*sign(y') = G*u + d", "B K F G d")), ModelError,
     ["sign(y')", "placed on the whole record", "load the record"]),
    (dict(equation=("y'' + B*y' + K*y + F*y'**3 = G*u + d", "B K F G d")), ModelError,
     ["derivative", "y'", "nonlinear factor"]),
    (dict(method="iv"), ModelError, ["method='iv'", "'bc' or 'ls'"]),
    (dict(refine=True), ModelError, ["refine:", "result.refine(record)"]),
    (dict(chunk=-1), InputDataError, ["chunk must be", "from 1"]),
    (dict(chunk=True), InputDataError, ["chunk must be"]),
    (dict(chunk="many"), InputDataError, ["chunk must be"]),
    (dict(data="list"), InputDataError, ["one at a time"]),
    (dict(data="jitter"), InputDataError, ["row", "off the uniform grid", "resample"]),
    (dict(data="missing.parquet"), InputDataError, ["missing.parquet", "no such file"]),
])
def test_what_cannot_be_streamed_is_refused_in_one_line(record, tmp_path, call, kind,
                                                        fragments):
    data, _ = record
    equation = call.pop("equation", LINEAR_EQUATION)
    which = call.pop("data", None)
    if which == "list":
        data = [data, data]
    elif which == "jitter":
        data = dict(data, t=data["t"] + np.where(np.arange(len(data["t"])) == 3000,
                                                 0.3 / 80, 0.0))
    elif which is not None:
        data = str(tmp_path / which)
    options = {"window": 0.5, "chunk": 600, **call}
    with pytest.raises(kind) as error:
        algid.identify(data, *equation, **options)
    message = str(error.value)
    assert "\n" not in message
    for fragment in fragments:
        assert fragment in message


def test_a_file_of_another_kind_and_a_bad_column_are_named(tmp_path, record):
    data, _ = record
    (tmp_path / "r.txt").write_text("t,u,y\n0,1,2\n")
    with pytest.raises(InputDataError, match="Parquet .* or CSV"):
        algid.identify(str(tmp_path / "r.txt"), *LINEAR_EQUATION)
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    frame = pd.DataFrame(data)
    frame["y"] = frame["y"].astype(str)
    frame.loc[5000, "y"] = "broken"
    frame.to_parquet(tmp_path / "bad.parquet")
    with pytest.raises(InputDataError) as error:
        algid.identify(tmp_path / "bad.parquet", *LINEAR_EQUATION, window=0.5)
    assert "'y'" in str(error.value) and "\n" not in str(error.value)


def test_the_command_line_streams_a_parquet_record(tmp_path, record, capsys):
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    data, _ = record
    pd.DataFrame(data).to_parquet(tmp_path / "r.parquet")
    memory = algid.identify(data, *LINEAR_EQUATION, window=0.5, refine=False)
    code = main(["identify", str(tmp_path / "r.parquet"), "--equation", LINEAR_EQUATION[0],
                 "--parameters", LINEAR_EQUATION[1], "--window", "0.5", "--json"])
    out, err = capsys.readouterr()
    assert code == 0, err
    import json

    values = json.loads(out)
    for p in memory.parameters:
        assert values[p] == pytest.approx(memory.values[p], rel=1e-9)
    code = main(["identify", str(tmp_path / "r.parquet"), "--equation",
                 "y'' + B*y' + K*y + F*sign(y') = G*u", "--parameters", "B K F G",
                 "--window", "0.5"])
    out, err = capsys.readouterr()
    assert_one_line_error(code, err, "sign(y')")


def test_a_dask_frame_is_reduced_on_the_cluster(record):
    pd = pytest.importorskip("pandas")
    dd = pytest.importorskip("dask.dataframe")
    distributed = pytest.importorskip("distributed")
    data, _ = record
    memory = algid.identify(data, *LINEAR_EQUATION, window=0.5, refine=False)
    frame = dd.from_pandas(pd.DataFrame(data), npartitions=5)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client, \
            distributed.get_task_stream(client) as tasks:
        streamed = algid.identify(frame, *LINEAR_EQUATION, window=0.5, chunk=1000)
    assert_same(streamed, memory)
    # the partitions were fed to the passes on the workers: a chain of five tasks a pass
    fed = [t for t in tasks.data if "_feed_partition" in t["key"][0]
           or "_feed_partition" in str(t["key"])]
    assert len(fed) >= 3 * 5   # the scan, the window's pass and the adequacy's two


@pytest.mark.parametrize("window", [0.5, None])
def test_a_model_nonlinear_in_the_output_streams_as_in_memory(window):
    """Its noise changes from window to window: covariances made with the rows, the
    sandwich's middle by a pass of its own."""
    from benchmarks.synthetic_records import CUBIC_EQUATION, cubic_spring

    data, _ = cubic_spring(2, n=6000)
    equation = ("y'' + B*y' + K*y + K3*y**3 = G*u + d + e*y*u", "B K K3 G d e")
    for eq in (CUBIC_EQUATION, equation):
        memory = algid.identify(data, *eq, window=window, refine=False)
        streamed = algid.identify(data, *eq, window=window, chunk=777)
        assert_same(streamed, memory)


# ------------------------------------------------------------------ found by trying to break it


def test_dates_masks_and_odd_column_types_are_read_as_in_memory(record, tmp_path):
    pd = pytest.importorskip("pandas")
    data, _ = record
    memory = algid.identify(data, *LINEAR_EQUATION, window=0.5, refine=False)
    stamps = pd.Timestamp("2024-01-01") + pd.to_timedelta(data["t"], unit="s")
    dated = pd.DataFrame({"t": stamps, "u": data["u"], "y": data["y"]})
    assert_same(algid.identify(dated, *LINEAR_EQUATION, window=0.5, chunk=1000), memory)
    assert_same(algid.identify(dated.set_index("t"), *LINEAR_EQUATION, window=0.5,
                               chunk=999), memory)
    pytest.importorskip("pyarrow")
    dated.to_parquet(tmp_path / "dated.parquet", row_group_size=1000)
    assert_same(algid.identify(tmp_path / "dated.parquet", *LINEAR_EQUATION, window=0.5),
                memory)
    # masked samples are missing, as in memory (not zeros)
    y = np.ma.masked_array(data["y"].copy(), mask=np.zeros(len(data["y"]), bool))
    y[[10, 2000, 2001, 4500]] = np.ma.masked
    masked = dict(data, y=y)
    assert_same(algid.identify(masked, *LINEAR_EQUATION, window=0.5, chunk=700),
                algid.identify(masked, *LINEAR_EQUATION, window=0.5, refine=False))
    for bad, fragment in ((data["u"] > 0, "boolean"), (data["u"] + 0j, "complex")):
        with pytest.raises(InputDataError, match=fragment):
            algid.identify(dict(data, u=bad), *LINEAR_EQUATION, window=0.5, chunk=700)


def test_excerpts_of_runs_shorter_than_an_excerpt_do_not_overlap(monkeypatch):
    monkeypatch.setattr(_identify, "EXCERPT_SAMPLES", 8 * 4096)
    data, _ = linear_offsets(3, n=7 * 3001)
    for j in range(1, 7):
        data["y"][j * 3001 - 1] = np.nan      # runs of 3000 samples, under 4096
    streamed = algid.identify(data, *LINEAR_EQUATION, chunk=5000)
    assert streamed.n_samples == 7 * 3001 - 6


@pytest.mark.parametrize("scale", [1e-200, 1e160])
def test_any_amplitude_gives_the_in_memory_estimate(record, scale):
    data, _ = record
    big = dict(data, u=data["u"] * scale, y=data["y"] * scale)
    equation = ("y'' + B*y' + K*y = G*u", "B K G")
    assert_same(algid.identify(big, *equation, window=0.5, chunk=600),
                algid.identify(big, *equation, window=0.5, refine=False))


def test_the_step_comes_from_more_than_the_first_chunk(record):
    data, _ = record
    lead = {k: np.concatenate([[v[0] - 0.5 if k == "t" else np.nan], v])
            for k, v in data.items()}
    memory = algid.identify(lead, *LINEAR_EQUATION, refine=False)
    for chunk in (1, 2, 3):
        assert_same(algid.identify(lead, *LINEAR_EQUATION, chunk=chunk), memory)


def test_single_precision_times_stream_as_uniform(record):
    data, _ = record
    coarse = dict(data, t=data["t"].astype(np.float32))
    streamed = algid.identify(coarse, *LINEAR_EQUATION, window=0.5, chunk=800)
    memory = algid.identify(coarse, *LINEAR_EQUATION, window=0.5, refine=False)
    for p in memory.parameters:   # in memory: the quantised times' own integrals
        assert abs(streamed.values[p] - memory.values[p]) < 0.1 * memory.stderr[p]


def test_a_missing_term_is_named_as_in_memory(record):
    data, _ = record
    equation = ("y'' + B*y' + K*y = G*u", "B K G")     # the offset is missing
    memory = algid.identify(data, *equation, window=0.5, refine=False)
    assert memory.warnings
    assert_same(algid.identify(data, *equation, window=0.5, chunk=1000), memory)


@pytest.mark.parametrize("call, fragment", [
    (dict(chunk=2**63), "from 1 to 2\\*\\*40"),
    (dict(chunk=0), "from 1 to 2\\*\\*40"),
    (dict(u=1.0), "u"),
    (dict(system=True), "system of equations"),
])
def test_more_bad_calls_get_one_line(record, call, fragment):
    data, _ = record
    equation = [LINEAR_EQUATION[0]] if call.pop("system", False) else LINEAR_EQUATION[0]
    if "u" in call:
        data = dict(data, u=call.pop("u"))
    with pytest.raises(InputDataError, match=fragment) as error:
        algid.identify(data, equation, LINEAR_EQUATION[1], window=0.5,
                       **{"chunk": 500, **call})
    assert "\n" not in str(error.value)


def test_rows_in_messages_are_the_records(record):
    data, _ = record
    bad = dict(data, y=data["y"].copy())
    bad["y"][4321] = np.inf
    with pytest.raises(InputDataError, match="row 4321") as error:
        algid.identify(bad, *LINEAR_EQUATION, window=0.5, chunk=1000)
    assert "chunk" not in str(error.value)


def test_a_gap_on_a_chunk_boundary_cuts_the_runs():
    data, _ = linear_offsets(3, n=12000)
    data["t"] = data["t"] + np.where(np.arange(12000) >= 6000, 10.0, 0.0)
    memory = algid.identify(data, *LINEAR_EQUATION, window=0.5, refine=False)
    for chunk in (6000, 3000, 1000):
        assert_same(algid.identify(data, *LINEAR_EQUATION, window=0.5, chunk=chunk), memory)


def test_an_output_growing_past_a_power_of_two_keeps_its_noise_bound(record):
    data, _ = record
    grown = dict(data, y=data["y"] / np.max(np.abs(data["y"])) * np.linspace(1.9, 2.1, 6000))
    memory = algid.identify(grown, *LINEAR_EQUATION, window=0.5, refine=False)
    for chunk in (7, 1000):
        assert_same(algid.identify(grown, *LINEAR_EQUATION, window=0.5, chunk=chunk), memory)


def test_an_empty_file_and_a_zone_aware_time_get_one_line(record, tmp_path):
    pd = pytest.importorskip("pandas")
    pytest.importorskip("pyarrow")
    data, _ = record
    pd.DataFrame({"t": [], "u": [], "y": []}).to_parquet(tmp_path / "empty.parquet")
    (tmp_path / "header.csv").write_text("t,u,y\n")
    for path in ("empty.parquet", "header.csv"):
        with pytest.raises(InputDataError, match="nothing to identify"):
            algid.identify(tmp_path / path, *LINEAR_EQUATION)
    stamps = pd.Timestamp("2024-01-01", tz="Europe/Paris") + pd.to_timedelta(data["t"],
                                                                             unit="s")
    zoned = pd.DataFrame({"t": stamps, "u": data["u"], "y": data["y"]})
    memory = algid.identify(data, *LINEAR_EQUATION, window=0.5, refine=False)
    assert_same(algid.identify(zoned, *LINEAR_EQUATION, window=0.5, refine=False), memory)
    assert_same(algid.identify(zoned, *LINEAR_EQUATION, window=0.5, chunk=1000), memory)


def test_jittered_double_precision_times_are_refused_not_smoothed(record):
    data, _ = record
    jitter = 0.002 / 80 * np.random.default_rng(1).uniform(-1, 1, 6000)
    with pytest.raises(InputDataError, match="off the uniform grid"):
        algid.identify(dict(data, t=data["t"] + jitter), *LINEAR_EQUATION, window=0.5,
                       chunk=1000)
