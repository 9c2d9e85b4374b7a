"""Lazy package attributes (PEP 562): `import ctrkin` or `import ctrkin.data` imports no submodule
until one of its names is used, so that a command or a script pays only for what it touches (numba
and torch cost seconds to import).

    __getattr__, __dir__ = lazy_attributes(__name__, {"Dataset": "ctrkin.data.dataset", ...})
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any


def lazy_attributes(package: str, where: Mapping[str, str]
                    ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module `__getattr__` and `__dir__` of `package` whose public names `where` maps to the
    modules that define them; a name is imported on first use and cached in the package."""

    def __getattr__(name: str) -> Any:
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        importlib.import_module(package).__dict__[name] = value     # later look-ups skip this function
        return value

    def __dir__() -> list[str]:
        return sorted(set(importlib.import_module(package).__dict__) | set(where))

    return __getattr__, __dir__
