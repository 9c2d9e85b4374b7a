"""Compare a predictor with an imported dataset (`ctrkin evaluate`): nominal TCM, a calibrated robot
file or a learned model, per sequence, with plots.

Position error is the Euclidean tip distance (mm); orientation error the angle between tip tangents
(deg), skipped for position-only datasets (meta["orientation"] == "absent"). The nominal TCM and a
robot file without a [calibration] registration are mapped to the tracker by a registration fitted
here on all samples (so their error is in-sample for those six parameters). A learned model flags
samples whose joints lie outside its training range by more than `margin` of that range.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.calibration.model import CalibratedTCM
from ctrkin.data.dataset import Dataset
from ctrkin.geometry import Registration, position_error, tangent_angle_error
from ctrkin.util.files import atomic_write_text

RANGE_MARGIN = 0.05


def out_of_range(kin: Any, joints: np.ndarray, names: list[str], margin: float = RANGE_MARGIN
                 ) -> dict[str, Any]:
    """Joints (T, 2N) outside a learned model's training range (from its input normalisation) by more
    than margin · range: {"rows": (T,) bool, "joints": {name: {"lo", "hi", "count"}}}."""
    lo, span = kin.bundle.x_norm.lo, kin.bundle.x_norm.span
    inputs = list(kin.layout.input_names)
    rows = np.zeros(len(joints), dtype=bool)
    per: dict[str, Any] = {}
    for j, name in enumerate(names):
        if name not in inputs:
            continue
        k = inputs.index(name)
        a, b = float(lo[k]), float(lo[k] + span[k])
        pad = margin * (b - a)
        bad = (joints[:, j] < a - pad) | (joints[:, j] > b + pad)
        per[name] = {"lo": a, "hi": b, "margin": pad, "count": int(bad.sum())}
        rows |= bad
    return {"rows": rows, "joints": per}


def predict(ds: Dataset, spec: str) -> tuple[np.ndarray, dict[str, Any]]:
    """(T, 6) predicted poses for predictor `spec`: "tcm", a robot file (.toml) or a model folder."""
    joints = ds.joints()
    info: dict[str, Any] = {"predictor": spec}
    if spec == "tcm" or spec.endswith(".toml"):
        model = CalibratedTCM(ds.robot) if spec == "tcm" else CalibratedTCM.from_file(spec)
        if not model.has_registration:
            pos, _ = model.robot_frame(joints)
            model.registration = Registration.fit(pos, ds.poses()[:, :3])
            info["registration"] = "fitted here on all samples (in-sample)"
        else:
            info["registration"] = "from the robot file's [calibration]"
        info["kind"] = "tcm"
        return model.predict(joints), info
    from ctrkin.inference.kinematics import Kinematics

    kin = Kinematics.load(spec)
    flags = out_of_range(kin, joints, ds.robot.joint_names())
    info.update(kind="learned", out_of_range=flags["joints"],
                out_of_range_samples=int(flags["rows"].sum()))
    pred = np.asarray(kin.predict(ds), dtype=float)
    info["flagged_rows"] = np.nonzero(flags["rows"])[0].tolist()
    return pred, info


def compare(ds: Dataset, pred: np.ndarray) -> dict[str, Any]:
    """Errors per sequence and overall: position (mm) and, where measured, orientation (deg)."""
    meas = ds.poses()
    pos_e = position_error(pred, meas)
    has_orient = ds.meta.get("orientation", "measured") != "absent"
    ang_e = tangent_angle_error(pred, meas) if has_orient else None
    sid = ds.frame["sequence_id"].to_numpy()
    labels = ds.meta.get("sequence_labels") or []

    def stats(rows: np.ndarray) -> dict[str, Any]:
        e = pos_e[rows]
        d: dict[str, Any] = {"samples": int(rows.sum()), "position_mean_mm": float(np.nanmean(e)),
                             "position_rmse_mm": float(np.sqrt(np.nanmean(e**2))),
                             "position_max_mm": float(np.nanmax(e))}
        if ang_e is not None:
            d["orientation_mean_deg"] = float(np.nanmean(ang_e[rows]))
        return d

    per = {}
    for k in np.unique(sid):
        name = str(labels[int(k)]) if int(k) < len(labels) else str(k)
        per[name] = stats(sid == k)
    return {"overall": stats(np.ones(len(sid), dtype=bool)), "per_sequence": per,
            "orientation": "measured" if has_orient else "absent (skipped)",
            "position_error_mm": pos_e}


def plots(ds: Dataset, pred: np.ndarray, pos_e: np.ndarray, out: Path) -> list[str]:
    """Predicted vs measured tips (x-y, x-z) and error against each joint; returns the file names."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    meas = ds.poses()
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.5))
    for ax, (a, b) in zip(axes, ((0, 1), (0, 2)), strict=True):
        ax.plot(meas[:, a], meas[:, b], ".", ms=4, label="measured")
        ax.plot(pred[:, a], pred[:, b], "x", ms=4, label="predicted")
        ax.set_xlabel("xyz"[a] + " (mm)")
        ax.set_ylabel("xyz"[b] + " (mm)")
        ax.set_aspect("equal", "datalim")
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(out / "tips.png", dpi=110)
    plt.close(fig)
    names = ds.robot.joint_names()
    joints = ds.joints()
    fig, axes = plt.subplots(1, len(names), figsize=(3.2 * len(names), 3.2), sharey=True)
    for j, ax in enumerate(np.atleast_1d(axes)):
        ax.plot(joints[:, j], pos_e, ".", ms=3)
        ax.set_xlabel(names[j] + (" (deg)" if names[j].startswith("alpha") else " (mm)"))
    np.atleast_1d(axes)[0].set_ylabel("tip error (mm)")
    fig.tight_layout()
    fig.savefig(out / "error_vs_joints.png", dpi=110)
    plt.close(fig)
    return ["tips.png", "error_vs_joints.png"]


def evaluate(ds: Dataset, spec: str, out: str | Path | None = None) -> dict[str, Any]:
    """Predict, compare and (with out) write results.json and the plots into folder `out`."""
    pred, info = predict(ds, spec)
    res = compare(ds, pred)
    pos_e = res.pop("position_error_mm")
    res.update(info)
    if out is not None:
        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        res["figures"] = plots(ds, pred, pos_e, folder)
        atomic_write_text(folder / "results.json", json.dumps(res, indent=2))
    return res
