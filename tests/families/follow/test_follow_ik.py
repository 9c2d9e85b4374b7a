"""The follow IK (ctrkin.families.follow.features): it reaches targets the direct IK misses, batch equals
streaming, start joints are honoured and checked, joints stay within limits or are flagged."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from ctrkin.errors import JointError, ModelError
from ctrkin.inference import Kinematics
from ctrkin.mechanics import follow
from ctrkin.robots import paper_robot
from ctrkin.training import TrainConfig, train


@pytest.fixture(scope="module")
def follow_dir(sweeps, tmp_path_factory):
    out = tmp_path_factory.mktemp("follow") / "ik_follow"
    cfg = TrainConfig(task="ik", model="follow_mlp", max_epochs=25, patience=25, batch_size=128, lr=2e-3,
                      lr_schedule="cosine", threads=1, options={"structure": "|D64,D64"})
    train(sweeps, cfg, out, progress=False)
    return out


def _reached(joints: np.ndarray) -> np.ndarray:
    """Tip positions (T, 3) the robot reaches along joints (continued from the first row)."""
    return follow(paper_robot(), paper_robot().project_joints(joints)).tip_poses[:, :3]


def test_follow_ik_reaches_targets_the_direct_ik_misses(follow_dir, model_dirs, sweeps):
    seq = sweeps.sequence_bounds()[1]
    targets = sweeps.poses(true=True)[seq[0]:seq[1]]
    direct = Kinematics.load(model_dirs["ik"]).predict(targets)
    res = Kinematics.load(follow_dir).predict(targets)
    e_direct = np.linalg.norm(_reached(direct.joints) - targets[:, :3], axis=1)
    e_follow = np.linalg.norm(_reached(res.joints) - targets[:, :3], axis=1)
    print(f"reached tip error: direct {e_direct.mean():.2f} mm, follow {e_follow.mean():.2f} mm")
    assert e_follow.mean() < 0.5 * e_direct.mean()
    assert np.isnan(res.residual_mm).all() and not res.jump.any()


def test_follow_ik_batch_equals_streaming_and_uses_start_joints(follow_dir, sweeps):
    a, b = sweeps.sequence_bounds()[2]
    targets, joints = sweeps.poses(true=True)[a:b], sweeps.joints()[a:b]
    kin = Kinematics.load(follow_dir)
    batch = kin.predict(targets, start_joints=joints[0]).joints
    kin.reset(joints[0])
    stream = np.array([kin.step(t).joints for t in targets])
    np.testing.assert_allclose(stream, batch, atol=1e-9)
    # the answers continue from the start joints: a start a whole turn further gives the same
    # configurations a turn further (not the representative the training data used)
    turned = kin.predict(targets, start_joints=joints[0] + np.r_[360.0, 360.0, 0.0, 0.0]).joints
    np.testing.assert_allclose(turned[:, :2] - 360.0, batch[:, :2], atol=1e-6)
    np.testing.assert_allclose(turned[:, 2:], batch[:, 2:], atol=1e-9)


def test_follow_ik_refuses_bad_start_joints_and_other_models(follow_dir, model_dirs, sweeps):
    kin = Kinematics.load(follow_dir)
    targets = sweeps.poses(true=True)[:5]
    with pytest.raises(ModelError, match="start_joints must have shape"):
        kin.predict(targets, start_joints=np.zeros((2, 4)))
    with pytest.raises(JointError):
        kin.reset(np.array([0.0, 0.0, 5.0, 0.0]))          # β1 > 0: not a configuration
    with pytest.raises(ModelError, match="follow IK"):
        Kinematics.load(model_dirs["ik"]).predict(targets, start_joints=np.zeros(4))


def test_follow_ik_joints_within_limits_or_flagged(follow_dir, sweeps):
    robot = paper_robot()
    targets = sweeps.poses(true=True)
    targets = targets + np.r_[0.0, 0.0, 4.0, 0.0, 0.0, 0.0]      # pushed beyond the deepest insertion
    res = Kinematics.load(follow_dir).predict(targets, sequence_id=sweeps.frame["sequence_id"].to_numpy())
    np.testing.assert_allclose(robot.project_joints(res.joints), res.joints, atol=1e-9)
    assert res.projected.any() and not res.in_workspace.all()


def test_far_targets_are_followed_through_substeps(follow_dir, sweeps):
    """Every 10th target of a path: the follower interpolates the gaps and ends about as close to
    those targets as when it is given the whole path."""
    a, b = sweeps.sequence_bounds()[1]
    targets = sweeps.poses(true=True)[a:b]
    kin = Kinematics.load(follow_dir)
    fine = kin.predict(targets).joints[::10]
    coarse = kin.predict(targets[::10]).joints
    e_fine = np.linalg.norm(_reached(fine) - targets[::10, :3], axis=1)
    e_coarse = np.linalg.norm(_reached(coarse) - targets[::10, :3], axis=1)
    print(f"mean reached error: whole path {e_fine.mean():.2f} mm, every 10th {e_coarse.mean():.2f} mm")
    assert e_coarse.mean() < 1.5 * e_fine.mean() + 0.2


def test_follow_ik_refuses_onnx_export(follow_dir, tmp_path):
    from ctrkin.inference.onnx_export import export_onnx

    with pytest.raises(ModelError, match="cannot be exported"):
        export_onnx(Kinematics.load(follow_dir), tmp_path / "follow.onnx")
    assert not (tmp_path / "follow.onnx").exists()


def test_follower_inverts_the_outer_tubes_play(follow_dir):
    """With an outer lag λ the follower's motor commands, put through the transmission's play
    operator (width 2λ, from rest), leave the outer tube exactly where the network meant it:
    θ = network αN − λ. A start at rest is seen by the network with the tube's angle + λ."""
    from ctrkin.virtual.transmission import play

    kin = Kinematics.load(follow_dir)
    f = kin.predictor.follower
    f.lag, f.hold_deg, f.inversion = (2.0, 0.0), 0.0, 1.0   # λ = 2° whatever the translations; exact
    q0 = np.array([10.0, 30.0, -20.0, 0.0])
    f.reset(q0)
    assert f.joints[1] == pytest.approx(32.0) and f.tube == f.motor == 30.0
    theta = np.r_[30.0, 31.0, 33.0, 33.0, 32.5, 29.0, 29.0, 29.5, 35.0]   # forward, still, back, forward
    motors = []
    for th in theta:
        q = q0.copy()
        q[1] = th + 2.0
        motors.append(f._backlash_inverse(q)[1])
    tube = np.empty((len(theta), 1))
    play(np.array(motors)[:, None], np.full((len(theta), 1), 4.0), np.array([30.0]), tube)
    np.testing.assert_allclose(tube[:, 0], theta, atol=1e-12)
    assert motors[3] == motors[2] and motors[4] == pytest.approx(30.5)   # still: no move; back: θ − λ


def test_follower_inverts_its_share_of_the_outer_lag(follow_dir):
    """The follower inverts `inversion` · λ as the play (OUTER_INVERSION unless the folder says
    otherwise, stored at training): with λ = 4° and a share of 0.5 its commands are those of a 2° play,
    and a start at rest is seen at the tube's angle + 2°; `follower_lag` stays the identified lag."""
    from ctrkin.families.follow.stepper import OUTER_INVERSION

    kin = Kinematics.load(follow_dir)
    assert kin.predictor.follower.inversion == OUTER_INVERSION
    assert kin.predictor.bundle.extra["follow"]["outer_inversion"] == OUTER_INVERSION
    f = kin.predictor.follower
    f.lag, f.hold_deg, f.inversion = (4.0, 0.0), 0.0, 0.5
    assert kin.predictor.follower_lag == (4.0, 0.0)
    q0 = np.array([10.0, 30.0, -20.0, 0.0])
    f.reset(q0)
    assert f.joints[1] == pytest.approx(32.0)
    motors = []
    for th in (31.0, 29.0):                              # forward, then back
        q = q0.copy()
        q[1] = th + 2.0
        motors.append(f._backlash_inverse(q)[1])
    assert motors == [pytest.approx(33.0), pytest.approx(27.0)]


def test_follower_makes_no_joint_change_inside_its_dead_zone(follow_dir, sweeps):
    """An application sends no α change below dead_zone[0] deg and no β change below dead_zone[1] mm,
    and the rest in full; the folder stores DEAD_ZONE."""
    from ctrkin.families.follow.stepper import DEAD_ZONE

    kin = Kinematics.load(follow_dir)
    f = kin.predictor.follower
    assert f.dead_zone == DEAD_ZONE == tuple(kin.predictor.bundle.extra["follow"]["dead_zone"])
    a, _ = sweeps.sequence_bounds()[1]
    target, previous, q = sweeps.poses(true=True)[a + 5], sweeps.poses(true=True)[a], sweeps.joints()[a]
    f.dead_zone = (0.0, 0.0)
    free, _ = f._apply(target, previous, q)
    dq = free - q
    zone = (float(np.median(np.abs(dq[:2]))), float(np.median(np.abs(dq[2:]))))
    f.dead_zone = zone
    held, _ = f._apply(target, previous, q)
    small = np.r_[np.abs(dq[:2]) < zone[0], np.abs(dq[2:]) < zone[1]]
    assert small.any() and not small.all()
    np.testing.assert_array_equal(held[small], q[small])
    np.testing.assert_allclose(held[~small], free[~small])


@pytest.mark.parametrize("bad", [{"dead_zone": [2.0]}, {"dead_zone": [2.0, -0.1]}, {"dead_zone": 2.0},
                                 {"outer_inversion": float("nan")}, {"outer_inversion": "x"},
                                 {"substep_cap": [3.0, 0.0]},
                                 {"substep_cap": 3.0}, {"substep_cap": [3.0, "x"]}])
def test_follow_settings_with_a_malformed_dead_zone_inversion_or_cap_are_refused(follow_dir, bad):
    from ctrkin.families.follow.stepper import Follower

    kin = Kinematics.load(follow_dir)
    bundle = copy.copy(kin.predictor.bundle)
    bundle.extra = {**bundle.extra, "follow": {**bundle.extra["follow"], **bad}}
    with pytest.raises(ModelError, match="substep_cap" if "substep_cap" in bad else "dead_zone"):
        Follower(bundle, None)


def test_a_capped_application_scales_the_whole_joint_change(follow_dir, sweeps):
    """With a cap (α deg, β mm) an application's joint change is the uncapped one scaled down as a
    whole until its largest α change or its largest β change meets the cap; within the cap it is
    the uncapped one. The folder stores SUBSTEP_CAP."""
    from ctrkin.families.follow.stepper import SUBSTEP_CAP

    kin = Kinematics.load(follow_dir)
    f = kin.predictor.follower
    assert f.substep_cap == SUBSTEP_CAP == tuple(kin.predictor.bundle.extra["follow"]["substep_cap"])
    a, _ = sweeps.sequence_bounds()[1]
    target, previous, q = sweeps.poses(true=True)[a + 40], sweeps.poses(true=True)[a], sweeps.joints()[a]
    free, _ = f._apply(target, previous, q, dead_zone=False)
    dq = free - q
    da, db = float(np.abs(dq[:2]).max()), float(np.abs(dq[2:]).max())
    assert da > 0 and db > 0
    capped, _ = f._apply(target, previous, q, dead_zone=False, cap=(da / 2, db))
    np.testing.assert_allclose(capped - q, dq / 2, atol=1e-12)
    capped, _ = f._apply(target, previous, q, dead_zone=False, cap=(2 * da, db / 4))
    np.testing.assert_allclose(capped - q, dq / 4, atol=1e-12)
    same, _ = f._apply(target, previous, q, dead_zone=False, cap=(2 * da, 2 * db))
    np.testing.assert_array_equal(same, free)


def test_follower_holds_the_motor_through_small_reversals(follow_dir):
    """A reversal of the outer tube smaller than hold_deg keeps the motor (the tube stays, within
    hold_deg of the network's angle) instead of a trip of 2λ through the play."""
    kin = Kinematics.load(follow_dir)
    f = kin.predictor.follower
    f.lag, f.hold_deg, f.inversion = (2.0, 0.0), 0.5, 1.0
    q0 = np.array([10.0, 30.0, -20.0, 0.0])
    f.reset(q0)

    def motor(theta):
        q = q0.copy()
        q[1] = theta + 2.0
        return f._backlash_inverse(q)[1]

    assert motor(30.2) == 30.0                     # at rest, less than hold_deg: nothing moves
    assert motor(31.0) == pytest.approx(33.0)      # forward: θ + λ
    assert motor(31.1) == pytest.approx(33.1)      # on along the taken-up side, however small
    assert motor(30.8) == pytest.approx(33.1) and f.tube == pytest.approx(31.1)   # small reversal: held
    assert motor(30.0) == pytest.approx(28.0)      # a reversal beyond hold_deg: θ − λ


def _small_follow_ik(sweeps, tmp_path_factory, name: str, **settings):
    """A follow IK of a few epochs on the sweeps, with the given TrainConfig settings."""
    out = tmp_path_factory.mktemp(name) / f"ik_{name}"
    cfg = TrainConfig(task="ik", model="follow_mlp", max_epochs=6, patience=6, batch_size=128, lr=2e-3,
                      lr_schedule="cosine", threads=1, options={"structure": "|D32"}, **settings)
    train(sweeps, cfg, out, progress=False)
    return out


@pytest.fixture(scope="module")
def follow_play_dir(sweeps, tmp_path_factory):
    return _small_follow_ik(sweeps, tmp_path_factory, "follow_play", play_lags=True)


def test_a_play_lag_follow_ik_sees_the_lags_of_its_target_path(follow_play_dir, sweeps, monkeypatch):
    from ctrkin.families.follow import stepper
    from ctrkin.models.play_lags import target_lags

    a, b = sweeps.sequence_bounds()[2]
    targets, joints = sweeps.poses(true=True)[a:b], sweeps.joints()[a:b]
    kin = Kinematics.load(follow_play_dir)
    assert kin.layout.play and kin.layout.family == "follow"
    kin.predictor.follower.max_step_mm = np.inf        # one application per target (no sub-steps)
    kin.predictor.follower.settle = 1
    batch = kin.predict(targets, start_joints=joints[0]).joints
    seen = []
    real = stepper.follow_features

    def spy(frame, n, target, previous, q, lags=None, outer_angle=False):
        seen.append(lags[0].copy())
        return real(frame, n, target, previous, q, lags, outer_angle)

    monkeypatch.setattr(stepper, "follow_features", spy)
    kin.reset(joints[0])
    stream = np.array([kin.step(t).joints for t in targets])
    np.testing.assert_allclose(stream, batch, atol=1e-9)
    # the lags of the targets' positions up to each target, from rest at the first one (as the
    # recipe computes them along a recorded sequence), not of the joints the network answered
    expected = target_lags(targets[:, :3], [(0, len(targets))])
    np.testing.assert_allclose(np.array(seen), expected, atol=1e-12)
    np.testing.assert_array_equal(expected[0], 0.0)
    assert np.abs(expected).max() > 0.5                                # the sweep took up the plays


@pytest.fixture(scope="module")
def follow_outer_dir(sweeps, tmp_path_factory):
    return _small_follow_ik(sweeps, tmp_path_factory, "follow_outer", outer_angle=True)


def test_an_outer_angle_follow_ik_sees_the_outer_angle_of_the_joints_it_is_at(follow_outer_dir, sweeps,
                                                                             monkeypatch):
    from ctrkin.families.follow import stepper

    a, b = sweeps.sequence_bounds()[2]
    targets, joints = sweeps.poses(true=True)[a:b], sweeps.joints()[a:b]
    kin = Kinematics.load(follow_outer_dir)
    assert kin.layout.outer_angle and kin.layout.input_names[-2:] == ("sin_alpha_2", "cos_alpha_2")
    kin.predictor.follower.max_step_mm = np.inf
    kin.predictor.follower.settle = 1
    batch = kin.predict(targets, start_joints=joints[0]).joints
    seen = []
    real = stepper.follow_features

    def spy(frame, n, target, previous, q, lags=None, outer_angle=False):
        f = real(frame, n, target, previous, q, lags, outer_angle)
        seen.append((q[0].copy(), f[0, -2:].copy()))
        return f

    monkeypatch.setattr(stepper, "follow_features", spy)
    kin.reset(joints[0])
    stream = np.array([kin.step(t).joints for t in targets])
    np.testing.assert_allclose(stream, batch, atol=1e-9)
    assert len(seen) == len(targets)
    for q, sc in seen:          # the joints the network is at (its own answers), not the recorded ones
        np.testing.assert_allclose(sc, [np.sin(np.radians(q[1])), np.cos(np.radians(q[1]))], atol=1e-12)


def test_a_follow_ik_is_refined_from_a_fresh_process(follow_dir, model_dirs, tmp_path):
    """assemble_refined as its docstring shows it, in a process that imported nothing else: the
    refined family reads a follow IK folder's task without the follow family (it imports no other)."""
    import subprocess
    import sys

    out = tmp_path / "ik_refined_follow"
    code = ("from ctrkin.families.refined import assemble_refined; "
            f"assemble_refined({str(follow_dir)!r}, {str(model_dirs['fk_branch'])!r}, {str(out)!r})")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    kin = Kinematics.load(out)
    assert kin.predictor.refined and kin.layout.family == "follow"


def test_catch_up_rows_start_from_the_recordings_own_earlier_joints_in_the_same_sequence(sweeps,
                                                                                         monkeypatch):
    """With every row a catch-up row and no perturbation, each row's current joints are the joints
    the recording had 1..CATCH_UP_ROWS rows before it in its own sequence (a sequence's first rows
    clamp to its start), and its label is the step from there to the recorded joints."""
    from ctrkin.families.follow import recipe as follow_recipe
    from ctrkin.models.recipe import TrainingData
    from ctrkin.training.data import split_rows

    monkeypatch.setattr(follow_recipe, "joint_noise", lambda rng, m, n: np.zeros((m, 2 * n)))
    cfg = TrainConfig(task="ik", model="follow_mlp", max_epochs=2, threads=1, catch_up=1.0)
    split, rows = split_rows(sweeps, cfg)
    rec = follow_recipe.FollowRecipe(cfg)
    rec.prepare(TrainingData(sweeps, cfg, split, rows))
    r = rows["train"]
    _, Y = rec._draw(r, np.random.default_rng(3))
    joints = sweeps.joints()
    current = joints[r] - Y
    seq = sweeps.frame["sequence_id"].to_numpy()
    start = {s: a for a, _ in sweeps.sequence_bounds() for s in [seq[a]]}
    back = []
    for i, row in enumerate(r):
        lo = max(start[seq[row]], row - 1 - follow_recipe.CATCH_UP_ROWS)
        hi = max(start[seq[row]], row - 2)          # at least one row further back than the previous
        match = [j for j in range(lo, hi + 1) if np.allclose(joints[j], current[i], atol=1e-9)]
        assert match, f"row {row}: its current joints are none of its sequence's earlier joints"
        back.append(row - match[-1])
    assert max(back) > 20 and np.mean(back) > 5            # the draws reach well back along the path


def test_a_destination_is_settled_on_and_a_jump_within_a_stream_is_not(follow_dir, sweeps):
    """A far target (reached through intermediate targets) after the sequence's first target or after
    another far one, as along waypoints, gets `arrive` more applications of the network there (as the
    first target gets `settle`); a close target none, and a far one right after a close one (a
    stream's jump, as at a snap) none."""
    from ctrkin.families.follow.stepper import ARRIVE_ITERATIONS, ARRIVE_SUBSTEPS

    a, b = sweeps.sequence_bounds()[1]
    targets = sweeps.poses(true=True)[a:b]
    kin = Kinematics.load(follow_dir)
    follower = kin.predictor.follower
    assert follower.arrive == ARRIVE_ITERATIONS == 4          # stored in the folder by the recipe
    applied: list[bool] = []                                 # each application: at the target itself?
    capped: list[bool] = []                                  # ... with the substep cap?
    original = follower._apply

    def counting(target, previous, q, lags=None, dead_zone=True, cap=None):
        applied.append(bool(np.array_equal(target, previous)))
        capped.append(cap is not None)
        assert cap is None or cap == follower.substep_cap
        return original(target, previous, q, lags, dead_zone, cap)

    follower._apply = counting
    far = targets[60]
    k = int(np.argmax(np.linalg.norm(targets[:, :3] - far[:3], axis=1)))
    farther, beside = targets[k], targets[k - 1 if k > 0 else 1]
    for x, y in ((targets[0], far), (far, farther), (beside, targets[0])):
        assert np.linalg.norm(x[:3] - y[:3]) > ARRIVE_SUBSTEPS * follower.max_step_mm

    def run(arrive: int) -> tuple[list[list[bool]], np.ndarray]:
        follower.arrive = arrive
        kin.reset(sweeps.joints()[a])
        kin.step(targets[0])
        got, answers = [], []
        for target, destination in ((far, True), (farther, True), (beside, False), (targets[0], False)):
            applied.clear()
            capped.clear()
            answers.append(kin.step(target).joints)
            got.append(list(applied))
            # on the way to a destination every application is capped, the settling there is not
            assert capped == [destination and not at for at in applied]
        return got, answers[0]

    (to_far, to_farther, close, jump), settled = run(3)
    assert to_far[-3:] == [True] * 3 and sum(to_far) == 3            # waypoints: each one settled on
    assert to_farther[-3:] == [True] * 3 and sum(to_farther) == 3
    assert close == [False]                                          # a training step away
    assert not any(jump) and len(jump) >= ARRIVE_SUBSTEPS            # far, but after a close target
    (to_far, *_), plain = run(0)
    assert not any(to_far)
    assert np.abs(settled - plain).max() > 1e-6
