"""The scripts under benchmarks/ as modules, for the tests of their machinery."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def load_benchmark(stem: str) -> ModuleType:
    """benchmarks/<stem>.py imported as the module `ctrkin_<stem>` (registered in sys.modules, so
    that its dataclasses and pickling work)."""
    spec = importlib.util.spec_from_file_location(f"ctrkin_{stem}", BENCHMARKS / f"{stem}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module
