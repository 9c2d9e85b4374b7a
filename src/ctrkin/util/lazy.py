"""Lazy package attributes (PEP 562): `import ctrkin` or `import ctrkin.data` imports no submodule
until one of its names is used, so that a command or a script pays only for what it touches (numba
and torch cost seconds to import).

A package declares its public names once, as the imports a type checker reads, and hands them to
`lazy_attributes`, which reads the same lines from the package's source:

    __all__ = ["Dataset", "Split"]

    if TYPE_CHECKING:       # imported on first use (ctrkin.util.lazy)
        from ctrkin.data.dataset import Dataset
        from ctrkin.data.splits import Split

    __getattr__, __dir__ = lazy_attributes(__name__, __file__)

(the scientific Python `lazy_loader.attach_stub` does the same from a .pyi stub). The names of
`__all__` and of those imports must agree, less what the package defines itself (`__version__`).
"""

from __future__ import annotations

import ast
import importlib
import sys
from collections.abc import Callable
from typing import Any


def type_checking_imports(init_file: str) -> dict[str, tuple[str, str]]:
    """name -> (module, attribute) of the `from module import attribute [as name]` statements under
    the top-level `if TYPE_CHECKING:` of a source file."""
    where = {}
    with open(init_file, encoding="utf-8") as f:      # not pathlib: it costs more to import than this
        tree = ast.parse(f.read())
    for node in tree.body:
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            for stmt in node.body:
                if isinstance(stmt, ast.ImportFrom) and stmt.module and stmt.level == 0:
                    where.update({a.asname or a.name: (stmt.module, a.name) for a in stmt.names})
    return where


def lazy_attributes(package: str, init_file: str) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module `__getattr__` and `__dir__` of `package`, whose public names are the imports under
    `if TYPE_CHECKING:` of its `__init__.py` (init_file); a name is imported on first use and cached
    in the package. ImportError if they and the package's `__all__` disagree."""
    where = type_checking_imports(init_file)
    namespace = sys.modules[package].__dict__
    declared = set(namespace.get("__all__", ()))
    if declared - set(namespace) != set(where):
        raise ImportError(f"{package}: __all__ {sorted(declared - set(namespace))} and the names imported "
                          f"under `if TYPE_CHECKING:` {sorted(where)} must be the same")

    def __getattr__(name: str) -> Any:
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        module, attribute = where[name]
        value = getattr(importlib.import_module(module), attribute)
        namespace[name] = value       # later look-ups skip this function
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(where))

    return __getattr__, __dir__
