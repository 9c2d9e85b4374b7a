"""The stages import in one direction (docs/design.md: Data flow): hardware sits between the virtual
robot and acquisition; the model folder is the centre of the learned side, `training` only
produces one and `inference` only consumes one, neither knows the virtual robot or the hardware,
and only `cli` and `evaluation` sit above them. The model families (docs/design.md: Model families)
sit between the shared `models` and those two: a family imports no other family and not the
registry, and `training` and `inference` reach the families only through the registry. No module
of the learned side imports itself back through others (no import circles), and no new circle
joins the known ones of the lower stages. Every import counts, including those
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
    "robots": {"hardware", "virtual", "acquisition", "planning", "control"},
    "mechanics": {"hardware", "virtual", "acquisition", "planning", "control"},
    "virtual": {"hardware", "acquisition", "planning", "control"},
    "hardware": {"acquisition", "data", "calibration", "models", "families", "training", "inference",
                 "evaluation", "cli", "planning", "control"},
    "models": {"families", "training", "inference", "evaluation", "cli", "virtual", "hardware", "planning",
               "control"},
    "families": {"training", "inference", "evaluation", "cli", "virtual", "hardware", "planning", "control"},
    "training": {"inference", "evaluation", "cli", "virtual", "hardware", "planning", "control"},
    "inference": {"training", "evaluation", "cli", "virtual", "hardware", "planning", "control"},
    # planning works on a robot's mechanics (nominal or calibrated), later on learned models through
    # inference; it runs nothing on a robot (hardware, virtual, acquisition) and trains nothing
    "planning": {"hardware", "virtual", "acquisition", "data", "calibration", "families", "training",
                 "evaluation", "cli", "control"},
    # control closes a loop on a learned FK (duck-typed: a Kinematics) and demonstrates it on the
    # virtual robot; it trains nothing and reads no datasets
    "control": {"acquisition", "data", "calibration", "families", "training", "evaluation", "cli"},
}
REGISTRY = "ctrkin.families.registry"
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


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _family(module: str) -> str | None:
    """The family a module belongs to (ctrkin.families.<name>...), None outside a family's folder."""
    parts = module.split(".")
    if len(parts) > 2 and parts[:2] == ["ctrkin", "families"] and parts[2] != "registry":
        return parts[2]
    return None


def family_violations() -> list[str]:
    """A family importing another family or the registry; training or inference importing a family
    other than through the registry."""
    out = []
    for module, path in _modules().items():
        mine = _family(module)
        stage = _subpackage(module)
        for imported in sorted(imports_of(path)):
            theirs = _family(imported)
            other = theirs is not None and theirs != mine
            if mine is not None and (imported.startswith(REGISTRY) or other):
                out.append(f"{module} imports {imported} (a family imports no other family nor the registry)")
            if stage in ("training", "inference") and imported.startswith("ctrkin.families") \
                    and not imported.startswith(REGISTRY):
                out.append(f"{module} imports {imported} ({stage} reaches the families through {REGISTRY})")
    return out


def import_cycles() -> list[list[str]]:
    """The module sets that import each other round (strongly connected components of more than one
    module, or a module importing itself), by every import the scanner sees."""
    modules = _modules()
    graph: dict[str, set[str]] = {}
    for module, path in modules.items():
        targets = set()
        for imported in imports_of(path):
            parts = imported.split(".")
            for k in range(len(parts), 0, -1):          # `ctrkin.a.b.Name` -> the module ctrkin.a.b
                if ".".join(parts[:k]) in modules:
                    targets.add(".".join(parts[:k]))
                    break
        graph[module] = targets - {module} if module.count(".") else set()   # the root's lazy table aside
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    cycles: list[list[str]] = []

    def visit(v: str) -> None:                        # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return cycles


def test_families_stand_alone_and_are_reached_through_the_registry() -> None:
    assert not family_violations(), "\n".join(family_violations())


def test_the_registry_names_every_family_folder() -> None:
    folders = {p.name for p in (PACKAGE / "families").iterdir() if (p / "__init__.py").is_file()}
    registry = imports_of(PACKAGE / "families" / "registry.py")
    assert folders and all(f"ctrkin.families.{name}" in registry for name in folders), sorted(folders)


LEARNED = ("models", "families", "training", "inference")


def test_no_import_circles_on_the_learned_side() -> None:
    """No circle through a module of the learned side. (The lower stages have a few of their own,
    a package's lazy table and a submodule, or a numba kernel imported in a function: not checked here.)"""
    cycles = [c for c in import_cycles() if any(_subpackage(m) in LEARNED for m in c)]
    assert not cycles, cycles


# the circles of the lower stages (a package's lazy table and its submodule, a numba kernel imported in
# a function, a package named as the anchor of its data files), all there at main 94a32c9: known, and
# no new one may join them (mechanics' circle, its lazy table, continuation and pointwise, is gone
# since they import their sibling modules by full name, issue 26)
KNOWN_CIRCLES = [
    ["ctrkin.data", "ctrkin.data.dataset"],
    ["ctrkin.robots", "ctrkin.robots.builtin"],
    ["ctrkin.robots.joint_check", "ctrkin.robots.robot"],
]


def test_no_import_circles_beyond_the_known_ones() -> None:
    extra = [c for c in import_cycles() if c not in KNOWN_CIRCLES]
    assert not extra, extra


def test_the_family_rules_see_a_family_importing_another() -> None:
    code = "from ctrkin.families.follow.stepper import Follower\n"
    assert _family("ctrkin.families.snap_aware.recipe") == "snap_aware"
    found = imports_in(code, "ctrkin.families.snap_aware.recipe")
    assert any(_family(m) == "follow" for m in found)
    assert _family(REGISTRY) is None and _family("ctrkin.models.recipe") is None


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
