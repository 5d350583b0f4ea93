"""Atomic file writes: write beside the target, then `os.replace`, so an interruption never leaves a partial
file where a complete one is expected."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path


def write_atomic(path: str | Path, write: Callable[[Path], None]) -> Path:
    """Call `write(tmp)` to produce a temporary file next to `path`, fsync it, then move it over `path`; if any of
    that fails, `path` keeps what it held before."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # Same suffix: SB3 appends .zip otherwise. The pid keeps jobs that write one file at once (shards) apart.
    tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp{path.suffix}")
    try:
        write(tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:  # a failed write leaves the previous file, and no partial one beside it
        tmp.unlink(missing_ok=True)
    return path


def write_text_atomic(path: str | Path, text: str) -> Path:
    return write_atomic(path, lambda tmp: tmp.write_text(text))
