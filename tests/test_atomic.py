"""Atomic writes: a complete new file or the old one, never a partial file, and no temporary left behind."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from searchrl.atomic import (
    check_writable,
    is_temporary,
    remove_temporaries,
    temporary_path,
    write_atomic,
    write_text_atomic,
)


def test_write_replaces_the_file_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "out" / "result.yaml"
    write_text_atomic(target, "first\n")
    write_text_atomic(target, "second\n")
    assert target.read_text() == "second\n"
    assert [p.name for p in target.parent.iterdir()] == ["result.yaml"]


def test_the_temporary_is_flushed_to_disk_before_it_replaces_the_target(tmp_path, monkeypatch):
    """A rename can reach the disk before the data it names: without an fsync of the temporary first, a machine
    crash can leave the target empty."""
    events = []
    real_fsync, real_replace = os.fsync, os.replace

    def fsync(fd):
        events.append(("fsync", os.readlink(f"/proc/self/fd/{fd}")))
        real_fsync(fd)

    def replace(src, dst):
        events.append(("replace", str(src)))
        real_replace(src, dst)

    monkeypatch.setattr(os, "fsync", fsync)
    monkeypatch.setattr(os, "replace", replace)
    target = tmp_path / "result.yaml"
    write_text_atomic(target, "data\n")
    tmp = str(temporary_path(target))
    assert ("replace", tmp) in events and ("fsync", tmp) in events
    assert events.index(("fsync", tmp)) < events.index(("replace", tmp))
    assert events[-1] == ("fsync", str(tmp_path))  # then the folder, so the rename itself survives a crash


def test_a_failed_write_keeps_the_old_file(tmp_path):
    target = tmp_path / "result.parquet"
    write_text_atomic(target, "complete\n")

    def interrupted(tmp: Path) -> None:
        tmp.write_text("half")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomic(target, interrupted)
    assert target.read_text() == "complete\n"
    assert [p.name for p in tmp_path.iterdir()] == ["result.parquet"]


def test_write_makes_the_missing_folders(tmp_path):
    target = tmp_path / "a" / "b" / "result.yaml"
    write_text_atomic(target, "x\n")
    assert target.read_text() == "x\n"


def test_temporaries_are_hidden_files_ending_in_tmp_and_only_they_are_removed(tmp_path):
    assert is_temporary(".cell.parquet.host.12.tmp") and is_temporary(".cell.12.tmp.parquet")  # now, and before
    assert not is_temporary("cell.parquet.tmp") and not is_temporary(".hidden.parquet") and not is_temporary("a.tmp")
    for name in (".n20_N1.parquet.h.1.tmp", ".n20_N2.parquet.h.1.tmp", "n20_N1.parquet", ".keep"):
        (tmp_path / name).write_text("x")
    assert [p.name for p in remove_temporaries(tmp_path, "n20_N1.parquet")] == [".n20_N1.parquet.h.1.tmp"]
    assert [p.name for p in remove_temporaries(tmp_path)] == [".n20_N2.parquet.h.1.tmp"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [".keep", "n20_N1.parquet"]
    assert remove_temporaries(tmp_path / "absent") == []


def test_a_temporary_removed_by_another_process_meanwhile_is_no_error(tmp_path, monkeypatch):
    gone = tmp_path / ".cell.parquet.h.1.tmp"  # listed, then deleted by someone else before this unlink
    monkeypatch.setattr(Path, "iterdir", lambda self: iter([gone]))
    assert remove_temporaries(tmp_path) == [gone]


def test_check_writable_names_the_path_and_what_is_wrong(tmp_path, monkeypatch):
    (tmp_path / "file").write_text("x")
    (tmp_path / "folder").mkdir()
    file, folder, under = tmp_path / "file", tmp_path / "folder", tmp_path / "file" / "sub" / "x.csv"
    cases = [(file, True, f"out={str(file)!r} is not allowed: a folder (this is a file)"),
             (folder, False, f"out={str(folder)!r} is not allowed: a file path (this is a folder)"),
             (under, False, f"out={str(under)!r} is not allowed: {file} is a file, not a folder")]  # fmt: skip
    for path, is_folder, message in cases:
        with pytest.raises(ValueError) as err:
            check_writable(path, "out", folder=is_folder)
        assert str(err.value) == message
    check_writable(tmp_path / "new" / "deeper", "out", folder=True)  # to be made: checked at its nearest parent
    check_writable(tmp_path / "folder" / "x.csv", "out")
    check_writable(file, "out")  # an existing file is replaced: its folder is what must be writable
    asked = []
    monkeypatch.setattr(os, "access", lambda path, mode: asked.append((Path(path), mode)) or False)
    with pytest.raises(ValueError) as err:
        check_writable(tmp_path / "new" / "x.csv", "out")
    assert str(err.value) == f"out={str(tmp_path / 'new' / 'x.csv')!r} is not allowed: {tmp_path} is not writable"
    assert asked == [(tmp_path, os.W_OK | os.X_OK)]  # the nearest existing folder, to write into and enter
    with pytest.raises(ValueError, match="is not writable"):
        check_writable(folder, "out", folder=True)  # an existing folder: itself, not its parent
    assert asked[-1] == (folder, os.W_OK | os.X_OK)
