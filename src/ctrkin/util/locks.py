"""Locks of a folder written as one unit (ctrkin.util.folders): one writer at a time, readers that
never see a swap half done.

Writer lock: `.NAME.lock`, a regular file in the folder's parent, held (flock, exclusive) for the
whole of a write: a second writer is refused at once, naming the holder's PID. It is opened with
O_NOFOLLOW and checked (a regular file of ours with one link) before the PID is written into it, so a
symbolic or hard link planted at its path cannot redirect the write. The kernel drops an flock when
its process dies, even by SIGKILL: a crash never leaves a stale lock. Re-entrant within one thread
(a command holds it from its first check to its last write; the library call it makes takes it again).

Reader lock: a shared flock on the folder itself (its directory), for the short time of a read; the
writer takes it exclusive only around the swap (ctrkin.util.folders.swap_in). A reader therefore
reads one version, old or new, never a mix; a writer waits for the reads in progress (short), never
fails because of them. So that readers which keep overlapping cannot hold a writer off, a writer
about to swap first closes a turnstile (an exclusive flock on the parent folder, for its renames
only) that new readers pass before they lock the folder (a thread that is reading already waits
there at most TURNSTILE_S, so nested reads never wait in a circle). Opening a directory needs only
read access, so this works in read-only places too; where even that is impossible the read goes on
unlocked and the folder's own checks (hashes in meta.json / manifest.json) stand guard.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import stat
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

READ_WAIT_S = 10.0          # a reader waits this long for a folder missing mid-swap to reappear
TURNSTILE_S = 1.0           # a thread that reads already waits at most this long at a turnstile
WRITER_WAIT_S = 1.0         # a writer finding the lock held tries this long before it is refused

_held: dict[str, tuple[int, int]] = {}        # writer locks held here: path -> (thread id, depth)
_held_guard = threading.Lock()


def lock_path(target: Path) -> Path:
    """The writer lock file of folder `target`: `.NAME.lock` in its parent."""
    return target.with_name(f".{target.name}.lock")


def _key(target: Path) -> str:
    return os.path.join(os.path.realpath(target.parent), target.name)


def _open_lock(path: Path, error: type[Exception]) -> int:
    """Open (creating) the lock file without following links; refuse anything but our own regular
    file with a single link (a planted link would make the PID land in another file)."""
    flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags, 0o666)
    except OSError as e:
        if os.path.islink(path):
            raise error(f"{path} is a symbolic link, not a ctrkin lock file; remove it and try "
                        "again") from None
        raise error(f"cannot open the lock file {path}: {e.strerror}") from None
    st = os.fstat(fd)
    # nlink 0: the holder before us has just removed it (the caller then locks anew); 2 or more: a
    # hard link planted to another file
    if not stat.S_ISREG(st.st_mode) or st.st_nlink > 1 or st.st_uid != os.geteuid():
        os.close(fd)
        raise error(f"{path} is not a lock file ctrkin made (not a regular file of yours with one "
                    "link); remove it and try again")
    return fd


def _flock_within(fd: int, seconds: float) -> bool:
    """Take an exclusive flock on fd, trying for up to `seconds` (a reader cleaning leftovers holds
    the writer lock for a moment; a writer is not refused for that). False if it stays held."""
    deadline = time.monotonic() + seconds
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return True
        except BlockingIOError:
            if time.monotonic() > deadline:
                return False
            time.sleep(0.005)


@contextlib.contextmanager
def writer_lock(target: Path, error: type[Exception], what: str = "write",
                wait: float = WRITER_WAIT_S) -> Iterator[None]:
    """Hold the writer lock of folder `target` (module docstring); `error` if another process or
    thread holds it. The lock file is removed on release."""
    target = Path(os.path.abspath(target))        # "." and "x/.." have a name only this way
    key = _key(target)
    me = threading.get_ident()
    with _held_guard:
        owner = _held.get(key)
        if owner is not None and owner[0] == me:
            _held[key] = (me, owner[1] + 1)
            nested = True
        else:
            nested = False
    if nested:
        try:
            yield
        finally:
            with _held_guard:
                tid, depth = _held[key]
                _held[key] = (tid, depth - 1)
        return
    target.parent.mkdir(parents=True, exist_ok=True)
    path = lock_path(target)
    while True:
        fd = _open_lock(path, error)
        if not _flock_within(fd, wait):
            holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "?"
            os.close(fd)
            raise error(f"{target} is being written by another process (pid {holder}); wait for it "
                        f"to finish or {what} into another folder")
        try:
            st, fst = os.stat(path, follow_symlinks=False), os.fstat(fd)
            same = (st.st_ino, st.st_dev) == (fst.st_ino, fst.st_dev)
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)            # the holder before us removed this file on release: lock anew
    with _held_guard:
        if key in _held:        # another thread of this process holds it
            os.close(fd)
            raise error(f"{target} is being written by another thread of this process; wait for "
                        f"it to finish or {what} into another folder")
        _held[key] = (me, 1)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, str(os.getpid()).encode(), 0)
        yield
    finally:
        with _held_guard:
            _held.pop(key, None)
        with contextlib.suppress(OSError):
            os.unlink(path)
        os.close(fd)


def writer_active(target: Path) -> bool:
    """Whether a writer holds the lock of `target` now (this process's own lock counts). False
    where the lock cannot be checked without creating it (no lock file: nobody holds it)."""
    if _key(target) in _held:
        return True
    try:
        fd = os.open(lock_path(target), os.O_RDONLY | os.O_NOFOLLOW | os.O_CLOEXEC)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)
    return False


def _open_dir(folder: Path) -> int:
    return os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)


_reads = threading.local()       # folders (device, inode) this thread is reading now


def _gate(fd: int, operation: int) -> None:
    """flock(fd, operation) on a turnstile: blocking, unless this thread holds a read lock already;
    then tried for at most TURNSTILE_S and given up (the writer we would wait for may be waiting for
    our read to end: a nested read or a write during a read never waits in a circle)."""
    if not getattr(_reads, "held", None):
        fcntl.flock(fd, operation)
        return
    deadline = time.monotonic() + TURNSTILE_S
    while True:
        try:
            fcntl.flock(fd, operation | fcntl.LOCK_NB)
            return
        except BlockingIOError:
            if time.monotonic() > deadline:
                return
            time.sleep(0.001)


def _pass_turnstile(parent: Path) -> None:
    """Wait while a writer in `parent` is swapping (it holds the parent folder's flock exclusive for
    its renames): without this, readers that keep overlapping would hold off a writer for good."""
    try:
        fd = _open_dir(parent)
    except OSError:
        return
    try:
        _gate(fd, fcntl.LOCK_SH)
    finally:
        os.close(fd)


@contextlib.contextmanager
def reading(folder: Path, missing: Callable[[Path], bool] | None = None) -> Iterator[None]:
    """Hold folder steady while it is read (module docstring): a shared flock on the folder, taken
    again if a swap replaced the folder between the open and the lock. Re-entrant within a thread.

    missing(folder): called when the folder does not exist; True if it may reappear (a swap in
    progress, ctrkin.util.folders) so the reader waits up to READ_WAIT_S for it. Otherwise, and for
    a folder that cannot be opened, the read goes on unlocked (the caller reports what is wrong)."""
    folder = Path(os.path.abspath(folder))
    held: set[tuple[int, int]] = getattr(_reads, "held", None) or set()
    _reads.held = held
    deadline = time.monotonic() + READ_WAIT_S
    while True:
        _pass_turnstile(folder.parent)
        try:
            fd = _open_dir(folder)
        except FileNotFoundError:
            if missing is not None and missing(folder) and time.monotonic() < deadline:
                time.sleep(0.002)
                continue
            yield
            return
        except OSError:          # not a folder, no read permission: nothing to lock
            yield
            return
        fst = os.fstat(fd)
        ident = (fst.st_dev, fst.st_ino)
        if ident in held:        # this thread reads it already (a nested load)
            os.close(fd)
            yield
            return
        fcntl.flock(fd, fcntl.LOCK_SH)
        try:
            st = os.stat(folder)
            same = (st.st_ino, st.st_dev) == (fst.st_ino, fst.st_dev)
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)             # swapped out while we waited: read the new one
    held.add(ident)
    try:
        yield
    finally:
        held.discard(ident)
        os.close(fd)


@contextlib.contextmanager
def swapping(folder: Path) -> Iterator[None]:
    """The writer's side of `reading`: the turnstile of the folder's parent closed (new readers
    wait), then an exclusive flock on the folder being replaced, for the renames only. It waits for
    the reads in progress (each short), never for readers that arrive after it."""
    try:
        gate = _open_dir(folder.parent)
    except OSError:             # a parent we may write but not read: no turnstile, still correct
        gate = -1
    try:
        if gate >= 0:
            _gate(gate, fcntl.LOCK_EX)
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            yield
        finally:
            os.close(fd)
    finally:
        if gate >= 0:
            os.close(gate)
