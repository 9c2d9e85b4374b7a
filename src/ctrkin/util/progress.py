"""Progress: a tqdm bar that stays on one line on a terminal; elsewhere (CI logs, files, pipes) a
few summary lines at the quarter marks instead of one line per update."""

from __future__ import annotations

import os
import sys
from typing import Any

from tqdm.auto import tqdm

QUARTERS = (0.25, 0.5, 0.75, 1.0)


class QuarterLog:
    """The tqdm calls ctrkin uses (update, set_postfix, close, context manager), printing one line
    to stderr when 25, 50, 75 and 100 % of `total` are reached, and on close a last line if the work
    ended early (early stopping); nothing without a total."""

    def __init__(self, total: int | None = None, desc: str = "", initial: int = 0, **_: Any) -> None:
        self.total, self.desc, self.n = total, desc, initial
        self.postfix = ""
        self._printed = initial
        self._closed = False
        self._next = 0
        while self.total and self._next < len(QUARTERS) and self.n >= QUARTERS[self._next] * self.total:
            self._next += 1

    def update(self, n: int = 1) -> None:
        self.n += n
        if not self.total:
            return
        while self._next < len(QUARTERS) and self.n >= QUARTERS[self._next] * self.total:
            self._line(f"{QUARTERS[self._next]:.0%}")
            self._next += 1

    def _line(self, what: str) -> None:
        print(f"{self.desc}: {self.n}/{self.total} ({what}){self.postfix}", file=sys.stderr, flush=True)
        self._printed = self.n

    def set_postfix(self, ordered_dict: Any = None, refresh: bool = True, **kw: Any) -> None:
        items = dict(ordered_dict or {}, **kw)
        self.postfix = "  " + ", ".join(f"{k}={v}" for k, v in items.items()) if items else ""

    def set_description(self, desc: str = "", refresh: bool = True) -> None:
        self.desc = desc

    def refresh(self) -> None:
        pass

    def close(self) -> None:
        if self.total and not self._closed and self.n > self._printed:
            self._line("stopped")
        self._closed = True

    def __enter__(self) -> QuarterLog:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def progress_bar(total: int | None = None, desc: str = "", **kw: Any) -> Any:
    """A tqdm bar on stderr when it is a terminal, quarter-mark lines (QuarterLog) when it is not;
    nothing with CTRKIN_NO_PROGRESS=1."""
    if os.environ.get("CTRKIN_NO_PROGRESS") == "1":
        return tqdm(total=total, desc=desc, disable=True, **kw)
    if not sys.stderr.isatty():
        return QuarterLog(total=total, desc=desc, **kw)
    return tqdm(total=total, desc=desc, mininterval=0.2, dynamic_ncols=True, **kw)
