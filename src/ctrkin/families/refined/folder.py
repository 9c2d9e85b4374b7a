"""A refined IK model folder: an IK model folder with the FK model it is refined on in `fk/` and the
refinement settings in `refine.json` (ctrkin.families.refined.refine). `Kinematics.load` opens it
like any model folder and refines every answer.

    from ctrkin.families.refined import assemble_refined
    assemble_refined("models/ik", "models/fk_branch", "models/ik_refined")
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from ctrkin.errors import ModelError
from ctrkin.families.refined.refine import RefineSettings
from ctrkin.models.store import FEATURES, ROBOT, read_json
from ctrkin.models.workspace import WORKSPACE_FILE, Workspace
from ctrkin.robots.robot import Robot
from ctrkin.util.folders import build_folder, reading_folder

REFINE_FILE, REFINE_FK = "refine.json", "fk"
_NOT_COPIED = shutil.ignore_patterns("checkpoint*", ".lock", "*.tmp")


def _task_and_robot(folder: Path) -> tuple[str, str]:
    """(task, the robot's mechanical fingerprint) of a model folder, from its files."""
    for name in (FEATURES, ROBOT):
        if not (folder / name).is_file():
            raise ModelError(f"{folder} is not a trained ctrkin model folder: missing {name}")
    # the task as stored: a family's own layout (the follow IK's) is only read whole once that family
    # is imported, which this family may not do (ctrkin.families: a family imports no other)
    stored = read_json(folder / FEATURES)
    task = stored.get("task") if isinstance(stored, dict) else None
    if task not in ("fk", "ik"):
        raise ModelError(f"{folder / FEATURES} names no task 'fk' or 'ik' (got {task!r})")
    robot = Robot.from_dict(read_json(folder / ROBOT)["robot"], source=str(folder / ROBOT))
    return str(task), robot.mechanical_fingerprint()


def check_parts(ik_dir: Path, fk_dir: Path, settings: RefineSettings) -> None:
    """Refuse an IK and an FK folder that cannot make a refined IK: not an IK and an FK model, another
    robot, an IK already refined, or a 'nearest' start without the training joints."""
    (ik_task, ik_robot), (fk_task, fk_robot) = _task_and_robot(ik_dir), _task_and_robot(fk_dir)
    if ik_task != "ik" or fk_task != "fk":
        raise ModelError(f"a refined IK is an IK model ({ik_dir}: {ik_task}) refined on an FK model "
                         f"({fk_dir}: {fk_task})")
    if (ik_dir / REFINE_FILE).is_file():
        raise ModelError(f"{ik_dir} is already a refined IK model")
    if fk_robot != ik_robot:
        raise ModelError("the FK model was trained on another robot than this IK model")
    ws = Workspace.load(ik_dir) if (ik_dir / WORKSPACE_FILE).is_file() else None
    if "nearest" in settings.starts and (ws is None or ws.joints is None):
        raise ModelError("the 'nearest' start needs the training joints in workspace.npz; retrain the "
                         "IK model or drop 'nearest' from RefineSettings.starts")


def assemble_refined(ik_dir: str | Path, fk_dir: str | Path, out: str | Path,
                     settings: RefineSettings | None = None) -> Path:
    """Write `out`: a copy of IK model `ik_dir` refined on FK model `fk_dir` (both trained on the
    same robot). Built beside `out` and swapped in, so a failure leaves the previous folder."""
    ik_src, fk_src, target = Path(ik_dir), Path(fk_dir), Path(out)
    settings = settings or RefineSettings()
    check_parts(ik_src, fk_src, settings)
    with (build_folder(target, "model", ModelError) as build, reading_folder(ik_src),
          reading_folder(fk_src)):
        shutil.copytree(ik_src, build, dirs_exist_ok=True, ignore=_NOT_COPIED)
        shutil.copytree(fk_src, build / REFINE_FK, ignore=_NOT_COPIED)
        (build / REFINE_FILE).write_text(json.dumps(settings.to_dict(), indent=2))
    return target
