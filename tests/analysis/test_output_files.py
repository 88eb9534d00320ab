"""Atomic output files: nothing half-written on failure, usual permissions on success."""
import os
import stat

import pytest

from analysis.errors import InputError
from analysis.output_files import atomic_path, prepare_out_dir, write_text


def test_failure_leaves_nothing(tmp_path):
    target = tmp_path / "table.csv"
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("boom")
    assert list(tmp_path.iterdir()) == []


def test_success_has_umask_permissions(tmp_path):
    target = tmp_path / "a.txt"
    write_text("x", target)
    mask = os.umask(0)
    os.umask(mask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~mask
    assert target.read_text() == "x"


def test_out_dir_that_is_a_file(tmp_path):
    f = tmp_path / "out"
    f.write_text("")
    with pytest.raises(InputError, match="is a file"):
        prepare_out_dir(f)
