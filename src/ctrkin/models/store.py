"""A trained model's folder: everything needed to use it, and to refuse data it does not fit.

    config.json         training configuration (TrainConfig), data provenance, ctrkin version
    features.json       feature layout: task, tubes, input buffer, input/output names
    normalization.json  min-max of inputs and outputs (fit on the training split)
    robot.json          robot description and fingerprint
    weights.pt          network state_dict (best validation epoch)
    split.json          the train/val/test rows used       (written by training)
    metrics.json        losses and errors in mm / deg      (written by training)
    history.csv, curves.png   loss curves (paper Fig. 9)   (written by training)
    workspace.npz       IK only: training targets and distance threshold (ctrkin.models.workspace)
    frame.json          FK in the outer tube's frame only: the registration (ctrkin.models.frame)
    tcm_prior.toml      FK trained with tcm_prior only: the calibrated TCM it learned the residual
                        of, a calibrated robot file (ctrkin.models.tcm_prior)
    checkpoint.pt       last epoch, optimiser and RNG state, to resume training
    manifest.json       SHA-256 of every file above but the checkpoint: loading refuses files that
                        were not written together (ctrkin.util.folders)

Training builds the folder aside and swaps it in whole (ctrkin.training.engine). weights.pt is
byte-identical for equal weights (the archive is written from memory, so it stores no file name).
"""

from __future__ import annotations

import io
import json
import pickle
import zipfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import torch

from ctrkin.errors import ModelError
from ctrkin.models.base import KinematicsNet
from ctrkin.models.features import FeatureLayout
from ctrkin.models.frame import OuterFrame
from ctrkin.models.normalize import MinMax
from ctrkin.robots.robot import Robot
from ctrkin.util.files import atomic_write_bytes, atomic_write_text
from ctrkin.util.folders import check_manifest, reading_folder, write_manifest
from ctrkin.version import __version__

if TYPE_CHECKING:
    from ctrkin.calibration.model import CalibratedTCM

CONFIG, FEATURES, NORMALIZATION, ROBOT, WEIGHTS = ("config.json", "features.json", "normalization.json",
                                                   "robot.json", "weights.pt")
FRAME = "frame.json"
CHECKPOINT = "checkpoint.pt"    # training's resumable state: not in the manifest (ctrkin.training.engine)
REQUIRED = (CONFIG, FEATURES, NORMALIZATION, ROBOT, WEIGHTS)


def write_json(path: Path, obj: Any) -> None:
    atomic_write_text(path, json.dumps(obj, indent=2))


MAX_JSON_BYTES = 64 << 20      # a model folder's JSON files hold settings and small tables


def read_json(path: Path) -> Any:
    try:
        if path.stat().st_size > MAX_JSON_BYTES:
            raise ModelError(f"{path} is larger than {MAX_JSON_BYTES >> 20} MB: not a file ctrkin wrote")
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError, UnicodeDecodeError, RecursionError) as e:
        raise ModelError(f"cannot read {path}: {e}") from None


@dataclass(frozen=True)
class ModelConfig:
    """The configuration a model was trained with: config.json's "train" entry
    (ctrkin.training.TrainConfig.to_dict()), typed where the model side reads it.

    model: registry name (ctrkin.models.MODELS); options: its resolved options; output_activation:
    "relu" | "linear"; pose_source: the pose columns learned from, "measured" | "true"; target_frame:
    FK poses learned in the "tracker" or the "outer" tube's frame (ctrkin.models.frame); training:
    the whole entry as written (how it was trained: provenance, and the resume check).
    """

    model: str
    options: dict[str, Any]
    output_activation: str
    pose_source: str = "measured"
    target_frame: str = "tracker"
    training: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, d: dict[str, Any], source: str = "config.json") -> ModelConfig:
        """From the "train" entry (older folders lack pose_source and target_frame: the defaults)."""
        if not isinstance(d, dict):
            raise ModelError(f"{source}: the training configuration is not a table")
        try:
            return cls(str(d["model"]), dict(d["options"]), str(d["output_activation"]),
                       str(d.get("pose_source", "measured")), str(d.get("target_frame", "tracker")),
                       dict(d))
        except (KeyError, TypeError, ValueError) as e:
            raise ModelError(f"{source}: the training configuration lacks or mangles {e}; retrain the "
                             "model with `ctrkin train`") from None

    def to_dict(self) -> dict[str, Any]:
        """The "train" entry: the keys as written, in their order, typed fields taking precedence."""
        return {**self.training, "model": self.model, "options": self.options,
                "output_activation": self.output_activation, "pose_source": self.pose_source,
                "target_frame": self.target_frame}

    def __getitem__(self, key: str) -> Any:
        """Dict-style read of a JSON key (the bundle's config was a dict before it was typed)."""
        return self.to_dict()[key]

    def get(self, key: str, default: Any = None) -> Any:
        return self.to_dict().get(key, default)


NetBuilder = Callable[[ModelConfig, FeatureLayout], KinematicsNet]   # a fresh network by registry name


@dataclass(eq=False)
class ModelBundle:
    """A network with the layout, normalisation and robot it was trained for.

    config: the typed training configuration (ModelConfig); x_norm, y_norm: the min-max pre/post
    step (ctrkin.models.normalize); extra: provenance stored beside the configuration in config.json;
    frame: the outer-tube frame of a model that learned in it; prior: the calibrated TCM of an FK
    trained with tcm_prior (ctrkin.models.tcm_prior), None otherwise.
    """

    config: ModelConfig
    layout: FeatureLayout
    x_norm: MinMax
    y_norm: MinMax
    robot: Robot
    net: KinematicsNet
    extra: dict[str, Any] = field(default_factory=dict)
    frame: OuterFrame | None = None
    prior: CalibratedTCM | None = None

    @classmethod
    def create(cls, config: ModelConfig | dict[str, Any], layout: FeatureLayout, x_norm: MinMax,
               y_norm: MinMax, robot: Robot, extra: dict[str, Any] | None = None,
               frame: OuterFrame | None = None, *, build: NetBuilder) -> ModelBundle:
        """A fresh network (seed torch first) for this configuration (a dict: TrainConfig.to_dict()),
        made by `build` (the registry's, ctrkin.families.registry.build_net)."""
        if not isinstance(config, ModelConfig):
            config = ModelConfig.from_dict(config)
        return cls(config, layout, x_norm, y_norm, robot, build(config, layout), dict(extra or {}), frame)

    def save(self, folder: str | Path) -> Path:
        out = Path(folder)
        out.mkdir(parents=True, exist_ok=True)
        write_json(out / CONFIG, {"train": self.config.to_dict(), "ctrkin_version": __version__,
                                  **self.extra})
        write_json(out / FEATURES, self.layout.to_dict())
        write_json(out / NORMALIZATION, {"inputs": self.x_norm.to_dict(), "outputs": self.y_norm.to_dict()})
        write_json(out / ROBOT, {"robot": self.robot.to_dict(), "fingerprint": self.robot.fingerprint()})
        if self.frame is not None:
            write_json(out / FRAME, self.frame.to_dict())
        if self.prior is not None:
            from ctrkin.models.tcm_prior import save_prior

            save_prior(self.prior, out)
        buf = io.BytesIO()      # in memory: the archive's inner name is fixed, not the temp file's
        torch.save(self.net.state_dict(), buf)
        atomic_write_bytes(out / WEIGHTS, buf.getvalue())
        write_manifest(out, skip=(CHECKPOINT,))
        return out

    @classmethod
    def load(cls, folder: str | Path, build: NetBuilder) -> ModelBundle:
        """The model folder `folder`, its network made by `build` (the registry's,
        ctrkin.families.registry.build_net: open_bundle) and given the stored weights, read as one
        version while another process may replace it (ctrkin.util.folders)."""
        with reading_folder(folder) as src:     # one version, never a mix
            return cls._load(src, build)

    @classmethod
    def _load(cls, src: Path, build: NetBuilder) -> ModelBundle:
        missing = [f for f in REQUIRED if not (src / f).is_file()]
        if missing:
            raise ModelError(f"{src} is not a trained ctrkin model folder: missing {missing} "
                             f"(train one with `ctrkin train --out {src}`)")
        check_manifest(src, REQUIRED, ModelError)
        cfg_file = read_json(src / CONFIG)
        if not isinstance(cfg_file, dict) or "train" not in cfg_file:
            raise ModelError(f"{src / CONFIG} has no training configuration (\"train\"); retrain the model")
        config = ModelConfig.from_dict(cfg_file.pop("train"), str(src / CONFIG))
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
        if config.target_frame == "outer":
            if not (src / FRAME).is_file():
                raise ModelError(f"{src} learned poses in the outer tube's frame but lacks {FRAME}")
            frame = OuterFrame.from_dict(read_json(src / FRAME))
        bundle = cls.create(config, layout, x_norm, y_norm, robot, cfg_file, frame, build=build)
        if config.training.get("tcm_prior"):
            from ctrkin.models.tcm_prior import load_prior

            bundle.prior = load_prior(src, layout.n_tubes)
        try:
            state = torch.load(src / WEIGHTS, map_location="cpu", weights_only=True)
            bundle.net.load_state_dict(state)
        except (RuntimeError, OSError, KeyError, EOFError, pickle.UnpicklingError, zipfile.BadZipFile) as e:
            raise ModelError(f"{src / WEIGHTS} does not fit model {config.model!r}: {e}") from None
        bundle.net.eval()
        return bundle
