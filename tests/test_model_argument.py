"""One API shape for a model of your own: ``estimate``, ``OnlineEstimator`` and ``identify``
take the same model argument (a built-in name, equation text with its parameters, or a
compiled model) and the same record form (named columns, a time column or a rate)."""

import numpy as np
import pytest

import algid
from algid.errors import InputDataError, ModelError

EQUATION = "y'' + B*y' + K*y = G*u + d"
PARAMETERS = "B K G d"
TRUE = {"B": 2.0, "K": 3.0, "G": 1.5, "d": 0.25}
RATE = 1000.0


@pytest.fixture(scope="module")
def record():
    """An exact response of ``y'' + 2 y' + 3 y = 1.5 u + 0.25`` to a sine (5 s, 1 kHz)."""
    from scipy.signal import lsim

    t = np.arange(5000) / RATE
    u = np.sin(2.0 * t) + 0.5 * np.sin(7.0 * t)
    # the offset d is a constant input of the same plant
    _, y, _ = lsim(([1.0], [1.0, TRUE["B"], TRUE["K"]]), TRUE["G"] * u + TRUE["d"], t)
    return {"t": t, "u": u, "y": y}


@pytest.fixture(scope="module")
def compiled():
    pytest.importorskip("sympy")
    return algid.compile_equation(EQUATION, PARAMETERS)


def test_estimate_takes_a_record_and_equation_text(record, compiled):
    by_text = algid.estimate(record, EQUATION, PARAMETERS, engine="numpy")
    by_module = algid.estimate(record, compiled, engine="numpy")
    by_arrays = algid.estimate(record["t"], signals={"u": record["u"], "y": record["y"]},
                               model=compiled, engine="numpy")
    for name in TRUE:
        assert np.array_equal(getattr(by_text, name), getattr(by_arrays, name), equal_nan=True)
        assert np.array_equal(getattr(by_module, name), getattr(by_arrays, name), equal_nan=True)
    # lsim interpolates the input linearly: the data are exact to about 1e-6
    assert by_text.final() == pytest.approx(TRUE, rel=1e-3)


def test_a_rate_replaces_the_time_column(record):
    with_time = algid.estimate(record, EQUATION, PARAMETERS, engine="numpy")
    with_rate = algid.estimate({"u": record["u"], "y": record["y"]}, EQUATION, PARAMETERS,
                               rate=RATE, engine="numpy")
    assert np.array_equal(with_time.K, with_rate.K, equal_nan=True)


def test_the_paper_model_takes_the_record_form_too(record):
    t, f, x = record["t"], record["u"], record["y"]
    arrays = algid.estimate(t, f, x, engine="numpy")
    named = algid.estimate({"time": t, "f": f, "x": x}, engine="numpy")
    assert np.array_equal(arrays.B, named.B, equal_nan=True)


@pytest.mark.parametrize("chunk", [1, 7, 1000])
def test_a_stream_of_record_chunks_equals_the_batch(record, compiled, chunk):
    n = 1500 if chunk == 1 else 5000
    part = {name: values[:n] for name, values in record.items()}
    batch = algid.estimate(part, compiled, engine="numpy")
    online = algid.OnlineEstimator(EQUATION, PARAMETERS, rate=RATE, engine="numpy")
    got = [online.update({"u": part["u"][i:i + chunk], "y": part["y"][i:i + chunk]})
           for i in range(0, n, chunk)]
    for name in TRUE:
        streamed = np.concatenate([getattr(r, name) for r in got])
        assert np.array_equal(streamed, getattr(batch, name), equal_nan=True)


def test_identify_takes_a_compiled_model(record, compiled):
    by_text = algid.identify(record, EQUATION, PARAMETERS)
    by_module = algid.identify(record, compiled)
    assert by_module.parameters == by_text.parameters
    assert by_text.parameters == pytest.approx(TRUE, rel=1e-3)


def test_bad_model_arguments_are_refused_in_one_line(record, compiled):
    with pytest.raises(ModelError, match="needs its parameters"):
        algid.estimate(record, EQUATION)
    with pytest.raises(ModelError, match="not those of the compiled model"):
        algid.OnlineEstimator(compiled, "B K")
    with pytest.raises(ModelError, match="model must be"):
        algid.estimate(record, 3.0)
    with pytest.raises(InputDataError, match="no column 'y'"):
        algid.estimate({"t": record["t"], "u": record["u"]}, EQUATION, PARAMETERS)
    with pytest.raises(InputDataError, match="go with a record"):
        algid.estimate(record["t"], record["u"], record["y"], rate=RATE)
    with pytest.raises(InputDataError, match="without f, x or signals"):
        algid.OnlineEstimator(EQUATION, PARAMETERS, rate=RATE).update(record, signals={})
