"""The refined IK (docs/learned_kinematics.md: IK refined on the learned FK): a direct IK's answers
refined by Levenberg-Marquardt on a learned FK model's next step after the robot's history. It is
assembled from two trained folders, not trained: the IK folder with the FK folder in `fk/` and
`refine.json` beside it, which makes the folder this family's whatever IK it holds.

    refine.py     the residual on the FK model and the solve from several starts
    folder.py     assemble_refined(ik_dir, fk_dir, out): the folder
    predictor.py  in use: the direct IK's predictor wrapped, the FK model's history advanced
"""

from __future__ import annotations

from pathlib import Path

from ctrkin.errors import ModelError
from ctrkin.families.refined.folder import REFINE_FILE, REFINE_FK, assemble_refined
from ctrkin.families.refined.predictor import RefinedPredictor
from ctrkin.families.refined.refine import RefineSettings
from ctrkin.models.predictor import Family, OpenFolder, Predictor
from ctrkin.models.store import read_json

__all__ = ["FAMILY", "RefineSettings", "RefinedPredictor", "assemble_refined"]


def _wrap(inner: Predictor, folder: Path, open_folder: OpenFolder) -> Predictor:
    if inner.bundle.layout.task != "ik" or not (folder / REFINE_FK).is_dir():
        raise ModelError(f"{folder / REFINE_FILE} needs an IK model with its FK model in "
                         f"{folder / REFINE_FK}")
    settings = RefineSettings.from_dict(read_json(folder / REFINE_FILE))
    return RefinedPredictor(inner, open_folder(folder / REFINE_FK), settings)


FAMILY = Family(
    name="refined",
    title="refined IK",
    predictors=(RefinedPredictor,),
    marker=REFINE_FILE,
    wrap=_wrap,
    files=(REFINE_FILE, REFINE_FK),
)
