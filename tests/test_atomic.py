"""Atomic writes: a complete new file or the old one, never a partial file, and no temporary left behind."""

from __future__ import annotations

from pathlib import Path

import pytest

from searchrl.atomic import write_atomic, write_text_atomic


def test_write_replaces_the_file_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "out" / "result.yaml"
    write_text_atomic(target, "first\n")
    write_text_atomic(target, "second\n")
    assert target.read_text() == "second\n"
    assert [p.name for p in target.parent.iterdir()] == ["result.yaml"]


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
