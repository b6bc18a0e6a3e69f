"""The record types every entry point takes (algid._record_input): mappings, pandas
DataFrames (time as a column or as the index), xarray Datasets, python-control's
TimeResponseData; and one reading of a column (masked samples are missing)."""

import numpy as np
import pytest
from benchmarks.synthetic_records import LINEAR_EQUATION, linear_offsets

import algid
from algid._record_input import as_record, read_column

pd = pytest.importorskip("pandas")
xr = pytest.importorskip("xarray")
control = pytest.importorskip("control")


@pytest.fixture(scope="module")
def record():
    return linear_offsets(0, n=2000)[0]


@pytest.fixture(scope="module")
def reference(record):
    return algid.identify(record, *LINEAR_EQUATION)


def _same_fit(fit, reference):
    return fit.values == reference.values and fit.stderr == reference.stderr


def test_a_dataframe_gives_the_mappings_numbers_with_time_as_a_column_or_the_index(
        record, reference):
    frame = pd.DataFrame(record)
    assert _same_fit(algid.identify(frame, *LINEAR_EQUATION), reference)
    assert _same_fit(algid.identify(frame.set_index("t"), *LINEAR_EQUATION), reference)
    # an unnamed float index is time too (under the name t)
    assert _same_fit(algid.identify(frame.drop(columns="t").set_axis(record["t"]),
                                    *LINEAR_EQUATION), reference)
    # set_index(drop=False): the index and the column agree
    assert _same_fit(algid.identify(frame.set_index("t", drop=False), *LINEAR_EQUATION),
                     reference)


def test_a_duration_index_is_seconds_from_the_first_sample(record, reference):
    frame = pd.DataFrame({"y": record["y"], "u": record["u"]},
                         index=pd.to_timedelta(record["t"] - record["t"][0], unit="s"))
    fit = algid.identify(frame, *LINEAR_EQUATION)
    for name, value in reference.values.items():
        assert fit.values[name] == pytest.approx(value, rel=1e-9, abs=1e-12)


def test_row_numbers_are_not_time(record):
    """A filtered frame keeps its old row numbers: an integer index is not a time axis."""
    frame = pd.DataFrame({"y": record["y"], "u": record["u"]})
    with pytest.raises(algid.InputDataError, match="no time column"):
        algid.identify(frame.iloc[::2], *LINEAR_EQUATION)
    fit = algid.identify(frame.iloc[100:], *LINEAR_EQUATION, rate=1 / np.diff(record["t"])[0])
    assert np.isfinite(fit.values["B"])


def test_an_index_and_a_time_column_that_differ_are_refused(record):
    frame = pd.DataFrame(record).set_index(pd.Index(record["t"] * 2, name="t"))
    frame["t"] = record["t"]
    with pytest.raises(algid.InputDataError, match="index and its column 't' both hold "
                                                   "times, and they differ"):
        algid.identify(frame, *LINEAR_EQUATION)


def test_a_nullable_column_s_missing_values_are_gaps_as_nan_is(record):
    y = record["y"].copy()
    y[700:705] = np.nan
    with_nan = algid.identify(dict(record, y=y), *LINEAR_EQUATION)
    nullable = pd.DataFrame(dict(record, y=y)).astype({"y": "Float64"})
    nullable.loc[700:704, "y"] = pd.NA
    assert _same_fit(algid.identify(nullable, *LINEAR_EQUATION), with_nan)


def test_a_dataset_and_a_timeresponse_give_the_mappings_numbers(record, reference):
    dataset = xr.Dataset({k: ("t", v) for k, v in record.items() if k != "t"},
                         coords={"t": record["t"]})
    assert _same_fit(algid.identify(dataset, *LINEAR_EQUATION), reference)
    # default labels u[0], y[0]: also u and y
    response = control.TimeResponseData(record["t"], record["y"], inputs=record["u"])
    assert _same_fit(algid.identify(response, *LINEAR_EQUATION), reference)
    labelled = control.TimeResponseData(record["t"], record["y"], inputs=record["u"],
                                        output_labels=["pos"], input_labels=["force"])
    assert set(as_record(labelled)) == {"t", "pos", "force"}
    fit = algid.identify(labelled, "pos'' + B*pos' + K*pos = G*force + d", "B K G d")
    assert fit.values == reference.values


def test_several_traces_are_refused(record):
    response = control.TimeResponseData(record["t"], np.stack([record["y"]] * 2)[:, None],
                                        inputs=np.stack([record["u"]] * 2)[:, None],
                                        multi_trace=True)
    with pytest.raises(algid.InputDataError, match="several traces"):
        algid.identify(response, *LINEAR_EQUATION)


def test_the_tracker_takes_the_same_records(record, reference):
    window = reference.window
    plain = algid.Tracker(*LINEAR_EQUATION, window=window).update(record)
    for data in (pd.DataFrame(record).set_index("t"),
                 xr.Dataset({k: ("t", v) for k, v in record.items() if k != "t"},
                            coords={"t": record["t"]})):
        out = algid.Tracker(*LINEAR_EQUATION, window=window).update(data)
        assert np.array_equal(out.values, plain.values, equal_nan=True)
        assert np.array_equal(out.t, plain.t)


def test_the_tracker_takes_a_masked_sample_as_missing(record, reference):
    """A masked glitch was used as a measurement by the tracker (identify ignored it)."""
    masked = np.ma.masked_array(record["y"].copy())
    masked[600] = 1e3
    masked[600] = np.ma.masked
    with_nan = record["y"].copy()
    with_nan[600] = np.nan
    out = algid.Tracker(*LINEAR_EQUATION, window=reference.window).update(
        dict(record, y=masked))
    expected = algid.Tracker(*LINEAR_EQUATION, window=reference.window).update(
        dict(record, y=with_nan))
    assert np.array_equal(out.values, expected.values, equal_nan=True)


def test_estimate_and_the_online_estimator_take_the_same_records():
    sim = algid.simulate("sine", m=1, c=2, k=3, noise_std=0.01, seed=0, duration=2.0)
    paper = algid.estimate(sim.t, sim.f, sim.x)
    response = sim.to_timeresponse()
    assert np.array_equal(algid.estimate(response).B, paper.B, equal_nan=True)
    equation = ("x'' + B*x' + K*x = F", "B K")
    from_response = algid.estimate(response, *equation)
    frame = pd.DataFrame({"t": sim.t, "F": sim.f, "x": sim.x})
    from_frame = algid.estimate(frame.set_index("t"), *equation)
    assert np.array_equal(from_frame.B, from_response.B, equal_nan=True)
    online = algid.OnlineEstimator(*equation, engine="numpy")
    for start in range(0, len(frame), 500):
        last = online.update(frame.iloc[start:start + 500])
    assert last.B[-1] == from_frame.B[-1]
    with pytest.raises(algid.InputDataError, match="TimeResponseData or the arrays"):
        algid.estimate(response, x=sim.x)


@pytest.mark.parametrize("values, message", [
    (np.array([1 + 1j, 2]), "is complex"),
    (np.array([True, False]), "holds booleans"),
    (np.zeros((3, 2)), r"has shape \(3, 2\)"),
    (np.array(["a", "b"]), "is not numeric"),
    (np.array([10**400, 1], dtype=object), "holds numbers too large for floating point"),
    (np.array(["2020-01-01", "2020-01-02"], dtype="datetime64[D]"), "holds dates or durations"),
])
def test_one_reading_of_a_column_with_the_same_refusals(values, message):
    with pytest.raises(algid.InputDataError, match=f"^column 'u' {message}"):
        read_column(values, "column 'u'")


def test_a_masked_column_reads_as_nan_where_masked():
    column = read_column(np.ma.masked_array([1.0, 2.0, 3.0], mask=[0, 1, 0]), "column 'u'")
    assert np.array_equal(column, [1.0, np.nan, 3.0], equal_nan=True)
    assert np.array_equal(read_column(np.array(["2020-01-01T00:00:00", "2020-01-01T00:00:02"],
                                               dtype="datetime64[s]"), "t", time=True), [0, 2])


def test_estimate_on_a_record_names_the_users_column_and_refuses_a_second_model():
    """It named the paper's 'f' for the user's 'u', and ignored model= beside an equation."""
    sim = algid.simulate("sine", m=1, c=2, k=3, seed=0, duration=1.0)
    u = sim.f.copy()
    u[10] = np.nan
    record = {"t": sim.t, "u": u, "y": sim.x}
    equation = ("y'' + B*y' + K*y = u", "B K")
    with pytest.raises(algid.InputDataError, match=r"^record 0: column 'u' has NaN at row 10"):
        algid.estimate(record, *equation)
    online = algid.OnlineEstimator(*equation, engine="numpy")
    with pytest.raises(algid.InputDataError, match=r"stream sample 0: column 'u' has NaN at "
                                                   r"row 10"):
        online.update(record)
    with pytest.raises(algid.InputDataError, match="the model is given twice"):
        algid.estimate(dict(record, u=sim.f), *equation, model="msd")
    named = algid.estimate({"t": sim.t, "f": sim.f, "x": sim.x}, model="msd")
    assert np.array_equal(named.B, algid.estimate(sim.t, sim.f, sim.x).B, equal_nan=True)


def test_hostile_frames_are_refused_in_one_line(record):
    frame = pd.DataFrame(record)
    for data, message in (
            (pd.concat([frame, frame[["y"]]], axis=1), "several columns named 'y'"),
            (frame["y"], "is a pandas Series, one signal"),
            (pd.DataFrame(np.column_stack([record["t"]] * 40)),
             r"no column 'y' .*columns: 0, 1, .*, 11, \.\.\. \(40 columns\)")):
        with pytest.raises(algid.InputDataError, match=message):
            algid.identify(data, *LINEAR_EQUATION)
        with pytest.raises(algid.InputDataError, match=message.replace("for", "in")):
            algid.Tracker(*LINEAR_EQUATION, window=0.1875, rate=80).update(data)


def test_dates_with_a_time_zone_are_read_as_utc(record, reference):
    frame = pd.DataFrame({"y": record["y"], "u": record["u"]},
                         index=pd.date_range("2020-03-29 00:59:59", periods=len(record["t"]),
                                             freq="12500us", tz="Europe/Paris"))
    fit = algid.identify(frame, *LINEAR_EQUATION)   # (across a change to summer time)
    for name, value in reference.values.items():
        assert fit.values[name] == pytest.approx(value, rel=1e-9, abs=1e-12)


def test_text_is_refused_everywhere_as_the_paper_s_form_refuses_it(record):
    """identify and the tracker took numbers stored as text; estimate(t, f, x) did not."""
    text = dict(record, y=record["y"].astype(str))
    message = (r"column 'y'( of the chunk starting at stream sample 0)? holds numbers "
               r"stored as text \(row 0: '")
    with pytest.raises(algid.InputDataError, match=message):
        algid.identify(text, *LINEAR_EQUATION)
    with pytest.raises(algid.InputDataError, match=message):
        algid.Tracker(*LINEAR_EQUATION, window=0.1875).update(text)
    mixed = dict(record, y=np.array([*record["y"][:5], "n/a", *record["y"][6:]], dtype=object))
    with pytest.raises(algid.InputDataError, match=r"is not numeric: row 5 holds 'n/a'"):
        algid.identify(mixed, *LINEAR_EQUATION)
    with pytest.raises(algid.InputDataError, match=r"signal 'x' holds numbers stored as text"):
        algid.estimate(record["t"], record["u"], record["y"].astype(str))


def test_a_frame_with_columns_named_like_a_timeresponse_is_a_frame(record, reference):
    """Columns time, inputs, outputs are attributes of a DataFrame: it was read as a
    TimeResponseData (an AttributeError)."""
    frame = pd.DataFrame({"time": record["t"], "u": record["u"], "y": record["y"],
                          "inputs": 0.0, "outputs": 0.0})
    assert _same_fit(algid.identify(frame, *LINEAR_EQUATION), reference)


def test_empty_text_and_object_booleans():
    with pytest.raises(algid.InputDataError, match="holds booleans"):
        read_column(np.array([True, 1.0], dtype=object), "column 'u'")
    assert read_column(np.array([], dtype="U3"), "column 'u'").size == 0


def test_the_stream_takes_a_timeresponse_in_the_paper_s_form():
    sim = algid.simulate("sine", m=1, c=2, k=3, seed=0, duration=1.0)
    online = algid.OnlineEstimator(engine="numpy")
    assert online.update(sim.to_timeresponse()).B[-1] == algid.estimate(
        sim.t, sim.f, sim.x, engine="numpy").B[-1]
