"""One wording of each refusal of bad samples, whichever entry point reads them.

The paper's form (``estimate(t, f, x)``, ``OnlineEstimator.update``), a record
(``estimate(record, ...)``, ``identify``) and a tracker's chunk name the place
differently (``signal 'f'``, ``record 0: column 'f'``, ``column 'f' of the chunk``); what
follows the place is the same words.
"""

import re

import numpy as np
import pytest

import algid
from algid.errors import InputDataError

EQUATION, PARAMETERS = "x'' + B*x' + K*x = f", "B K"


@pytest.fixture(scope="module")
def record():
    sim = algid.simulate("sine", m=1, c=2, k=3, noise_std=0.01, seed=0, duration=2.0)
    return {"t": sim.t, "f": sim.f, "x": sim.x}


def _at(values, row, value):
    out = np.array(values, dtype=float)
    out[row] = value
    return out


# bad input f -> the words after the place (identify and the tracker take NaN as a gap)
CASES = {
    "text": (lambda f: ["a"] * len(f), "is not numeric: row 0 holds 'a'"),
    "booleans": (lambda f: f > 0, "holds booleans, not measurements (convert with "
                                  ".astype(float) if 0 and 1 are meant)"),
    "complex": (lambda f: f + 1j, "is complex; give real measurements"),
    "2-D": (lambda f: np.c_[f, f], "has shape (2001, 2): give one 1-D array per signal"),
    "one number": (lambda f: 3.0, "is one number (3.0): give one 1-D array of samples"),
}


def _refusals(record, bad):
    """The messages of every entry point for the record with ``f`` replaced by ``bad``."""
    rec = dict(record, f=bad)
    calls = {
        "signal 'f'": lambda: algid.estimate(rec["t"], rec["f"], rec["x"]),
        "record 0: column 'f'": lambda: algid.estimate(rec, EQUATION, PARAMETERS),
        "signal 'f' of the chunk starting at stream sample 0":
            lambda: algid.OnlineEstimator().update(rec["t"], rec["f"], rec["x"]),
        "record 0: column 'f' ": lambda: algid.identify(rec, EQUATION, PARAMETERS),
        "column 'f' of the chunk":
            lambda: algid.Tracker(EQUATION, PARAMETERS, window=0.2).update(rec),
    }
    messages = {}
    for place, call in calls.items():
        with pytest.raises(InputDataError) as info:
            call()
        messages[place.strip()] = str(info.value)
    return messages


@pytest.mark.parametrize("case", CASES)
def test_every_entry_point_refuses_a_bad_signal_in_the_same_words(record, case):
    make, words = CASES[case]
    bad = make(record["f"])
    for place, message in _refusals(record, bad).items():
        if case == "one number" and "chunk" in place:   # a chunk may be one sample
            assert "different lengths" in message or words in message, message
            continue
        assert message.startswith(f"{place} {words}"), (place, message)


def test_infinite_and_missing_samples(record):
    bad = _at(record["f"], 500, np.inf)
    every = "has inf at row 500; the estimator needs every sample (identify takes NaN as a gap)"
    gaps = "has inf at row 500; a missing sample is NaN"
    messages = _refusals(record, bad)
    assert messages["signal 'f'"] == f"signal 'f' {every}"
    assert messages["record 0: column 'f'"].endswith(f"column 'f' {gaps}")  # identify's
    assert messages["column 'f' of the chunk"] == f"column 'f' of the chunk {gaps}"
    masked = np.ma.masked_array(record["f"], mask=np.arange(len(record["f"])) == 7)
    words = "has a masked sample at row 7 (1 masked): the estimator needs every sample"
    with pytest.raises(InputDataError, match="^" + re.escape(f"signal 'f' {words}")):
        algid.estimate(record["t"], masked, record["x"])
    with pytest.raises(InputDataError, match="^" + re.escape(f"record 0: column 'f' {words}")):
        algid.estimate(dict(record, f=masked), EQUATION, PARAMETERS)


def test_lengths_and_time_in_the_same_words(record):
    short = dict(record, f=record["f"][:-3])
    lengths = re.escape("signals have different lengths (")
    with pytest.raises(InputDataError, match=rf"^{lengths}t: 2001, f: 1998, x: 2001\)"):
        algid.estimate(short["t"], short["f"], short["x"])
    with pytest.raises(InputDataError, match=rf"^record 0: {lengths}"):
        algid.identify(short, EQUATION, PARAMETERS)
    with pytest.raises(InputDataError, match=rf"^the chunk: {lengths}"):
        algid.Tracker(EQUATION, PARAMETERS, window=0.2).update(short)
    back = dict(record, t=_at(record["t"], 100, 0.05))
    words = "does not increase at {} 100: 0.05 after 0.099"
    with pytest.raises(InputDataError, match="^time 't' " + words.format("row")):
        algid.estimate(back["t"], back["f"], back["x"])
    with pytest.raises(InputDataError, match="^record 0: time column 't' " + words.format("row")):
        algid.identify(back, EQUATION, PARAMETERS)
    with pytest.raises(InputDataError, match="^time 't' " + words.format("stream sample")):
        algid.OnlineEstimator().update(back["t"], back["f"], back["x"])
    with pytest.raises(InputDataError,
                       match="^time column 't' " + words.format("stream sample")):
        algid.Tracker(EQUATION, PARAMETERS, window=0.2).update(back)
    late = dict(record, t=np.where(np.arange(len(record["t"])) > 1000, record["t"] + 0.01,
                                   record["t"]))
    words = "is not uniformly sampled: step 0.011 at {} 1001 where 0.001 is expected"
    with pytest.raises(InputDataError, match="^time 't' " + words.format("row")):
        algid.estimate(late["t"], late["f"], late["x"])
    with pytest.raises(InputDataError, match="^time 't' " + words.format("stream sample")):
        algid.OnlineEstimator().update(late["t"], late["f"], late["x"])
