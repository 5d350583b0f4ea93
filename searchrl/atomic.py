"""The file rules of every app, in one place: atomic writes, temporaries that loaders never read, and folder locks.

- **Atomic writes.** A file is written to a hidden temporary beside its target (`.<name>.<host>.<pid>.tmp`), fsynced,
  then moved over the target with `os.replace`: a reader sees the old file or the new one, never a partial one.
  Temporaries are dot-files ending in `.tmp`, so no `*.parquet` / `step_*.zip` pattern matches them, and
  `remove_temporaries` clears those a killed writer left, once the caller holds the lock that writer held.
- **Locks.** `hold(path)` takes an exclusive `flock` on a lock file. The kernel releases it when its process dies,
  kill -9 included, so a killed run never leaves a lock to clear by hand; on NFS, Linux turns `flock` into a POSIX
  lock the server arbitrates across nodes, and Lustre/GPFS honour it when mounted with `flock` (the usual cluster
  setting). A lock file that outlived its owner (the O_EXCL "pid file" alternative) cannot tell a dead job on
  another node from a live one, which is why it is not used (docs/files.md).
"""

from __future__ import annotations

import errno
import fcntl
import os
import socket
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from searchrl.world.config import ConfigError

TMP_SUFFIX = ".tmp"


class FolderBusy(ConfigError):
    """Another process holds the lock; the message names it and says what to do. A refusal (exit status 2)."""


def temporary_path(path: str | Path) -> Path:
    """The hidden temporary that `write_atomic` fills for `path`; host and pid keep concurrent writers apart."""
    path = Path(path)
    return path.with_name(f".{path.name}.{socket.gethostname()}.{os.getpid()}{TMP_SUFFIX}")


def is_temporary(path: str | Path) -> bool:
    """A writer's temporary (this module's, or the `.<stem>.<pid>.tmp<suffix>` form of earlier versions)."""
    name = Path(path).name
    return name.startswith(".") and (name.endswith(TMP_SUFFIX) or f"{TMP_SUFFIX}." in name)


def remove_temporaries(folder: str | Path, target: str | None = None) -> list[Path]:
    """Delete the temporaries in `folder` (those of the file named `target`, or all): call it only while holding
    the lock every writer of those files holds, so none of them is still being written. Returns what went."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    stems = None if target is None else (f".{target}.", f".{Path(target).stem}.")
    gone = [p for p in folder.iterdir() if is_temporary(p) and (stems is None or p.name.startswith(stems))]
    for path in gone:
        path.unlink(missing_ok=True)
    return gone


def check_writable(path: str | Path, name: str, folder: bool = False) -> None:
    """ConfigError "name=path is not allowed: ..." unless `path` (a file, or a folder if `folder`) can be made
    here: each part of it that exists is a folder (its last part a file or a folder, as asked), and the nearest
    existing one is writable. Checked before any work, so a run never ends unable to write its result."""
    path = Path(path)
    what = "a folder" if folder else "a file path"
    if path.exists() and path.is_dir() != folder:
        raise ConfigError(f"{name}={str(path)!r} is not allowed: {what} (this is {'a file' if folder else 'a folder'})")
    parent = path if folder else path.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise ConfigError(f"{name}={str(path)!r} is not allowed: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ConfigError(f"{name}={str(path)!r} is not allowed: {parent} is not writable")


STORAGE_ERRORS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS)  # a full disk, a quota, a read-only file system


def check_own_files(folder: str | Path, name: str) -> None:
    """ConfigError in one line unless every entry of `folder` and of its subfolders one level down (a run's
    checkpoints/, an evaluation's cells/) is its own: a link out of the folder would be written through, and a
    resume's pruning would delete what it finds there."""
    folder = Path(folder)
    if not folder.is_dir():
        return
    inside = folder.resolve()
    entries = [*folder.iterdir()]
    entries += [part for entry in entries if entry.is_dir() and not entry.is_symlink() for part in entry.iterdir()]
    for entry in sorted(entries):
        if entry.is_symlink() and not entry.resolve().is_relative_to(inside):
            raise ConfigError(
                f"{name}={str(folder)!r} is not allowed: its {entry.relative_to(folder)} is a link out of it (to "
                f"{entry.resolve()}); a run's or an evaluation's files stay in its folder, so replace the link by them"
            )


def storage_message(err: OSError) -> str | None:
    """One line for an OSError the storage gave (full, over quota, read-only), naming the file; None for others,
    which are bugs or faults to show whole."""
    if err.errno not in STORAGE_ERRORS:
        return None
    where = f" writing {err.filename}" if err.filename else ""
    return f"{err.strerror or 'storage error'}{where}: free space (or ask for quota) and run the same command again"


def write_atomic(path: str | Path, write: Callable[[Path], None]) -> Path:
    """Call `write(tmp)` to produce a temporary file next to `path`, fsync it, then move it over `path`; if any of
    that fails, `path` keeps what it held before. `tmp` ends in `.tmp`: writers must not add a suffix."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = temporary_path(path)
    try:
        write(tmp)
        with open(tmp, "rb+") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
        _fsync_folder(path.parent)  # the rename itself survives a crash of the machine
    finally:  # a failed write leaves the previous file, and no partial one beside it
        tmp.unlink(missing_ok=True)
    return path


def write_text_atomic(path: str | Path, text: str) -> Path:
    return write_atomic(path, lambda tmp: tmp.write_text(text))


def _fsync_folder(folder: Path) -> None:
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    except OSError:  # some file systems refuse fsync on a directory; the rename is still atomic
        pass
    finally:
        os.close(fd)


@contextmanager
def hold(lock_file: str | Path, what: str, wait_s: float = 0.0) -> Iterator[None]:
    """Hold an exclusive lock on `lock_file` (created if needed) for the `with` block. If another process holds
    it after `wait_s` seconds, raise FolderBusy naming `what`, the holder (host, pid, since when) and what to do.
    The lock file stays after release: deleting it would let two processes lock two different files."""
    lock_file = Path(lock_file)
    lock_file.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(lock_file, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        deadline = time.monotonic() + wait_s
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= deadline:
                    holder = os.pread(fd, 512, 0).decode(errors="replace").strip() or "another process"
                    raise FolderBusy(
                        f"{what} is in use by {holder}: wait for it to finish or stop it, then run again"
                    ) from None
                time.sleep(0.1)
            except OSError as err:  # a file system without locks (Lustre mounted with noflock)
                raise FolderBusy(f"{what} cannot be locked on this file system ({err}): see docs/files.md") from None
        stamp = f"host {socket.gethostname()} pid {os.getpid()} since {time.strftime('%Y-%m-%d %H:%M:%S')}"
        os.ftruncate(fd, 0)
        os.pwrite(fd, stamp.encode(), 0)
        yield
    finally:
        os.close(fd)  # releases the lock
