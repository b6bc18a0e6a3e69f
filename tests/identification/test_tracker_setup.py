"""Refusals of a tracker's configuration once the stream shows its step."""

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
