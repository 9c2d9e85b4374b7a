"""Record a protocol plan on the virtual robot into a `ctrkin.data.Dataset`.

Runs are independent (each starts at rest from a point-wise solve), so they are recorded in parallel
worker processes; every run draws its measurement noise from its own stream
SeedSequence([seed, run index]), so a dataset does not depend on the number of workers.

Columns beyond the schema (src/ctrkin/data/schema.py):
  run        int64  the run the sequence belongs to (state carries over between its sequences)
  level      int64  index into meta["levels"] (relative translation level), −1 if none
  direction  int8   sign of the commanded inner-tube rotation step into the sample (+1, −1, 0)
  is_target  bool   a target configuration (random-points protocol)
  n_readings int64  tracker readings averaged into the sample
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from ctrkin.acquisition.plan import Plan, Run
from ctrkin.data import Dataset, schema
from ctrkin.util.progress import progress_bar
from ctrkin.virtual.robot import VirtualRobot

NOISE_STREAM = 0xDA7A


class _NullBar:
    def update(self, n: int = 1) -> None:
        pass


@dataclass(frozen=True, eq=False)
class _Chunk:
    """One recorded segment (one sequence)."""

    joints: np.ndarray
    measured: np.ndarray
    true: np.ndarray
    snap: np.ndarray
    outlier: np.ndarray
    direction: np.ndarray
    is_target: np.ndarray
    level: int


def record_run(virtual: VirtualRobot, run: Run, run_index: int, seed: int,
               on_segment: Any = None) -> list[_Chunk]:
    """Perform one run on the virtual robot and keep its recorded segments.

    Parameters
    ----------
    virtual : VirtualRobot
    run : Run
        Starts at rest at its first joints; state carries over between its segments.
    run_index : int
        Selects the run's own noise stream (the data do not depend on how runs are spread over
        workers).
    seed : int
        The recording's seed.
    on_segment : callable, optional
        Called with the segment's step count after each segment (progress).

    Returns
    -------
    list of _Chunk
        One per recorded segment. A snap during an unrecorded transition is flagged on the next
        recorded sample.
    """
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), NOISE_STREAM, int(run_index)]))
    state = virtual.rest(run.start)
    prev_alpha = float(run.start[0])
    pending_snap = False
    chunks = []
    for seg in run.segments:
        motion, state = virtual.move(state, seg.q)
        if on_segment is not None:
            on_segment(seg.q.shape[0])
        if not seg.record:
            pending_snap = pending_snap or bool(motion.snaps.any())
            prev_alpha = float(seg.q[-1, 0])
            continue
        rec = virtual.record(motion, rng)
        snaps = motion.snaps.copy()
        snaps[0] |= pending_snap
        pending_snap = False
        direction = np.sign(np.diff(np.r_[prev_alpha, seg.q[:, 0]])).astype(np.int8)
        target = seg.is_target if seg.is_target is not None else np.zeros(seg.q.shape[0], dtype=bool)
        chunks.append(_Chunk(rec.joints, rec.measured, motion.true_poses, snaps, rec.outlier,
                             direction, target, seg.level))
        prev_alpha = float(seg.q[-1, 0])
    return chunks


# --- worker processes (fork: the parent's compiled kernels and objects are inherited) ------------
_JOB: dict[str, Any] = {}


def _worker_run(run_index: int) -> list[_Chunk]:
    counter = _JOB["counter"]

    def bump(k: int) -> None:
        with counter.get_lock():
            counter.value += k

    return record_run(_JOB["virtual"], _JOB["plan"].runs[run_index], run_index, _JOB["seed"], bump)


def _record_parallel(plan: Plan, virtual: VirtualRobot, seed: int, workers: int,
                     make_bar: Callable[[], Any]) -> list[list[_Chunk]]:
    """Record the runs in `workers` forked processes; the progress bar (and its monitor thread) is
    started only after the fork."""
    ctx = mp.get_context("fork")
    counter = ctx.Value("q", 0)
    _JOB.update(virtual=virtual, plan=plan, seed=seed, counter=counter)
    try:
        with ctx.Pool(workers) as pool, make_bar() as bar:
            # longest (most steps) runs first, so the last worker is not left with a long run alone
            order = sorted(range(len(plan.runs)), key=lambda i: -plan.runs[i].n_steps)
            pending = {i: pool.apply_async(_worker_run, (i,)) for i in order}
            done = 0
            while True:
                ready = all(r.ready() for r in pending.values())
                now = counter.value
                bar.update(now - done)
                done = now
                if ready:
                    break
                time.sleep(0.2)
            return [pending[i].get() for i in range(len(plan.runs))]
    finally:
        _JOB.clear()


def record(plan: Plan, virtual: VirtualRobot, seed: int = 0, workers: int | None = None,
           progress: bool = True, meta: dict[str, Any] | None = None) -> Dataset:
    """Perform a plan on the virtual robot and return the dataset of its recorded segments.

    Parameters
    ----------
    plan : Plan
        What to do (`ctrkin.acquisition.protocols.build`).
    virtual : VirtualRobot
        The robot (its robot seed is the hardware draw).
    seed : int
        Measurement noise and encoder glitches; each run draws from its own stream, so the dataset
        does not depend on `workers` (tested).
    workers : int, optional
        Processes (default: all cores, at most one per run; 1 records in this process).
    progress : bool
        Report progress on stderr (`ctrkin.util.progress`).
    meta : dict, optional
        Extra entries for the dataset's meta.

    Returns
    -------
    Dataset
        One sequence per recorded segment, with the true poses, the `run`, `level`, `direction`,
        `is_target` and `n_readings` columns, and the virtual robot's description in the meta.
    """
    n_workers = min(workers if workers is not None else (os.cpu_count() or 1), len(plan.runs))
    n_workers = max(n_workers, 1)

    def make_bar() -> Any:
        if not progress:
            return contextlib.nullcontext(_NullBar())
        return progress_bar(total=plan.n_steps, desc=f"collect {plan.protocol}", unit="step")

    if n_workers == 1 or "fork" not in mp.get_all_start_methods():
        with make_bar() as bar:
            per_run = [record_run(virtual, run, i, seed, bar.update) for i, run in enumerate(plan.runs)]
    else:
        virtual.rest(plan.runs[0].start)  # compile / load the kernels once before forking
        per_run = _record_parallel(plan, virtual, seed, n_workers, make_bar)
    frame = _frame(virtual, per_run)
    info = {"protocol": plan.protocol, "protocol_params": plan.params, "levels": list(plan.levels),
            "seed": int(seed), "source": "virtual robot", "virtual_robot": virtual.describe(),
            "extra_columns": {"run": "run index (state carries over between its sequences)",
                              "level": "index into levels, -1 if none",
                              "direction": "sign of the commanded inner rotation step into the sample",
                              "is_target": "a target configuration (random-points)",
                              "n_readings": "tracker readings averaged into the sample"},
            **(meta or {})}
    return Dataset(frame=frame, robot=virtual.nominal, meta=info)


def _frame(virtual: VirtualRobot, per_run: list[list[_Chunk]]) -> pd.DataFrame:
    n = virtual.nominal.n_tubes
    chunks = [(ri, c) for ri, run in enumerate(per_run) for c in run]
    if not chunks:
        raise ValueError("the plan records no samples")
    lengths = np.array([c.joints.shape[0] for _, c in chunks])
    cols: dict[str, Any] = {
        "sequence_id": np.repeat(np.arange(len(chunks), dtype=np.int64), lengths),
        "step": np.concatenate([np.arange(k, dtype=np.int64) for k in lengths]),
    }
    joints = np.concatenate([c.joints for _, c in chunks])
    for k, name in enumerate(schema.joint_columns(n)):
        cols[name] = joints[:, k]
    measured = np.concatenate([c.measured for _, c in chunks])
    true = np.concatenate([c.true for _, c in chunks])
    for k, name in enumerate(schema.POSE_COLUMNS):
        cols[name] = measured[:, k]
    for k, name in enumerate(schema.TRUE_POSE_COLUMNS):
        cols[name] = true[:, k]
    cols["snap"] = np.concatenate([c.snap for _, c in chunks])
    cols["outlier"] = np.concatenate([c.outlier for _, c in chunks])
    cols["run"] = np.repeat(np.array([ri for ri, _ in chunks], dtype=np.int64), lengths)
    cols["level"] = np.repeat(np.array([c.level for _, c in chunks], dtype=np.int64), lengths)
    cols["direction"] = np.concatenate([c.direction for _, c in chunks])
    cols["is_target"] = np.concatenate([c.is_target for _, c in chunks])
    cols["n_readings"] = np.full(lengths.sum(), virtual.config.readings_per_sample, dtype=np.int64)
    return pd.DataFrame(cols)
