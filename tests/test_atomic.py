"""Outputs are written whole or not at all, with ordinary file permissions."""
import os
import stat

import pytest

from kinid.files import atomic_write, write_text
from kinid.errors import DataError


def test_new_file_gets_the_umask_mode(tmp_path):
    old = os.umask(0o022)
    try:
        write_text(tmp_path / "out.csv", "a,b\n")
    finally:
        os.umask(old)
    assert stat.S_IMODE(os.stat(tmp_path / "out.csv").st_mode) == 0o644
    assert (tmp_path / "out.csv").read_text() == "a,b\n"


def test_existing_file_keeps_its_mode(tmp_path):
    target = tmp_path / "fit.json"
    target.write_text("old")
    os.chmod(target, 0o640)
    write_text(target, "new")
    assert stat.S_IMODE(os.stat(target).st_mode) == 0o640
    assert target.read_text() == "new"


def test_failure_leaves_the_old_file_and_no_temporary(tmp_path):
    target = tmp_path / "pred.csv"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_write(target) as f:
            f.write("half")
            raise RuntimeError("interrupted")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["pred.csv"]


def test_missing_folder_is_a_clear_error(tmp_path):
    with pytest.raises(DataError, match="output folder .* does not exist"):
        write_text(tmp_path / "nope" / "x.txt", "x")
