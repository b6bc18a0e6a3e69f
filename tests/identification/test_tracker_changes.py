"""algid.Tracker on records whose parameters change: tracking, alarms, false alarms,
coverage of the standard errors."""

import numpy as np
from benchmarks.change_records import cubic_change, friction_change
from benchmarks.synthetic_records import (
    CUBIC_EQUATION,
    FRICTION_EQUATION,
    LINEAR_EQUATION,
    linear_offsets,
)

from algid.identification._tracker import Tracker


def at(out, name, time):
    """The estimate of the last report at or before ``time``."""
    return out[name][np.searchsorted(out.t, time, side="right") - 1]


def test_friction_loop_mass_change():
    record, before, after = friction_change()
    equation, names = FRICTION_EQUATION
    out = Tracker(equation, names, half_life=1.0, every=0.05).update(record)
    assert abs(at(out, "M", 10.0) / before["M"] - 1) < 0.01
    assert abs(at(out, "M", 14.0) / after["M"] - 1) < 0.03
    assert len(out.alarms) >= 1 and 10.0 < out.alarms[0] < 12.0


def test_cubic_spring_stiffness_drop():
    record, before, after = cubic_change()
    equation, names = CUBIC_EQUATION
    out = Tracker(equation, names, time="t", half_life=1.0, every=0.05).update(record)
    assert abs(at(out, "K", 25.0) / before["K"] - 1) < 0.01
    assert abs(at(out, "K", 29.0) / after["K"] - 1) < 0.01
    assert len(out.alarms) >= 1 and 25.0 < out.alarms[0] < 27.0


def test_false_alarm_rate_as_designed():
    """Stationary records: the alarms count within a factor 2 of the design rate (a
    high design rate, so that 150 s of stream hold about 70 alarms)."""
    equation, names = LINEAR_EQUATION
    alarms, duration = 0, 0.0
    for seed in range(3):
        record, _ = linear_offsets(seed, n=4400)
        out = Tracker(equation, names, time="t", window=0.1875, false_alarm_rate=0.5,
                      every=100.0).update(record)
        alarms += len(out.alarms)
        duration += record["t"][-1] - 5.0   # the first tested windows come after ~5 s
    assert 0.5 < alarms / (0.5 * duration) < 2.0


def test_coverage_with_and_without_forgetting():
    """The truth within two (standard + numerical) errors at >= 90 % of checkpoints."""
    equation, names = LINEAR_EQUATION
    for half_life in (None, 2.0):
        inside = []
        for seed in range(10):
            record, truth = linear_offsets(seed, n=1600)
            out = Tracker(equation, names, time="t", window=0.1875, half_life=half_life,
                          every=2.0).update(record)
            truth = np.array([truth[p] for p in names.split()])
            ok = np.isfinite(out.values[:, 0])
            error = np.hypot(out.stderr[ok], out.numerical_error[ok])
            inside.append(np.abs(out.values[ok] - truth) <= 2 * error)
        assert np.concatenate(inside).mean() >= 0.9, half_life
