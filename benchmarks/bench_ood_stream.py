"""The OOD score's streaming step against a baseline revision's (issue 24, goal 2: the step cost
with uncertainty ≤ 3× without): what the joint-aware IK score's generalised parts cost the FK.

    python benchmarks/bench_ood_stream.py                      # against main before the change (dbab9a8)
    python benchmarks/bench_ood_stream.py --baseline REV [--baseline REV2 ...]
    python benchmarks/bench_ood_stream.py --baseline REV --folder DIR/paper_fk   # a real FK
                                                               # (learned_loop.py --keep DIR)

The baseline's `ctrkin/models/uncertainty.py` (and its `ctrkin/models/ood.py` where it has one) is
loaded from its `git archive` (benchmarks/bench_streaming.py's tree) beside this tree's, in one
process: the same synthetic walks of a two-tube robot (40 of 60 steps to train on, 20 to calibrate;
1,000 reference rows), the scores checked equal (to 1e-9), then `UncertainStream.step` of each timed
in alternating rounds (the load falls on all alike): medians over rounds of the best of 3 × 300
calls, µs. This tree's scores are fitted with the baselines' parts (split "blocks") to compare, and
timed again with its default split (the translations in a part of their own too). Also the IK score
(pose and joints, four parts) on the same walks with random poses beside them, of this tree and of
each baseline that has it (uncertainty format 2 on). With
--folder, a calibrated FK's own score instead (folder_study). Prints `uptime` and ends with one
JSON line.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import time
import timeit
from types import ModuleType
from typing import Any

os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import numpy as np

from bench_streaming import baseline_tree  # benchmarks/, beside this file
from ctrkin.models import uncertainty as new

BASELINE = "dbab9a8"          # main before the IK's score took the joints


def _load(name: str, path: str, text: str | None = None) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    if text is None:
        spec.loader.exec_module(mod)
    else:                                   # the baseline's own text, its ood import pointed at its own ood
        exec(compile(text, path, "exec"), mod.__dict__)
    return mod


def module_of(src: str, rev: str) -> ModuleType:
    """The baseline's uncertainty module, under a name of its own (with its own ctrkin.models.ood
    where it has one)."""
    name = f"uncertainty_{rev}"
    path = f"{src}/ctrkin/models/uncertainty.py"
    if not os.path.exists(f"{src}/ctrkin/models/ood.py"):
        return _load(name, path)
    _load(f"ood_{rev}", f"{src}/ctrkin/models/ood.py")
    text = open(path, encoding="utf-8").read()
    text = text.replace("from ctrkin.models.ood import", f"from ood_{rev} import")
    return _load(name, path, text)


def walks(rng: np.random.Generator, count: int, steps: int) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Random joint walks (count·steps, 4) of a two-tube robot (α 3° steps, β 0.1 mm) and their runs."""
    rows, bounds = [], []
    for k in range(count):
        a = np.cumsum(rng.uniform(-3, 3, (steps, 2)), axis=0) + rng.uniform(-180, 180, 2)
        d = np.clip(rng.uniform(4, 12) + np.cumsum(rng.uniform(-0.1, 0.1, steps)), 4, 12)
        rows.append(np.column_stack([a, -d - 2, np.full(steps, -2.0)]))
        bounds.append((k * steps, (k + 1) * steps))
    return np.vstack(rows), bounds


def best_us(step: object, x: np.ndarray) -> float:
    return min(timeit.repeat(lambda: step(x), number=300, repeat=3)) / 300 * 1e6  # type: ignore[operator]


def per_step_us(fn: Any, xs: np.ndarray, reset: Any) -> list[float]:
    """Each call of fn over the inputs xs (T, ·) of one sequence, timed alone (µs)."""
    reset()
    out = []
    clock = time.perf_counter
    for x in xs:
        t0 = clock()
        fn(x)
        out.append((clock() - t0) * 1e6)
    return out


def folder_study(folder: str, olds: dict[str, ModuleType], rounds: int) -> dict[str, Any]:
    """A calibrated FK folder's own OOD score, streamed along five walks of benchmarks/learned_loop.py's
    training region (other draws than its training walks), with each baseline's kernel and this
    tree's (scores checked equal), and Kinematics.step against step_uncertain (this tree): medians of
    the steps timed one by one, in alternating rounds."""
    import learned_loop  # benchmarks/, beside this file
    from ctrkin import Kinematics
    from ctrkin.errors import ModelError

    kin = Kinematics.load(folder)
    if kin.task != "fk":
        raise SystemExit("--folder takes a calibrated FK folder")
    robot = kin.robot
    rng = np.random.default_rng(12345)
    xs = [learned_loop.walk(robot, rng, 40, **learned_loop.regions(robot)["train"]) for _ in range(5)]
    streams = {}
    for rev, m in olds.items():
        try:
            streams[f"{rev} FK stream"] = m.Uncertainty.load(folder).stream()
        except ModelError as exc:        # a baseline older than the file's format: left out
            print(f"{rev} left out: {exc}")
    streams["this FK stream"] = new.Uncertainty.load(folder).stream()
    want = [kin.uncertainty.ood_scores(x, [(0, len(x))]) for x in xs]  # type: ignore[union-attr]
    for name, st in streams.items():
        for x, w in zip(xs, want, strict=True):
            st.reset()
            if not np.allclose([st.step(q) for q in x], w, rtol=0, atol=1e-9):
                raise SystemExit(f"{name}'s score differs from this tree's batch score: no comparison")
    times: dict[str, list[float]] = {k: [] for k in (*streams, "step", "step_uncertain")}
    for _ in range(rounds):
        for x in xs:
            for name, st in streams.items():
                times[name] += per_step_us(st.step, x, st.reset)
            times["step"] += per_step_us(kin.step, x, kin.reset)
            times["step_uncertain"] += per_step_us(kin.step_uncertain, x, kin.reset)
    med = {k: float(np.median(v)) for k, v in times.items()}
    return {"folder": folder, "step_us": med, "ratio": med["step_uncertain"] / med["step"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", action="append", default=None,
                    help=f"a revision to time beside this tree, repeatable (default {BASELINE})")
    ap.add_argument("--rounds", type=int, default=20)
    ap.add_argument("--folder", default=None,
                    help="a calibrated FK folder (learned_loop.py --keep): its own score on walks, and its "
                         "step with and without the uncertainty")
    args = ap.parse_args()
    revs = args.baseline or [BASELINE]
    olds = {rev: module_of(str(baseline_tree(rev)), rev) for rev in revs}
    if args.folder:
        res = folder_study(args.folder, olds, args.rounds)
        load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
        print(f"{args.folder}: one streamed step (µs, median over {args.rounds} rounds of 5 walks of 40 "
              f"steps); {load}")
        for k, v in res["step_us"].items():
            print(f"  {k:30s} {v:7.2f}")
        print(f"  step_uncertain / step          {res['ratio']:7.2f}")
        print(json.dumps({"baselines": revs, **res, "uptime": load}))
        return
    rng = np.random.default_rng(0)
    x, b = walks(rng, 40, 60)
    cx, cb = walks(rng, 20, 60)
    err = rng.normal(0, 0.3, (len(cx), 3))
    streams = {f"{rev} FK": m.Uncertainty.fit("fk", 2, x, b, cx, cb, err).stream() for rev, m in olds.items()}
    streams["this FK"] = new.Uncertainty.fit("fk", 2, x, b, cx, cb, err, split="blocks").stream()  # theirs
    seq = x[:60]
    this = [streams["this FK"].step(q) for q in seq]
    for name, st in streams.items():
        st.reset()
        if not np.allclose([st.step(q) for q in seq], this, rtol=0, atol=1e-9):
            raise SystemExit(f"{name}'s FK score differs from this tree's: not the same score, no comparison")
    streams["this FK (default split)"] = new.Uncertainty.fit("fk", 2, x, b, cx, cb, err).stream()
    poses = rng.normal(0, 1, (len(x), 6)), rng.normal(0, 1, (len(cx), 6))
    ik_fit = (np.hstack([poses[0], x]), b, np.hstack([poses[1], cx]), cb, np.zeros((len(cx), 4)))
    iks = {f"{rev} IK (pose + joints)": m.Uncertainty.fit("ik", 2, *ik_fit).stream()
           for rev, m in olds.items() if getattr(m, "FORMAT", 1) >= 2}
    iks["this IK (pose + joints)"] = new.Uncertainty.fit("ik", 2, *ik_fit, split="blocks").stream()
    iks["this IK (default split)"] = new.Uncertainty.fit("ik", 2, *ik_fit).stream()
    times: dict[str, list[float]] = {k: [] for k in (*streams, *iks)}
    row = np.hstack([poses[0][10], x[10]])
    for _ in range(args.rounds):
        for name, st in streams.items():
            st.reset()
            for q in seq[:3]:
                st.step(q)
            times[name].append(best_us(st.step, seq[10]))
        for name, ik in iks.items():
            ik.reset()
            for q, p in zip(seq[:3], poses[0][:3], strict=True):
                ik.step(p, q)
            times[name].append(best_us(lambda r, ik=ik: ik.step(r[:6], r[6:]), row))
    med = {k: float(np.median(v)) for k, v in times.items()}
    load = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(f"OOD score, one streamed step (µs, median of {args.rounds} rounds; baselines {', '.join(revs)}); "
          f"{load}")
    for k, v in med.items():
        print(f"  {k:30s} {v:7.2f}")
    for rev in revs:
        print(f"  this FK − {rev} FK{'':{max(0, 15 - len(rev))}s} {med['this FK'] - med[f'{rev} FK']:+7.2f}")
    print(json.dumps({"baselines": revs, "step_us": med,
                      "fk_extra_us": {rev: med["this FK"] - med[f"{rev} FK"] for rev in revs},
                      "uptime": load}))


if __name__ == "__main__":
    main()
