"""`import ctrkin` (and each subpackage) is lazy: no numba or torch until a name is used, and every
name in an `__all__` resolves."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

PACKAGES = ["ctrkin", "ctrkin.calibration", "ctrkin.data", "ctrkin.inference", "ctrkin.mechanics",
            "ctrkin.models", "ctrkin.robots", "ctrkin.training", "ctrkin.virtual"]


@pytest.mark.parametrize("package", PACKAGES)
def test_every_name_in_all_resolves(package: str) -> None:
    module = importlib.import_module(package)
    for name in module.__all__:
        assert getattr(module, name) is not None, f"{package}.{name}"
        assert name in dir(module)
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        module.nope  # noqa: B018


def test_from_ctrkin_import_every_name() -> None:
    import ctrkin

    namespace: dict[str, object] = {}
    exec(f"from ctrkin import {', '.join(ctrkin.__all__)}", namespace)
    assert namespace["Kinematics"] is importlib.import_module("ctrkin.inference.kinematics").Kinematics
    assert namespace["solve"] is importlib.import_module("ctrkin.mechanics.pointwise").solve


def _imported_after(statement: str) -> set[str]:
    code = f"import sys; {statement}; print(' '.join(sorted(sys.modules)))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    return set(out.split())


def test_import_ctrkin_and_its_data_package_cost_no_numba_or_torch() -> None:
    for statement in ("import ctrkin", "import ctrkin.data", "import ctrkin.cli.main",
                      "from ctrkin import paper_robot"):
        loaded = _imported_after(statement)
        assert "numba" not in loaded and "torch" not in loaded, statement
    assert "numba" in _imported_after("from ctrkin import solve")
