"""A refined IK model folder: an IK model folder with the FK model it is refined on in `fk/` and the
refinement settings in `refine.json` (ctrkin.inference.refine). `Kinematics.load` opens it like any
model folder and refines every answer."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from ctrkin.errors import ModelError
from ctrkin.inference.kinematics import REFINE_FILE, REFINE_FK, Kinematics
from ctrkin.inference.refine import RefineSettings
from ctrkin.util.folders import build_folder, reading_folder

_NOT_COPIED = shutil.ignore_patterns("checkpoint*", ".lock", "*.tmp")


def assemble_refined(ik_dir: str | Path, fk_dir: str | Path, out: str | Path,
                     settings: RefineSettings | None = None) -> Path:
    """Write `out`: a copy of IK model `ik_dir` refined on FK model `fk_dir` (both trained on the
    same robot). Built beside `out` and swapped in, so a failure leaves the previous folder."""
    ik_src, fk_src, target = Path(ik_dir), Path(fk_dir), Path(out)
    ik, fk = Kinematics.load(ik_src), Kinematics.load(fk_src)
    if ik.refined:
        raise ModelError(f"{ik_src} is already a refined IK model")
    ik.attach_fk(fk, settings)          # checks task, robot and the workspace's training joints
    with (build_folder(target, "model", ModelError) as build, reading_folder(ik_src),
          reading_folder(fk_src)):
        shutil.copytree(ik_src, build, dirs_exist_ok=True, ignore=_NOT_COPIED)
        shutil.copytree(fk_src, build / REFINE_FK, ignore=_NOT_COPIED)
        (build / REFINE_FILE).write_text(json.dumps((settings or RefineSettings()).to_dict(), indent=2))
    return target
