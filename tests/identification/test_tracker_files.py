"""Saved trackers: damaged, altered and foreign files are refused in one line."""

import json
import zipfile

import numpy as np
import pytest
from benchmarks.synthetic_records import CUBIC_EQUATION, LINEAR_EQUATION, linear_offsets

from algid.errors import InputDataError
from algid.identification import _tracker_file
from algid.identification._tracker import Tracker

EQUATION, NAMES = LINEAR_EQUATION
WINDOW = 0.1875


def feed(tracker, record, start, stop, size=100):
    outs = [tracker.update({c: v[i:min(i + size, stop)] for c, v in record.items()})
            for i in range(start, stop, size)]
    return {key: np.concatenate([getattr(o, key) for o in outs])
            for key in ("t", "values", "stderr", "numerical_error", "alarms")}


@pytest.fixture(scope="module")
def saved(tmp_path_factory):
    """A tracker of the linear model saved mid-stream, and the record it streams."""
    record, _ = linear_offsets(3, n=700)
    path = tmp_path_factory.mktemp("saved") / "state.npz"
    tracker = Tracker(EQUATION, NAMES, time="t", window=WINDOW, half_life=1.0)
    feed(tracker, record, 0, 333)
    tracker.save(path)
    return path, record


def contents(path):
    with np.load(path, allow_pickle=False) as data:
        return {name: data[name] for name in data.files}


def rewrite(path, members, checksum=True):
    """Write ``members`` to ``path``; with ``checksum``, one that matches them (a file
    made by hand: only the checks of the state can refuse it)."""
    members = dict(members)
    if checksum:
        arrays = {k: v for k, v in members.items() if k.startswith("s/")}
        members["checksum"] = np.array(_tracker_file._checksum(str(members["header"]),
                                                               arrays))
    with open(path, "wb") as f:
        np.savez(f, **members)
    return path


def refused(path, match):
    with pytest.raises(InputDataError, match=match) as info:
        Tracker.load(path)
    message = str(info.value)
    assert "\n" not in message and str(path) in message
    return message


def test_save_and_load_continue_bit_for_bit(saved, tmp_path):
    path, record = saved
    whole = feed(Tracker(EQUATION, NAMES, time="t", window=WINDOW, half_life=1.0),
                 record, 0, 700)
    restored = Tracker.load(path)
    second = feed(restored, record, 333, 700)
    first = whole["t"] < second["t"][0]
    for key in ("t", "values", "stderr", "numerical_error"):
        joined = np.concatenate([whole[key][first], second[key]])
        assert np.array_equal(joined, whole[key], equal_nan=True), key
    # loaded, every array holds the saved bytes
    loaded = Tracker.load(path)
    for key, value in contents(path).items():
        if key.startswith("s/"):
            assert loaded.state.flat()[key[2:]].tobytes() == value.tobytes(), key


def test_state_before_the_window_is_chosen(tmp_path):
    record, _ = linear_offsets(4, n=100)
    tracker = Tracker(EQUATION, NAMES, time="t", warmup=5.0)
    feed(tracker, record, 0, 100)
    assert not tracker.state.configured
    tracker.save(tmp_path / "warm.npz")
    restored = Tracker.load(tmp_path / "warm.npz")
    assert restored.state.flat().keys() == tracker.state.flat().keys()
    assert np.array_equal(restored.state.warmup.signals["y"], tracker.state.warmup.signals["y"])


@pytest.mark.parametrize("key", ["U", "ring_rows", "buf_t", "buf:y", "fac:0", "R"])
def test_array_cut_to_half_its_rows(saved, tmp_path, key):
    members = contents(saved[0])
    array = members[f"s/{key}"]
    members[f"s/{key}"] = array[:len(array) // 2]
    message = refused(rewrite(tmp_path / "cut.npz", members), "array|counters")
    assert repr(key) in message or "counters" in message


def test_cut_array_without_a_new_checksum(saved, tmp_path):
    members = contents(saved[0])
    members["s/U"] = members["s/U"][:len(members["s/U"]) // 2]
    refused(rewrite(tmp_path / "cut.npz", members, checksum=False), "checksum")


def test_altered_equation(saved, tmp_path):
    members = contents(saved[0])
    header = str(members["header"])
    assert "K*y " in header
    members["header"] = np.array(header.replace("K*y ", "K*y**3 "))
    refused(rewrite(tmp_path / "altered.npz", members, checksum=False),
            "altered after it was saved")


def test_flipped_byte_in_an_array(saved, tmp_path):
    data = bytearray(saved[0].read_bytes())
    members = contents(saved[0])
    needle = members["s/R"].tobytes()[8:24]
    at = data.find(needle)
    assert at > 0
    data[at + 3] ^= 0x10
    (tmp_path / "flipped.npz").write_bytes(bytes(data))
    refused(tmp_path / "flipped.npz", "not a saved tracker .Bad CRC")   # zip's own check
    # the archive rewritten around the flipped bit: the checksum's refusal
    flipped = members["s/R"].copy()
    flipped.reshape(-1).view(np.uint8)[11] ^= 0x10
    members["s/R"] = flipped
    refused(rewrite(tmp_path / "rewritten.npz", members, checksum=False),
            "altered after it was saved")


@pytest.mark.parametrize("fraction", [0.1, 0.5, 0.99])
def test_truncated_file(saved, tmp_path, fraction):
    data = saved[0].read_bytes()
    (tmp_path / "short.npz").write_bytes(data[:int(len(data) * fraction)])
    refused(tmp_path / "short.npz", "not a saved tracker")


def test_header_without_config(saved, tmp_path):
    members = contents(saved[0])
    header = json.loads(str(members["header"]))
    del header["config"]
    members["header"] = np.array(json.dumps(header))
    refused(rewrite(tmp_path / "noconfig.npz", members), "config")


def test_config_of_wrong_type(saved, tmp_path):
    members = contents(saved[0])
    header = json.loads(str(members["header"]))
    header["config"]["window"] = "long"
    members["header"] = np.array(json.dumps(header))
    refused(rewrite(tmp_path / "badconfig.npz", members), "config 'window'")


def test_plain_npy_and_other_files(tmp_path):
    np.save(tmp_path / "plain.npy", np.zeros(3))
    refused(tmp_path / "plain.npy", "not a saved tracker")
    (tmp_path / "empty.npz").write_bytes(b"")
    refused(tmp_path / "empty.npz", "not a saved tracker")
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    refused(tmp_path / "other.npz", "no header")
    with zipfile.ZipFile(tmp_path / "compressed.npz", "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("header.npy", b"0" * 100)
    refused(tmp_path / "compressed.npz", "not a saved tracker")
    refused(tmp_path / "missing.npz", "file not found")


def test_arrays_of_another_model(saved, tmp_path):
    record, _ = linear_offsets(3, n=400)
    equation, names = CUBIC_EQUATION
    other = Tracker(equation, names, time="t", window=WINDOW, half_life=1.0)
    feed(other, record, 0, 333)
    other.save(tmp_path / "cubic.npz")
    members = {k: v for k, v in contents(tmp_path / "cubic.npz").items()
               if k.startswith("s/")}
    members["header"] = contents(saved[0])["header"]
    refused(rewrite(tmp_path / "mixed.npz", members), "not this tracker's state|shape")
    members = contents(saved[0])
    del members["s/fac:0"]
    refused(rewrite(tmp_path / "missing.npz", members), "missing fac:0")


@pytest.mark.parametrize("change, match", [
    (lambda a: a.astype(complex), "complex128"),
    (lambda a: a[..., None], "dimension"),
    (lambda a: a.astype(np.float32), "float32"),
    (lambda a: np.where(a == a.flat[0], np.inf, a), "non-finite"),
])
def test_array_of_another_dtype_or_dimension(saved, tmp_path, change, match):
    members = contents(saved[0])
    members["s/U"] = change(members["s/U"])
    refused(rewrite(tmp_path / "changed.npz", members), match)


def test_counters_that_overrun_the_arrays(saved, tmp_path):
    members = contents(saved[0])
    header = json.loads(str(members["header"]))
    header["scalars"]["seg_ready"] += 1000
    members["header"] = np.array(json.dumps(header))
    refused(rewrite(tmp_path / "counters.npz", members), "counters")


def test_older_format_refused(saved, tmp_path):
    members = contents(saved[0])
    header = json.loads(str(members["header"]))
    header["format"] = "algid.Tracker/2"
    members = {k: v for k, v in members.items() if k != "checksum"}
    members["header"] = np.array(json.dumps(header))
    refused(rewrite(tmp_path / "old.npz", members, checksum=False), "format 'algid.Tracker/2'")


@pytest.mark.parametrize("key, value", [("ring_count", 2**70), ("seen", -1),
                                        ("configured", 1), ("row_valid", "yes")])
def test_scalars_out_of_range(saved, tmp_path, key, value):
    members = contents(saved[0])
    header = json.loads(str(members["header"]))
    header["scalars"][key] = value
    members["header"] = np.array(json.dumps(header))
    refused(rewrite(tmp_path / "scalar.npz", members), f"scalar '{key}'")
