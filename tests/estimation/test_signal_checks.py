"""Tests of algid._signal_checks: signal checks made before estimation."""

import numpy as np
import pytest

from algid._signal_checks import as_signal, check_experiment
from algid.errors import AlgidError, InputDataError


def experiment(n=100, h=1e-3):
    t = np.arange(n) * h
    f = np.ones(n)
    x = 0.5 * t**2
    return t, f, x


# ------------------------------------------------------------------ as_signal


def test_as_signal_returns_float64_1d():
    out = as_signal([1, 2, 3], name="x")
    assert out.dtype == np.float64
    assert out.shape == (3,)
    np.testing.assert_array_equal(out, [1.0, 2.0, 3.0])


def test_as_signal_accepts_object_array_of_numbers():
    out = as_signal(np.array([1, 2.5, np.float32(3)], dtype=object), name="x")
    np.testing.assert_array_equal(out, [1.0, 2.5, 3.0])


def test_errors_are_value_errors():
    assert issubclass(InputDataError, AlgidError)
    assert issubclass(InputDataError, ValueError)


@pytest.mark.parametrize(
    "bad, what",
    [(np.nan, "NaN"), (np.inf, "inf"), (-np.inf, "-inf")],
)
def test_as_signal_non_finite_names_signal_and_row(bad, what):
    values = np.arange(30.0)
    values[17] = bad
    values[20] = bad
    with pytest.raises(InputDataError) as info:
        as_signal(values, name="x")
    assert str(info.value) == (f"signal 'x' has {what} at row 17; the estimator needs every "
                               f"sample (identify takes NaN as a gap)")


def test_as_signal_not_1d():
    with pytest.raises(InputDataError, match=r"signal 'f' has shape \(3, 2\): give one 1-D array"):
        as_signal(np.zeros((3, 2)), name="f")


def test_as_signal_scalar():
    with pytest.raises(InputDataError,
                       match=r"signal 'f' is one number \(1.0\): give one 1-D array"):
        as_signal(1.0, name="f")


def test_as_signal_empty():
    with pytest.raises(InputDataError, match="signal 'x' is empty"):
        as_signal([], name="x")


def test_as_signal_non_numeric_names_row():
    with pytest.raises(InputDataError, match="signal 'x' is not numeric: row 2 holds 'abc'"):
        as_signal([1.0, 2.0, "abc", 4.0], name="x")


def test_as_signal_text_array_names_first_non_number():
    with pytest.raises(InputDataError, match="row 1 holds 'x1'"):
        as_signal(np.array(["1.5", "x1", "2"]), name="x")
    with pytest.raises(InputDataError, match=r"holds numbers stored as text \(row 0: '1.5'\)"):
        as_signal(np.array(["1.5", "2"]), name="x")


def test_as_signal_none_is_not_numeric():
    with pytest.raises(InputDataError, match="row 1 holds None"):
        as_signal([1.0, None], name="x")


def test_as_signal_ragged():
    with pytest.raises(InputDataError, match="signal 'x' is not a 1-D array"):
        as_signal([[1.0, 2.0], [3.0]], name="x")


def test_as_signal_complex():
    with pytest.raises(InputDataError, match="signal 'x' is complex; give real measurements"):
        as_signal(np.array([1.0, 1j, 2.0]), name="x")


def test_messages_are_one_line():
    values = np.zeros(20)
    values[3] = np.nan
    with pytest.raises(InputDataError) as info:
        as_signal(values, name="x")
    assert "\n" not in str(info.value)


# ----------------------------------------------------------- check_experiment


def test_check_experiment_ok_returns_step():
    t, f, x = experiment(n=50, h=0.01)
    t2, f2, x2, h = check_experiment(list(t), f, x)
    assert h == pytest.approx(0.01)
    for arr in (t2, f2, x2):
        assert arr.dtype == np.float64 and arr.shape == (50,)


def test_check_experiment_nan_uses_names():
    t, f, x = experiment()
    x[17] = np.nan
    with pytest.raises(InputDataError, match="signal 'V2' has NaN at row 17"):
        check_experiment(t, f, x, names=("time", "V1", "V2"))


def test_check_experiment_inf_in_input():
    t, f, x = experiment()
    f[5] = np.inf
    with pytest.raises(InputDataError, match="signal 'f' has inf at row 5"):
        check_experiment(t, f, x)


def test_check_experiment_lengths_differ():
    t, f, x = experiment()
    with pytest.raises(InputDataError) as info:
        check_experiment(t, f, x[:-3])
    message = str(info.value)
    assert "different lengths" in message
    assert "x: 97" in message and "t: 100" in message


def test_check_experiment_too_few_samples():
    t, f, x = experiment(n=10)
    with pytest.raises(InputDataError, match="only 10 samples: at least 16 are needed"):
        check_experiment(t, f, x)


def test_check_experiment_min_samples_is_configurable():
    t, f, x = experiment(n=10)
    check_experiment(t, f, x, min_samples=10)
    with pytest.raises(InputDataError, match="at least 2"):
        check_experiment(t[:1], f[:1], x[:1], min_samples=0)


def test_check_experiment_time_not_increasing():
    t, f, x = experiment()
    t[41] = t[40]
    with pytest.raises(InputDataError) as info:
        check_experiment(t, f, x)
    message = str(info.value)
    assert message == "time 't' does not increase at row 41: 0.04 after 0.04"


def test_check_experiment_time_decreasing():
    t, f, x = experiment()
    t = t[::-1].copy()
    with pytest.raises(InputDataError, match="does not increase at row 1"):
        check_experiment(t, f, x)


def test_check_experiment_non_uniform_sampling():
    t, f, x = experiment()
    t[60:] += 0.5e-3  # one step of 1.5 ms instead of 1 ms
    with pytest.raises(InputDataError) as info:
        check_experiment(t, f, x)
    message = str(info.value)
    assert message.startswith("time 't' is not uniformly sampled: step 0.0015 at row 60 "
                              "where 0.001 is expected")
    assert message.endswith("the estimator needs uniform sampling (resample first)")


def test_check_experiment_non_uniform_names_jump_row():
    n = 1001
    t = np.arange(n) * 1e-3
    t[700] += 0.3e-3  # one sample late
    with pytest.raises(InputDataError) as info:
        check_experiment(t, np.ones(n), np.ones(n))
    assert "step 0.0013 at row 700" in str(info.value)
    assert "where 0.001 is expected" in str(info.value)


def test_check_experiment_slow_drift_is_refused():
    n = 1001
    t = np.cumsum(np.linspace(1e-3, 1.01e-3, n)) - 1e-3  # steps grow by 1 %
    with pytest.raises(InputDataError, match="not uniformly sampled"):
        check_experiment(t, np.ones(n), np.ones(n))


def test_check_experiment_tiny_jitter_is_uniform():
    t, f, x = experiment(n=1000)
    rng = np.random.default_rng(0)
    t = t + rng.uniform(-1e-9, 1e-9, t.size) * 1e-3
    _, _, _, h = check_experiment(t, f, x)
    assert h == pytest.approx(1e-3, rel=1e-9)


def test_check_experiment_no_excitation():
    t, _, _ = experiment()
    with pytest.raises(InputDataError) as info:
        check_experiment(t, np.zeros(100), np.zeros(100))
    assert str(info.value) == "no excitation: input 'f' and output 'x' are both zero"


def test_check_experiment_free_response_is_excitation():
    t, _, x = experiment()
    _, f_checked, x_checked, _ = check_experiment(t, np.zeros(100), x)
    np.testing.assert_array_equal(f_checked, 0.0)
    np.testing.assert_array_equal(x_checked, x)
