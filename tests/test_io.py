"""Tests of algid.io.read_experiment on CSV/text and MATLAB files."""

import numpy as np
import pytest
import scipy.io

from algid.errors import AlgidError, DataFileError, InputDataError
from algid.io import read_columns, read_experiment


def write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture
def good_csv(tmp_path):
    return write(tmp_path / "data.csv", "t,f,x\n0,1,0\n0.1,1,0.005\n0.2,1,0.02\n")


# ---------------------------------------------------------------------- CSV


def test_read_csv(good_csv):
    t, f, x = read_experiment(good_csv)
    np.testing.assert_array_equal(t, [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(f, [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(x, [0.0, 0.005, 0.02])
    for arr in (t, f, x):
        assert arr.dtype == np.float64


def test_read_csv_accepts_str_path_and_column_order(tmp_path):
    path = write(tmp_path / "d.CSV", "x , time , force\n1, 0, 5\n2, 1, 6\n")
    t, f, x = read_experiment(str(path), time="time", input="force", output="x")
    np.testing.assert_array_equal(t, [0, 1])
    np.testing.assert_array_equal(f, [5, 6])
    np.testing.assert_array_equal(x, [1, 2])


def test_read_silverbox_style_header_with_rate(tmp_path):
    rows = "".join(f"{0.1 * i:.6f},{0.2 * i:.6f},\n" for i in range(5))
    path = write(tmp_path / "SNLS80mV.csv", '"V1","V2",\n' + rows)
    t, f, x = read_experiment(path, input="V1", output="V2", rate=10.0)
    np.testing.assert_allclose(t, np.arange(5) / 10.0)
    np.testing.assert_allclose(f, 0.1 * np.arange(5))
    np.testing.assert_allclose(x, 0.2 * np.arange(5))


def test_rate_ignores_time_argument(tmp_path):
    path = write(tmp_path / "d.csv", "f,x\n1,2\n3,4\n")
    t, _, _ = read_experiment(path, time="does-not-exist", rate=2)
    np.testing.assert_array_equal(t, [0.0, 0.5])


def test_read_tab_and_whitespace_separated_txt(tmp_path):
    tab = write(tmp_path / "tab.txt", "t\tf\tx\n0\t1\t2\n1\t3\t4\n")
    spaces = write(tmp_path / "sp.txt", "# comment line\nt   f  x\n0 1 2\n\n1 3 4\n")
    for path in (tab, spaces):
        t, f, x = read_experiment(path)
        np.testing.assert_array_equal(t, [0, 1])
        np.testing.assert_array_equal(f, [1, 3])
        np.testing.assert_array_equal(x, [2, 4])


def test_utf8_bom_is_ignored(tmp_path):
    path = tmp_path / "bom.csv"
    path.write_bytes("\ufefft,f,x\n0,1,2\n".encode("utf-8"))
    t, _, _ = read_experiment(path)
    np.testing.assert_array_equal(t, [0])


def test_nan_cell_is_left_to_validation(tmp_path):
    path = write(tmp_path / "d.csv", "t,f,x\n0,1,nan\n1,1,2\n")
    _, _, x = read_experiment(path)
    assert np.isnan(x[0])


def test_missing_column_lists_available(tmp_path):
    path = write(tmp_path / "data.csv", "t,f,y\n0,1,2\n")
    with pytest.raises(DataFileError) as info:
        read_experiment(path)
    assert str(info.value) == f"{path}: column 'x' not found (columns: t, f, y)"


def test_missing_time_column_suggests_rate(tmp_path):
    path = write(tmp_path / "data.csv", '"V1","V2",\n1,2,\n')
    with pytest.raises(DataFileError) as info:
        read_experiment(path, input="V1", output="V2")
    message = str(info.value)
    assert message.startswith(f"{path}: time column 't' not found (columns: V1, V2)")
    assert "--rate" in message


def test_non_numeric_cell_names_column_and_line(tmp_path):
    path = write(tmp_path / "data.csv", "t,f,x\n0,1,2\n1,1,2\n2,1,abc\n")
    with pytest.raises(DataFileError) as info:
        read_experiment(path)
    assert str(info.value) == f"{path}: column 'x', line 4: 'abc' is not a number"


def test_non_numeric_in_unused_column_is_ignored(tmp_path):
    path = write(tmp_path / "data.csv", "t,f,x,note\n0,1,2,start\n1,1,2,end\n")
    t, _, _ = read_experiment(path)
    assert t.size == 2


def test_empty_cell_names_column_and_line(tmp_path):
    path = write(tmp_path / "data.csv", "t,f,x\n0,1,2\n1,,2\n")
    with pytest.raises(DataFileError, match=r"column 'f', line 3: an empty cell is not a number"):
        read_experiment(path)


def test_row_with_missing_fields(tmp_path):
    path = write(tmp_path / "data.csv", "t,f,x\n0,1,2\n1,1\n")
    with pytest.raises(DataFileError, match="line 3 has 2 fields but the header has 3 columns"):
        read_experiment(path)


@pytest.mark.parametrize("text", ["", "\n\n  \n"])
def test_empty_file(tmp_path, text):
    path = write(tmp_path / "empty.csv", text)
    with pytest.raises(DataFileError) as info:
        read_experiment(path)
    assert str(info.value) == f"{path}: file is empty"


def test_header_only_file(tmp_path):
    path = write(tmp_path / "head.csv", "t,f,x\n")
    with pytest.raises(DataFileError) as info:
        read_experiment(path)
    assert str(info.value) == f"{path}: no data rows after the header (line 1)"


def test_file_without_header(tmp_path):
    path = write(tmp_path / "nohead.csv", "0,1,2\n1,2,3\n")
    with pytest.raises(DataFileError, match="line 1 holds numbers, expected a header line"):
        read_experiment(path)


def test_missing_file(tmp_path):
    path = tmp_path / "missing.csv"
    with pytest.raises(DataFileError) as info:
        read_experiment(path)
    assert str(info.value) == f"{path}: file not found"


def test_directory(tmp_path):
    path = tmp_path / "dir.csv"
    path.mkdir()
    with pytest.raises(DataFileError, match="is a directory"):
        read_experiment(path)


def test_unknown_extension(tmp_path):
    path = write(tmp_path / "data.xlsx", "t,f,x\n0,1,2\n")
    with pytest.raises(DataFileError) as info:
        read_experiment(path)
    message = str(info.value)
    assert message.startswith(f"{path}: unknown file type (extension '.xlsx')")
    assert ".csv" in message and ".mat" in message


def test_binary_csv(tmp_path):
    path = tmp_path / "bin.csv"
    path.write_bytes(b"\xff\xfe\x00\x81garbage")
    with pytest.raises(DataFileError, match="not a UTF-8 text file"):
        read_experiment(path)


@pytest.mark.parametrize("rate", [0, -5, float("nan"), "fast"])
def test_bad_rate(good_csv, rate):
    with pytest.raises(InputDataError, match="rate must be"):
        read_experiment(good_csv, rate=rate)


def test_all_errors_are_value_errors(tmp_path):
    with pytest.raises(ValueError):
        read_experiment(tmp_path / "nope.csv")
    assert issubclass(DataFileError, AlgidError)


def test_messages_are_one_line(tmp_path):
    path = write(tmp_path / "data.csv", "a,b\n1,2\n")
    with pytest.raises(DataFileError) as info:
        read_experiment(path)
    assert "\n" not in str(info.value)


# ---------------------------------------------------------------------- MAT


def test_read_mat_column_vectors(tmp_path):
    path = tmp_path / "exp.mat"
    n = 20
    scipy.io.savemat(path, {
        "t": np.arange(n)[:, None] * 0.1,
        "f": np.ones((n, 1)),
        "x": np.arange(n, dtype=np.int32)[:, None],
    })
    t, f, x = read_experiment(path)
    assert t.shape == f.shape == x.shape == (n,)
    assert x.dtype == np.float64
    np.testing.assert_allclose(t, np.arange(n) * 0.1)
    np.testing.assert_array_equal(x, np.arange(n))


def test_read_mat_with_rate_and_names(tmp_path):
    path = tmp_path / "sb.mat"
    scipy.io.savemat(path, {"V1": np.arange(4.0), "V2": 2 * np.arange(4.0)})
    t, f, x = read_experiment(path, input="V1", output="V2", rate=4)
    np.testing.assert_allclose(t, [0, 0.25, 0.5, 0.75])
    np.testing.assert_array_equal(x, [0, 2, 4, 6])


def test_mat_lengths_are_not_checked_here(tmp_path):
    path = tmp_path / "exp.mat"
    scipy.io.savemat(path, {"t": np.arange(5.0), "f": np.ones(5), "x": np.ones(4)})
    t, _, x = read_experiment(path)
    assert (t.size, x.size) == (5, 4)


def test_mat_missing_variable_lists_available(tmp_path):
    path = tmp_path / "exp.mat"
    scipy.io.savemat(path, {"t": np.arange(5.0), "u": np.ones(5), "y": np.ones(5)})
    with pytest.raises(DataFileError) as info:
        read_experiment(path)
    assert str(info.value) == f"{path}: variable 'f' not found (variables: t, u, y)"


def test_mat_missing_time_suggests_rate(tmp_path):
    path = tmp_path / "exp.mat"
    scipy.io.savemat(path, {"f": np.ones(5), "x": np.ones(5)})
    with pytest.raises(DataFileError, match="time variable 't' not found.*--rate"):
        read_experiment(path)


@pytest.mark.parametrize(
    "value, what",
    [("hello", "is text"), ({"a": 1.0}, "is a struct"), (np.ones((3, 2)), "is a 3x2 matrix"),
     (np.zeros((0, 0)), "is empty"), (np.array([1 + 2j, 3j]), "is complex")],
)
def test_mat_non_numeric_variable(tmp_path, value, what):
    path = tmp_path / "exp.mat"
    scipy.io.savemat(path, {"t": np.arange(3.0), "f": np.ones(3), "x": value})
    with pytest.raises(DataFileError) as info:
        read_experiment(path)
    assert str(info.value).startswith(f"{path}: variable 'x' {what}")


def test_mat_corrupt_file(tmp_path):
    path = tmp_path / "bad.mat"
    path.write_text("this is not a MATLAB file")
    with pytest.raises(DataFileError) as info:
        read_experiment(path)
    assert str(info.value).startswith(f"{path}: not a readable MATLAB file")
    assert "\n" not in str(info.value)


# ---------------------------------------------------------------- gzip CSV


def test_gzip_csv_reads_as_the_plain_file(tmp_path, good_csv):
    import gzip

    packed = tmp_path / "data.csv.gz"
    packed.write_bytes(gzip.compress(good_csv.read_bytes()))
    for got, expected in zip(read_experiment(packed), read_experiment(good_csv)):
        np.testing.assert_array_equal(got, expected)
    assert sorted(read_columns(packed, ["f"], optional=["t"])) == ["f", "t"]


def test_shipped_silverbox_file_reads_from_its_path():
    from importlib import resources

    from algid import datasets

    with resources.as_file(resources.files("algid").joinpath("data", "SNLS80mV.csv.gz")) as p:
        t, f, x = read_experiment(p, input="V1", output="V2", rate=610.35)
    sb = datasets.silverbox()
    np.testing.assert_array_equal(f, sb.V1)
    np.testing.assert_array_equal(x, sb.V2)


def test_gzip_errors_are_one_line(tmp_path):
    broken = tmp_path / "broken.csv.gz"
    broken.write_bytes(b"t,f,x\n0,1,2\n")  # not compressed
    with pytest.raises(DataFileError, match=r"broken.csv.gz: not a readable gzip file \(") as info:
        read_experiment(broken)
    assert "\n" not in str(info.value)
    bare = write(tmp_path / "data.gz", "t,f,x\n")
    with pytest.raises(DataFileError, match=r"unknown file type \(extension '.gz'\); "
                                            r"supported: .*\.csv\.gz"):
        read_experiment(bare)


def test_gzip_csv_too_large_for_memory_is_refused_by_its_decompressed_size(
        tmp_path, monkeypatch):
    import gzip

    import algid._memory

    text = "t,f,x\n" + "0.5,1,2\n" * 20000
    packed = tmp_path / "big.csv.gz"
    packed.write_bytes(gzip.compress(text.encode()))
    assert packed.stat().st_size * 100 < len(text)  # the file's own size would pass
    monkeypatch.setattr(algid._memory, "available_memory", lambda: 6 * len(text) - 6)
    with pytest.raises(DataFileError, match="big.csv.gz: too large to read: its decompressed"):
        read_experiment(packed)
    monkeypatch.setattr(algid._memory, "available_memory", lambda: 6 * len(text))
    assert read_experiment(packed)[0].size == 20000


@pytest.mark.parametrize("row, words", [
    ("0.001,1,", "column 'x', line 3: an empty cell is not a number"),  # was: 2 fields
    ("0.001,1", "line 3 has 2 fields but the header has 3 columns"),
])
def test_an_empty_last_cell_is_named_as_such(tmp_path, row, words):
    path = tmp_path / "d.csv"
    path.write_text(f"t,f,x\n0,1,2\n{row}\n")
    with pytest.raises(DataFileError, match=words):
        read_columns(path, ["t", "f", "x"])
    path.write_text("t,f\n0,1,\n0.001,1,\n")  # a trailing delimiter on every line
    assert read_columns(path, ["t", "f"])["f"].tolist() == [1.0, 1.0]
