"""Compare a predictor with an imported dataset (`ctrkin evaluate`): nominal TCM, a calibrated robot
file or a learned model, per part and per sequence, with plots (real_plots.py).

Position error is the Euclidean tip distance (mm); orientation error the angle between tip tangents
(deg), skipped for position-only datasets (meta["orientation"] == "absent").

Every row is labelled with what the predictor knew of it (`parts`), so that no figure mixes rows a
model was fitted on with rows it never saw:
- a learned model on the data it was trained on: its own split (split.json in the model folder):
  training, validation and held-out (test) rows; outliers it dropped are left out of every part,
  so the test figures are those `ctrkin train` reported (tested);
- the nominal TCM, and a robot file without a registration: a registration is fitted here on all
  samples, so every row is in-sample for those six parameters;
- a calibrated robot file on the data it was calibrated on (the [calibration] table's data_sha256):
  in-sample; on other data: held out.
`loso` (evaluate --loso) gives honest held-out figures for all of them: each sequence predicted by
a calibration, or a model, fitted to the other sequences only. A learned model flags samples whose
joints lie outside its training range by more than `margin` of that range.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.calibration.model import CalibratedTCM
from ctrkin.data.dataset import Dataset
from ctrkin.data.splits import Split, joint_coverage, split_with_test_val_rows
from ctrkin.geometry import Registration, position_error, tangent_angle_error
from ctrkin.util.files import atomic_write_text

RANGE_MARGIN = 0.05
MIN_PAD_DEG, MIN_PAD_MM = 1.0, 0.5   # the least margin: a joint held still in training still moves this much
TRAIN, VAL, TEST = "training", "validation", "held out (test)"
IN_SAMPLE_REG = "in-sample (registration fitted here)"
IN_SAMPLE_CAL = "in-sample (calibrated on these samples)"
HELD_OUT = "held out (fitted on other data)"
NOT_USED = "outlier (not used by the model)"
HELD_OUT_PARTS = (TEST, HELD_OUT)


def _arc(ok: np.ndarray, grid: np.ndarray) -> tuple[float, float]:
    """The smallest arc (deg, lo ≤ hi, hi − lo < 360) holding every angle of `grid` where `ok`."""
    if ok.all():
        return -180.0, 180.0
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return float("nan"), float("nan")
    gaps = np.diff(np.r_[idx, idx[0] + len(grid)])       # steps to the next consistent angle, wrapped
    k = int(np.argmax(gaps))                              # the largest gap lies outside the arc
    start = float(grid[idx[(k + 1) % idx.size]])
    end = float(grid[idx[k]])
    return start, end + 360.0 if end < start else end


def out_of_range(kin: Any, joints: np.ndarray, names: list[str], margin: float = RANGE_MARGIN
                 ) -> dict[str, Any]:
    """Joints (T, 2N) outside a learned model's training range by more than margin · range (at
    least MIN_PAD: an encoder's repeatability), read from its input normalisation in every angle
    encoding: a joint that is an input itself (min-max angles, β), or an angle the model sees as sin
    and cos (flagged where either leaves its trained range; the range reported is the arc of angles
    whose sin and cos both lie in theirs). Returns {"rows": (T,) bool, "joints": {name: {"lo", "hi",
    "margin", "count"}}} (deg, mm)."""
    trained = kin.bundle.x_norm.trained_range()
    inputs = list(kin.layout.input_names)
    rows = np.zeros(len(joints), dtype=bool)
    per: dict[str, Any] = {}
    for j, name in enumerate(names):
        q = joints[:, j]
        pad_min = MIN_PAD_DEG if name.startswith("alpha") else MIN_PAD_MM
        if name in inputs:
            k = inputs.index(name)
            a, b = float(trained[0][k]), float(trained[1][k])
            pad = max(margin * (b - a), pad_min)
            bad = (q < a - pad) | (q > b + pad)
        elif f"sin_{name}" in inputs and f"cos_{name}" in inputs:
            grid = np.arange(-180.0, 180.0, 0.25)
            bad = np.zeros(len(q), dtype=bool)
            ok = np.ones(len(grid), dtype=bool)
            for f, fn in (("sin", np.sin), ("cos", np.cos)):
                k = inputs.index(f"{f}_{name}")
                a, b = float(trained[0][k]), float(trained[1][k])
                pad = max(margin * (b - a), float(np.sin(np.radians(pad_min))))
                v, g = fn(np.radians(q)), fn(np.radians(grid))
                bad |= (v < a - pad) | (v > b + pad)
                ok &= (g >= a - pad) & (g <= b + pad)
            a, b = _arc(ok, grid)
            pad = 0.0                                         # already inside the arc
        else:
            continue
        per[name] = {"lo": a, "hi": b, "margin": pad, "count": int(bad.sum())}
        rows |= bad
    return {"rows": rows, "joints": per}


def is_robot_file(spec: str) -> bool:
    return spec == "tcm" or spec.endswith(".toml")


def predictor_name(spec: str) -> str:
    """A short name for tables and folders: tcm, the robot file's or the model folder's name."""
    return "tcm" if spec == "tcm" else Path(spec.rstrip("/")).stem or spec


def _calibration_table(spec: str) -> dict[str, Any]:
    return tomllib.loads(Path(spec).read_text()).get("calibration", {}) if spec.endswith(".toml") else {}


def parts(ds: Dataset, spec: str) -> tuple[np.ndarray, str]:
    """(T,) the part of each row for predictor `spec` (module docstring) and a note saying why."""
    n = len(ds.frame)
    if is_robot_file(spec):
        cal = _calibration_table(spec)
        if spec == "tcm" or "registration" not in cal:
            return np.full(n, IN_SAMPLE_REG), "a registration is fitted here on all samples"
        if cal.get("data_sha256") and cal.get("data_sha256") == ds.meta.get("data_sha256"):
            return np.full(n, IN_SAMPLE_CAL), "the robot file was calibrated on this dataset"
        if cal.get("data_sha256") is None and str(cal.get("dataset", "")) and \
                Path(str(cal.get("dataset"))).resolve() == Path(str(ds.meta.get("path", "-"))).resolve():
            return np.full(n, IN_SAMPLE_CAL), "the robot file was calibrated on this dataset folder"
        return np.full(n, HELD_OUT), "the robot file was calibrated on other data"
    from ctrkin.training.data import data_signature

    folder = Path(spec)
    config = json.loads((folder / "config.json").read_text())
    if (folder / "split.json").is_file() and config.get("data", {}).get("signature") == data_signature(ds):
        split = Split.load(folder / "split.json")
        out = np.full(n, NOT_USED, dtype=object)
        keep = np.ones(n, dtype=bool)
        if config.get("train", {}).get("drop_outliers", True):
            keep = ~ds.frame["outlier"].to_numpy(dtype=bool)
        for name, rows in ((TRAIN, split.train), (VAL, split.val), (TEST, split.test)):
            out[rows[keep[rows]]] = name
        return out.astype(str), "the model's own split (split.json in the model folder)"
    return np.full(n, HELD_OUT), "the model was trained on other data"


def predict(ds: Dataset, spec: str) -> tuple[np.ndarray, dict[str, Any]]:
    """(T, 6) predicted poses for predictor `spec`: "tcm", a robot file (.toml) or a model folder."""
    joints = ds.joints()
    info: dict[str, Any] = {"predictor": spec, "name": predictor_name(spec)}
    if is_robot_file(spec):
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


def _stats(pos_e: np.ndarray, ang_e: np.ndarray | None, rows: np.ndarray) -> dict[str, Any]:
    e = pos_e[rows]
    d: dict[str, Any] = {"samples": int(rows.sum()), "position_mean_mm": float(np.nanmean(e)),
                         "position_rmse_mm": float(np.sqrt(np.nanmean(e**2))),
                         "position_max_mm": float(np.nanmax(e))}
    if ang_e is not None:
        d["orientation_mean_deg"] = float(np.nanmean(ang_e[rows]))
    return d


def sequence_names(ds: Dataset) -> list[str]:
    """The label of each sequence id (imported logs: the file's name)."""
    labels = ds.meta.get("sequence_labels") or []
    ids = np.unique(ds.frame["sequence_id"].to_numpy())
    return [str(labels[int(k)]) if int(k) < len(labels) else str(k) for k in ids]


def compare(ds: Dataset, pred: np.ndarray, part: np.ndarray | None = None) -> dict[str, Any]:
    """Errors per part, per sequence (with the parts it holds) and over all rows: position (mm) and,
    where measured, orientation (deg)."""
    meas = ds.poses()
    pos_e = position_error(pred, meas)
    has_orient = ds.meta.get("orientation", "measured") != "absent"
    ang_e = tangent_angle_error(pred, meas) if has_orient else None
    sid = ds.frame["sequence_id"].to_numpy()
    part = np.full(len(sid), "", dtype=object) if part is None else part
    order = [TRAIN, VAL, TEST, IN_SAMPLE_REG, IN_SAMPLE_CAL, HELD_OUT, NOT_USED]
    present = sorted({str(p) for p in part.tolist() if p}, key=lambda p: [*order, p].index(p))
    per_part = {p: _stats(pos_e, ang_e, part == p) for p in present}
    per = {}
    for name, k in zip(sequence_names(ds), np.unique(sid), strict=True):
        rows = sid == k
        per[name] = {**_stats(pos_e, ang_e, rows),
                     "parts": sorted({str(p) for p in part[rows] if p})}
    return {"overall": _stats(pos_e, ang_e, np.ones(len(sid), dtype=bool)), "per_part": per_part,
            "per_sequence": per, "orientation": "measured" if has_orient else "absent (skipped)",
            "position_error_mm": pos_e}


def coverage_warnings(ds: Dataset, part: np.ndarray) -> list[str]:
    """Joints the held-out rows move that the training rows never moved (data.splits.joint_coverage)."""
    joints, names = ds.joints(), ds.robot.joint_names()
    train = np.isin(part, [TRAIN])
    held = np.isin(part, [TEST])
    return joint_coverage(joints[train], joints[held], names) if train.any() and held.any() else []


def evaluate(ds: Dataset, spec: str, out: str | Path | None = None) -> dict[str, Any]:
    """Predict, compare and (with out) write results.json and the plots into folder `out`."""
    pred, info = predict(ds, spec)
    part, why = parts(ds, spec)
    res = compare(ds, pred, part)
    pos_e = res.pop("position_error_mm")
    res.update(info)
    res["parts_source"] = why
    res["warnings"] = coverage_warnings(ds, part)
    if out is not None:
        from ctrkin.evaluation.real_plots import plots

        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        res["figures"] = plots(ds, pred, pos_e, np.isin(part, HELD_OUT_PARTS), sequence_names(ds),
                               predictor_name(spec), res, folder)
        atomic_write_text(folder / "results.json", json.dumps(res, indent=2))
    return res


# --- leave one sequence out ----------------------------------------------------------------------------
def loso(ds: Dataset, spec: str, work: Path, max_epochs: int | None = None) -> dict[str, Any]:
    """Each sequence predicted by the predictor refitted to the other sequences: for a robot file
    (or tcm) the calibration groups it was fitted with (registration only for tcm or an uncalibrated
    file), refitted from the dataset's nominal robot; for a model folder its training configuration,
    retrained with the held-out sequence as test and 15 % of the other rows as validation (the
    benchmark's split). Returns {"per_sequence": {label: mean mm}, "mean_mm", "samples", "how",
    "warnings"}; models are written under `work`."""
    names = sequence_names(ds)
    sid = ds.frame["sequence_id"].to_numpy()
    if len(names) < 2:
        from ctrkin.errors import CtrkinError

        raise CtrkinError("leave-one-sequence-out needs at least 2 sequences")
    joints = ds.joints()
    warnings = []
    for name, k in zip(names, np.unique(sid), strict=True):
        for w in joint_coverage(joints[sid != k], joints[sid == k], ds.robot.joint_names()):
            warnings.append(f"{name}: {w}")
    if is_robot_file(spec):
        from ctrkin.calibration import leave_one_sequence_out

        cal = _calibration_table(spec)
        fit = cal.get("fit", {}) if "registration" in cal else {}
        groups = tuple(fit.get("groups", ("registration",)))
        res = leave_one_sequence_out(ds, ds.robot, groups, prior=bool(cal.get("prior", True)))
        return {**res, "how": f"calibration groups {list(groups)} refitted on the other sequences from "
                f"the dataset's nominal robot", "warnings": warnings}
    return _loso_learned(ds, spec, work, names, max_epochs) | {"warnings": warnings}


def _loso_learned(ds: Dataset, spec: str, work: Path, names: list[str], max_epochs: int | None
                  ) -> dict[str, Any]:
    import dataclasses

    from ctrkin.inference.kinematics import Kinematics
    from ctrkin.training import TrainConfig, train

    config = json.loads((Path(spec) / "config.json").read_text())["train"]
    cfg = dataclasses.replace(TrainConfig.from_dict(config), split="dataset")
    if max_epochs:
        cfg = dataclasses.replace(cfg, max_epochs=max_epochs)
    sid = ds.frame["sequence_id"].to_numpy()
    meas = ds.poses()[:, :3]
    per, errs = {}, []
    for name in names:
        split = split_with_test_val_rows(sid, names, [name], 0.15, seed=cfg.split_seed)
        fold = Dataset(frame=ds.frame, robot=ds.robot, meta=dict(ds.meta), split=split)
        folder = work / f"loso_{name}"
        train(fold, cfg, folder, overwrite=True, progress=False)
        test = split.test
        e = np.linalg.norm(np.asarray(Kinematics.load(folder).predict(fold))[test, :3] - meas[test], axis=1)
        per[name] = float(np.mean(e))
        errs.append(e)
    all_e = np.concatenate(errs)
    return {"per_sequence": per, "mean_mm": float(np.mean(all_e)), "samples": int(all_e.size),
            "how": f"{cfg.model} retrained per fold (its config.json), test = the held-out sequence, "
                   "validation = 15 % of the other rows"}
