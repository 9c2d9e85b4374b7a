"""The output folder of a reproduction: whose it is, and what a rerun may do with it.

A reproduction reuses what an earlier run of the same settings left in its folder (data, models),
so a rerun continues. A folder that holds a reproduction of other settings (scale, robot, robot
seed, the virtual robot's effects, what the recommended models train on: TRAINING_DATA) is refused
before anything is recorded, unless `overwrite`, which replaces it as a whole
(ctrkin.util.ownership: only a ctrkin reproduction holding nothing else is ever replaced). The
settings live in the folder's marker (ctrkin-output.json); a folder of ctrkin before 0.2 has none,
and is judged by the key its paper dataset was recorded with.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path
from typing import Any

from ctrkin.errors import OutputError
from ctrkin.evaluation.datasets import paper_key, virtual_overrides
from ctrkin.evaluation.scales import ReproScale
from ctrkin.robots.robot import Robot
from ctrkin.util.folders import new_build
from ctrkin.util.ownership import check_replaceable, read_marker, write_marker
from ctrkin.virtual.config import VirtualConfig

KIND = "reproduction"
# what the recommended models train on (a reproduction before the excitation protocol: "paper")
TRAINING_DATA = "paper+excitation"


def settings(robot: Robot, scale: ReproScale, robot_seed: int,
             virtual: VirtualConfig | None = None) -> dict[str, Any]:
    """What a reproduction folder is a reproduction of (kept in its marker); virtual_settings: the
    effect magnitudes that differ from the default (datasets.virtual_overrides)."""
    return {"scale": scale.name, "robot": robot.name, "robot_fingerprint": robot.fingerprint(),
            "robot_seed": int(robot_seed), "virtual_settings": virtual_overrides(virtual),
            "training_data": TRAINING_DATA}


def _recorded(out: Path) -> dict[str, Any] | None:
    """The settings the folder's reproduction was made with; None for a new or empty folder.
    A folder of ctrkin before 0.2: {"paper_key", "robot_fingerprint"} of its paper dataset.
    virtual_config: the whole virtual robot configuration its paper dataset was recorded with (None
    if it has none yet): the marker keeps only what differs from the default of its time, and the
    defaults changed (docs/virtual_robot.md: Effects and default magnitudes)."""
    marker = read_marker(out)
    if marker is not None:      # a marker before --set has no virtual_settings: the default's
        return {**{k: marker.get(k) for k in ("scale", "robot", "robot_fingerprint", "robot_seed")},
                "virtual_settings": marker.get("virtual_settings", {}),
                "training_data": marker.get("training_data", "paper"),
                "virtual_config": _paper_config(out)}
    try:
        meta = json.loads((out / "data" / "paper" / "meta.json").read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(meta, dict):
        return None
    return {"paper_key": meta.get("reproduce_key"), "robot_fingerprint": meta.get("robot_fingerprint")}


def _paper_config(out: Path) -> Any:
    """The virtual robot configuration in the folder's paper dataset meta, None if there is none."""
    try:
        meta = json.loads((out / "data" / "paper" / "meta.json").read_text())
        return meta["virtual_robot"]["config"]
    except (OSError, ValueError, KeyError, TypeError):
        return None


def claim(out: Path, robot: Robot, scale: ReproScale, robot_seed: int, overwrite: bool,
          virtual: VirtualConfig | None = None) -> None:
    """Make `out` this reproduction's folder (call it holding its writer lock): keep it when it holds
    one of the same settings, refuse one of other settings (OutputError) unless `overwrite`, which
    clears it first; then mark it."""
    if os.path.lexists(out) and (not out.is_dir() or any(out.iterdir())):
        check_replaceable(out, KIND, OutputError)
        want = settings(robot, scale, robot_seed, virtual)
        got = _recorded(out)
        same = got is not None and (
            {k: got[k] for k in want} == want if "paper_key" not in got else
            (got["paper_key"] == paper_key(scale, robot_seed, robot, virtual)
             and got["robot_fingerprint"] == want["robot_fingerprint"]))
        config = (virtual if virtual is not None else VirtualConfig()).to_dict()
        earlier = got is not None and got.get("virtual_config") not in (None, config)
        if overwrite:
            _clear(out)
        elif same and earlier:
            raise OutputError(
                f"{out} holds a reproduction recorded with other virtual robot effects (the defaults "
                "of an earlier version, docs/virtual_robot.md: Effects and default magnitudes; "
                "`--set` with the central values gives those back); pass --overwrite to replace it, "
                "or choose another --out")
        elif not same:
            what = (f"scale {got.get('scale')}, robot {got.get('robot')}, robot seed {got.get('robot_seed')}"
                    f"{_effects(got.get('virtual_settings'))}, its recommended models trained on "
                    f"{got.get('training_data')}"
                    if got is not None and "paper_key" not in got else "other settings")
            raise OutputError(f"{out} holds a reproduction of {what}; pass --overwrite to replace it, or "
                              "choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    if read_marker(out) is None:
        write_marker(out, KIND, **settings(robot, scale, robot_seed, virtual))


def _effects(changed: Any) -> str:
    """", virtual robot KEY=VALUE, ..." of a reproduction's --set settings ("" for the default)."""
    if not changed:
        return ""
    return ", virtual robot " + " ".join(f"{k}={v}" for k, v in sorted(dict(changed).items()))


def _clear(out: Path) -> None:
    """Replace `out` by an empty folder: moved aside under a build name first (a kill leaves a
    leftover that the next write cleans), then removed."""
    aside = new_build(out)
    os.rmdir(aside)
    out.rename(aside)
    shutil.rmtree(aside, ignore_errors=True)
