"""Are two reproductions the same? Every model folder's weights byte for byte, and results.json figure
for figure except those that measure time or memory (wall times, time per prediction, samples/s,
peak memory: they differ between any two runs).

    ctrkin reproduce --scale tiny --out /tmp/before        # on one commit
    ctrkin reproduce --scale tiny --out /tmp/after         # on another
    python benchmarks/compare_reproductions.py /tmp/before /tmp/after

Prints each difference (a weights file, or a results.json key with both values) and one JSON line:
the counts of weights files compared and differing, of results.json figures compared and differing,
and of figures skipped as timings.
"""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path
from typing import Any

TIME_KEYS = {"seconds", "timing", "memory", "samples_per_s"}
TIME_NAME = re.compile(r"(^|_)(ms|us)(_|$)")


def _is_time(path: tuple[str, ...]) -> bool:
    return any(p in TIME_KEYS or TIME_NAME.search(p) for p in path)


def _leaves(tree: Any, path: tuple[str, ...] = ()) -> dict[tuple[str, ...], Any]:
    if isinstance(tree, dict):
        out: dict[tuple[str, ...], Any] = {}
        for k, v in tree.items():
            out |= _leaves(v, (*path, str(k)))
        return out
    if isinstance(tree, list) and tree and isinstance(tree[0], (dict, list)):
        out = {}
        for k, v in enumerate(tree):
            out |= _leaves(v, (*path, str(k)))
        return out
    return {path: tree}


def compare(before: Path, after: Path) -> dict[str, int]:
    counts = {"weights": 0, "weights_differ": 0, "figures": 0, "figures_differ": 0, "timings_skipped": 0}
    names = sorted({p.relative_to(before) for p in before.glob("models/**/weights.pt")}
                   | {p.relative_to(after) for p in after.glob("models/**/weights.pt")})
    for rel in names:
        a, b = before / rel, after / rel
        counts["weights"] += 1
        if not (a.is_file() and b.is_file() and a.read_bytes() == b.read_bytes()):
            counts["weights_differ"] += 1
            print(f"weights differ: {rel}")
    ra = _leaves(json.loads((before / "results.json").read_text()))
    rb = _leaves(json.loads((after / "results.json").read_text()))
    for key in sorted(set(ra) | set(rb)):
        if _is_time(key):
            counts["timings_skipped"] += 1
            continue
        counts["figures"] += 1
        if key not in ra or key not in rb or ra[key] != rb[key]:
            counts["figures_differ"] += 1
            print(f"results.json {'.'.join(key)}: {ra.get(key, '(absent)')!r} vs {rb.get(key, '(absent)')!r}")
    return counts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    args = ap.parse_args()
    counts = compare(args.before, args.after)
    same = counts["weights_differ"] == 0 and counts["figures_differ"] == 0
    print(f"{counts['weights']} weights files, {counts['weights_differ']} differ; {counts['figures']} "
          f"results.json figures, {counts['figures_differ']} differ ({counts['timings_skipped']} timings "
          f"not compared): {'the same' if same else 'DIFFERENT'}")
    print(json.dumps({**counts, "same": same}))


if __name__ == "__main__":
    main()
