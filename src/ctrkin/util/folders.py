"""Folders written as one unit (datasets, model folders): built aside, swapped in, locked, checked.

A folder `NAME` is built in a sibling (`.NAME.xxxx`), then swapped in with two renames: `NAME` →
`.NAME.old-<hex>`, build → `NAME`; the old copy is removed last. A crash between the two renames
leaves no `NAME` but the previous content in `.NAME.old-*`: `recover` puts it back (the previous
content, never a mix). A manifest (`manifest.json`: SHA-256 of every file) lets a reader check that
the files of a folder were written together.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import shutil
import uuid
from collections.abc import Iterator
from pathlib import Path

MANIFEST = "manifest.json"


def old_copies(target: Path) -> list[Path]:
    """`.NAME.old-*` siblings of `target` left by an interrupted swap, newest first."""
    if not target.parent.is_dir():
        return []
    found = [p for p in target.parent.glob(f".{target.name}.old-*") if p.is_dir()]
    return sorted(found, key=lambda p: p.stat().st_mtime, reverse=True)


def recover(target: Path) -> str | None:
    """Finish an interrupted swap of folder `target`. Returns what was done, or None.

    No `target` but an old copy: the swap stopped between its two renames; the old copy (the
    previous content) is renamed back. `target` and old copies: the swap finished but the old copy
    was not removed yet; it is removed."""
    olds = old_copies(target)
    if not olds:
        return None
    if target.exists():
        for p in olds:
            shutil.rmtree(p, ignore_errors=True)
        return f"removed {len(olds)} superseded copy(ies) of {target}"
    olds[0].rename(target)
    for p in olds[1:]:
        shutil.rmtree(p, ignore_errors=True)
    return f"restored {target} from {olds[0].name} (an interrupted write had swapped it out)"


def swap_in(tmp: Path, target: Path, error: type[Exception]) -> None:
    """Replace folder `target` by the complete folder `tmp`; the old one is removed only after."""
    old = None
    if target.exists():
        if not target.is_dir():
            raise error(f"{target} exists and is not a folder")
        old = target.with_name(f".{target.name}.old-{uuid.uuid4().hex[:8]}")
        target.rename(old)
    try:
        tmp.rename(target)
    except OSError:
        if old is not None:
            old.rename(target)
        raise
    _fsync_dir(target.parent)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


@contextlib.contextmanager
def folder_lock(target: Path, error: type[Exception], what: str = "write") -> Iterator[None]:
    """Hold an exclusive lock on folder `target` (file `.NAME.lock` beside it) while writing it.

    The lock is an flock: the kernel releases it when the process dies, even by SIGKILL, so a crash
    never leaves a stale lock (at most an unlocked file). A second writer gets `error` at once
    instead of racing the first. The file is removed on release; a locker that finds the file it
    locked already replaced tries again."""
    target.parent.mkdir(parents=True, exist_ok=True)
    path = target.with_name(f".{target.name}.lock")
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise error(f"{target} is being written by another process (pid {holder}); wait for it "
                        f"to finish or {what} into another folder") from None
        try:
            same = os.stat(path).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)            # the holder before us removed this file on release: lock anew
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        yield
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)
        os.close(fd)


def file_hash(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def write_manifest(folder: Path, skip: tuple[str, ...] = ()) -> None:
    """Write `manifest.json`: SHA-256 of every file directly in `folder` (except `skip`)."""
    files = sorted(p.name for p in folder.iterdir()
                   if p.is_file() and p.name != MANIFEST and p.name not in skip)
    blob = {"files": {name: file_hash(folder / name) for name in files}}
    (folder / MANIFEST).write_text(json.dumps(blob, indent=2, sort_keys=True))


def check_manifest(folder: Path, required: tuple[str, ...], error: type[Exception]) -> None:
    """Refuse a folder whose files were not written together: `required` must be listed in the
    manifest and every listed file must be present with its recorded hash."""
    path = folder / MANIFEST
    if not path.is_file():
        raise error(f"{folder} has no {MANIFEST}: its files cannot be checked to belong together "
                    "(a folder from an older ctrkin or an interrupted write); train it again")
    try:
        files = json.loads(path.read_text())["files"]
        if not isinstance(files, dict):
            raise TypeError("'files' is not an object")
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise error(f"{path} is not a valid manifest: {e}") from None
    missing = [name for name in required if name not in files]
    if missing:
        raise error(f"{path} does not list {missing}: the folder was not written as one unit")
    for name, digest in files.items():
        f = folder / str(name)
        if not f.is_file():
            raise error(f"{folder} lacks {name}, which its manifest lists: an incomplete folder")
        if file_hash(f) != digest:
            raise error(f"{f} is not the file written with the rest of {folder} (hash differs from "
                        f"{MANIFEST}): a mix of two writes or an edited file; train it again")
