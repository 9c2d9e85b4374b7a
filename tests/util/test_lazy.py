"""ctrkin.util.lazy: a package's lazy names are the imports under its `if TYPE_CHECKING:`."""

from __future__ import annotations

import importlib
import textwrap

import pytest

from ctrkin.util.lazy import type_checking_imports

INIT = '''
from __future__ import annotations

from typing import TYPE_CHECKING

from ctrkin.util.lazy import lazy_attributes

__version__ = "1"
__all__ = {names}

if TYPE_CHECKING:
    from json import dumps, loads as read
    from os.path import join

__getattr__, __dir__ = lazy_attributes(__name__, __file__)
'''


def _package(tmp_path, monkeypatch, name: str, names: list[str]):
    folder = tmp_path / name
    folder.mkdir()
    (folder / "__init__.py").write_text(textwrap.dedent(INIT.format(names=names)))
    monkeypatch.syspath_prepend(str(tmp_path))
    return importlib.import_module(name)


def test_type_checking_imports_are_read_with_their_aliases(tmp_path) -> None:
    path = tmp_path / "m.py"
    path.write_text("import os\nfrom typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                    "    from json import dumps, loads as read\n    from os.path import join\n")
    assert type_checking_imports(str(path)) == {"dumps": ("json", "dumps"), "read": ("json", "loads"),
                                                "join": ("os.path", "join")}


def test_names_are_imported_on_first_use(tmp_path, monkeypatch) -> None:
    pkg = _package(tmp_path, monkeypatch, "lazy_ok", ["__version__", "dumps", "join", "read"])
    assert "read" not in vars(pkg)
    assert pkg.read is importlib.import_module("json").loads and "read" in vars(pkg)
    assert {"dumps", "join", "read", "__version__"} <= set(dir(pkg))
    with pytest.raises(AttributeError, match="module 'lazy_ok' has no attribute 'nope'"):
        pkg.nope  # noqa: B018


def test_all_and_the_imports_must_agree(tmp_path, monkeypatch) -> None:
    with pytest.raises(ImportError, match="must be the same"):
        _package(tmp_path, monkeypatch, "lazy_bad", ["dumps", "join"])         # read is not public
