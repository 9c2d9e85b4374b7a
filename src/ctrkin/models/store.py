"""A trained model's folder: everything needed to use it, and to refuse data it does not fit.

    config.json         training configuration (TrainConfig), data provenance, ctrkin version
    features.json       feature layout: task, tubes, input buffer, input/output names
    normalization.json  min-max of inputs and outputs (fit on the training split)
    robot.json          robot description and fingerprint
    weights.pt          network state_dict (best validation epoch)
    split.json          the train/val/test rows used       (written by training)
    metrics.json        losses and errors in mm / deg      (written by training)
    history.csv, curves.png   loss curves (paper Fig. 9)   (written by training)
    workspace.npz       IK only: training targets and distance threshold (ctrkin.inference.workspace)
    frame.json          FK in the outer tube's frame only: the registration (ctrkin.models.frame)
    checkpoint.pt       last epoch, optimiser and RNG state, to resume training
    manifest.json       SHA-256 of every file above but the checkpoint: loading refuses files that
                        were not written together (ctrkin.util.folders)

Training builds the folder aside and swaps it in whole (ctrkin.training.loop). weights.pt is
byte-identical for equal weights (the archive is written from memory, so it stores no file name).
"""

from __future__ import annotations

import io
import json
import pickle
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch

from ctrkin import __version__
from ctrkin.errors import ModelError
from ctrkin.models.base import KinematicsNet
from ctrkin.models.features import FeatureLayout
from ctrkin.models.frame import OuterFrame
from ctrkin.models.normalize import MinMax
from ctrkin.models.registry import build_model
from ctrkin.robots.robot import Robot
from ctrkin.util.files import atomic_write_bytes, atomic_write_text
from ctrkin.util.folders import check_manifest, write_manifest

CONFIG, FEATURES, NORMALIZATION, ROBOT, WEIGHTS = ("config.json", "features.json", "normalization.json",
                                                   "robot.json", "weights.pt")
FRAME = "frame.json"
REQUIRED = (CONFIG, FEATURES, NORMALIZATION, ROBOT, WEIGHTS)


def write_json(path: Path, obj: Any) -> None:
    atomic_write_text(path, json.dumps(obj, indent=2))


def read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise ModelError(f"cannot read {path}: {e}") from None


@dataclass(eq=False)
class ModelBundle:
    """A network with the layout, normalisation and robot it was trained for.

    config: the training configuration as a dict (TrainConfig.to_dict()) with "model", "options" and
    "output_activation"; extra: provenance stored beside it in config.json.
    """

    config: dict[str, Any]
    layout: FeatureLayout
    x_norm: MinMax
    y_norm: MinMax
    robot: Robot
    net: KinematicsNet
    extra: dict[str, Any] = field(default_factory=dict)
    frame: OuterFrame | None = None

    @classmethod
    def create(cls, config: dict[str, Any], layout: FeatureLayout, x_norm: MinMax, y_norm: MinMax,
               robot: Robot, extra: dict[str, Any] | None = None, frame: OuterFrame | None = None
               ) -> ModelBundle:
        """A fresh network (seed torch first) for this configuration."""
        net = build_model(config["model"], layout.n_inputs, layout.n_outputs, layout.ib,
                          config["output_activation"], config["options"])
        return cls(config, layout, x_norm, y_norm, robot, net, dict(extra or {}), frame)

    def save(self, folder: str | Path) -> Path:
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        write_json(out / CONFIG, {"train": self.config, "ctrkin_version": __version__, **self.extra})
        write_json(out / FEATURES, self.layout.to_dict())
        write_json(out / NORMALIZATION, {"inputs": self.x_norm.to_dict(), "outputs": self.y_norm.to_dict()})
        write_json(out / ROBOT, {"robot": self.robot.to_dict(), "fingerprint": self.robot.fingerprint()})
        if self.frame is not None:
            write_json(out / FRAME, self.frame.to_dict())
        buf = io.BytesIO()      # in memory: the archive's inner name is fixed, not the temp file's
        torch.save(self.net.state_dict(), buf)
        atomic_write_bytes(out / WEIGHTS, buf.getvalue())
        write_manifest(out, skip=("checkpoint.pt",))
        return out

    @classmethod
    def load(cls, folder: str | Path) -> ModelBundle:
        src = Path(folder)
        missing = [f for f in REQUIRED if not (src / f).is_file()]
        if missing:
            raise ModelError(f"{src} is not a trained ctrkin model folder: missing {missing} "
                             f"(train one with `ctrkin train --out {src}`)")
        check_manifest(src, REQUIRED, ModelError)
        cfg_file = read_json(src / CONFIG)
        config = cfg_file.pop("train")
        cfg_file.pop("ctrkin_version", None)
        layout = FeatureLayout.from_dict(read_json(src / FEATURES))
        norm = read_json(src / NORMALIZATION)
        x_norm, y_norm = MinMax.from_dict(norm["inputs"]), MinMax.from_dict(norm["outputs"])
        if len(x_norm.lo) != layout.n_inputs or len(y_norm.lo) != layout.n_outputs:
            raise ModelError(f"{src}: normalisation sizes ({len(x_norm.lo)}, {len(y_norm.lo)}) do not "
                             f"match the feature layout ({layout.n_inputs}, {layout.n_outputs})")
        rob = read_json(src / ROBOT)
        robot = Robot.from_dict(rob["robot"], source=str(src / ROBOT))
        if robot.fingerprint() != rob.get("fingerprint"):
            raise ModelError(f"{src / ROBOT}: the robot description does not match its stored "
                             f"fingerprint (edited by hand?)")
        frame = None
        if config.get("target_frame", "tracker") == "outer":
            if not (src / FRAME).is_file():
                raise ModelError(f"{src} learned poses in the outer tube's frame but lacks {FRAME}")
            frame = OuterFrame.from_dict(read_json(src / FRAME))
        bundle = cls.create(config, layout, x_norm, y_norm, robot, cfg_file, frame)
        try:
            state = torch.load(src / WEIGHTS, map_location="cpu", weights_only=True)
            bundle.net.load_state_dict(state)
        except (RuntimeError, OSError, KeyError, EOFError, pickle.UnpicklingError, zipfile.BadZipFile) as e:
            raise ModelError(f"{src / WEIGHTS} does not fit model {config['model']!r}: {e}") from None
        bundle.net.eval()
        return bundle
