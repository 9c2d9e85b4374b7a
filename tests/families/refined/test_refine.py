"""IK refined on the learned FK: lowers the tip error, keeps joints within limits, loads as a folder."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.errors import ModelError
from ctrkin.families.refined.folder import assemble_refined
from ctrkin.inference import Kinematics
from ctrkin.mechanics import follow
from ctrkin.robots import paper_robot
from ctrkin.training import TrainConfig, train


@pytest.fixture(scope="module")
def fk_good(sweeps, tmp_path_factory):
    """An FK model trained long enough to be a useful residual (the sweeps are TCM-made: the truth
    is ctrkin.follow on the paper robot)."""
    out = tmp_path_factory.mktemp("fk_good") / "fk"
    cfg = TrainConfig(task="fk", model="lstm_mlp_branch", max_epochs=40, patience=40, batch_size=64,
                      lr=3e-3, lr_schedule="cosine", threads=1, options={"structure": "L32|D32"})
    train(sweeps, cfg, out, progress=False)
    return out


def _reached(joints: np.ndarray) -> np.ndarray:
    """Tip positions (T, 3) the robot reaches along joints (continued from the first row)."""
    return follow(paper_robot(), paper_robot().project_joints(joints)).tip_poses[:, :3]


def test_refinement_lowers_the_reached_tip_error(model_dirs, fk_good, sweeps, tmp_path):
    seq = sweeps.sequence_bounds()[1]
    targets = sweeps.poses(true=True)[seq[0]:seq[1]]
    direct = Kinematics.load(model_dirs["ik"]).predict(targets)
    refined_dir = assemble_refined(model_dirs["ik"], fk_good, tmp_path / "ik_refined")
    refined = Kinematics.load(refined_dir)
    assert refined.refined
    res = refined.predict(targets)
    e_direct = np.linalg.norm(_reached(direct.joints) - targets[:, :3], axis=1)
    e_refined = np.linalg.norm(_reached(res.joints) - targets[:, :3], axis=1)
    print(f"reached tip error: direct {e_direct.mean():.2f} mm, refined {e_refined.mean():.2f} mm")
    assert e_refined.mean() < 0.9 * e_direct.mean()
    assert np.all(np.isfinite(res.residual_mm))


def test_refined_ik_keeps_joints_within_limits_or_flags_them(model_dirs, sweeps):
    robot = paper_robot()
    for name in ("ik", "ik_refined"):
        kin = Kinematics.load(model_dirs[name])
        far = sweeps.poses()[:30].copy()
        far[:, :3] += np.array([0.0, 0.0, 25.0])        # beyond the reachable length
        for targets in (sweeps.poses()[:60], far):
            res = kin.predict(targets)
            robot.check_joints(res.joints)               # never outside the limits...
            assert res.projected is not None and res.projected.dtype == bool   # ...projection is flagged
            kin.reset()
            for t in targets[:10]:
                st = kin.step(t)
                robot.check_joints(st.joints)


def test_refined_folder_refuses_mismatched_parts(model_dirs, tmp_path):
    with pytest.raises(ModelError):
        assemble_refined(model_dirs["fk"], model_dirs["fk_branch"], tmp_path / "x")     # not an IK model
    with pytest.raises(ModelError, match="already"):
        assemble_refined(model_dirs["ik_refined"], model_dirs["fk_branch"], tmp_path / "y")
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()
