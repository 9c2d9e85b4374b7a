"""The stages import in one direction (docs/design.md: Data flow): hardware sits between the virtual
robot and acquisition; the model folder is the centre of the learned side, `training` only
produces one and `inference` only consumes one, neither knows the virtual robot or the hardware,
and only `cli` and `evaluation` sit above them. Every import counts, including those
inside functions and under TYPE_CHECKING, and module paths named in strings (lazy attribute tables,
importlib)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "ctrkin"
MODULE_PATH = re.compile(r"ctrkin(\.\w+)+")

# subpackage -> subpackages it must not import
FORBIDDEN = {
    # hardware sits between the virtual robot and acquisition: it may drive the virtual robot, and
    # only acquisition (and what sits above it) runs protocols on it
    "robots": {"hardware", "virtual", "acquisition"},
    "mechanics": {"hardware", "virtual", "acquisition"},
    "virtual": {"hardware", "acquisition"},
    "hardware": {"acquisition", "data", "calibration", "models", "training", "inference", "evaluation",
                 "cli"},
    "models": {"training", "inference", "evaluation", "cli", "virtual", "hardware"},
    "training": {"inference", "evaluation", "cli", "virtual", "hardware"},
    "inference": {"training", "evaluation", "cli", "virtual", "hardware"},
}
ABOVE_ALL = {"cli": {"cli"}, "evaluation": {"cli", "evaluation"}}   # imported only by these


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports_of(path: Path) -> set[str]:
    """Every ctrkin module the file `path` of the package imports or names in a string."""
    return imports_in(path.read_text(encoding="utf-8"), _module_name(path), path.name == "__init__.py")


def imports_in(source: str, module: str, is_package: bool = False) -> set[str]:
    """Every ctrkin module that `source`, the code of `module`, imports or names as a module path in
    a string."""
    here = module.split(".")
    package = here if is_package else here[:-1]
    out: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            name = ".".join([*base, *([node.module] if node.module else [])])
            out.add(name)
            out |= {f"{name}.{a.name}" for a in node.names}       # `from ctrkin import inference`
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            if MODULE_PATH.fullmatch(node.value):
                out.add(node.value)
    return {m for m in out if m == "ctrkin" or m.startswith("ctrkin.")}


def _subpackage(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and (PACKAGE / parts[1]).is_dir() else None


def violations() -> list[str]:
    out = []
    for path in sorted(PACKAGE.rglob("*.py")):
        mine = _subpackage(_module_name(path))
        for module in sorted(imports_of(path)):
            theirs = _subpackage(module)
            if theirs is None or theirs == mine:
                continue
            if theirs in FORBIDDEN.get(mine or "", set()):
                out.append(f"{path.relative_to(PACKAGE)} imports {module} ({mine} must not import {theirs})")
            if theirs in ABOVE_ALL and mine not in ABOVE_ALL[theirs]:
                out.append(f"{path.relative_to(PACKAGE)} imports {module} (only {sorted(ABOVE_ALL[theirs])} "
                           f"may import {theirs})")
    return out


def test_the_stages_import_in_one_direction() -> None:
    assert not violations(), "\n".join(violations())


def test_training_does_not_import_inference() -> None:
    found = {m for p in (PACKAGE / "training").rglob("*.py") for m in imports_of(p)}
    assert found and not any(m.startswith("ctrkin.inference") for m in found), sorted(found)


def test_the_scanner_sees_every_kind_of_import() -> None:
    code = ("import ctrkin.inference.kinematics\n"
            "from ctrkin import inference\n"
            "from ..inference import engine\n"
            "def f():\n    from ctrkin.evaluation.report import write_report\n"
            "LAZY = {'Kinematics': 'ctrkin.cli.main'}\n"
            "DOC = 'see ctrkin.virtual for the robot'\n")
    found = imports_in(code, "ctrkin.training.probe")
    assert {"ctrkin.inference.kinematics", "ctrkin.inference", "ctrkin.inference.engine",
            "ctrkin.evaluation.report", "ctrkin.cli.main"} <= found
    assert not any(m.startswith("ctrkin.virtual") for m in found)      # prose is not an import
