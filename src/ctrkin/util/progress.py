"""Progress bars that stay quiet when output is not a terminal (CI logs stay readable)."""

from __future__ import annotations

import os
import sys
from typing import Any

from tqdm.auto import tqdm


def progress_bar(total: int | None = None, desc: str = "", **kw: Any) -> tqdm:
    """A tqdm bar on stderr; disabled with CTRKIN_NO_PROGRESS=1, and throttled when not a TTY."""
    disable = os.environ.get("CTRKIN_NO_PROGRESS") == "1"
    mininterval = 0.2 if sys.stderr.isatty() else 10.0
    return tqdm(total=total, desc=desc, disable=disable, mininterval=mininterval,
                dynamic_ncols=True, **kw)
