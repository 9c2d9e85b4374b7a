"""Protocols on a rig (ctrkin.acquisition.rig_recorder): the virtual robot behind the rig interfaces,
replayed logs for the tracker side (statuses, reference body, averaging, tracker loss), a real
Ctrl-C (KeyboardInterrupt delivered to the main thread) and resume. Everything in tmp_path."""

from __future__ import annotations

import _thread
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from ctrkin.acquisition import protocols
from ctrkin.acquisition.plan import Plan, Run, Segment
from ctrkin.acquisition.rig_recorder import LOG_FILE, RigCollection, RigInterrupted
from ctrkin.data import Dataset
from ctrkin.hardware import open_rig
from ctrkin.hardware.interfaces import MISSING, OK, PARTIAL, RigStop, TrackerFrame
from ctrkin.hardware.readings_log import LoggedSample, ReadingsLog
from ctrkin.hardware.rig import parse_rig

IDENTITY = {"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "translation_mm": [0, 0, 0]}


def virtual_rig(readings: int = 3):
    return parse_rig({"name": "v", "robot": "paper", "home": [0.0, 0.0, -4.0, 0.0],
                      "actuator": {"kind": "virtual"},
                      "tracker": {"kind": "virtual", "readings": readings, "registration": IDENTITY},
                      "virtual": {"seed": 3, "robot_seed": 1}}, source="v.toml")


def small_paper_plan(robot):
    # two runs (levels d = 4 and 20 mm), two outer angles, the inner tube in 30° steps
    return protocols.paper(robot, scale="quick", levels=(4.0, 20.0), step_deg=30.0, outer_step_deg=180.0)


def collect(plan, rig, out: Path) -> Dataset:
    actuator, tracker = open_rig(rig)
    return RigCollection(plan, rig, actuator, tracker, out, progress=False).run()


def without_time(ds: Dataset) -> pd.DataFrame:
    return ds.frame.drop(columns=["time"])


def test_virtual_rig_records_the_protocol_in_the_dataset_format(tmp_path):
    rig = virtual_rig()
    plan = small_paper_plan(rig.robot)
    ds = collect(plan, rig, tmp_path / "out")
    f = ds.frame
    assert len(f) == plan.n_samples and f["sequence_id"].nunique() == 4
    assert (f["n_readings"] == 3).all() and (f["tracker_status"] == OK).all()
    assert (f["readings_rejected"] == 0).all() and f["time"].is_monotonic_increasing
    np.testing.assert_allclose(ds.joints(), np.concatenate([s.q for r in plan.runs for s in r.segments
                                                             if s.record]))
    assert ds.meta["collection"]["complete"] and ds.meta["orientation"] == "measured"
    # the averaged readings lie near the virtual robot's sensor, within its noise
    log = ReadingsLog(tmp_path / "out" / LOG_FILE, rig.robot.joint_names(), 1).read()
    assert len(log) == len(f) and all(len(s.frames) == 3 for s in log)
    mean0 = np.mean([fr.poses[0, :3] for fr in log[0].frames], axis=0)
    np.testing.assert_allclose(f[["x", "y", "z"]].to_numpy()[0], mean0)


def _interrupt_when(path: Path, lines: int) -> threading.Thread:
    """A real Ctrl-C: KeyboardInterrupt in the main thread once `path` has `lines` lines."""

    def watch() -> None:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if path.is_file() and path.read_text().count("\n") >= lines:
                _thread.interrupt_main()
                return
            time.sleep(0.002)

    t = threading.Thread(target=watch, daemon=True)
    t.start()
    return t


@pytest.fixture
def ctrl_c():
    """Python's own Ctrl-C handler for the test (a shell that starts pytest in the background
    ignores SIGINT, and interrupt_main then does nothing)."""
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, old)


def test_ctrl_c_stops_keeps_the_journal_and_resume_gives_the_uninterrupted_result(tmp_path, ctrl_c):
    rig = virtual_rig()
    plan = small_paper_plan(rig.robot)
    whole = collect(plan, rig, tmp_path / "whole")
    out = tmp_path / "cut"
    actuator, tracker = open_rig(rig)
    watcher = _interrupt_when(out / LOG_FILE, 1 + 3 * 40)     # header + 40 samples of 3 readings
    with pytest.raises(RigInterrupted, match=r"motors stopped.*resume"):
        RigCollection(plan, rig, actuator, tracker, out, progress=False).run()
    watcher.join()
    assert actuator._stopped                                   # the motors were told to stop
    kept = ReadingsLog(out / LOG_FILE, rig.robot.joint_names(), 1).read()
    assert 40 <= len(kept) < plan.n_samples
    resumed = collect(plan, rig, out)
    pd.testing.assert_frame_equal(without_time(resumed), without_time(whole))


def test_ctrl_c_inside_a_compiled_call_stops_as_ctrl_c_does(tmp_path):
    """A Ctrl-C that lands while numba dispatches a compiled function (the joint check) comes back as a
    SystemError caused by the KeyboardInterrupt (seen on CI): the collection stops as for Ctrl-C, the
    journal kept, and a resume gives the uninterrupted result."""
    rig = virtual_rig()
    plan = small_paper_plan(rig.robot)
    whole = collect(plan, rig, tmp_path / "whole")
    out = tmp_path / "cut"
    actuator, tracker = open_rig(rig)
    move, calls = actuator.move, [0]

    def move_interrupted_at_the_30th(q, velocity):
        calls[0] += 1
        if calls[0] == 30:
            try:
                raise KeyboardInterrupt
            except KeyboardInterrupt as e:
                raise SystemError("CPUDispatcher(<function joint_violations>) returned a result with an "
                                  "exception set") from e
        return move(q, velocity)

    actuator.move = move_interrupted_at_the_30th
    with pytest.raises(RigInterrupted, match=r"motors stopped.*resume"):
        RigCollection(plan, rig, actuator, tracker, out, progress=False).run()
    assert actuator._stopped
    kept = ReadingsLog(out / LOG_FILE, rig.robot.joint_names(), 1).read()
    assert 20 <= len(kept) < plan.n_samples
    resumed = collect(plan, rig, out)
    pd.testing.assert_frame_equal(without_time(resumed), without_time(whole))


def test_another_error_inside_a_compiled_call_is_not_taken_for_ctrl_c(tmp_path):
    rig = virtual_rig()
    plan = small_paper_plan(rig.robot)
    actuator, tracker = open_rig(rig)

    def move_failing(q, velocity):
        raise SystemError("a result with an exception set") from ValueError("not an interrupt")

    actuator.move = move_failing
    with pytest.raises(SystemError):
        RigCollection(plan, rig, actuator, tracker, tmp_path / "out", progress=False).run()
    assert actuator._stopped


def test_resume_drops_an_incomplete_last_sample_and_refuses_another_protocol(tmp_path):
    rig = virtual_rig()
    plan = small_paper_plan(rig.robot)
    whole = collect(plan, rig, tmp_path / "whole")
    out = tmp_path / "cut"
    collect(plan, rig, out)
    text = (out / LOG_FILE).read_text().splitlines(keepends=True)
    (out / LOG_FILE).write_text("".join(text[:1 + 3 * 30 + 2]) + text[1 + 3 * 30 + 2][:17])  # a cut line
    resumed = collect(plan, rig, out)
    pd.testing.assert_frame_equal(without_time(resumed), without_time(whole))
    other = protocols.sweeps(rig.robot, levels=(4.0,), step_deg=90.0)
    with pytest.raises(Exception, match="another protocol"):
        collect(other, rig, out)


def _logged_plan(tmp_path: Path, statuses, ref_rot: Rotation, ref_pos, tips):
    """A 4-step plan and a readings log for it: two tools (tip, reference), the tip given in the
    reference frame; statuses[k] lists the tip status of each reading of sample k."""
    q = np.array([[0.0, 0.0, -10.0, 0.0], [10.0, 0.0, -10.0, 0.0], [20.0, 0.0, -10.0, 0.0],
                  [30.0, 0.0, -10.0, 0.0]])
    plan = Plan("test", (Run((Segment(q),)),))
    joints = ["alpha_1", "alpha_2", "beta_1", "beta_2"]
    log = ReadingsLog(tmp_path / "rec.csv", joints, 2)
    log.start()
    qref = np.roll(ref_rot.as_quat(), 1)          # (w, x, y, z)
    for k, st in enumerate(statuses):
        s = LoggedSample((0, 0, k), q[k], q[k] + 0.01)
        for r, status in enumerate(st):
            tip = ref_rot.apply(tips[k] + 0.1 * r) + ref_pos
            tip_q = np.roll((ref_rot * Rotation.from_rotvec([0.2, 0.0, 0.0])).as_quat(), 1)
            poses = np.array([[*tip, *tip_q], [*ref_pos, *qref]])
            if status == MISSING:
                poses[0] = np.nan
            s.frames.append(TrackerFrame(float(r), poses, (status, OK), np.array([0.1, 0.1])))
            s.used.append(False)
            s.times.append(float(r))
        log.append(s)
    rig = parse_rig({"robot": "paper", "home": [0.0, 0.0, -10.0, 0.0],
                     "actuator": {"kind": "replay", "log": "rec.csv"},
                     "tracker": {"kind": "replay", "log": "rec.csv", "readings": 2, "sensor_tool": 1,
                                 "reference_tool": 2, "max_bad_readings": 2}},
                    source=str(tmp_path / "replay.toml"), folder=tmp_path)
    return plan, rig


def test_replay_averages_accepted_readings_relative_to_the_reference(tmp_path):
    ref_rot, ref_pos = Rotation.from_rotvec([0.3, -0.2, 1.0]), np.array([100.0, -50.0, -1200.0])
    tips = np.array([[1.0, 2.0, 60.0], [3.0, 2.0, 61.0], [5.0, 1.0, 62.0], [6.0, 0.0, 63.0]])
    statuses = [[OK, OK], [PARTIAL, OK, OK], [MISSING, MISSING, OK, OK], [OK, OK]]
    plan, rig = _logged_plan(tmp_path, statuses, ref_rot, ref_pos, tips)
    ds = collect(plan, rig, tmp_path / "out")
    f = ds.frame
    # used readings: sample 1 its readings 1, 2; sample 2 its readings 2, 3 (offsets 0.1 r)
    used_r = [[0, 1], [1, 2], [2, 3], [0, 1]]
    expect = np.array([tips[k] + 0.1 * np.mean(r) for k, r in enumerate(used_r)])
    np.testing.assert_allclose(f[["x", "y", "z"]].to_numpy(), expect, atol=1e-9)
    assert f["readings_rejected"].tolist() == [0, 1, 2, 0]
    np.testing.assert_allclose(ds.joints(), plan.runs[0].segments[0].q + 0.01)   # the encoders
    tangent = Rotation.from_rotvec([0.2, 0.0, 0.0]).apply([0, 0, 1.0])         # the tip axis in the ref frame
    from ctrkin.geometry import tangent_from_quat

    np.testing.assert_allclose(tangent_from_quat(ds.poses()[:, 3:]), np.tile(tangent, (4, 1)), atol=1e-9)


def test_tracker_loss_stops_the_rig_and_keeps_what_was_recorded(tmp_path):
    ref_rot, ref_pos = Rotation.identity(), np.zeros(3)
    tips = np.array([[1.0, 2.0, 60.0]] * 4)
    statuses = [[OK, OK], [OK, OK], [MISSING, MISSING, MISSING, OK], [OK, OK]]
    plan, rig = _logged_plan(tmp_path, statuses, ref_rot, ref_pos, tips)
    actuator, tracker = open_rig(rig)
    collection = RigCollection(plan, rig, actuator, tracker, tmp_path / "out", progress=False)
    with pytest.raises(RigStop, match=r"tool 1 missing in 3 readings.*2 samples kept"):
        collection.run()
    part = collection.dataset(complete=False)
    assert len(part.frame) == 2 and not part.meta["collection"]["complete"]


def test_a_move_outside_the_limits_is_refused_before_the_motors_move(tmp_path):
    rig = parse_rig({"robot": "paper", "home": [0.0, 0.0, -4.0, 0.0], "actuator": {"kind": "virtual",
                     "drives": [{"joint": "alpha_1", "min": -40.0, "max": 40.0}]},
                     "tracker": {"kind": "virtual", "readings": 1}}, source="lim.toml")
    plan = protocols.sweeps(rig.robot, levels=(4.0,), step_deg=30.0)
    actuator, tracker = open_rig(rig)
    collection = RigCollection(plan, rig, actuator, tracker, tmp_path / "out", progress=False)
    with pytest.raises(RigStop, match=r"alpha_1 = 60 is outside the rig's limits \[-40, 40\].*kept"):
        collection.run()
    assert abs(actuator.read()[0] - 30.0) < 0.1     # the last move it made (to an encoder count)
    assert len(collection.dataset(complete=False).frame) == 2


def test_replaying_a_recorded_collection_gives_its_dataset_again(tmp_path):
    rig = virtual_rig()
    plan = small_paper_plan(rig.robot)
    first = collect(plan, rig, tmp_path / "rec")
    replay = parse_rig({"robot": "paper", "home": rig.home.tolist(),
                        "actuator": {"kind": "replay", "log": str(tmp_path / "rec" / LOG_FILE)},
                        "tracker": {"kind": "replay", "log": str(tmp_path / "rec" / LOG_FILE), "readings": 3,
                                    "registration": IDENTITY}}, source="replay.toml")
    again = collect(plan, replay, tmp_path / "again")
    cols = [c for c in first.frame.columns if c != "time"]
    pd.testing.assert_frame_equal(again.frame[cols], first.frame[cols])
