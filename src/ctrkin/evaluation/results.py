"""The results of a reproduction, typed: what results.json holds and report.md is written from.

One dataclass per section whose figures are read by name (dataset, snapping, recommended models,
timing, memory); the per-model tables (fk, ik, experiments, grids, training) stay mappings from a
row's name to its figures, as `ctrkin.evaluation.context.summary` and the experiments build them.
`to_dict()` gives the nested tree in results.json's key order; `flat()` the headline figures again
under flat dotted names ("fk.lstm_mlp.position_rmse_mm"), which results.json also carries for tools
that read flat keys. `from_dict` reads a results.json back (its flat keys are ignored).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, ClassVar

from ctrkin.evaluation.scales import ReproScale
from ctrkin.evaluation.table import flat_rows
from ctrkin.util.files import atomic_write_text

# the figures copied under flat names (the rows: Row.flat in ctrkin.evaluation.table), in results.json's
# order; an experiment's position_rmse_mm and within_1mm_fraction where it reports them
FLAT_FK = ("position_rmse_mm", "orientation_rmse_deg", "position_rmse_true_mm")
FLAT_IK = ("joint_rmse_mm", "joint_rmse_deg", "tip_error_mm", "joint_alpha_median_deg")
FLAT_SNAP = ("precision", "recall", "timing_error_steps", "magnitude_error_deg")


@dataclass(frozen=True)
class DatasetSummary:
    """The training dataset (paper protocol): sizes, snap and outlier samples, split sizes."""

    samples: int
    sequences: int
    snaps: int
    outliers: int
    split: dict[str, int]

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class Snapping:
    """Snap prediction on the sweeps (paper's 10° T(L) rule, vs the noise-free truth): the headline
    is the recommended FK model's (`model`), precision and recall 0 where undefined (the counts
    beside them); `per_model` every predictor's score (also per direction and vs measured),
    `snap_turns` the same on the snap turns."""

    precision: float
    recall: float
    n_reference: float
    n_predicted: float
    n_matched: float
    timing_error_steps: float | None        # None (NaN before results.json) without a matched snap
    magnitude_error_deg: float | None
    position_at_snap_true_mm: float | None
    position_away_from_snap_true_mm: float
    model: str
    rule: str
    per_model: dict[str, dict[str, Any]]
    snap_turns: dict[str, Any]

    HEADLINE: ClassVar[tuple[str, ...]] = (
        "n_reference", "n_predicted", "n_matched", "timing_error_steps", "magnitude_error_deg",
        "position_at_snap_true_mm", "position_away_from_snap_true_mm")

    def to_dict(self) -> dict[str, Any]:
        return {"precision": self.precision, "recall": self.recall,
                **{k: getattr(self, k) for k in self.HEADLINE},
                "model": self.model, "rule": self.rule, **self.per_model, "snap_turns": self.snap_turns}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Snapping:
        named = {"precision", "recall", *cls.HEADLINE, "model", "rule", "snap_turns"}
        return cls(**{k: d[k] for k in named},
                   per_model={k: v for k, v in d.items() if k not in named})


@dataclass(frozen=True)
class Recommended:
    """The recommended models' folders, relative to the output folder."""

    fk: str
    ik: str


@dataclass(frozen=True)
class Timing:
    """Time per prediction, streaming one step a call (ms mean / std, µs median): the recommended
    FK and IK, the paper's FK and IK and the refined IK, and the point-wise TCM on the test rows."""

    fk_ms_mean: float
    fk_ms_std: float
    fk_us_median: float
    fk_paper_us_median: float
    ik_paper_us_median: float
    ik_refined_us_median: float
    ik_ms_mean: float
    ik_ms_std: float
    ik_us_median: float
    tcm_ms_mean: float
    tcm_ms_std: float
    tcm_us_median: float
    tcm_calibrated_us_mean: float | None = None            # point-wise, per point
    tcm_calibrated_continued_us_mean: float | None = None  # followed, per step


@dataclass(frozen=True)
class Memory:
    """Peak resident memory (MB): this process, the largest finished local training worker, and the
    bound of both at once (this process + the workers)."""

    peak_rss_mb_main: float
    peak_rss_mb_worker: float
    peak_rss_mb_bound: float


@dataclass(frozen=True)
class ReproResults:
    """Everything a reproduction measured (fields in results.json's order). seconds: wall time per
    stage and "total"; the per-model tables are described in docs/reproduction.md. virtual_settings:
    the virtual robot's effect magnitudes that differ from the default (`--set`), in results.json
    after virtual_robot_seed only where there are any."""

    scale: ReproScale
    robot: dict[str, Any]
    virtual_robot_seed: int
    ctrkin_version: str
    registration: dict[str, Any]
    grids: dict[str, Any]
    dataset: DatasetSummary
    fk: dict[str, Any]
    ik: dict[str, Any]
    experiments: dict[str, Any]
    snapping: Snapping
    recommended: Recommended
    timing: Timing
    training: dict[str, Any]
    notes: list[str]
    seconds: dict[str, float]
    memory: Memory
    virtual_settings: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The nested tree of results.json (without the flat keys)."""
        return {
            "scale": self.scale.to_dict(),
            "robot": self.robot,
            "virtual_robot_seed": self.virtual_robot_seed,
            **({"virtual_settings": self.virtual_settings} if self.virtual_settings else {}),
            "ctrkin_version": self.ctrkin_version,
            "registration": self.registration,
            "grids": self.grids,
            "dataset": self.dataset.to_dict(),
            "fk": self.fk,
            "ik": self.ik,
            "experiments": self.experiments,
            "snapping": self.snapping.to_dict(),
            "recommended": asdict(self.recommended),
            "timing": asdict(self.timing),
            "training": self.training,
            "notes": self.notes,
            "seconds": self.seconds,
            "memory": asdict(self.memory),
        }

    def flat(self) -> dict[str, Any]:
        """The headline figures under flat dotted names, in results.json's order."""
        out: dict[str, Any] = {}
        ex = self.experiments
        out |= {f"fk.{m}.{k}": self.fk[m][k] for m in flat_rows("fk") if m in self.fk for k in FLAT_FK}
        out |= {f"ik.{m}.{k}": self.ik[m][k] for m in flat_rows("ik") for k in FLAT_IK}
        out |= {f"snapping.{m}.{k}": self.snapping.per_model[m][k] for m in flat_rows("snapping")
                for k in FLAT_SNAP}
        out |= {f"experiments.{e}.within_1mm_fraction": v["within_1mm_fraction"] for e, v in ex.items()
                if "within_1mm_fraction" in v}
        out |= {"recommended.fk": self.recommended.fk, "recommended.ik": self.recommended.ik}
        out |= {f"experiments.{e}.position_rmse_mm": v["position_rmse_mm"] for e, v in ex.items()
                if "position_rmse_mm" in v}
        t, d = self.timing, self.dataset
        out |= {"snapping.precision": self.snapping.precision, "snapping.recall": self.snapping.recall,
                "timing.fk_ms_mean": t.fk_ms_mean, "timing.fk_ms_std": t.fk_ms_std,
                "timing.ik_ms_mean": t.ik_ms_mean, "timing.tcm_ms_mean": t.tcm_ms_mean,
                "timing.tcm_calibrated_continued_us_mean": t.tcm_calibrated_continued_us_mean,
                "dataset.samples": d.samples, "dataset.sequences": d.sequences, "dataset.snaps": d.snaps}
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ReproResults:
        """From results.json's tree. `registration` and `training`, which the report does not read,
        may be missing (a trimmed file, e.g. the tests' tiny_results.json)."""
        return cls(
            scale=ReproScale.from_dict(d["scale"]),
            robot=d["robot"],
            virtual_robot_seed=d["virtual_robot_seed"],
            ctrkin_version=d["ctrkin_version"],
            registration=d.get("registration", {}),
            grids=d["grids"],
            dataset=DatasetSummary(**d["dataset"]),
            fk=d["fk"],
            ik=d["ik"],
            experiments=d["experiments"],
            snapping=Snapping.from_dict(d["snapping"]),
            recommended=Recommended(**d["recommended"]),
            timing=Timing(**d["timing"]),
            training=d.get("training", {}),
            notes=d["notes"],
            seconds=d["seconds"],
            memory=Memory(**d["memory"]),
            virtual_settings=d.get("virtual_settings", {}),
        )


def write_results(results: ReproResults, path: Path) -> ReproResults:
    """Write results.json: the nested tree, JSON-safe, then the flat keys. Returns the results as
    written (NaN as None, numpy scalars as Python numbers), which the report is made from."""
    tree = _clean(results.to_dict())
    written = ReproResults.from_dict(tree)
    atomic_write_text(path, json.dumps({**tree, **written.flat()}, indent=2))
    return written


def _clean(x: Any) -> Any:
    """JSON-safe: NaN and inf become null (they are not JSON)."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if hasattr(x, "item") and callable(x.item):  # numpy scalars
        return _clean(x.item())
    return x
