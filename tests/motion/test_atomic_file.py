"""motion.osim.atomic_file: the file appears whole or not at all, with the umask's permissions."""
import os
import stat

import pytest

from motion.osim.atomic_file import atomic_write


@pytest.fixture
def umask_027():
    old = os.umask(0o027)
    try:
        yield
    finally:
        os.umask(old)


def test_success_renames_into_place_with_umask_permissions(tmp_path, umask_027):
    target = tmp_path / "model.osim"
    with atomic_write(target) as tmp:
        assert tmp.parent == tmp_path and tmp.name.startswith(".model.osim.") and tmp.suffix == ".part"
        assert not target.exists()                     # nothing at the name until the block ends
        tmp.write_text("<OpenSimDocument/>")
    assert target.read_text() == "<OpenSimDocument/>"
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~0o027    # = 0o640, as open() gives
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.osim"]


@pytest.mark.parametrize("error", [RuntimeError, KeyboardInterrupt])
def test_failure_leaves_the_old_file_and_no_temporary(tmp_path, error):
    target = tmp_path / "motion.mot"
    target.write_text("old")
    with pytest.raises(error):
        with atomic_write(target) as tmp:
            tmp.write_text("half")
            raise error("boom")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["motion.mot"]


def test_temporary_names_do_not_collide(tmp_path):
    target = tmp_path / "a.txt"
    with atomic_write(target) as first, atomic_write(target) as second:
        assert first != second
        first.write_text("1")
        second.write_text("2")
    assert target.read_text() == "1"                   # the outer block ends last
    assert [p.name for p in tmp_path.iterdir()] == ["a.txt"]
