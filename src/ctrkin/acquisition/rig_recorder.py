"""Run a protocol plan on a rig (`ctrkin collect --rig`): the same plans as the virtual recorder,
performed by an actuator and read by a tracker (ctrkin.hardware), into the same dataset format.

Per protocol run: the rig homes (when `home_every_run`, as each run starts from rest on the virtual
robot), approaches the run's first joints from home in 1°/0.1 mm steps, then performs every
segment step by step. Before every move the joints are checked against the drives' limits and the
robot's valid set, and the velocity is capped by the drives' `max_velocity`. After a recorded
step it takes `readings` tracker readings that the safety rules accept (the tip sensor, and the
reference body if any, seen with an accepted status and inside `volume_mm`) and averages them, as
the paper averaged five (position: mean; orientation: normalised mean tip tangent). More than
`max_bad_readings` unusable readings in a row stop the motors (RigStop); so does Ctrl-C.

Every sample's readings are appended to `readings.csv` in --out and flushed before the next move
(hardware/readings_log.py): the journal. Whatever stops a collection, what was recorded stays, and
the same command resumes it: the rig homes, re-drives the interrupted run from its start without
reading (so backlash and the snapping branch are where an uninterrupted run would have them) and
records from the first missing sample on. On the virtual rig, whose noise is keyed to the run and
move, the resumed dataset equals the uninterrupted one (tested). At the end, or after a stop, the
dataset is built from the journal (data.parquet, meta.json beside it; meta["collection"] says
whether it is complete).

Extra columns (beyond data/schema.py): run, level, direction, is_target (as the virtual
recorder), tracker_status (the worst status among the averaged readings), readings_rejected
(unusable readings taken for the sample), n_readings, time (s since the collection's first reading).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ctrkin.acquisition.plan import Plan, move
from ctrkin.data import Dataset, schema
from ctrkin.data.cleaning import CleaningConfig, snap_mask
from ctrkin.errors import CtrkinError, JointError
from ctrkin.geometry import RigidTransform, quat_from_tangent, quaternion_to_matrix
from ctrkin.hardware.interfaces import (
    STATUSES,
    Actuator,
    HardwareError,
    RigStop,
    Tracker,
    TrackerFrame,
)
from ctrkin.hardware.readings_log import LoggedSample, ReadingsLog
from ctrkin.hardware.rig import RigDescription
from ctrkin.util.ownership import MARKER, RIG_JOURNAL, write_marker
from ctrkin.util.progress import progress_bar
from ctrkin.version import __version__

SESSION_FILE, LOG_FILE = RIG_JOURNAL     # the journal (util.ownership counts it as the dataset's)
OWNED_FILES = (LOG_FILE, SESSION_FILE, "data.parquet", "meta.json", "split.json")


class RigInterrupted(RigStop):
    """Ctrl-C during a collection: the motors were stopped, what was recorded is kept."""


class CollectionMismatch(CtrkinError):
    """--out holds a collection made with another protocol, parameters or rig file."""


@dataclass(frozen=True, eq=False)
class _Step:
    """One commanded step of the plan: run, its position in the run, joints; a recorded step also
    has its sample key (run, sequence, step) and the segment's level / target flag."""

    run: int
    q: np.ndarray
    key: tuple[int, int, int] | None
    level: int = -1
    is_target: bool = False


def plan_steps(plan: Plan) -> list[list[_Step]]:
    """Per run, its steps in order; recorded segments numbered as dataset sequences in plan order."""
    runs, seq = [], 0
    for r, run in enumerate(plan.runs):
        steps = []
        for seg in run.segments:
            for k, q in enumerate(seg.q):
                key = (r, seq, k) if seg.record else None
                target = bool(seg.is_target[k]) if seg.is_target is not None else False
                steps.append(_Step(r, q, key, seg.level, target))
            seq += int(seg.record)
        runs.append(steps)
    return runs


def session_info(plan: Plan, rig: RigDescription) -> dict[str, Any]:
    """What must match for a collection in --out to be resumed."""
    blob = json.dumps({"protocol": plan.protocol, "params": plan.params,
                       "joints": plan.all_joints().round(9).tolist()}, sort_keys=True, default=str)
    return {"protocol": plan.protocol, "protocol_params": plan.params,
            "plan_sha256": hashlib.sha256(blob.encode()).hexdigest(),
            "rig": rig.name, "rig_fingerprint": rig.fingerprint(), "ctrkin_version": __version__}


class _Clock:
    """Steps done and time left, for the progress bar (mean seconds per step of this session)."""

    def __init__(self, total: int, done: int) -> None:
        self.total, self.done, self.t0, self.here = total, done, time.monotonic(), 0

    def step(self) -> str:
        self.done += 1
        self.here += 1
        left = (self.total - self.done) * (time.monotonic() - self.t0) / max(self.here, 1)
        h, m = divmod(int(left) // 60, 60)
        return f"{h}h{m:02d}m" if h else f"{m}m{int(left) % 60:02d}s"


class RigCollection:
    """One collection of `plan` on a rig into folder `out` (module docstring)."""

    def __init__(self, plan: Plan, rig: RigDescription, actuator: Actuator, tracker: Tracker,
                 out: str | Path, progress: bool = True, log: Callable[[str], None] | None = None) -> None:
        self.plan, self.rig, self.actuator, self.tracker = plan, rig, actuator, tracker
        self.out = Path(out)
        self.progress, self.say = progress, log or (lambda _m: None)
        spec = rig.tracker
        self.sensor = spec.sensor_tool - 1
        self.reference = spec.reference_tool - 1
        self.n_tools = max(getattr(tracker, "n_tools", 1), spec.sensor_tool, spec.reference_tool)
        self.journal = ReadingsLog(self.out / LOG_FILE, rig.robot.joint_names(), self.n_tools)
        self.info = session_info(plan, rig)

    # --- journal and resume -----------------------------------------------------------------------
    def recorded(self) -> dict[tuple[int, int, int], LoggedSample]:
        """The complete samples already in the journal (a last incomplete one is dropped from it)."""
        session = self.out / SESSION_FILE
        if not session.is_file():
            return {}
        stored = json.loads(session.read_text())
        for key in ("plan_sha256", "rig_fingerprint"):
            if stored.get(key) != self.info[key]:
                what = "protocol or its parameters" if key == "plan_sha256" else "rig file"
                raise CollectionMismatch(f"{self.out} holds a collection made with another {what}; resume it "
                                    "with the same command, or pass --overwrite to start over")
        samples = self.journal.read()
        need = self.rig.tracker.readings
        complete = [s for s in samples if sum(s.used) >= need]
        if len(complete) != len(samples):
            self.journal.rewrite(complete)
        return {s.key: s for s in complete}

    def _start_session(self) -> None:
        self.out.mkdir(parents=True, exist_ok=True)
        if not (self.out / MARKER).is_file():    # a ctrkin dataset from its first reading (util.ownership)
            write_marker(self.out, "dataset")
        session = self.out / SESSION_FILE
        if not session.is_file():
            session.write_text(json.dumps(self.info, indent=2, default=str))
        self.journal.start()

    # --- safety and readings ----------------------------------------------------------------------
    def _usable(self, frame: TrackerFrame) -> str | None:
        """None if the frame can be averaged, else why not."""
        spec = self.rig.tracker
        tools = [self.sensor] + ([self.reference] if self.reference >= 0 else [])
        for k in tools:
            if not frame.ok(k, spec.accept):
                return f"tool {k + 1} {frame.status[k]}"
        if spec.volume_min:
            p = frame.poses[self.sensor, :3]
            if (p < np.array(spec.volume_min)).any() or (p > np.array(spec.volume_max)).any():
                return f"tool {self.sensor + 1} outside volume_mm at {np.round(p, 1).tolist()}"
        return None

    def _sample(self, step: _Step, encoder: np.ndarray) -> LoggedSample:
        spec = self.rig.tracker
        key = step.key if step.key is not None else (step.run, -1, -1)
        s = LoggedSample(key, np.asarray(step.q, float), encoder)
        bad = 0
        while sum(s.used) < spec.readings:
            frame = self.tracker.read()
            why = self._usable(frame)
            s.frames.append(frame)
            s.used.append(why is None)
            s.times.append(time.time())
            bad = 0 if why is None else bad + 1
            if bad > spec.max_bad_readings:
                raise RigStop(f"tracker: {why} in {bad} readings in a row (run {key[0]}, sequence "
                              f"{key[1]}, step {key[2]}); motors stopped")
        return s

    def _move(self, q: np.ndarray) -> np.ndarray:
        self.rig.check(q)           # drive limits and the robot's valid joints, before every move
        return self.actuator.move(q, self.rig.velocity())

    # --- the run loop -----------------------------------------------------------------------------
    def run(self) -> Dataset:
        """Perform the plan (resuming what the journal holds) and return the complete dataset; a
        stop (RigStop, RigInterrupted, HardwareError) leaves the journal and a partial dataset."""
        self._start_session()
        done = self.recorded()
        runs = plan_steps(self.plan)
        total = sum(len(r) for r in runs)
        skip = sum(len(r) for r in runs if all(s.key is None or s.key in done for s in r))
        if done:
            self.say(f"resuming: {len(done)} samples already recorded in {self.out / LOG_FILE}")
        clock = _Clock(total, skip)
        bar = (progress_bar(total=total, desc=f"collect {self.plan.protocol} on {self.rig.name}",
                            unit="step", initial=skip) if self.progress else None)
        try:
            self.tracker.start()
            self._runs(runs, done, clock, bar)
        except (RigStop, HardwareError) as e:
            self._halt()
            raise type(e)(f"{e}; {self._kept()}") from None
        except JointError as e:         # a joint limit: a safety stop like the others
            self._halt()
            raise RigStop(f"refused to move: {e}; motors stopped; {self._kept()}") from None
        except (KeyboardInterrupt, Exception) as e:
            self._halt()
            if _caused_by_interrupt(e):     # Ctrl-C, also one that a compiled (numba) call re-raised
                raise RigInterrupted(f"interrupted (Ctrl-C): motors stopped; {self._kept()}") from None
            raise
        finally:
            if bar is not None:
                bar.close()
            self._close()
        return self.dataset(complete=True)

    def _runs(self, runs: list[list[_Step]], done: dict, clock: _Clock, bar: Any) -> None:
        homed = False
        for r, steps in enumerate(runs):
            if all(s.key is None or s.key in done for s in steps):
                continue
            self.actuator.begin_run(r)
            self.tracker.begin_run(r)
            if self.rig.home_every_run or not homed:
                here = self.actuator.home()
                homed = True
            else:
                here = self.actuator.read()
            for q in move(here, steps[0].q, self.rig.robot.n_tubes)[:-1]:   # approach, not recorded;
                self._move(q)                                              # the run's first step ends it
            for step in steps:
                encoder = self._move(step.q)
                if step.key is not None and step.key not in done:
                    sample = self._sample(step, encoder)
                    self.journal.append(sample)
                    done[step.key] = sample
                left = clock.step()
                if bar is not None:
                    bar.update(1)
                    bar.set_postfix(left=left)

    def _halt(self) -> None:
        try:
            self.actuator.stop()
        except Exception as e:      # the original error matters more; say this one too
            self.say(f"warning: stopping the motors failed: {e}")

    def _close(self) -> None:
        for what in (self.tracker.stop, self.actuator.close):
            try:
                what()
            except Exception as e:
                self.say(f"warning: closing the rig: {e}")

    def _kept(self) -> str:
        n = len(self.journal.read())
        return (f"{n} samples kept in {self.out / LOG_FILE}; run the same command to resume "
                "(the run in progress is re-driven from its start, then recording goes on)")

    # --- the dataset --------------------------------------------------------------------------------
    def dataset(self, complete: bool) -> Dataset:
        """The dataset of the journal's samples, in plan order (empty journal: a HardwareError)."""
        samples = self.journal.read()
        if not samples:
            raise HardwareError(f"{self.out / LOG_FILE} holds no complete sample yet")
        frame, orientation = samples_frame(samples, self.rig, self.sensor, self.reference)
        runs = plan_steps(self.plan)
        extra = {s.key: s for r in runs for s in r if s.key is not None}
        frame["level"] = np.array([extra[s.key].level for s in samples], dtype=np.int64)
        frame["is_target"] = np.array([extra[s.key].is_target for s in samples], dtype=bool)
        expected = sum(1 for r in runs for s in r if s.key is not None)
        meta = {"protocol": self.plan.protocol, "protocol_params": self.plan.params,
                "levels": list(self.plan.levels), "seed": self.rig.virtual.get("seed"),
                "source": f"rig {self.rig.name}", "rig": self.rig.to_dict(),
                "orientation": orientation,
                "collection": {"complete": complete and len(samples) == expected, "samples": len(samples),
                               "planned_samples": expected, "readings_log": LOG_FILE,
                               "readings_per_sample": self.rig.tracker.readings},
                "frame": ("robot base (the rig file's registration)" if self.rig.tracker.registration
                          else "reference tool" if self.reference >= 0 else "tracker"),
                "extra_columns": {
                    "run": "protocol run (state carries over between its sequences)",
                    "level": "index into levels, -1 if none",
                    "direction": "sign of the commanded inner rotation step into the sample",
                    "is_target": "a target configuration (random-points)",
                    "tracker_status": "worst tool status among the averaged readings",
                    "readings_rejected": "unusable readings taken for the sample (safety rules)",
                    "n_readings": "tracker readings averaged into the sample"}}
        return Dataset(frame=frame, robot=self.rig.robot, meta=meta)


def samples_frame(samples: list[LoggedSample], rig: RigDescription, sensor: int, reference: int
                  ) -> tuple[pd.DataFrame, str]:
    """The dataset rows of logged samples (module docstring) and the orientation ("measured" or
    "absent")."""
    n = rig.robot.n_tubes
    registration = (RigidTransform.from_dict(rig.tracker.registration)
                    if rig.tracker.registration else None)
    tangent_orientation = rig.tracker.orientation == "tangent"
    pos, tan, status, rejected, used_n, t0 = [], [], [], [], [], []
    rank = {s: k for k, s in enumerate(STATUSES)}
    for s in samples:
        use = [f for f, u in zip(s.frames, s.used, strict=True) if u]
        p = np.array([f.poses[sensor, :3] for f in use])
        R = quaternion_to_matrix(np.array([f.poses[sensor, 3:7] for f in use]))
        axis = R[:, :, 2]                       # the sensor's z axis: the tip tangent (5-DOF sensor)
        if reference >= 0:
            Rr = quaternion_to_matrix(np.array([f.poses[reference, 3:7] for f in use]))
            pr = np.array([f.poses[reference, :3] for f in use])
            p = np.einsum("rji,rj->ri", Rr, p - pr)          # p = R_refᵀ (p_tip − p_ref)
            axis = np.einsum("rji,rj->ri", Rr, axis)
        mean_axis = axis.mean(axis=0)
        pos.append(p.mean(axis=0))
        tan.append(mean_axis / np.linalg.norm(mean_axis))
        status.append(max((f.status[sensor] for f in use), key=lambda x: rank.get(x, len(rank))))
        rejected.append(len(s.used) - len(use))
        used_n.append(len(use))
        t0.append(s.times[0])
    position, tangent = np.array(pos), np.array(tan)
    if registration is not None:          # tracker -> robot base: p = Rᵀ (p_tracker − t)
        position = (position - registration.translation) @ registration.rotation
        tangent = tangent @ registration.rotation
    if not tangent_orientation:
        tangent = np.tile([0.0, 0.0, 1.0], (len(samples), 1))
    keys = np.array([s.key for s in samples])
    seq = keys[:, 1]
    joints = np.array([s.encoder for s in samples])
    cols: dict[str, Any] = {"sequence_id": np.unique(seq, return_inverse=True)[1].astype(np.int64),
                            "step": keys[:, 2].astype(np.int64)}
    for k, name in enumerate(schema.joint_columns(n)):
        cols[name] = joints[:, k]
    pose = np.column_stack([position, quat_from_tangent(tangent)])
    for k, name in enumerate(schema.POSE_COLUMNS):
        cols[name] = pose[:, k]
    snap = np.zeros(len(samples), dtype=bool)
    if registration is not None:            # the T(L) rule needs the robot base frame
        for a, b in schema.sequence_bounds(seq):
            snap[a:b] = snap_mask(joints[a:b], position[a:b], n, CleaningConfig())
    cols["snap"] = snap
    cols["outlier"] = np.zeros(len(samples), dtype=bool)
    cols["run"] = keys[:, 0].astype(np.int64)
    cmd = np.array([s.command[0] for s in samples])
    direction = np.zeros(len(samples), dtype=np.int8)
    for a, b in schema.sequence_bounds(seq):
        direction[a + 1:b] = np.sign(np.diff(cmd[a:b])).astype(np.int8)
    cols["direction"] = direction
    cols["tracker_status"] = status
    cols["readings_rejected"] = np.array(rejected, dtype=np.int64)
    cols["n_readings"] = np.array(used_n, dtype=np.int64)
    cols["time"] = np.array(t0) - t0[0]
    return pd.DataFrame(cols), "measured" if tangent_orientation else "absent"


def write_dataset(ds: Dataset, out: Path) -> None:
    """data.parquet and meta.json of `ds` into the collection folder `out`, beside its journal
    (each file replaced in one rename; meta's data_sha256 tells a reader if they do not belong
    together, and the journal can always rebuild them)."""
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.dataset.", dir=out.parent))
    try:
        ds.save(tmp / "ds")
        for name in ("data.parquet", "meta.json"):
            os.replace(tmp / "ds" / name, out / name)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _caused_by_interrupt(e: BaseException) -> bool:
    """Whether a KeyboardInterrupt is among the causes of `e`: a Ctrl-C delivered while numba
    dispatches a compiled function comes back as a SystemError ("... returned a result with an
    exception set") whose cause is the interrupt."""
    seen: set[int] = set()
    cause: BaseException | None = e
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, KeyboardInterrupt):
            return True
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return False
