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
        "column 'f' of the chunk starting at stream sample 0":
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
    chunk = "column 'f' of the chunk starting at stream sample 0"
    assert messages[chunk] == f"{chunk} {gaps}"
    masked = np.ma.masked_array(record["f"], mask=np.arange(len(record["f"])) == 7)
    words = "has a masked sample at row 7 (1 masked): every sample is needed here"
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
    with pytest.raises(InputDataError,
                       match=rf"^the chunk starting at stream sample 0: {lengths}"):
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


def test_a_record_names_its_own_columns(record):
    """estimate on a record named the paper's t, f and x whatever the columns."""
    renamed = {"stamp": record["t"], "u": 0 * record["f"], "y": 0 * record["x"]}
    with pytest.raises(InputDataError, match="input 'u' and output 'y' are both zero"):
        algid.estimate(renamed, "y'' + B*y' + K*y = u", "B K", time="stamp")
    late = dict(renamed, u=record["f"], stamp=np.where(np.arange(len(record["t"])) > 1000,
                                                       record["t"] + 0.01, record["t"]))
    with pytest.raises(InputDataError, match="^time 'stamp' is not uniformly sampled"):
        algid.estimate(late, "y'' + B*y' + K*y = u", "B K", time="stamp")
    few = {k: v[:2] for k, v in record.items()}   # (it asked for 2, then for 12)
    with pytest.raises(InputDataError, match="^record 0: only 2 samples: at least 12 are"):
        algid.estimate(few, EQUATION, PARAMETERS)


def test_a_streams_chunk_is_named_by_its_first_sample(record):
    """The rows of a stream's chunks were numbered within the chunk, unnamed."""
    tracker = algid.Tracker(EQUATION, PARAMETERS, window=0.2)
    tracker.update({k: v[:1000] for k, v in record.items()})
    bad = {k: v[1000:1200].copy() for k, v in record.items()}
    bad["f"][7] = np.inf
    with pytest.raises(InputDataError, match=re.escape(
            "column 'f' of the chunk starting at stream sample 1000 has inf at row 7")):
        tracker.update(bad)
    online = algid.OnlineEstimator()
    online.update({k: v[:1000] for k, v in record.items()})
    back = {k: v[1000:1010].copy() for k, v in record.items()}
    back["t"][5] = 0.1
    with pytest.raises(InputDataError, match=re.escape(
            "the chunk starting at stream sample 1000: time column 't' does not increase at "
            "row 5")):
        online.update(back)
    online.update({k: float(v[1000]) for k, v in record.items()})   # one row: one sample


@pytest.mark.parametrize("value, words", [
    (True, "holds booleans"), (1 + 2j, "is complex"), (10**400, "too large for floating"),
    (np.datetime64("2020-01-01"), "holds dates or durations")])
def test_a_single_number_of_the_wrong_kind_is_named_as_such(record, value, words):
    """A chunk may be one sample; a boolean, complex, date or huge one was called "one
    number" (tracker) or raised an OverflowError (the paper's form)."""
    chunk = {"t": 0.0, "x": 1.0, "f": value}
    with pytest.raises(InputDataError, match=words):
        algid.Tracker(EQUATION, PARAMETERS, window=0.2).update(chunk)
    with pytest.raises(InputDataError, match=words):
        algid.OnlineEstimator().update(0.0, value, 1.0)


def test_dates_are_seconds_in_a_record_and_refused_in_a_stream(record):
    """A stream's chunk of dates became seconds from its own first sample (the second
    chunk "did not increase"); the paper's form refused durations as measurements."""
    pd = pytest.importorskip("pandas")
    stamps = pd.to_datetime("2026-01-01") + pd.to_timedelta(record["t"], unit="s")
    frame = pd.DataFrame({"f": record["f"], "x": record["x"]}, index=stamps)
    with pytest.raises(InputDataError, match="holds dates or durations: a stream's times"):
        algid.Tracker(EQUATION, PARAMETERS, window=0.2).update(frame.iloc[:100])
    with pytest.raises(InputDataError, match="holds dates or durations: a stream's times"):
        algid.OnlineEstimator().update(frame.iloc[:100])
    seconds = algid.estimate(record["t"], record["f"], record["x"])
    durations = algid.estimate(pd.to_timedelta(record["t"], unit="s").to_numpy(),
                               record["f"], record["x"])
    assert np.allclose(durations.B, seconds.B, rtol=1e-9, atol=1e-12, equal_nan=True)
