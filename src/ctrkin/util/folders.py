"""Folders written as one unit (datasets, model folders, task paths, sweeps, evaluations): built aside,
swapped in, locked, checked, owned.

A folder `NAME` is built in a sibling `.NAME.tmp-<hex>` (`new_build`; mode from the umask, like any
file the user writes), marked as a ctrkin output of its kind (ctrkin.util.ownership) and swapped in
(`swap_in`) by one atomic exchange of the two names (renameat2 RENAME_EXCHANGE); the build name then
holds the previous content, which is removed last. Where the exchange is not available, two renames
(`NAME` → `.NAME.old-<hex>`, build → `NAME`); a crash between them leaves no `NAME` but the previous
content in `.NAME.old-*`, which `recover` puts back. Readers hold the folder steady while they read
(ctrkin.util.locks.reading); the swap takes it exclusive only for the renames.

Leftovers of killed runs (`.NAME.tmp-*` builds, `.NAME.old-*` copies) are cleaned or restored by the
next write of that folder, under its writer lock (`tidy`), and an old copy by the next read when no
writer holds the lock. Siblings are found by exact listing and name match, never by glob, so a name
with glob or odd characters (`exp[1]`, `a*`) touches only its own leftovers.

A manifest (`manifest.json`: SHA-256 of every file) lets a reader check that the files of a folder
were written together; it may name only plain files directly in its folder.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import hashlib
import json
import os
import re
import shutil
import stat
import uuid
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ctrkin.util.locks import reading, swapping, writer_active, writer_lock
from ctrkin.util.ownership import MARKER, check_replaceable, looks_like_output, write_marker

MANIFEST = "manifest.json"
MAX_MANIFEST_FILES = 256

__all__ = ["MANIFEST", "build_folder", "check_manifest", "file_hash", "folder_lock", "new_build",
           "old_copies", "reading_folder", "recover", "stale_builds", "swap_in", "tidy",
           "tidy_if_free", "write_manifest"]


def _sibling(target: Path, pattern: str) -> re.Pattern[str]:
    return re.compile(rf"\.{re.escape(target.name)}\.{pattern}")


def _siblings(target: Path, pattern: str) -> list[Path]:
    """Sibling folders of `target` whose whole name is `.NAME.` + pattern (exact listing, no glob)."""
    rx = _sibling(target, pattern)
    try:
        names = os.listdir(target.parent)
    except OSError:
        return []
    out = []
    for name in names:
        if rx.fullmatch(name):
            p = target.parent / name
            with contextlib.suppress(OSError):      # gone meanwhile (a writer's own build)
                if stat.S_ISDIR(os.lstat(p).st_mode):
                    out.append(p)
    return out


def _mtime(p: Path) -> float:
    try:
        return p.lstat().st_mtime
    except OSError:
        return 0.0


def old_copies(target: Path) -> list[Path]:
    """`.NAME.old-*` siblings of `target` left by an interrupted swap, newest first."""
    found = _siblings(target, r"old-[0-9a-f]{8}")
    return sorted(found, key=_mtime, reverse=True)


def stale_builds(target: Path) -> list[Path]:
    """Build folders of `target` left by killed writes: `.NAME.tmp-<hex>`, and `.NAME.<8 characters>`
    from the tempfile names of ctrkin before 0.2 (train's resumable `.NAME.build` is not one), that
    hold nothing but files ctrkin writes into an output (a folder of the user's that happens to be
    named so is left alone)."""
    return [p for p in _siblings(target, r"(tmp-[0-9a-f]{16}|[a-z0-9_]{8})") if looks_like_output(p)]


def recover(target: Path) -> str | None:
    """Finish an interrupted two-rename swap of folder `target`; call it holding the writer lock.
    Returns what was done, or None.

    No `target` but an old copy: the swap stopped between its two renames; the old copy (the
    previous content) is renamed back. `target` and old copies: the swap finished but the old copy
    was not removed yet; it is removed."""
    olds = old_copies(target)
    if not olds:
        return None
    if os.path.lexists(target):
        for p in olds:
            shutil.rmtree(p, ignore_errors=True)
        return f"removed {len(olds)} superseded copy(ies) of {target}"
    olds[0].rename(target)
    for p in olds[1:]:
        shutil.rmtree(p, ignore_errors=True)
    return f"restored {target} from {olds[0].name} (an interrupted write had swapped it out)"


def tidy(target: Path) -> list[str]:
    """Clean up after killed writes of `target` (call it holding the writer lock): restore or remove
    old copies, remove stale build folders. Returns what was done."""
    done = [d for d in [recover(target)] if d]
    stale = stale_builds(target)
    for p in stale:
        shutil.rmtree(p, ignore_errors=True)
    if stale:
        done.append(f"removed {len(stale)} unfinished build(s) of {target} left by killed runs")
    return done


@contextlib.contextmanager
def folder_lock(target: Path, error: type[Exception], what: str = "write") -> Iterator[None]:
    """The writer lock of `target` (ctrkin.util.locks.writer_lock), with the leftovers of killed
    writes cleaned up once it is held."""
    target = Path(os.path.abspath(target))
    with writer_lock(target, error, what):
        tidy(target)
        yield


def _missing_mid_swap(folder: Path) -> bool:
    """A reader found no `folder`: True while a swap may bring it back (an old copy exists and a
    writer holds the lock). With an old copy and no writer, the swap was killed between its renames:
    the old copy is restored now (if this process may), so the read finds the previous version."""
    if not old_copies(folder):
        return False
    if writer_active(folder):
        return True
    with contextlib.suppress(OSError, RuntimeError), writer_lock(folder, RuntimeError, wait=0.0):
        recover(folder)
    return os.path.isdir(folder)


class _Busy(Exception):
    pass


def tidy_if_free(target: Path) -> list[str]:
    """`tidy` for a reader: only when leftovers exist and no writer holds the lock (and this
    process may take it); otherwise nothing. Returns what was done."""
    if not (old_copies(target) or stale_builds(target)) or writer_active(target):
        return []
    try:
        with writer_lock(target, _Busy, wait=0.0):
            return tidy(target)
    except (_Busy, OSError):
        return []


@contextlib.contextmanager
def reading_folder(folder: str | Path) -> Iterator[Path]:
    """Read `folder` as one version (ctrkin.util.locks.reading). Leftovers of killed writes are
    cleaned first where no writer holds the lock; restoring an old copy warns. Yields the path."""
    src = Path(folder)
    for done in tidy_if_free(Path(os.path.abspath(src))):
        if done.startswith("restored"):
            warnings.warn(done, stacklevel=3)
    with reading(src, _missing_mid_swap):
        yield src


def new_build(target: Path) -> Path:
    """An empty build folder `.NAME.tmp-<hex>` beside `target`, with the umask's permissions."""
    target.parent.mkdir(parents=True, exist_ok=True)
    while True:
        build = target.with_name(f".{target.name}.tmp-{uuid.uuid4().hex[:16]}")
        try:
            os.mkdir(build, 0o777)
            return build
        except FileExistsError:
            continue


@contextlib.contextmanager
def build_folder(target: str | Path, kind: str, error: type[Exception], what: str = "write",
                 **marker: object) -> Iterator[Path]:
    """Write folder `target` as one unit: hold its writer lock, yield an empty build folder to fill,
    then mark it as a ctrkin output of `kind` and swap it in. On an exception nothing is swapped and
    the build is removed; the previous `target` stays as it was."""
    out = Path(os.path.abspath(target))
    with folder_lock(out, error, what):
        check_replaceable(out, kind, error)      # before the work: refuse early, touch nothing
        build = new_build(out)
        try:
            yield build
            write_marker(build, kind, **marker)
            swap_in(build, out, error, kind)
        finally:
            if build.exists():
                shutil.rmtree(build, ignore_errors=True)


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100
_renameat2: Any
try:
    _renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
except (OSError, AttributeError):      # not glibc >= 2.28: two renames instead
    _renameat2 = None


def _exchange(a: Path, b: Path) -> bool:
    """Exchange the names of two folders atomically; False where the system cannot."""
    if _renameat2 is None:
        return False
    if _renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EOPNOTSUPP):
        return False
    raise OSError(err, os.strerror(err), str(b))


def swap_in(tmp: Path, target: Path, error: type[Exception], kind: str | None = None) -> None:
    """Replace folder `target` by the complete folder `tmp`; the old one is removed only after.

    kind: `target`, if it exists, must be a ctrkin output of this kind (ctrkin.util.ownership) or it
    is refused (`error`), untouched. Readers of `target` see the old or the new folder."""
    target = Path(os.path.abspath(target))
    if not os.path.lexists(target):
        tmp.rename(target)
        _fsync_dir(target.parent)
        return
    if os.path.islink(target) or not target.is_dir():
        raise error(f"{target} exists and is not a folder")
    if kind is not None:
        check_replaceable(target, kind, error)
    with swapping(target):
        if _exchange(tmp, target):
            old = tmp                                   # the build's name now holds the old folder
        else:
            old = target.with_name(f".{target.name}.old-{uuid.uuid4().hex[:8]}")
            target.rename(old)
            try:
                tmp.rename(target)
            except OSError:
                old.rename(target)
                raise
    _fsync_dir(target.parent)
    shutil.rmtree(old, ignore_errors=True)


def _fsync_dir(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def file_hash(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def write_manifest(folder: Path, skip: tuple[str, ...] = ()) -> None:
    """Write `manifest.json`: SHA-256 of every file directly in `folder` (except `skip` and the
    ownership marker, which a later copy of the folder may rewrite)."""
    files = sorted(p.name for p in folder.iterdir()
                   if p.is_file() and p.name not in (MANIFEST, MARKER) and p.name not in skip)
    blob = {"files": {name: file_hash(folder / name) for name in files}}
    (folder / MANIFEST).write_text(json.dumps(blob, indent=2, sort_keys=True))


def manifest_names(folder: Path) -> list[str] | None:
    """The file names `folder`'s manifest lists (None if it has none or it cannot be read)."""
    try:
        files = json.loads((folder / MANIFEST).read_text())["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return [str(k) for k in files] if isinstance(files, dict) else None


def _plain_name(name: object) -> bool:
    """A file name directly in the folder: no separator, no `..`, not absolute, not empty."""
    return (isinstance(name, str) and name not in ("", ".", "..") and "/" not in name
            and "\\" not in name and "\0" not in name)


def check_manifest(folder: Path, required: tuple[str, ...], error: type[Exception]) -> None:
    """Refuse a folder whose files were not written together: `required` must be listed in the
    manifest and every listed file must be present with its recorded hash. The manifest may list
    only regular files directly in `folder` (no paths, no symbolic links), at most
    MAX_MANIFEST_FILES."""
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
    if len(files) > MAX_MANIFEST_FILES:
        raise error(f"{path} lists {len(files)} files (at most {MAX_MANIFEST_FILES}): not a ctrkin "
                    "manifest")
    outside = [name for name in files if not _plain_name(name)]
    if outside:
        raise error(f"{path} names {outside[0]!r}, which is not a file directly in {folder}: a "
                    "manifest may name only the folder's own files")
    missing = [name for name in required if name not in files]
    if missing:
        raise error(f"{path} does not list {missing}: the folder was not written as one unit")
    for name, digest in files.items():
        f = folder / str(name)
        try:
            mode = os.lstat(f).st_mode
        except OSError:
            mode = 0
        if stat.S_ISLNK(mode):
            raise error(f"{f} is a symbolic link: a model folder holds its own files, not links "
                        "to others")
        if not stat.S_ISREG(mode):
            raise error(f"{folder} lacks {name}, which its manifest lists: an incomplete folder")
        if file_hash(f) != digest:
            raise error(f"{f} is not the file written with the rest of {folder} (hash differs from "
                        f"{MANIFEST}): a mix of two writes or an edited file; train it again")
