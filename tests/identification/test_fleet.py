"""identify_many: a fleet of records, one row each, bit for bit what identify gives, on a
two-process Dask cluster as in this process; refused records as rows; the long table,
mapping and Dask DataFrame inputs; the command line on a Parquet table; hostile input."""

import json
import math
import pickle

import numpy as np
import pytest
from conftest import assert_one_line_error

import algid
from algid.cli import main
from algid.errors import AlgidError, InputDataError, ModelError

pd = pytest.importorskip("pandas")
dd = pytest.importorskip("dask.dataframe")
distributed = pytest.importorskip("distributed")
pytest.importorskip("pyarrow")

EQUATION = ("x'' + B*x' + K*x = f", "B K")
#: The fast path (no output-error refinement): the fleet's records take 0.1 s each.
FAST = {"refine": False}
#: The records identify refuses: too short, and NaN throughout.
BAD = {"m03": "too short", "m07": "NaN only"}


def make_fleet(n=20):
    """Small mass-spring-damper records (2 s at 200 Hz), the damping varying, two bad."""
    fleet = {}
    for i in range(n):
        sim = algid.simulate("sine", c=1.5 + 0.05 * i, frequency=3.0, duration=2.0,
                             rate=200.0, noise_std=1e-4, seed=i)
        fleet[f"m{i:02d}"] = {"t": sim.t, "f": sim.f, "x": sim.x}
    fleet["m03"] = {name: values[:6] for name, values in fleet["m03"].items()}
    fleet["m07"] = dict(fleet["m07"], x=np.full_like(fleet["m07"]["x"], np.nan))
    return fleet


def long_table(fleet):
    """The fleet as one long DataFrame, an id column ``machine``."""
    return pd.concat([pd.DataFrame(record).assign(machine=key)
                      for key, record in fleet.items()], ignore_index=True)


def expected_row(record, equation=EQUATION, **options):
    """What identify says of one record, as a row of the fleet's table."""
    try:
        row = algid.identify(record, *equation, **options).to_dict()
    except AlgidError as exc:
        return {"error": " ".join(str(exc).split())}
    row["error"] = None
    return row


def assert_rows_are_identify(table, records, equation=EQUATION, **options):
    """Every row of ``table`` bit for bit identify's on its record."""
    assert list(table.index) == list(records)
    for key, record in records.items():
        expected = expected_row(record, equation, **options)
        row = table.loc[key]
        assert row["error"] == expected["error"], key
        if expected["error"] is not None:
            assert all(math.isnan(row[p]) for p in table.columns[:6]), key
            continue
        for column, value in expected.items():
            if isinstance(value, float):
                assert np.array_equal(row[column], value, equal_nan=True), (key, column)
            else:
                assert row[column] == value, (key, column)


@pytest.fixture(scope="module")
def fleet():
    return make_fleet()


@pytest.fixture(scope="module")
def serial_table(fleet):
    return algid.identify_many(fleet, *EQUATION, **FAST)


@pytest.fixture(scope="module")
def client():
    """A two-process local cluster for this module; not the default client: a test runs
    on it inside ``client.as_current()``."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        with distributed.Client(cluster, set_as_default=False) as client:
            yield client


# ------------------------------------------------------------------ results as data


def test_a_result_is_one_flat_row(fleet):
    result = algid.identify(fleet["m00"], *EQUATION)
    row = result.to_dict()
    assert list(row) == ["B", "K", "stderr_B", "stderr_K", "numerical_error_B",
                         "numerical_error_K", "window", "n_samples", "estimate", "warnings"]
    assert row["B"] == result.B and row["stderr_K"] == result.stderr["K"]
    assert row["numerical_error_B"] == result.numerical_error["B"]
    assert (row["window"], row["n_samples"], row["estimate"]) == (
        result.window, result.n_samples, result.estimate)
    assert all(type(v) in (float, int, str) for v in row.values())
    json.dumps(row)
    table = result.to_pandas()
    assert table.shape == (1, 10) and list(table.columns) == list(row)
    assert table.loc[0, "B"] == result.B


def test_warnings_are_joined_and_split_back(fleet):
    result = algid.identify(fleet["m00"], *EQUATION)
    warned = result.with_parameters(result.values)
    warned.warnings = ["first; with a semicolon", "second"]
    assert warned.to_dict()["warnings"] == "first; with a semicolon | second"
    assert warned.to_dict()["warnings"].split(" | ") == warned.warnings


def test_a_parameter_named_like_a_column_is_refused():
    result = algid.IdentificationResult.from_values("x'' + window*x' + K*x = f",
                                                    {"window": 1.0, "K": 2.0})
    with pytest.raises(ModelError, match="'window' is also a column"):
        result.to_dict()


# ----------------------------------------------------------------------- fleets


def test_serial_fleet_is_identify_on_each_record_and_refusals_are_rows(fleet, serial_table):
    table = serial_table
    assert table.index.name == "id" and len(table) == 20
    assert list(table.columns[-5:]) == ["window", "n_samples", "estimate", "warnings",
                                        "error"]
    refused = table.index[table["error"].notna()].tolist()
    assert refused == sorted(BAD)
    assert all("\n" not in message for message in table.loc[refused, "error"])
    assert table["n_samples"].dtype == "Int64" and table.loc["m03", "n_samples"] is pd.NA
    assert_rows_are_identify(table, fleet, **FAST)
    good = table.drop(index=refused)
    assert np.allclose(good["B"], [1.5 + 0.05 * int(k[1:]) for k in good.index], rtol=0.02)


def test_cluster_fleet_is_bit_for_bit_the_serial_one(fleet, serial_table, client, capsys):
    with client.as_current(), distributed.get_task_stream(client) as stream:
        table = algid.identify_many(fleet, *EQUATION, progress=True, **FAST)
    pd.testing.assert_frame_equal(table, serial_table, check_exact=True)
    err = capsys.readouterr().err
    assert err.splitlines()[-1] == "identify_many: 20/20 records, 2 refused"
    # a task per record, run by both workers
    ran = [task for task in stream.data if str(task["key"]).startswith("fleet_row")]
    assert len(ran) == 20 and len({task["worker"] for task in ran}) == 2


def test_cluster_refined_fleet_and_a_compiled_model(fleet, client):
    records = {key: fleet[key] for key in ("m00", "m05", "m07")}
    with client.as_current():
        table = algid.identify_many(records, *EQUATION)   # refined where it is safe
    assert table.loc["m00", "estimate"] == "refined"
    assert_rows_are_identify(table, records)
    pytest.importorskip("sympy")
    compiled = algid.compile_equation(*EQUATION)
    with pytest.raises(TypeError):
        pickle.dumps(compiled)   # a module: sent to the workers as its Model
    with client.as_current():
        again = algid.identify_many(records, compiled, **FAST)
    assert_rows_are_identify(again, records, (compiled, None), **FAST)


def test_long_dataframe_groups_are_the_records(fleet, serial_table, client):
    frame = long_table(fleet)
    table = algid.identify_many(frame, *EQUATION, by="machine", **FAST)
    assert table.index.name == "machine"
    groups = {key: frame[frame["machine"] == key].drop(columns="machine") for key in fleet}
    assert_rows_are_identify(table, groups, **FAST)
    # the same values as the mapping of the same records
    pd.testing.assert_frame_equal(table.rename_axis("id"), serial_table, check_exact=True)
    with client.as_current():
        on_cluster = algid.identify_many(frame, *EQUATION, by="machine", **FAST)
    pd.testing.assert_frame_equal(on_cluster, table, check_exact=True)


def test_rows_of_a_record_need_not_be_together_and_ids_keep_their_order(fleet):
    records = {key: fleet[key] for key in ("m02", "m00", "m01")}
    interleaved = long_table(records).sort_values("t", kind="stable")
    assert interleaved["machine"].iloc[:3].tolist() == ["m02", "m00", "m01"]
    table = algid.identify_many(interleaved, *EQUATION, by="machine", **FAST)
    assert_rows_are_identify(table.rename_axis("id"), records, **FAST)


def test_dask_dataframe_on_the_cluster_and_without_one(fleet, serial_table, client, capsys):
    frame = long_table({key: fleet[key] for key in list(fleet)[:8]})
    # partitions cut through records: each record is put together from its pieces
    ddf = dd.from_pandas(frame, npartitions=5, sort=False)
    assert ddf.npartitions > 1
    expected = serial_table.iloc[:8].rename_axis("machine")
    with client.as_current():
        table = algid.identify_many(ddf, *EQUATION, by="machine", **FAST)
    pd.testing.assert_frame_equal(table, expected, check_exact=True)
    local = algid.identify_many(ddf, *EQUATION, by="machine", progress=True, **FAST)
    pd.testing.assert_frame_equal(local, expected, check_exact=True)
    assert capsys.readouterr().err.splitlines()[-1] == "identify_many: 8/8 records, 2 refused"


# -------------------------------------------------------------------- refusals


@pytest.mark.parametrize("case, fragment", [
    ("list", "data is a list"),
    ("one record", "data is one record"),
    ("empty mapping", "no records"),
    ("empty frame", "no records"),
    ("no by", "needs by="),
    ("unknown by", "by='unit' is not a column"),
    ("by list", "by must name one column"),
    ("by on mapping", "the keys of a mapping are its ids"),
    ("missing ids", "has missing values"),
    ("string", "got str"),
    ("array", "got ndarray"),
    ("none", "got NoneType"),
    ("progress", "progress must be"),
    ("dask unknown by", "by='unit' is not a column of the Dask DataFrame"),
    ("dask missing ids", "has missing values"),
])
def test_hostile_input_is_one_line(fleet, case, fragment):
    records = {key: fleet[key] for key in ("m00", "m01")}
    frame = long_table(records)
    with_gap = frame.astype({"machine": object})
    with_gap.loc[3, "machine"] = None
    arguments = {
        "list": (list(records.values()), {}),
        "one record": (records["m00"], {}),
        "empty mapping": ({}, {}),
        "empty frame": (frame.iloc[:0], {"by": "machine"}),
        "no by": (frame, {}),
        "unknown by": (frame, {"by": "unit"}),
        "by list": (frame, {"by": ["machine"]}),
        "by on mapping": (records, {"by": "machine"}),
        "missing ids": (with_gap, {"by": "machine"}),
        "string": ("fleet.parquet", {}),
        "array": (np.zeros((3, 3)), {}),
        "none": (None, {}),
        "progress": (records, {"progress": "yes"}),
        "dask unknown by": (dd.from_pandas(frame, npartitions=2), {"by": "unit"}),
        "dask missing ids": (dd.from_pandas(with_gap, npartitions=2), {"by": "machine"}),
    }
    data, options = arguments[case]
    with pytest.raises(InputDataError) as info:
        algid.identify_many(data, *EQUATION, **options, **FAST)
    assert isinstance(info.value, ValueError)
    assert fragment in str(info.value) and "\n" not in str(info.value)


def test_model_and_option_errors_refuse_the_fleet_before_any_record(fleet):
    records = {"m00": fleet["m00"]}
    with pytest.raises(ModelError):
        algid.identify_many(records, "x'' + B*x' = f", "B K")
    with pytest.raises(InputDataError, match="unknown method"):
        algid.identify_many(records, *EQUATION, method="magic")
    with pytest.raises(ModelError, match="'error' is also a column"):
        algid.identify_many(records, "x'' + error*x' + K*x = f", "error K")
    with pytest.raises(TypeError, match="unexpected keyword argument 'windo'"):
        algid.identify_many(records, *EQUATION, windo=0.2)


# ----------------------------------------------------------------- command line


@pytest.fixture(scope="module")
def fleet_files(fleet, tmp_path_factory):
    folder = tmp_path_factory.mktemp("fleet")
    frame = long_table({key: fleet[key] for key in list(fleet)[:8]})
    frame.to_parquet(folder / "fleet.parquet")
    frame.to_csv(folder / "fleet.csv", index=False)
    return folder


def run(capsys, *argv):
    code = main([str(arg) for arg in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_command_line_writes_csv_and_parquet(fleet_files, serial_table, capsys):
    expected = serial_table.iloc[:8].rename_axis("machine")
    table = fleet_files / "fleet.parquet"
    code, out, err = run(capsys, "identify", table, "--by", "machine", "--equation",
                         EQUATION[0], "--parameters", EQUATION[1], "--no-refine", "--out",
                         fleet_files / "results.csv")
    assert code == 0, err
    assert out.strip().endswith("8 records (2 refused): wrote " + str(fleet_files /
                                                                      "results.csv"))
    assert "2 of 8 records refused" in err
    written = pd.read_csv(fleet_files / "results.csv", index_col="machine")
    pd.testing.assert_frame_equal(written[expected.columns[:7]], expected.iloc[:, :7],
                                  check_exact=True)
    assert written["error"].notna().tolist() == expected["error"].notna().tolist()
    code, _, err = run(capsys, "identify", fleet_files / "fleet.csv", "--by", "machine",
                       "--equation", EQUATION[0], "--parameters", EQUATION[1],
                       "--no-refine", "--out", fleet_files / "results.parquet")
    assert code == 0, err
    pd.testing.assert_frame_equal(pd.read_parquet(fleet_files / "results.parquet"),
                                  expected, check_exact=True, check_dtype=False)


def test_command_line_on_a_scheduler_prints_json_rows(fleet_files, serial_table, client,
                                                      capsys):
    code, out, err = run(capsys, "identify", fleet_files / "fleet.parquet", "--by",
                         "machine", "--equation", EQUATION[0], "--parameters", EQUATION[1],
                         "--no-refine", "--json", "--scheduler", client.scheduler.address)
    assert code == 0, err
    rows = json.loads(out)
    assert [row["machine"] for row in rows] == list(serial_table.index[:8])
    assert rows[0]["B"] == serial_table.iloc[0]["B"]
    assert rows[3]["error"] == serial_table.loc["m03", "error"] and rows[3]["B"] is None


@pytest.mark.parametrize("extra, fragments", [
    (["--by", "unit"], ["no column 'unit' for --by", "machine"]),
    (["--by", "machine", "--out", "results.xlsx"], ["--out results.xlsx", ".parquet"]),
    (["--by", "x"], ["the id column is also a signal"]),
    (["--workers", "2"], ["--workers goes with --by"]),
])
def test_command_line_bad_input_is_one_line(fleet_files, capsys, extra, fragments):
    code, out, err = run(capsys, "identify", fleet_files / "fleet.parquet", "--equation",
                         EQUATION[0], "--parameters", EQUATION[1], "--json", *extra)
    assert_one_line_error(code, err, *fragments)
    assert set(json.loads(out)) == {"error"}   # --json: the refusal on stdout too


def test_command_line_refuses_an_unreadable_table(tmp_path, capsys):
    broken = tmp_path / "broken.parquet"
    broken.write_bytes(b"not parquet")
    code, _, err = run(capsys, "identify", broken, "--by", "machine", "--equation",
                       EQUATION[0], "--parameters", EQUATION[1])
    assert_one_line_error(code, err, "not a readable Parquet table")


# ------------------------------------------------------------------ outliers


def test_outliers_are_flagged_against_the_fleet_spread_and_their_own_error():
    from algid.identification import fleet_outliers

    rng = np.random.default_rng(0)
    k = 30 * (1 + 0.02 * rng.normal(size=60))
    k[[7, 40]] = [36.0, 24.0]
    table = pd.DataFrame({"K": k, "stderr_K": np.full(60, 0.05), "B": np.full(60, 2.0),
                          "stderr_B": np.full(60, 0.01)},
                         index=[f"m{i}" for i in range(60)])
    table.loc["m3", ["K", "stderr_K"]] = np.nan          # a refused record
    flags = fleet_outliers(table)
    assert list(table.index[flags["K"]]) == ["m7", "m40"]
    assert not flags["B"].any() and not flags.loc["m3"].any()
    # a record whose own error covers its distance is not one
    table.loc["m7", "stderr_K"] = 5.0
    assert list(table.index[fleet_outliers(table, "K")["K"]]) == ["m40"]


@pytest.mark.parametrize("call, fragment", [
    (dict(parameters=["M"]), "no column 'M'"),
    (dict(threshold=0), "threshold must be a positive number"),
    (dict(threshold=True), "threshold must be a positive number"),
])
def test_outliers_refuse_what_the_table_does_not_hold(call, fragment):
    from algid.identification import fleet_outliers

    table = pd.DataFrame({"K": [1.0, 2.0], "stderr_K": [0.1, 0.1]})
    with pytest.raises(InputDataError, match=fragment):
        fleet_outliers(table, **call)


def test_the_fleet_figure_names_the_outliers_and_counts_the_refused():
    pytest.importorskip("matplotlib")
    from algid.plotting import plot_fleet

    table = pd.DataFrame({"K": [3.0, 3.1, 2.9, 3.05, 6.0, np.nan],
                          "stderr_K": [0.05] * 5 + [np.nan],
                          "error": [None] * 5 + ["record 0: too short"]},
                         index=["a", "b", "c", "d", "e", "f"])
    fig = plot_fleet(table, true_values={"K": 3.0})
    assert fig.axes[0].get_title() == "K: 1 outlier (e)"
    assert "1 refused" in fig.axes[0].get_xlabel()
