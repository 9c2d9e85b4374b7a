"""The `Examples` sections of the public docstrings run (the API reference shows them)."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = ("ctrkin.robots.tube", "ctrkin.robots.robot", "ctrkin.acquisition.protocols")


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str) -> None:
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0 and result.failed == 0
