"""algid.Tracker: identify's window equations on a stream."""

import numpy as np
import pytest
from benchmarks.synthetic_records import LINEAR_EQUATION, linear_gaps, linear_offsets

import algid
from algid.errors import InputDataError
from algid.identification._tracker import Tracker

EQUATION, NAMES = LINEAR_EQUATION
PARAMETERS = NAMES.split()
WINDOW = 0.1875   # identify's choice on the linear record (16 samples at 80 Hz)


def stream(tracker, record, sizes):
    """Feed ``record`` in chunks of the given sizes (cycled); concatenate the outputs."""
    n = len(next(iter(record.values())))
    outputs, start, k = [], 0, 0
    while start < n:
        size = sizes[k % len(sizes)]
        outputs.append(tracker.update({c: v[start:start + size] for c, v in record.items()}))
        start, k = start + size, k + 1
    return {key: np.concatenate([getattr(o, key) for o in outputs])
            for key in ("t", "values", "stderr", "numerical_error", "alarms")}


def test_last_estimate_equals_identify_without_forgetting():
    record, truth = linear_offsets(0, n=1500)
    out = stream(Tracker(EQUATION, PARAMETERS, time="t", window=WINDOW), record, [1000])
    reference = algid.identify(record, EQUATION, PARAMETERS, window=WINDOW, refine=False)
    expected = np.array([reference.values[p] for p in PARAMETERS])
    assert np.max(np.abs(out["values"][-1] / expected - 1)) < 1e-9
    truth = np.array([truth[p] for p in PARAMETERS])
    assert np.all(np.abs(out["values"][-1] - truth) < 3 * out["stderr"][-1])
    # the numerical error is that of identify: the two multiplicities' difference
    numerical = np.array([reference.numerical_error[p] for p in PARAMETERS])
    np.testing.assert_allclose(out["numerical_error"][-1], numerical, rtol=1e-6)


def test_gaps_as_identify():
    record, _ = linear_gaps(1, n=1500)
    out = stream(Tracker(EQUATION, PARAMETERS, time="t", window=WINDOW), record, [333])
    reference = algid.identify(record, EQUATION, PARAMETERS, window=WINDOW, refine=False)
    expected = np.array([reference.values[p] for p in PARAMETERS])
    assert np.max(np.abs(out["values"][-1] / expected - 1)) < 1e-9


def test_same_output_whatever_the_chunking():
    record, _ = linear_offsets(2, n=700)
    outputs = [stream(Tracker(EQUATION, PARAMETERS, rate=80.0, window=WINDOW, half_life=2.0),
                      {k: v for k, v in record.items() if k != "t"}, sizes)
               for sizes in ([1000], [1], [7], [3, 50, 1, 400])]
    assert np.isfinite(outputs[0]["values"][-1]).all()
    for other in outputs[1:]:
        for key, value in outputs[0].items():
            assert np.array_equal(value, other[key], equal_nan=True), key


def test_save_and_load_continue_bit_for_bit(tmp_path):
    record, _ = linear_offsets(3, n=700)
    whole = stream(Tracker(EQUATION, PARAMETERS, time="t", window=WINDOW, half_life=1.0),
                   record, [100])
    tracker = Tracker(EQUATION, PARAMETERS, time="t", window=WINDOW, half_life=1.0)
    first = stream(tracker, {k: v[:333] for k, v in record.items()}, [100])
    tracker.save(tmp_path / "state.npz")
    restored = Tracker.load(tmp_path / "state.npz")
    second = stream(restored, {k: v[333:] for k, v in record.items()}, [67])
    for key in ("t", "values", "stderr"):
        joined = np.concatenate([first[key], second[key]])
        assert np.array_equal(joined, whole[key], equal_nan=True), key
    with pytest.raises(InputDataError, match="not a saved tracker"):
        Tracker.load(tmp_path / "missing.npz")


def test_window_chosen_on_the_warmup_and_state_bounded():
    record, truth = linear_offsets(4, n=4000)
    tracker = Tracker(EQUATION, PARAMETERS, time="t", warmup=10.0, half_life=5.0)
    sizes = []
    for start in range(0, 4000, 100):
        tracker.update({k: v[start:start + 100] for k, v in record.items()})
        sizes.append(tracker.state_size())
    assert tracker.window == pytest.approx(algid.identify(
        {k: v[:801] for k, v in record.items()}, EQUATION, PARAMETERS).window)
    # nothing grows with the stream once the window is chosen
    assert max(sizes[20:]) <= max(sizes[8:20])


def _one_hertz_mode(seconds=20.0, rate=100.0, seed=0):
    """The window rule study's linear record (a 1 Hz mode, 30 dB), shorter and slower."""
    from benchmarks.window_rule_study import LINEAR, simulate

    t, u, y = simulate(LINEAR, rate=rate, duration=seconds)
    noise = 10 ** -1.5 * np.std(y) * np.random.default_rng(seed).standard_normal(len(t))
    return {"t": t, "u": u, "y": y + noise}, LINEAR["equation"], LINEAR["parameters"]


def _identify_on(record, seconds, equation, names):
    cut = int(np.searchsorted(record["t"], record["t"][0] + seconds, side="left")) + 1
    return algid.identify({k: v[:cut] for k, v in record.items()}, equation, names,
                          refine=False).window


def test_warmup_extended_while_its_window_is_near_the_longest_it_allows():
    """On 4 s of a 1 Hz mode identify keeps the longest window (0.3 s), on 8 s 0.6 s: the
    span doubles (three times) up to 16 s, where the window is 1.29 s (on 30 s of the
    same mode at 1 kHz the final estimate had 1.9 to 6.9 times identify's RMSE at the 2 s
    warm-up's window: ``benchmarks.tracker_window``); with forgetting, up to two thirds
    of its memory."""
    record, equation, names = _one_hertz_mode()
    whole = Tracker(equation, names, time="t")
    last = whole.update(record, last=True)
    assert whole.window == pytest.approx(_identify_on(record, 16.0, equation, names))
    assert whole.window > 1.0
    chunked = Tracker(equation, names, time="t")
    outs = [chunked.update({k: v[i:i + 250] for k, v in record.items()}, last=i + 250 >= 2001)
            for i in range(0, 2001, 250)]
    assert np.array_equal(np.concatenate([o.values for o in outs]), last.values,
                          equal_nan=True)
    forgetting = Tracker(equation, names, time="t", half_life=2.0)
    forgetting.update(record)
    span = 2 / 3 * 2 * 2.0 / np.log(2.0)   # two thirds of the memory: 3.85 s, not 4 s
    assert forgetting.window == pytest.approx(_identify_on(record, span, equation, names))


def test_stream_that_ends_in_the_warmup_has_the_last_accepted_span_s_window():
    """12 s of the 1 Hz mode: the window of 8 s (near the longest they allow) would be
    extended on 16 s; the stream's end (``last=True``) keeps the 8 s one."""
    record, equation, names = _one_hertz_mode(seconds=12.0)
    expected_window = _identify_on(record, 8.0, equation, names)
    for size in (7, 10000):
        tracker = Tracker(equation, names, time="t")
        outs = [tracker.update({k: v[i:i + size] for k, v in record.items()},
                               last=i + size >= 1201) for i in range(0, 1201, size)]
        assert tracker.window == pytest.approx(expected_window)
        last = [o for o in outs if len(o)][-1]
        # identify at that window on the samples up to the last window end
        cut = int(np.searchsorted(record["t"], last.t[-1])) + 1
        reference = algid.identify({k: v[:cut] for k, v in record.items()}, equation, names,
                                   window=tracker.window, refine=False)
        expected = np.array([reference.values[p] for p in names.split()])
        assert np.max(np.abs(last.values[-1] / expected - 1)) < 1e-9
    # without last=True the stream still waits for its warm-up's span
    assert Tracker(equation, names, time="t").update(record).values.size == 0


def test_estimates_nan_until_determined():
    record, _ = linear_offsets(0, n=400)
    out = Tracker(EQUATION, PARAMETERS, time="t", window=WINDOW).update(record)
    assert np.isnan(out.values[0]).all()
    assert np.isfinite(out.values[-1]).all()


@pytest.mark.parametrize("kwargs, chunk, message", [
    ({"method": "iv"}, None, "method must be 'bc' or 'ls'"),
    ({"half_life": -1.0}, None, "half_life must be a positive"),
    ({}, {"y": [1.0, 2.0]}, "no column 'u'"),
    ({}, {"y": [1.0, 2.0], "u": [1.0]}, "different lengths"),
    ({"time": "t"}, {"y": [1.0, 2.0], "u": [1.0, 2.0], "t": [0.0, 0.0]}, "does not increase"),
    ({}, {"y": [[1.0, 2.0], [3.0, 4.0]], "u": [1.0, 2.0, 3.0, 4.0]}, "has shape \\(2, 2\\)"),
    ({}, {"y": [1.0, 2.0], "u": [True, False]},
     "column 'u' of the chunk starting at stream sample 0 holds booleans"),
    # a time column beside rate= that contradicts it (it was ignored: wrong estimates)
    ({"rate": 40.0}, {"y": [1.0, 2.0, 3.0], "u": [1.0, 2.0, 3.0], "t": [0.0, 0.0125, 0.025]},
     "rate 40 Hz contradicts time column 't'"),
    # beyond the run lengths the CUSUM threshold is tuned to (a LinAlgError)
    ({"window": WINDOW, "false_alarm_rate": 1e-30}, {"y": [1.0, 2.0], "u": [1.0, 2.0]},
     "false_alarm_rate 1e-30 per second is one alarm in"),
    # inf is no missing sample (it was dropped as NaN is)
    ({}, {"y": [1.0, float("inf")], "u": [1.0, 2.0]},
     "column 'y' of the chunk starting at stream sample 0 has inf at row 1; a missing "
     "sample is NaN"),
    ({"window": 0.0}, None, "window must be a positive number"),
    ({"window": -1.0}, None, "window must be a positive number"),
    # refused before the arrays of 8e7 samples are made (a MemoryError or the OOM killer)
    ({"window": 1e6}, {"y": [1.0, 2.0], "u": [1.0, 2.0]}, "longer than a tracker keeps"),
    # forgetting faster than windows accumulate: NaN for ever (the 4 parameters need 12)
    ({"window": WINDOW, "half_life": 0.5}, {"y": [1.0, 2.0], "u": [1.0, 2.0]},
     "half_life 0.5 s is too short for the window 0.1875 s"),
])
def test_bad_input_one_line(kwargs, chunk, message):
    """One line, at construction or at the first update (where the rate is known)."""
    with pytest.raises(InputDataError, match=message) as info:
        tracker = Tracker(EQUATION, PARAMETERS, **({"rate": 80.0} | kwargs
                                                   if "time" not in kwargs else kwargs))
        tracker.update(chunk)
    assert "\n" not in str(info.value)


def test_a_half_life_of_no_consequence_is_no_forgetting():
    """2**(-stride/h) rounds to 1 for a huge half-life: nothing to refuse (the check of
    short half-lives took it as none), the estimates of no forgetting."""
    record, _ = linear_offsets(0, n=1500)
    long = Tracker(EQUATION, PARAMETERS, time="t", window=WINDOW, half_life=1e300)
    np.testing.assert_array_equal(long.update(record).values[-1], Tracker(
        EQUATION, PARAMETERS, time="t", window=WINDOW).update(record).values[-1])
