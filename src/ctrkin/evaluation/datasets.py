"""The datasets a reproduction needs, recorded on one virtual robot (one hardware draw), and the
truth as the tracker would see it without noise (the reference for "vs true" errors)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.acquisition import protocols
from ctrkin.acquisition.ranges import ProtocolRanges
from ctrkin.acquisition.recorder import record
from ctrkin.acquisition.task_paths import task_path
from ctrkin.data.dataset import Dataset
from ctrkin.errors import DatasetError
from ctrkin.evaluation.scales import ReproScale
from ctrkin.robots.robot import Robot
from ctrkin.virtual import VirtualConfig, VirtualRobot
from ctrkin.virtual.truth import tracker_truth

# noise seeds: training and each test experiment see independent measurement noise
SEEDS = {"paper": 0, "sweeps": 1, "random-points": 2, "arbitrary": 3, "square": 4, "triangle": 5,
         "snap-turns": 6, "excitation": 8}


@dataclass(eq=False)
class ReproData:
    """paper: training data; sweeps, random_points, arbitrary: test experiments (Fig. 10);
    square, triangle: IK target poses (P, 6) in the tracker frame (Fig. 12); snap_turns: full turns
    at full overlap off the training grid (ctrkin.acquisition.protocols.snap_turns); excitation:
    training-only runs (ctrkin.acquisition.excitation) added to the recommended models' training rows
    (with_training_runs), never to a validation or test part."""

    virtual: VirtualRobot
    paper: Dataset
    sweeps: Dataset
    random_points: Dataset
    arbitrary: Dataset
    square: np.ndarray
    triangle: np.ndarray
    snap_turns: Dataset
    excitation: Dataset


def registered_truth(ds: Dataset, virtual: VirtualRobot | None = None) -> np.ndarray:
    """(T, 6) noise-free tracker view of the true poses (see ctrkin.virtual.truth)."""
    truth = tracker_truth(ds, virtual)
    if truth is None:
        raise DatasetError("this dataset has no virtual-robot truth (true_* columns and virtual_robot meta)")
    return truth


def collect(
    robot: Robot,
    scale: ReproScale,
    out: Path,
    robot_seed: int = 0,
    workers: int | None = None,
    progress: bool = True,
    config: VirtualConfig | None = None,
) -> ReproData:
    """Record every dataset of a reproduction into out/<name> (reused when already there, recorded
    with the same settings); config: the virtual robot's effects (default VirtualConfig())."""
    config = VirtualConfig() if config is None else config
    virtual = VirtualRobot(robot, config, seed=robot_seed)

    def get(name: str, **kw: object) -> Dataset:
        folder = out / name
        key = _key(name, scale, robot_seed, kw, config)
        if (folder / "meta.json").is_file():
            ds = Dataset.load(folder, robot=robot)
            if (ds.meta.get("reproduce_key") == key
                    and ds.meta.get("virtual_robot", {}).get("config") == config.to_dict()):
                return ds      # (the key holds only what differs from the defaults of its time)
        plan = protocols.build(
            name,
            robot,
            scale=scale.protocol_scale,  # type: ignore[arg-type]
            seed=SEEDS[name],
            **kw,
        )
        ds = record(
            plan,
            virtual,
            seed=SEEDS[name],
            workers=workers,
            progress=progress,
            meta={"reproduce_key": key},
        )
        ds.save(folder)
        return Dataset.load(folder, robot=robot)

    paper = get("paper", **_paper_kw(scale, robot))
    shapes = {
        s: virtual.tracker.registered(task_path(virtual, s, n_points=10, seed=SEEDS[s]).poses)
        for s in ("square", "triangle")
    }
    return ReproData(
        virtual=virtual,
        paper=paper,
        sweeps=get("sweeps"),
        random_points=get("random-points", n_points=20),
        arbitrary=get("arbitrary"),
        square=shapes["square"],
        triangle=shapes["triangle"],
        snap_turns=get("snap-turns"),
        excitation=get("excitation"),
    )


def with_training_runs(ds: Dataset, extra: Dataset) -> Dataset:
    """`ds` with the rows of `extra` appended as TRAINING rows only (e.g. the excitation protocol's:
    ctrkin.acquisition.excitation): their sequence ids and runs renumbered after those of `ds` (each
    extra run starts from rest, as recorded), the split `ds`'s with every extra row added to its
    training part, so validation and test are the rows of `ds` they were.

    Raises
    ------
    DatasetError
        `ds` has no split, or the two were recorded on different robots.
    """
    if ds.split is None:
        raise DatasetError("with_training_runs: the dataset needs its split (save_split) first")
    if ds.robot.fingerprint() != extra.robot.fingerprint():
        raise DatasetError(f"with_training_runs: the extra runs were recorded on robot {extra.robot.name!r}, "
                           f"not on {ds.robot.name!r}")
    import pandas as pd

    more = extra.frame.copy()
    for col in ("sequence_id", "run"):             # `run` is optional (recorded datasets have it)
        if col in ds.frame.columns and col in more.columns:
            more[col] = more[col].to_numpy() + int(ds.frame[col].max()) + 1
    frame = pd.concat([ds.frame, more[ds.frame.columns]], ignore_index=True)
    n = len(ds.frame)
    split = dataclasses.replace(ds.split, train=np.r_[ds.split.train, n + np.arange(len(more))],
                                n_rows=len(frame))
    meta = {**ds.meta, "training_runs": {"protocol": extra.meta.get("protocol"), "samples": len(more),
                                         "data_sha256": extra.meta.get("data_sha256"),
                                         "params": extra.meta.get("protocol_params")}}
    return Dataset(frame, ds.robot, meta, split=split)


TRAINING_FOLDER = "paper+excitation"      # beside data/paper: the recommended models' training data


def save_training_set(data: ReproData, folder: Path) -> Path:
    """Save the paper dataset (its split saved) with the excitation runs among its training rows
    (with_training_runs) into `folder`, unless it already holds exactly that (the same paper and
    excitation data and split: a rerun reuses it, and the models trained on it); the folder."""
    combined = with_training_runs(data.paper, data.excitation)
    key = {"paper": data.paper.meta.get("data_sha256"), "excitation": data.excitation.meta.get("data_sha256"),
           "split": data.paper.get_split().to_dict()}
    if (folder / "meta.json").is_file():
        old = Dataset.load(folder)
        if old.meta.get("training_set_key") == key:
            return folder
    combined.meta["training_set_key"] = key
    combined.save(folder)
    return folder


def collect_training_data(robot: Robot, scale: ReproScale, data_dir: Path, robot_seed: int = 0,
                          config: VirtualConfig | None = None, progress: bool = True
                          ) -> tuple[ReproData, Path]:
    """What `ctrkin reproduce` records before it trains: every dataset (`collect`) into data_dir, the
    paper data's split (seed 0) saved beside it, and the recommended models' training set
    (`save_training_set`, data_dir/TRAINING_FOLDER); the data and that folder."""
    data = collect(robot, scale, data_dir, robot_seed=robot_seed, progress=progress, config=config)
    data.paper.save_split(data_dir / "paper", data.paper.get_split(seed=0))
    return data, save_training_set(data, data_dir / TRAINING_FOLDER)


def virtual_overrides(config: VirtualConfig | None) -> dict[str, Any]:
    """The effect magnitudes of `config` that differ from VirtualConfig()'s: {} for the default (what
    `--set` changed, whatever way it was spelled)."""
    if config is None:
        return {}
    default = VirtualConfig().to_dict()
    return {k: v for k, v in config.to_dict().items() if default.get(k) != v}


def _key(name: str, scale: ReproScale, robot_seed: int, kw: dict[str, object],
         config: VirtualConfig | None = None) -> str:
    """The settings a dataset of a reproduction is recorded with (its meta's reproduce_key); the
    virtual robot's effects only where they are not the default (the key of earlier reproductions)."""
    key = f"{name}|{scale.protocol_scale}|{robot_seed}|{sorted((k, str(v)) for k, v in kw.items())}"
    changed = virtual_overrides(config)
    return key + (f"|{sorted((k, str(v)) for k, v in changed.items())}" if changed else "")


def _paper_kw(scale: ReproScale, robot: Robot) -> dict[str, object]:
    """The paper protocol's options at `scale`: its levels (the paper robot's, carried over to
    `robot`, ctrkin.acquisition.ranges) and outer step."""
    kw: dict[str, object] = {}
    if scale.paper_levels is not None:
        kw["levels"] = ProtocolRanges.of(robot).levels(scale.paper_levels)
    if scale.paper_outer_step_deg is not None:
        kw["outer_step_deg"] = scale.paper_outer_step_deg
    return kw


def paper_key(scale: ReproScale, robot_seed: int, robot: Robot,
              config: VirtualConfig | None = None) -> str:
    """The key the paper dataset of a reproduction at `scale` is recorded with (its meta.json)."""
    return _key("paper", scale, robot_seed, _paper_kw(scale, robot), config)
