"""Refusals of a tracker's configuration once the stream shows its step."""

import numpy as np
import pytest
from benchmarks.synthetic_records import LINEAR_EQUATION, linear_offsets

import algid
from algid.identification._tracker import TrackerSetupError


@pytest.mark.parametrize("rate, accepted", [(5.0, False), (1e3, False), (2.0, True),
                                            (1e-3, True)])
def test_a_false_alarm_rate_beyond_one_per_two_tests_is_refused(rate, accepted):
    """Beyond one alarm per two tests (0.19 s here) the threshold was tuned to another rate
    (that of two tests), silently."""
    record, _ = linear_offsets(0, n=800)
    tracker = algid.Tracker(*LINEAR_EQUATION, window=0.1875, false_alarm_rate=rate)
    if accepted:
        assert len(tracker.update(record)) > 0
        return
    with pytest.raises(TrackerSetupError, match=r"more than one alarm in two tests \(every "
                                                r"[0-9.]+ s\); use at most [0-9.]+"):
        tracker.update(record)


def test_a_setup_refusal_leaves_the_tracker_as_it_was():
    """The refusal came after the state was marked configured: every later call raised an
    AttributeError."""
    record, _ = linear_offsets(0, n=800)
    tracker = algid.Tracker(*LINEAR_EQUATION, window=0.1875, false_alarm_rate=1e3)
    for rows in (slice(0, 400), slice(400, 800)):
        with pytest.raises(TrackerSetupError, match="more than one alarm in two tests"):
            tracker.update({k: v[rows] for k, v in record.items()})
        assert not tracker.state.configured and tracker.state_size() > 0


def test_a_rate_beside_a_named_time_column_must_agree_with_it():
    """With time= and rate= the rate was used and the column's steps made every row a gap:
    no output, no word."""
    record, _ = linear_offsets(0, n=800)
    with pytest.raises(algid.InputDataError, match="contradicts time column 't'"):
        algid.Tracker(*LINEAR_EQUATION, window=0.1875, time="t", rate=160).update(record)
    out = algid.Tracker(*LINEAR_EQUATION, window=0.1875, time="t", rate=80).update(record)
    assert len(out) > 0


@pytest.mark.parametrize(("time", "rate"), [(None, 160), ("t", 100)])
def test_one_row_chunks_stamped_against_the_rate_are_refused(tmp_path, time, rate):
    """A stream of one-row chunks has no step of its own: stamps at 80 Hz beside
    rate=160 were taken as 160 Hz (every estimate off by a factor) without a word.  With
    time= the column's times are used, and a step of two or more is a gap; 1.25 steps
    is neither."""
    record, _ = linear_offsets(0, n=40)
    rows = [{k: v[i:i + 1] for k, v in record.items()} for i in range(40)]
    tracker = algid.Tracker(*LINEAR_EQUATION, window=0.1875, time=time, rate=rate)
    tracker.update(rows[0])
    with pytest.raises(algid.InputDataError, match=rf"rate {rate} Hz contradicts time column "
                       r"'t': stream sample 1 is stamped 0\.0125 s after the one before"):
        tracker.update(rows[1])
    agreeing = algid.Tracker(*LINEAR_EQUATION, window=0.1875, time=time, rate=80)
    for row in rows[:10]:
        agreeing.update(row)
    if time is None:   # the last stamp is the stream's state: saved, and checked on
        agreeing.save(tmp_path / "state.npz")
        loaded = algid.Tracker.load(tmp_path / "state.npz")
        with pytest.raises(algid.InputDataError, match="stream sample 10 is stamped"):
            loaded.update(rows[12])   # (two rows missing: the count's times are wrong)
        loaded.update(rows[10])


def test_last_reports_the_stream_s_last_window_end():
    record, _ = linear_offsets(0, n=800)
    every = algid.Tracker(*LINEAR_EQUATION, window=0.1875, every=1.0)
    first = every.update({k: v[:700] for k, v in record.items()})
    end = every.update({k: v[700:] for k, v in record.items()}, last=True)
    whole = algid.Tracker(*LINEAR_EQUATION, window=0.1875).update(record)
    assert first.t[-1] < 8.5 < end.t[0] and end.t[-1] == whole.t[-1]
    completed = whole.t >= end.t[0]   # every window end the last chunk completed
    assert np.array_equal(end.t, whole.t[completed])
    assert np.array_equal(end.values, whole.values[completed], equal_nan=True)


def test_an_empty_first_chunk_waits_for_samples():
    """It was an IndexError (the warm-up's last time of no samples)."""
    tracker = algid.Tracker("y' + a*y = b*u", "a b", rate=100)
    assert len(tracker.update({"y": np.empty(0), "u": np.empty(0)})) == 0
