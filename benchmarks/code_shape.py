"""How the learned side is laid out (issue 25): where each model family is named, where code asks
which kind of model it holds, the longest functions and the largest modules.

    python benchmarks/code_shape.py                       # this checkout's src/ctrkin
    python benchmarks/code_shape.py --src /tmp/main/src/ctrkin --top 10

Read from the source with `ast`, nothing imported:

- files naming a family: modules whose code (names, attributes, imports and string constants; not
  docstrings or comments) names one of the family's markers below, and the subpackages they lie in;
- kind checks: `isinstance(x, C)` where C is a network or predictor class of a family, and reads of
  the flags that said which family a model was (`.follow`, `.stateful`, `.refiner`, `.refined`,
  `._follower`, `.fold_gate is None/not None`), outside the family's own folder (`ctrkin/families/<name>`);
- report rows: modules of evaluation/ and viz/ whose strings spell a predictor row of the report (a
  results.json key such as "lstm_mlp_branch"; a registry model name counts too);
- the longest functions (lines from `def` to the last line of the body) and the modules over 500 lines;
- import circles: module sets that import each other round (every import, in functions too; the
  root package's lazy table aside), those through the learned side (models, families, training,
  inference) listed, and the modules that import a name from the package root (`from ctrkin import
  __version__` lifts the root above every stage).

Prints the tables, then one JSON line of the figures.
"""

from __future__ import annotations

import argparse
import ast
import json
import re
from collections import defaultdict
from pathlib import Path

# what names a family in code: identifiers (whole words) and string constants (whole strings)
FAMILIES = {
    "snap_aware": {"names": {"BranchNet", "FoldGate", "fold_gate", "branch_labels", "relay_scan",
                             "build_fold_gate", "_BranchBatch", "branch_states", "BranchRecipe",
                             "SnapAwarePredictor", "FOLD_GATE_FILE"},
                   "strings": {"lstm_mlp_branch"}},
    "follow": {"names": {"Follower", "follow_features", "train_follow", "joint_noise", "substeps",
                         "FollowRecipe", "FollowPredictor", "_follower", "follower_lag"},
               "strings": {"follow_mlp"}},
    "refined": {"names": {"RefineSettings", "FKResidual", "refine", "assemble_refined", "REFINE_FILE",
                          "RefinedPredictor", "attach_fk", "refiner"},
                "strings": {"refine.json"}},
}
# the report's predictor rows (results.json keys): modules that spell them as strings ("tcm" aside:
# the TCM itself is also a predictor spec of `ctrkin evaluate` and a key of the paper's numbers)
REPORT_NAMES = {"lstm_mlp_paper", "lstm_mlp_branch", "lstm_mlp_refined", "follow_mlp", "tcm_continued",
                "lstm_mlp_branch_tcm_gate", "lstm_mlp_branch_learned_gate"}
KIND_CLASSES = {"BranchNet", "SeqNet", "CNN", "TCN", "ResNet", "KinematicsNet", "Follower", "Kinematics",
                "FoldGate", "SequenceFK", "SnapAwarePredictor", "FollowPredictor", "RefinedPredictor"}
FLAG_ATTRS = {"follow", "stateful", "refiner", "refined", "_follower"}


def _docstrings(tree: ast.AST) -> set[int]:
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = getattr(node, "body", [])
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                out.add(id(body[0].value))
    return out


def _names(tree: ast.AST) -> tuple[set[str], set[str]]:
    """Identifiers and (non-docstring) string constants of a module."""
    docs = _docstrings(tree)
    names: set[str] = set()
    strings: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            names.add(node.id)
        elif isinstance(node, ast.Attribute):
            names.add(node.attr)
        elif isinstance(node, ast.alias):
            names |= set(node.name.split(".")) | ({node.asname} if node.asname else set())
        elif isinstance(node, ast.ImportFrom) and node.module:
            names |= set(node.module.split("."))
        elif isinstance(node, (ast.FunctionDef, ast.ClassDef, ast.AsyncFunctionDef)):
            names.add(node.name)
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs:
            strings.add(node.value)
    return names, strings


def _own_family(rel: Path) -> str | None:
    parts = rel.parts
    return parts[1] if len(parts) > 2 and parts[0] == "families" else None


def _kind_checks(tree: ast.AST) -> list[tuple[int, str]]:
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "isinstance" \
                and len(node.args) == 2:
            target = node.args[1]
            classes = target.elts if isinstance(target, ast.Tuple) else [target]
            hit = [c.id if isinstance(c, ast.Name) else c.attr for c in classes
                   if isinstance(c, (ast.Name, ast.Attribute))]
            hit = [h for h in hit if h in KIND_CLASSES]
            if hit:
                out.append((node.lineno, f"isinstance {','.join(hit)}"))
        elif isinstance(node, ast.Attribute) and node.attr in FLAG_ATTRS and isinstance(node.ctx, ast.Load):
            out.append((node.lineno, f".{node.attr}"))
        elif isinstance(node, ast.Compare) and isinstance(node.left, ast.Attribute) \
                and node.left.attr in ("fold_gate", "_fold_gate") \
                and any(isinstance(op, (ast.Is, ast.IsNot)) for op in node.ops):
            out.append((node.lineno, f".{node.left.attr} is (not) None"))
    return out


def _functions(tree: ast.AST, rel: str) -> list[tuple[int, str]]:
    out = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            out.append((node.end_lineno - node.lineno + 1, f"{rel}:{node.lineno} {node.name}"))
    return out


LEARNED = ("models", "families", "training", "inference")


def _module(rel: Path) -> str:
    parts = ("ctrkin", *rel.with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(tree: ast.AST, module: str, is_package: bool) -> tuple[set[str], bool]:
    """The ctrkin names `module` imports (`a.b` and `a.b.Name` for `from a.b import Name`), and
    whether it imports a name from the package root itself."""
    package = module.split(".") if is_package else module.split(".")[:-1]
    out: set[str] = set()
    root = False
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            name = ".".join([*base, *([node.module] if node.module else [])])
            out |= {name} | {f"{name}.{a.name}" for a in node.names}
            root |= name == "ctrkin"
    return {m for m in out if m.startswith("ctrkin.")}, root


def _circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Sets of modules that reach each other through imports (more than one module each)."""
    reach: dict[str, set[str]] = {}
    for start in graph:
        seen: set[str] = set()
        todo = list(graph[start])
        while todo:
            m = todo.pop()
            if m not in seen:
                seen.add(m)
                todo += graph.get(m, ())
        reach[start] = seen
    groups = {frozenset({m} | {o for o in reach[m] if m in reach[o]}) for m in graph if m in reach[m]}
    return sorted(sorted(g) for g in groups if len(g) > 1)


def measure(src: Path, top: int) -> dict:
    per_family: dict[str, set[str]] = defaultdict(set)
    kinds: list[str] = []
    functions: list[tuple[int, str]] = []
    big: list[tuple[int, str]] = []
    named: list[str] = []
    raw: dict[str, set[str]] = {}
    root_importers: list[str] = []
    for path in sorted(src.rglob("*.py")):
        rel = path.relative_to(src)
        text = path.read_text(encoding="utf-8")
        tree = ast.parse(text)
        names, strings = _names(tree)
        for fam, marks in FAMILIES.items():
            if names & marks["names"] or strings & marks["strings"]:
                per_family[fam].add(str(rel))
        if rel.parts[0] in ("evaluation", "viz") and strings & REPORT_NAMES:
            named.append(str(rel))
        if _own_family(rel) is None:
            kinds += [f"{rel}:{line} {what}" for line, what in sorted(_kind_checks(tree))]
        functions += _functions(tree, str(rel))
        module = _module(rel)
        raw[module], root = _imports(tree, module, path.name == "__init__.py")
        if root and module != "ctrkin":
            root_importers.append(str(rel))
        lines = text.count("\n")
        if lines > 500:
            big.append((lines, str(rel)))
    functions.sort(key=lambda f: (-f[0], f[1]))
    fam_rows = {}
    for fam in FAMILIES:
        files = sorted(per_family[fam])
        subs = sorted({f.split("/")[0] if "/" in f else "(root)" for f in files})
        outside = [f for f in files if not re.match(rf"families/{fam}/", f)]
        fam_rows[fam] = {"files": len(files), "subpackages": len(subs), "outside_own_folder": len(outside),
                         "where": subs, "outside": outside}
    graph = {}
    for module, imported in raw.items():
        targets = set()
        for name in imported:            # `ctrkin.a.b.Name` -> the module ctrkin.a.b
            parts = name.split(".")
            hit = next((".".join(parts[:k]) for k in range(len(parts), 1, -1)
                        if ".".join(parts[:k]) in raw), None)
            if hit is not None and hit != module:
                targets.add(hit)
        graph[module] = targets
    circles = _circles(graph)
    learned = [c for c in circles if any(m.split(".")[1] in LEARNED for m in c)]
    return {"families": fam_rows, "circles": circles, "learned_circles": learned,
            "root_importers": root_importers, "kind_checks": kinds, "longest": functions[:top],
            "report_names": named,
            "big_modules": sorted(big, reverse=True)}


def _files(rows: list[str]) -> int:
    return len({k.split(":")[0] for k in rows})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--src", type=Path, default=Path(__file__).resolve().parents[1] / "src" / "ctrkin")
    ap.add_argument("--top", type=int, default=10)
    args = ap.parse_args()
    m = measure(args.src, args.top)
    print(f"source: {args.src}")
    print("\nfamily      files subpackages outside-own-folder  where")
    for fam, r in m["families"].items():
        print(f"{fam:11s} {r['files']:5d} {r['subpackages']:11d} {r['outside_own_folder']:18d}  "
              f"{', '.join(r['where'])}")
        for f in r["outside"]:
            print(f"{'':12s}  {f}")
    isinst = [k for k in m["kind_checks"] if " isinstance " in k]
    flags = [k for k in m["kind_checks"] if " isinstance " not in k]
    for title, rows in (("isinstance on model kinds", isinst), ("model-kind flag reads", flags)):
        print(f"\n{title} outside a family's own folder: {len(rows)} in {_files(rows)} files")
        for k in rows:
            print(f"  {k}")
    print(f"\nmodules spelling the report's predictor rows: {len(m['report_names'])}: "
          f"{', '.join(m['report_names'])}")
    print("\nlongest functions (lines):")
    for n, where in m["longest"]:
        print(f"  {n:4d}  {where}")
    print(f"\nimport circles: {len(m['circles'])}, through the learned side: {len(m['learned_circles'])}")
    for c in m["circles"]:
        print(f"  {'(learned) ' if c in m['learned_circles'] else ''}{' <-> '.join(c)}")
    print(f"modules importing from the package root: {len(m['root_importers'])}: "
          f"{', '.join(m['root_importers']) or 'none'}")
    print(f"\nmodules over 500 lines: {', '.join(f'{p} ({n})' for n, p in m['big_modules']) or 'none'}")
    print(json.dumps({
        **{f"{fam}_files": r["files"] for fam, r in m["families"].items()},
        **{f"{fam}_outside_own_folder": r["outside_own_folder"] for fam, r in m["families"].items()},
        "isinstance_sites": len(isinst), "isinstance_files": _files(isinst),
        "flag_reads": len(flags), "flag_read_files": _files(flags),
        "longest_function_lines": m["longest"][0][0] if m["longest"] else 0,
        "top_function_lines": [n for n, _ in m["longest"]],
        "modules_over_500": len(m["big_modules"]),
        "report_name_modules": len(m["report_names"]),
        "import_circles": len(m["circles"]), "learned_import_circles": len(m["learned_circles"]),
        "root_importers": len(m["root_importers"]),
    }))


if __name__ == "__main__":
    main()
