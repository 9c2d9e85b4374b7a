"""Inverse-kinematics experiments: held-out sequences, 20 random poses (Fig. 11) and the square and
triangle paths (Fig. 12), for every IK row (the paper's LSTM-MLP, and the same network refined on the
snap-aware FK, ctrkin.families.refined.refine). Predicted joints are checked two ways: through the learned
FK model (as the paper did) and by driving the virtual robot to them (what hardware would do)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ctrkin.acquisition.plan import move
from ctrkin.data.schema import sequence_bounds
from ctrkin.evaluation.context import Context, summary, valid_rows
from ctrkin.evaluation.table import HEADLINE, IK_ROWS, RECOMMENDED, Experiment, Figure, Row, with_headline
from ctrkin.metrics import joint_errors
from ctrkin.models.motion import outer_motion, recorded_motion
from ctrkin.models.outer_lag import lag_deg
from ctrkin.virtual import VirtualRobot
from ctrkin.virtual.transmission import clip_to_valid
from ctrkin.viz import experiments as fig

if TYPE_CHECKING:
    from ctrkin.models.ik import IKResult

FIG11 = Figure("fig11_ik_random", "Fig. 11: IK at random poses",
               "The recommended IK at the 20 random poses: predicted (×) and recorded (○) α and β per "
               "point (a mirror solution may differ in α and still reach the pose), and the targets "
               "with the tips the predicted joints reach through the learned FK model and by driving "
               "the virtual robot (x–y, mm).")
FIG12_SQUARE = Figure("fig12_ik_square", "Fig. 12: IK along a square",
                      "The recommended IK along a square of 10 target poses: targets and the tips reached "
                      "through the learned FK model and by driving the virtual robot (3-D, mm), and the "
                      "predicted joints per point. Both checks move through the same 1°/0.1 mm steps "
                      "from target to target (the FK model sees the history the robot has); where the "
                      "two disagree, the learned FK model is wrong there, and the robot is the check "
                      "that counts.")
FIG12_TRIANGLE = Figure("fig12_ik_triangle", "Fig. 12: IK along a triangle",
                        "As the square (Fig. 12 above), along a triangle of 10 target poses: targets, tips "
                        "reached and predicted joints.")


def joined(Q: np.ndarray, n_tubes: int, bounds_: list[tuple[int, int]]
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joints Q (T, 2N) as the robot is driven through them: each sequence from its first row, and
    consecutive rows joined by 1°/0.1 mm moves (the paper's increments, ctrkin.acquisition.plan.move).
    Returns the dense path (P, 2N), the index of each row of Q in it (T,), and each path row's
    sequence (P,)."""
    path, rows, sid = [], np.empty(len(Q), int), []
    start = 0
    for s, (a, b) in enumerate(bounds_):
        rows[a] = start
        parts = [Q[a][None]]
        for k in range(a + 1, b):
            seg = move(Q[k - 1], Q[k], n_tubes)
            parts.append(seg if len(seg) else Q[k][None])
            rows[k] = rows[k - 1] + len(parts[-1])
        seq = np.vstack(parts)
        path.append(seq)
        sid.append(np.full(len(seq), s))
        start += len(seq)
    return np.vstack(path), rows, np.concatenate(sid)


def drive(
    virtual: VirtualRobot, Q: np.ndarray, bounds_: list[tuple[int, int]] | None = None
) -> tuple[np.ndarray, int]:
    """Command the virtual robot through joints Q (T, 2N), each sequence from rest at its first row;
    consecutive rows are joined by 1°/0.1 mm moves (`joined`). Returns the noise-free tracker view of
    the tip at every row (T, 6) and how many rows had to be projected onto the valid joint set."""
    robot = virtual.nominal
    Qv = clip_to_valid(robot, Q)
    clipped = int(np.any(np.abs(Qv - Q) > 1e-9, axis=1).sum())
    out = np.empty((len(Q), 6))
    for a, b in bounds_ or [(0, len(Q))]:
        path, rows, _ = joined(Qv[a:b], robot.n_tubes, [(0, b - a)])
        motion, _ = virtual.move(virtual.rest(Qv[a]), path)
        out[a:b] = virtual.tracker.registered(motion.true_poses[rows])
    return out, clipped


def _within(reached: np.ndarray, targets: np.ndarray, mm: float = 1.0) -> np.ndarray:
    return np.linalg.norm(reached[:, :3] - targets[:, :3], axis=1) < mm


def _ik_checks(
    ctx: Context, res: IKResult, targets: np.ndarray, b: list[tuple[int, int]]
) -> tuple[dict[str, Any], np.ndarray, np.ndarray]:
    """Errors of the tips reached through the recommended FK model and by driving the robot, the
    flags of the result, and those tips."""
    fk = ctx.models[str(RECOMMENDED["fk"].folder)]
    joints = res.joints
    Qv = clip_to_valid(ctx.data.virtual.nominal, joints)
    # the FK model sees the joints as the robot is driven through them (1°/0.1 mm moves between the
    # targets, the steps it was trained on): fed the targets' joints alone, a 40° jump between two
    # targets is a Δα0 no training sequence had, and its tips drifted away from the targets (Fig. 12)
    # (IK joints jump between turns; the FK model refuses a sequence that leaves its range by a turn)
    path, at, sid = joined(fk.alpha_into_range(Qv), ctx.data.virtual.nominal.n_tubes, b)
    via_fk = np.asarray(fk.predict(path, sequence_id=sid), float)[at]
    via_robot, clipped = drive(ctx.data.virtual, joints, b)
    flags = {
        "joints_projected_to_valid": clipped,
        "flagged_projected": int(np.sum(res.projected)) if res.projected is not None else 0,
        "flagged_jumps": int(np.sum(res.jump)) if res.jump is not None else 0,
        "unflagged_outside_limits": int(np.sum(np.any(np.abs(Qv - joints) > 1e-9, axis=1)
                                               & ~(res.projected if res.projected is not None
                                                   else np.zeros(len(joints), bool)))),
    }
    return (
        {
            "via_fk_model": summary(via_fk, targets, None),
            "via_robot": summary(via_robot, targets, None),
            "within_1mm_fraction": float(np.mean(_within(via_robot, targets))),
            **flags,
        },
        via_fk,
        via_robot,
    )


def ik_heldout(ctx: Context, rows_: tuple[Row, ...]) -> dict[str, Any]:
    """IK on the paper dataset's test sequences: joint errors, and the tip the joints reach. A row
    with `heldout_sequences` (the refined IK: step-by-step optimisation, milliseconds a step) is
    evaluated on the first so many test sequences only; `n` says how many targets each row saw."""
    ds = ctx.data.paper
    all_rows = valid_rows(ds, ds.get_split().test)
    sid = ds.frame["sequence_id"].to_numpy()
    out: dict[str, Any] = {}
    for row in rows_:
        name, folder = row.name, str(row.folder)
        rows = all_rows
        if row.heldout_sequences is not None:
            first = np.unique(sid[all_rows])[:row.heldout_sequences]
            rows = all_rows[np.isin(sid[all_rows], first)]
        b = sequence_bounds(sid[rows])
        res = ctx.models[folder].predict(ds.poses()[rows], sequence_id=sid[rows])
        je = joint_errors(res.joints, ds.joints()[rows], ds.n_tubes)
        checks, _, _ = _ik_checks(ctx, res, ds.poses()[rows], b)
        out[name] = {
            "model": folder,
            "joint_rmse_mm": je["beta_mm"]["rmse"],
            "joint_rmse_deg": je["alpha_deg"]["rmse"],
            "joint_mae_mm": je["beta_mm"]["mae"],
            "joint_mae_deg": je["alpha_deg"]["mae"],
            "joint_alpha_median_deg": je["alpha_deg"]["median"],
            "tip_error_mm": checks["via_robot"]["position_rmse_mm"],
            "tip_error_via_fk_mm": checks["via_fk_model"]["position_rmse_mm"],
            "in_workspace_fraction": float(np.mean(res.in_workspace)),
            "n": len(rows),
            **checks,
        }
        if row.from_robot_start:
            out[name]["from_robot_start"] = _from_robot_start(ctx, folder, rows, sid, b)
            out[name]["joint_alpha_median_tube_deg"] = _tube_alpha_median(ctx, folder, res.joints, rows, b)
    return with_headline(out, "ik")


def _tube_alpha_median(ctx: Context, folder: str, joints: np.ndarray, rows: np.ndarray,
                       b: list[tuple[int, int]]) -> float:
    """Median α error (deg, wrapped) of the outer tube's angle rather than its motor's: both the
    recorded and the predicted αN less λ(β)·m_N (the follow IK's outer lag, ctrkin.models.outer_lag;
    m_N of the recording followed across its runs, of the prediction from rest), so that motor
    commands on either side of the play for the same tube angle count as equal."""
    ds = ctx.data.paper
    lag = ctx.models[folder].follower_lag
    n = ds.n_tubes
    rec = ds.joints()[rows].copy()
    m_rec, _ = recorded_motion(ds.frame, ds.joints(), ds.sequence_bounds(), n)
    ours = np.array(joints, float)
    rec[:, n - 1] -= lag_deg(ds.robot, rec, lag) * m_rec[rows]
    ours[:, n - 1] -= lag_deg(ds.robot, ours, lag) * outer_motion(joints, b, n)
    return joint_errors(ours, rec, n)["alpha_deg"]["median"]


def _from_robot_start(ctx: Context, folder: str, rows: np.ndarray, sid: np.ndarray,
                      b: list[tuple[int, int]]) -> dict[str, Any]:
    """A follow IK started from the joints the robot is at when each sequence begins (what a
    controller knows), instead of from the nearest training target's joints."""
    ds = ctx.data.paper
    starts = ds.joints()[rows][[a for a, _ in b]]
    res = ctx.models[folder].predict(ds.poses()[rows], sequence_id=sid[rows], start_joints=starts)
    je = joint_errors(res.joints, ds.joints()[rows], ds.n_tubes)
    checks, _, _ = _ik_checks(ctx, res, ds.poses()[rows], b)
    return {"tip_error_mm": checks["via_robot"]["position_rmse_mm"],
            "within_1mm_fraction": checks["within_1mm_fraction"],
            "joint_rmse_deg": je["alpha_deg"]["rmse"], "joint_alpha_median_deg": je["alpha_deg"]["median"],
            "joint_rmse_mm": je["beta_mm"]["rmse"]}


def ik_random(ctx: Context, rows_: tuple[Row, ...]) -> dict[str, Any]:
    """Fig. 11: IK at the 20 random poses (with the history of the moves between them)."""
    ds = ctx.data.random_points
    is_t = ds.frame["is_target"].to_numpy()
    rows = valid_rows(ds, np.nonzero(is_t)[0])
    b = ds.sequence_bounds()
    whole = [(b[0][0], b[-1][1])]
    targets = ds.poses()[rows]
    out: dict[str, Any] = {}
    for row in rows_:
        name, folder = row.name, str(row.folder)
        res = ctx.models[folder].predict(ds)
        je = joint_errors(res.joints[rows], ds.joints()[rows], ds.n_tubes)
        # the robot is driven along the predicted joints of the whole run, looked at on the targets
        checks, via_fk, via_robot = _ik_checks(ctx, res, ds.poses(), whole)
        out[name] = {
            "model": folder,
            "joint_rmse_mm": je["beta_mm"]["rmse"],
            "joint_rmse_deg": je["alpha_deg"]["rmse"],
            "via_fk_model": summary(via_fk[rows], targets, None),
            "via_robot": summary(via_robot[rows], targets, None),
            "in_workspace": int(res.in_workspace[rows].sum()),
            "n_points": len(rows),
            "joints_projected_to_valid": checks["joints_projected_to_valid"],
            "within_1mm_via_robot": int(_within(via_robot[rows], targets).sum()),
            "within_1mm_fraction": float(np.mean(_within(via_robot[rows], targets))),
            "position_rmse_mm": summary(via_robot[rows], targets, None)["position_rmse_mm"],
        }
        if row is RECOMMENDED["ik"]:
            fig.ik_points_figure(ds.joints()[rows], res.joints[rows], targets, via_fk[rows],
                                 via_robot[rows], ctx.figures / f"{FIG11.stem}.png")
    out = with_headline(out, "ik")
    out["position_rmse_mm"] = out[HEADLINE]["position_rmse_mm"]
    out["within_1mm_fraction"] = out[HEADLINE]["within_1mm_fraction"]
    return out


def ik_path(ctx: Context, rows_: tuple[Row, ...], shape: str, figure: Figure) -> dict[str, Any]:
    """Fig. 12: IK along a square or triangle of 10 target poses (tracker frame)."""
    targets = getattr(ctx.data, shape)
    out: dict[str, Any] = {}
    for row in rows_:
        name, folder = row.name, str(row.folder)
        res = ctx.models[folder].predict(targets)
        checks, via_fk, via_robot = _ik_checks(ctx, res, targets, [(0, len(targets))])
        out[name] = {
            "model": folder,
            **checks,
            "position_rmse_mm": checks["via_robot"]["position_rmse_mm"],
            "in_workspace": int(res.in_workspace.sum()),
            "n_points": len(targets),
            "outside_workspace_reasons": [r for r, ok in zip(res.reasons, res.in_workspace, strict=True)
                                          if not ok],
        }
        if row is RECOMMENDED["ik"]:
            fig.ik_path_figure(targets, via_fk, via_robot, res.joints, ctx.figures / f"{figure.stem}.png",
                               f"IK along a {shape}")
    out = with_headline(out, "ik")
    out["position_rmse_mm"] = out[HEADLINE]["position_rmse_mm"]
    out["within_1mm_fraction"] = out[HEADLINE]["within_1mm_fraction"]
    return out


def ik_square(ctx: Context, rows_: tuple[Row, ...]) -> dict[str, Any]:
    return ik_path(ctx, rows_, "square", FIG12_SQUARE)


def ik_triangle(ctx: Context, rows_: tuple[Row, ...]) -> dict[str, Any]:
    return ik_path(ctx, rows_, "triangle", FIG12_TRIANGLE)


STAGE = "IK: held-out sequences, random poses, square and triangle (Fig. 11, 12)"
EXPERIMENTS = (
    Experiment("ik", STAGE, ik_heldout, IK_ROWS, top_level=True),
    Experiment("ik_random", STAGE, ik_random, IK_ROWS, (FIG11,), section="ik"),
    Experiment("ik_square", STAGE, ik_square, IK_ROWS, (FIG12_SQUARE,), section="ik"),
    Experiment("ik_triangle", STAGE, ik_triangle, IK_ROWS, (FIG12_TRIANGLE,), section="ik"),
)
