"""A summary of a dataset (what `ctrkin dataset info` prints): sizes, ranges, snaps, cleaning, noise."""

from __future__ import annotations

from typing import Any

import numpy as np

from ctrkin.data import schema
from ctrkin.data.dataset import Dataset
from ctrkin.geometry import position_error, tangent_angle_error

VIRTUAL_NOISE_KEYS = ("noise_mm", "noise_deg", "readings_per_sample", "glitch_rate", "glitch_deg",
                      "glitch_mm")


def noise_info(ds: Dataset) -> dict[str, Any] | None:
    """meta["noise"] (imported logs: the spread of repeated readings), or the virtual robot's
    tracker noise and glitch settings; plus, with true poses, the measured-minus-true error of the
    samples not flagged as outliers (position RMS mm, tangent angle RMS deg)."""
    out: dict[str, Any] = {}
    if isinstance(ds.meta.get("noise"), dict):
        out.update(ds.meta["noise"])
    config = (ds.meta.get("virtual_robot") or {}).get("config")
    if isinstance(config, dict):
        out.update({k: config[k] for k in VIRTUAL_NOISE_KEYS if k in config})
    if ds.has_truth:
        keep = ~ds.frame["outlier"].to_numpy(dtype=bool)
        meas, true = ds.poses()[keep], ds.poses(true=True)[keep]
        if len(meas):
            out["measured_vs_true_position_rms_mm"] = float(np.sqrt(np.mean(position_error(meas, true) ** 2)))
            out["measured_vs_true_tangent_rms_deg"] = float(
                np.sqrt(np.mean(tangent_angle_error(meas, true) ** 2)))
    return out or None


def summarize(ds: Dataset) -> dict[str, Any]:
    """A JSON-ready dict: samples, sequences (count and lengths), per-column ranges with units,
    snaps, outliers, split sizes, and the protocol, seed, robot, cleaning and noise entries of meta."""
    frame = ds.frame
    lengths = np.array([b - a for a, b in ds.sequence_bounds()])
    columns = schema.joint_columns(ds.n_tubes) + schema.POSE_COLUMNS
    columns += [c for c in schema.TRUE_POSE_COLUMNS if c in frame.columns]
    if "time" in frame.columns:
        columns.append("time")
    ranges = {}
    for c in columns:
        v = frame[c].to_numpy(dtype=float)
        ranges[c] = {"min": float(v.min()), "max": float(v.max()), "mean": float(v.mean()),
                     "unit": schema.column_unit(c)}
    meta = ds.meta
    split = None
    if ds.split is not None:
        split = {"kind": ds.split.kind, "seed": ds.split.seed, "fractions": list(ds.split.fractions),
                 **ds.split.sizes()}
    return {
        "robot": {"name": ds.robot.name, "n_tubes": ds.n_tubes, "fingerprint": ds.robot.fingerprint(),
                  "transmission": ds.robot.transmission},
        "format_version": meta.get("format_version", schema.FORMAT_VERSION),
        "ctrkin_version": meta.get("ctrkin_version"),
        "protocol": meta.get("protocol"),
        "protocol_params": meta.get("protocol_params"),
        "seed": meta.get("seed"),
        "samples": len(frame),
        "sequences": len(lengths),
        "sequence_length": {"min": int(lengths.min()), "median": float(np.median(lengths)),
                            "max": int(lengths.max())},
        "snaps": int(frame["snap"].sum()),
        "outliers_flagged": int(frame["outlier"].sum()),
        "has_truth": ds.has_truth,
        "ranges": ranges,
        "cleaning": meta.get("cleaning"),
        "noise": noise_info(ds),
        "split": split,
    }
