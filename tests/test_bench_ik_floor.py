"""benchmarks/bench_ik_floor.py's floor (issue 21): the recorded joints driven as an IK's are, each
sequence from rest. On a frictionless robot away from the bistable band a rest start is the recorded
state and the floor is the noise (none here); with friction between the tubes a sequence that
continued a run starts elsewhere from rest, and the floor is that start's transient, which replaying
the run up to the sequence removes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ctrkin.acquisition.plan import Plan, Run, Segment
from ctrkin.acquisition.protocols import config
from ctrkin.acquisition.recorder import record
from ctrkin.data.splits import Split
from ctrkin.robots import paper_robot
from ctrkin.virtual import VirtualConfig, VirtualRobot
from tests.benchmark_scripts import load_benchmark


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("bench_ik_floor")


def _two_legs(virtual: VirtualRobot, d: float):
    """One run from rest: the inner tube turns 0 → 120° (a sequence), then back to 0° (another)."""
    robot = virtual.nominal
    up, down = np.arange(0.0, 121.0, 1.0), np.arange(119.0, -1.0, -1.0)
    segs = tuple(Segment(config(2, a, np.zeros(len(a)), -5.0, d), level=0) for a in (up, down))
    ds = record(Plan("legs", (Run(segs),), ({"relative_translation_mm": d},), {}), virtual, seed=0,
                workers=1, progress=False)
    rows = np.arange(len(ds.frame))
    ds.split = Split(rows[:0], rows[:0], rows, "sequence", 0, (0.0, 0.0, 1.0), len(rows))
    assert ds.robot.fingerprint() == robot.fingerprint()
    return ds


def test_the_floor_is_the_noise_where_a_rest_start_is_the_recorded_state(bench) -> None:
    ideal = VirtualConfig().ideal()
    virtual = VirtualRobot(paper_robot(), ideal, seed=0)
    floor = bench.recorded(virtual, _two_legs(virtual, 4.0))
    assert floor["noise_mm"] == 0.0
    assert floor["recorded_mm"] < 1e-6 and floor["recorded_within_1mm"] == 1.0


def test_with_friction_the_second_leg_starts_elsewhere_from_rest(bench) -> None:
    sticky = dataclasses.replace(VirtualConfig().ideal(), tube_friction=0.69)
    virtual = VirtualRobot(paper_robot(), sticky, seed=0)
    ds = _two_legs(virtual, 4.0)
    floor = bench.recorded(virtual, ds)
    assert floor["noise_mm"] == 0.0
    # the first leg starts from rest as recorded; the second one was wound up the other way
    assert floor["recorded_first_mm"] > 0.1
    assert floor["recorded_first_mm"] > 3 * floor["recorded_after_mm"]
    # with the run replayed up to it, the second leg starts where the recording did
    assert bench.replayed(virtual, ds)["replayed_mm"] < 1e-6


def test_the_lookup_reference_answers_a_training_sequence_with_its_own_joints(bench) -> None:
    virtual = VirtualRobot(paper_robot(), VirtualConfig().ideal(), seed=0)
    ds = _two_legs(virtual, 4.0)
    rows = np.arange(len(ds.frame))
    ds.split = Split(rows, rows, rows, "sequence", 0, (1.0, 1.0, 1.0), len(rows))
    figures = bench.lookup(virtual, ds, ds)
    assert figures["lookup_test_mm"] < 1e-6 and figures["lookup_val_mm"] < 1e-6


def test_bench_generalisation_reads_the_floor_of_a_reproductions_data(bench, tmp_path) -> None:
    gen = load_benchmark("bench_generalisation")
    virtual = VirtualRobot(paper_robot(), VirtualConfig().ideal(), seed=0)
    ds = _two_legs(virtual, 4.0)
    ds.save(tmp_path / "paper")
    ds.save_split(tmp_path / "paper", ds.split)
    floor = gen.ik_floor(tmp_path / "paper")
    assert set(floor) == {"ik_floor_mm", "ik_floor_within_1mm", "ik_floor_first_mm", "ik_floor_after_mm",
                          "ik_floor_noise_mm"}
    assert floor["ik_floor_mm"] < 1e-6 and floor["ik_floor_within_1mm"] == 1.0


def test_the_pose_fit_finds_a_reachable_pose_and_the_position_alone(bench) -> None:
    """bench_ik_floor's square/triangle reach: a corner of the path is a pose the robot takes, so the
    fit from perturbed joints returns to it; with the tangent unweighted a target whose tangent no
    joints give is still reached in position."""
    from ctrkin.acquisition.task_paths import task_path
    from ctrkin.geometry import quat_from_tangent, tangent_angle_error, tangent_from_quat
    from ctrkin.mechanics import solve

    virtual = VirtualRobot(paper_robot(), VirtualConfig().ideal(), seed=0)
    path = task_path(virtual, "triangle", n_points=3, seed=5)
    corner, q_corner = path.poses[0], path.corner_joints[0]

    def tip(q: np.ndarray) -> np.ndarray:
        return solve(virtual.true_robot, virtual.base_joints(q[None])[0]).tip_pose

    start = q_corner + np.r_[15.0, -10.0, 1.0, 0.5]
    assert np.linalg.norm(tip(start)[:3] - corner[:3]) > 1.0
    q, pose = bench._best_pose_joints(virtual, corner, start[None], bench.PATH_TANGENT_MM)
    assert np.linalg.norm(tip(q)[:3] - corner[:3]) < 1e-3
    np.testing.assert_allclose(pose, tip(q), atol=1e-9)
    tilted = corner.copy()
    t = tangent_from_quat(corner[3:6])
    tilted[3:6] = quat_from_tangent(t + np.array([0.5, 0.0, 0.0]) * np.linalg.norm(t))
    q, _ = bench._best_pose_joints(virtual, tilted, q_corner[None], 0.0)
    assert np.linalg.norm(tip(q)[:3] - tilted[:3]) < 1e-3
    assert tangent_angle_error(tip(q), tilted) > 5.0


@pytest.fixture(scope="module")
def friction_ik(tmp_path_factory):
    """A robot whose tubes rub (μ 0.69), its two legs as every part of a dataset, and a small follow IK
    trained on them: (virtual robot, dataset, the IK's folder)."""
    from ctrkin.training import TrainConfig, train

    virtual = VirtualRobot(paper_robot(), dataclasses.replace(VirtualConfig().ideal(), tube_friction=0.69),
                           seed=0)
    ds = _two_legs(virtual, 4.0)
    rows = np.arange(len(ds.frame))
    ds.split = Split(rows, rows, rows, "sequence", 0, (1.0, 1.0, 1.0), len(rows))
    cfg = TrainConfig(task="ik", model="follow_mlp", max_epochs=4, patience=4, batch_size=64, lr=2e-3,
                      threads=1, options={"structure": "|D32"})
    folder = tmp_path_factory.mktemp("friction_ik") / "ik"
    train(ds, cfg, folder, progress=False)
    return virtual, ds, folder


def test_inversion_scores_each_share_of_the_outer_lag_and_keeps_the_models_own(bench, friction_ik) -> None:
    """--inversion: a follow IK's figures with each share of its outer lag inverted as a play; a share
    of 0 and of 1 drive the outer motor differently (so the figures differ), and the model keeps its
    own share afterwards."""
    from ctrkin.inference import Kinematics

    virtual, ds, folder = friction_ik
    ik = Kinematics.load(folder)
    follower = ik.predictor.follower
    follower.lag, own, zone = (6.0, 0.0), follower.inversion, follower.dead_zone
    got = bench.setting_figures(virtual, ik, "inversion", (0.0, 1.0), ds, ds, base={"dead_zone": (1.0, 0.1)})
    assert set(got) == {0.0, 1.0}
    assert set(got[0.0]) == {"ik_val_mm", "ik_test_mm", "random_within_1mm"}
    assert got[0.0]["ik_val_mm"] != got[1.0]["ik_val_mm"]
    assert follower.inversion == own and follower.dead_zone == zone


def test_cap_scores_the_paths_with_each_cap_and_keeps_the_models_own(bench, friction_ik, capsys) -> None:
    """--cap: a follow IK's figures with each cap on its joint change on the way to a destination (None:
    no cap), the validation squares and triangles among them; the cap moves the paths' figures, not
    the close targets' of the sequences, and the model's folder is left as it was."""
    from ctrkin.inference import Kinematics

    virtual, ds, folder = friction_ik
    follower = Kinematics.load(folder).predictor.follower
    assert follower.substep_cap is not None and follower.arrive == 4
    config = (folder / "config.json").read_bytes()
    report = bench._cap_report(virtual, [folder], (None, (0.5, 0.05)), (3,), ds, ds)
    got = report["substep_cap"]["3"][str(folder)]
    assert set(got) == {"None", "(0.5, 0.05)"}
    assert set(got["None"]) == {"ik_val_mm", "ik_test_mm", "random_within_1mm", "val_square_mm",
                                "val_triangle_mm"}
    assert got["None"]["val_square_mm"] != got["(0.5, 0.05)"]["val_square_mm"]
    assert got["None"]["ik_val_mm"] == got["(0.5, 0.05)"]["ik_val_mm"]       # close targets: no cap
    assert "none" in capsys.readouterr().out
    assert (folder / "config.json").read_bytes() == config
