"""The shipped benchmark records (algid.datasets): shapes, sampling, exact values."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from importlib import resources

import numpy as np
import pytest
from conftest import ROOT

from algid import datasets
from algid.errors import InputDataError

# the originals, beside the project's root (or beside a worktree's parent folder)
SHARED = next((folder for folder in (ROOT.parent / "shared" / "data",
                                     ROOT.parent.parent / "shared" / "data")
               if folder.is_dir()), ROOT.parent / "shared" / "data")
SHIPPED = (datasets.SILVERBOX_FILE, *datasets.EMPS_FILES.values(), "README.md")


def test_silverbox_shape_sampling_and_segments():
    sb = datasets.silverbox()
    assert list(sb) == ["V1", "V2"]
    assert sb.V1.shape == sb.V2.shape == (131072,) and sb.n_samples == 131072
    assert sb.V1.dtype == np.float64
    assert sb.fs == sb.rate == 610.35
    assert sb.segments == {"arrow": (100, 40575), "estimation": (40650, 105712),
                           "test": (105712, 127400)}
    arrow = sb.segment("arrow")
    assert arrow["V2"].shape == (40475,)
    np.testing.assert_array_equal(arrow["V1"], sb["V1"][100:40575])
    # the input is designed with zero mean; the measurement chain adds about 6 mV
    assert 0.004 < sb.V1.mean() < 0.008
    assert "Wigren" in sb.citation


def test_reachable_as_an_attribute_of_the_package():
    code = "import algid; print(algid.datasets.emps().n_samples)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "24841", done.stderr


def test_silverbox_arrays_are_fresh_copies():
    first = datasets.silverbox()
    first.V1[:] = 0.0
    assert datasets.silverbox().V1[0] != 0.0


@pytest.mark.parametrize("run", ["estimation", "validation"])
def test_emps_signals_and_constants(run):
    rec = datasets.emps(run)
    expected = ["t", "qm", "vir", "qg", "F"] + (["pulses_N"] if run == "validation" else [])
    assert sorted(rec) == sorted(expected)
    for key in expected:
        assert rec[key].shape == (24841,) and rec[key].dtype == np.float64
    step = np.diff(rec.t)
    assert np.all(np.abs(step - 1e-3) < 1e-7) and rec.rate == 1000.0
    assert rec.gtau == pytest.approx(35.15065188, rel=1e-9)
    assert (rec.kp, rec.kv) == (160.18, 243.45)
    np.testing.assert_array_equal(rec.F, rec.gtau * rec.vir)
    assert "Janot" in rec.citation


def test_emps_pulses_are_already_in_the_drive_command():
    """On the validation run vir = kv kp (qg - qm) - kv qm' + c pulses: the pulses are
    in the command, so F = gtau vir is the whole force (see the docstring of emps)."""
    rec = datasets.emps("validation")
    velocity = np.gradient(rec.qm, rec.t)
    columns = np.c_[rec.qg - rec.qm, velocity, rec.pulses_N]
    coef, *_ = np.linalg.lstsq(columns, rec.vir, rcond=None)
    residual = rec.vir - columns @ coef
    assert np.std(residual) < 0.05 * np.std(rec.vir)
    assert 0.5 < coef[2] < 2.0


def test_unknown_names_are_clear_errors():
    with pytest.raises(InputDataError, match="unknown EMPS run 'train'"):
        datasets.emps("train")
    with pytest.raises(InputDataError, match="no segment 'nope'"):
        datasets.silverbox().segment("nope")
    with pytest.raises(AttributeError, match="no signal or constant 'V3'"):
        getattr(datasets.silverbox(), "V3")  # noqa: B009 - the attribute access is the test


def test_silverbox_equals_the_shared_original():
    path = SHARED / "silverbox" / "SNLS80mV.csv"
    if not path.is_file():
        pytest.skip("the shared original records are not available")
    rows = path.read_text(encoding="ascii").splitlines()
    assert rows[0] == '"V1","V2",'
    values = np.array([[float(x) for x in row.split(",")[:2]] for row in rows[1:] if row])
    sb = datasets.silverbox()
    np.testing.assert_array_equal(sb.V1, values[:, 0])
    np.testing.assert_array_equal(sb.V2, values[:, 1])


@pytest.mark.parametrize("run", ["estimation", "validation"])
def test_emps_equals_the_shared_original(run):
    from scipy.io import loadmat

    path = SHARED / "emps" / datasets.EMPS_FILES[run]
    if not path.is_file():
        pytest.skip("the shared original records are not available")
    original = loadmat(path)
    rec = datasets.emps(run)
    for key in ("t", "qm", "vir", "qg") + (("pulses_N",) if run == "validation" else ()):
        np.testing.assert_array_equal(rec[key], original[key].ravel().astype(float))
    assert rec.gtau == original["gtau"].item()


def test_data_files_are_package_resources_and_small():
    folder = resources.files("algid").joinpath("data")
    total = 0
    for name in SHIPPED:
        resource = folder.joinpath(name)
        assert resource.is_file(), name
        total += len(resource.read_bytes())
    assert total < 3_000_000  # bytes: the package stays small


def test_wheel_contains_the_data_files(tmp_path):
    """Build a wheel from a copy of the sources; the data files must be inside."""
    source = tmp_path / "source"
    source.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, source / name)
    shutil.copytree(ROOT / "src", source / "src",
                    ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    done = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q",
         "-w", str(tmp_path / "dist"), str(source)],
        capture_output=True, text=True, timeout=600)
    if done.returncode != 0 and ("No matching distribution" in done.stderr
                                 or "Could not find a version" in done.stderr):
        pytest.skip("no package index to install the build backend from")
    assert done.returncode == 0, done.stderr[-2000:]
    (wheel,) = (tmp_path / "dist").glob("algid-*.whl")
    names = set(zipfile.ZipFile(wheel).namelist())
    for name in SHIPPED:
        assert f"algid/data/{name}" in names


def test_export_writes_exact_csv_files_that_the_readers_take(tmp_path):
    from algid.io import read_columns

    written = datasets.export("emps", tmp_path)
    assert [p.name for p in written] == ["emps_estimation.csv", "emps_validation.csv"]
    assert (tmp_path / datasets.EXPORT_NOTE).read_text() == \
        resources.files("algid").joinpath("data", "README.md").read_text()
    for path, run in zip(written, ("estimation", "validation")):
        record = datasets.emps(run)
        names = ["t", "qm", "vir", "qg", "F"] + (["pulses_N"] if run == "validation" else [])
        assert path.read_text().splitlines()[0] == ",".join(names)
        columns = read_columns(path, names)
        for name in names:
            np.testing.assert_array_equal(columns[name], record[name])

    written = datasets.export("silverbox", tmp_path / "sb")
    assert [p.name for p in written] == ["silverbox.csv", "silverbox_arrow.csv",
                                         "silverbox_estimation.csv", "silverbox_test.csv"]
    sb = datasets.silverbox()
    columns = read_columns(written[0], ["t", "V1", "V2"])
    np.testing.assert_array_equal(columns["V2"], sb.V2)
    np.testing.assert_array_equal(columns["t"], np.arange(sb.n_samples) / sb.rate)
    start, stop = sb.segments["test"]
    part = read_columns(written[3], ["t", "V1"])
    np.testing.assert_array_equal(part["V1"], sb.V1[start:stop])
    np.testing.assert_array_equal(part["t"], columns["t"][start:stop])


def test_export_of_an_unknown_name_is_a_clear_error(tmp_path):
    with pytest.raises(InputDataError,
                       match=r"unknown dataset 'wiener' \(known: silverbox, emps\)"):
        datasets.export("wiener", tmp_path)
