"""Progress: a tqdm bar that stays on one line on a terminal; elsewhere (CI logs, files, pipes) a
few summary lines (at the quarter marks, and at least once a minute while work goes on) instead of
one line per update."""

from __future__ import annotations

import os
import sys
import threading
import time
import weakref
from typing import Any

from tqdm.auto import tqdm

QUARTERS = (0.25, 0.5, 0.75, 1.0)
HEARTBEAT_S = 60.0   # longest silence of a log line while work goes on (s)


def _duration(seconds: float) -> str:
    """'45 s', '3 min 05 s', '1 h 02 min'."""
    s = round(seconds)
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class QuarterLog:
    """The tqdm calls ctrkin uses (update, set_postfix, close, context manager) for a log or pipe.

    Prints one line to stderr when 25, 50, 75 and 100 % of `total` are reached (one line for an
    update that crosses several marks, naming the highest), on close a last line if the work ended
    early (early stopping), and a heartbeat line when `heartbeat_s` seconds have passed without a
    line, so that a log shows at least once a minute that the work goes on, even while a single
    unit of work (an epoch, a model) takes minutes. Each line gives the count, the elapsed time and,
    once there is a rate, the time left at that rate.

    Parameters
    ----------
    total : int, optional
        Units of work; without it only heartbeats are printed.
    desc : str
        What is being done (the line's prefix).
    initial : int
        Units already done (a resumed run): they count towards the marks but not the rate.
    heartbeat_s : float
        Longest silence in seconds (a daemon thread prints the heartbeat; 0 or less: none).
    """

    def __init__(self, total: int | None = None, desc: str = "", initial: int = 0,
                 heartbeat_s: float = HEARTBEAT_S, **_: Any) -> None:
        self.total, self.desc, self.n = total, desc, initial
        self.postfix = ""
        self._initial = initial
        self._printed = initial
        self._closed = False
        self._next = 0
        self._lock = threading.Lock()
        self._start = self._last_line = time.monotonic()
        while self.total and self._next < len(QUARTERS) and self.n >= QUARTERS[self._next] * self.total:
            self._next += 1
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        if heartbeat_s > 0:
            # the thread holds a weak reference: a reporter nobody closed is still collected
            self._thread = threading.Thread(target=_beat, args=(weakref.ref(self), self._stop, heartbeat_s),
                                            daemon=True, name=f"ctrkin-progress-{desc}")
            self._thread.start()

    def _heartbeat(self, interval: float) -> float:
        """A line if `interval` seconds passed without one; the seconds until the next check."""
        with self._lock:
            if self._closed:
                return interval
            silent = time.monotonic() - self._last_line
            if silent >= interval:
                self._line("running")
                silent = 0.0
            return interval - silent

    def update(self, n: int = 1) -> None:
        with self._lock:
            self.n += n
            if not self.total:
                return
            reached = None
            while self._next < len(QUARTERS) and self.n >= QUARTERS[self._next] * self.total:
                reached = QUARTERS[self._next]
                self._next += 1
            if reached is not None:
                self._line(f"{reached:.0%}")

    def _line(self, what: str) -> None:
        """One line (the caller holds the lock)."""
        now = time.monotonic()
        elapsed = now - self._start
        count = f"{self.n}/{self.total}" if self.total else f"{self.n}"
        timing = _duration(elapsed)
        done = self.n - self._initial
        if self.total and 0 < done and self.n < self.total and what not in ("100%", "stopped"):
            timing += f", ~{_duration(elapsed / done * (self.total - self.n))} left"
        print(f"{self.desc}: {count} ({what}, {timing}){self.postfix}", file=sys.stderr, flush=True)
        self._printed = self.n
        self._last_line = now

    def set_postfix(self, ordered_dict: Any = None, refresh: bool = True, **kw: Any) -> None:
        items = dict(ordered_dict or {}, **kw)
        self.postfix = "  " + ", ".join(f"{k}={v}" for k, v in items.items()) if items else ""

    def set_description(self, desc: str = "", refresh: bool = True) -> None:
        self.desc = desc

    def refresh(self) -> None:
        pass

    def close(self) -> None:
        with self._lock:
            if self.total and not self._closed and self.n > self._printed:
                self._line("stopped")
            self._closed = True
        self._stop.set()

    def __enter__(self) -> QuarterLog:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        stop = getattr(self, "_stop", None)   # absent if __init__ failed early
        if stop is not None:
            stop.set()


def _beat(ref: weakref.ref[QuarterLog], stop: threading.Event, interval: float) -> None:
    """Heartbeat thread of a QuarterLog: runs until it is closed or collected."""
    wait = interval
    while not stop.wait(wait):
        log = ref()
        if log is None:
            return
        wait = log._heartbeat(interval)
        del log


def progress_bar(total: int | None = None, desc: str = "", **kw: Any) -> Any:
    """A progress reporter on stderr.

    Parameters
    ----------
    total : int, optional
        Units of work.
    desc : str
        What is being done.
    **kw
        Passed to tqdm (e.g. ``unit``, ``initial``, ``leave``).

    Returns
    -------
    tqdm or QuarterLog
        A tqdm bar when stderr is a terminal; quarter-mark and heartbeat lines (`QuarterLog`) when
        it is not (a log file, a pipe, CI); a disabled bar with ``CTRKIN_NO_PROGRESS=1``.
    """
    if os.environ.get("CTRKIN_NO_PROGRESS") == "1":
        return tqdm(total=total, desc=desc, disable=True, **kw)
    if not sys.stderr.isatty():
        return QuarterLog(total=total, desc=desc, **kw)
    return tqdm(total=total, desc=desc, mininterval=0.2, dynamic_ncols=True, **kw)
