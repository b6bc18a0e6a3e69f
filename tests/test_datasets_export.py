"""algid.datasets.export and `algid datasets export`: no file replaced unasked, no link
followed."""

import os

import pytest

from algid import datasets
from algid.cli import main
from algid.errors import AlgidError

FILES = ["emps_estimation.csv", "emps_validation.csv", datasets.EXPORT_NOTE]


def test_an_existing_file_is_kept_without_overwrite(tmp_path):
    (tmp_path / "emps_validation.csv").write_text("mine\n")
    with pytest.raises(AlgidError, match="emps_validation.csv: exists; not replaced") as info:
        datasets.export("emps", tmp_path)
    assert "\n" not in str(info.value)
    assert sorted(os.listdir(tmp_path)) == ["emps_validation.csv"]   # nothing written
    assert (tmp_path / "emps_validation.csv").read_text() == "mine\n"
    written = datasets.export("emps", tmp_path, overwrite=True)
    assert (tmp_path / "emps_validation.csv").read_text().startswith("t,qm,vir,qg,F")
    assert [p.name for p in written] == FILES[:2]
    assert sorted(os.listdir(tmp_path)) == sorted(FILES)   # no temporary file left


def test_a_link_is_never_written_through(tmp_path):
    outside = tmp_path / "outside.txt"
    outside.write_text("precious\n")
    folder = tmp_path / "records"
    folder.mkdir()
    (folder / "emps_estimation.csv").symlink_to(outside)
    (folder / datasets.EXPORT_NOTE).symlink_to(tmp_path / "nowhere")   # dangling
    with pytest.raises(AlgidError, match="emps_estimation.csv: exists"):
        datasets.export("emps", folder)
    assert outside.read_text() == "precious\n"
    assert not (tmp_path / "nowhere").exists()
    datasets.export("emps", folder, overwrite=True)
    for name in FILES:   # the links replaced by regular files
        assert not (folder / name).is_symlink() and (folder / name).is_file()
    assert outside.read_text() == "precious\n"
    assert not (tmp_path / "nowhere").exists()


def test_both_records_into_one_folder(tmp_path):
    datasets.export("emps", tmp_path)
    datasets.export("silverbox", tmp_path)   # the same provenance note: kept as it is
    assert {"silverbox.csv", *FILES} <= set(os.listdir(tmp_path))


def test_command_line_refuses_then_forces(capsys, tmp_path):
    (tmp_path / "emps_estimation.csv").write_text("mine\n")
    code = main(["datasets", "export", "emps", str(tmp_path)])
    captured = capsys.readouterr()
    assert code == 2 and captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "emps_estimation.csv: exists" in lines[0] \
        and "--force" in lines[0]
    assert (tmp_path / "emps_estimation.csv").read_text() == "mine\n"
    code = main(["datasets", "export", "emps", str(tmp_path), "--force"])
    captured = capsys.readouterr()
    assert code == 0 and captured.out.count("wrote ") == 2
    assert (tmp_path / "emps_estimation.csv").read_text().startswith("t,qm,vir,qg,F")


def test_a_file_in_place_of_the_folder_is_named_as_such(tmp_path):
    """It was 'exists; not replaced without overwrite=True', even with overwrite=True."""
    (tmp_path / "records").write_text("not a folder")
    for overwrite in (False, True):
        with pytest.raises(AlgidError, match="records: not a folder"):
            datasets.export("emps", tmp_path / "records", overwrite=overwrite)
