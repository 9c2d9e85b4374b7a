"""One command that answers "does it do what the paper shows, and how much better": collect the
data on the virtual robot, train every model, run every experiment, write report.md and
results.json. Each stage reuses what an earlier run of the same scale left in the output folder."""

from __future__ import annotations

import dataclasses
import resource
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.calibration.fit import CalibrationResult, calibrate
from ctrkin.calibration.params import FRICTION, GROUPS
from ctrkin.errors import OutputError
from ctrkin.evaluation.context import Context
from ctrkin.evaluation.datasets import ReproData, collect_training_data, virtual_overrides
from ctrkin.evaluation.experiments import EXPERIMENTS
from ctrkin.evaluation.experiments_fk import SNAP_TURNS, SWEEPS
from ctrkin.evaluation.report import write_report
from ctrkin.evaluation.repro_folder import claim
from ctrkin.evaluation.results import (
    DatasetSummary,
    Memory,
    Recommended,
    ReproResults,
    Snapping,
    Timing,
    write_results,
)
from ctrkin.evaluation.scales import ReproScale
from ctrkin.evaluation.table import RECOMMENDED, TCM_CALIBRATED_ROW, TCM_ROW
from ctrkin.evaluation.tcm_baseline import TCMBaseline
from ctrkin.evaluation.training_runs import train_all
from ctrkin.inference import Kinematics
from ctrkin.robots.robot import Robot
from ctrkin.training.device import resolve_device
from ctrkin.util.folders import folder_lock
from ctrkin.version import __version__
from ctrkin.virtual.config import VirtualConfig

NOTES = [
    "The robot is the virtual robot (the TCM with perturbed tubes, backlash, friction, tracker noise, "
    "registration error and a sensor offset; docs/virtual_robot.md), not the paper's hardware.",
    "Splits are by sequence (whole 0→360→0° turns held out), stricter than the paper's random "
    "70:15:15 split, where neighbouring samples of a test point are in the training set.",
    "The TCM baseline is the point-wise solve from the default guess (no history) of the nominal "
    "robot, mapped to the tracker frame by a rigid registration fitted on training rows.",
    "The calibrated TCM (rows tcm_calibrated, point-wise, and tcm_calibrated_continued, followed "
    "along each sequence with the friction state) is `ctrkin calibrate` on training rows: every "
    "parameter group and μ between the tubes (fitted on the continued TCM).",
    "IK joints are checked through the learned FK model (as in the paper) and by driving the virtual "
    "robot to them; targets the IK model flags as outside its trained workspace are counted.",
    "Fig. 5 and Table II/III report test-set errors in mm and deg (and the normalised test loss), "
    "where the paper plotted normalised training MAE.",
]


class _Stages:
    """Logs each stage's name as it starts and records its wall time (s) under that name (a stage
    entered again, by the next experiment of the same stage, adds to it and is not logged again)."""

    def __init__(self, log: Callable[[str], None]) -> None:
        self.log = log
        self.seconds: dict[str, float] = {}
        self.t0 = time.perf_counter()

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        if name not in self.seconds:
            self.log(f"== {name}")
        t = time.perf_counter()
        yield
        self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t

    def total(self) -> dict[str, float]:
        return {**self.seconds, "total": time.perf_counter() - self.t0}


def reproduce(
    robot: Robot,
    scale: ReproScale,
    out: str | Path,
    robot_seed: int = 0,
    workers: int = 2,
    log: Callable[[str], None] = print,
    executor: str = "local",
    overwrite: bool = False,
    virtual: VirtualConfig | None = None,
    device: str = "auto",
) -> ReproResults:
    """Run the whole reproduction into `out`; workers: trainings run in parallel (one thread each);
    executor: where they run, "local" processes or "ray" tasks (ctrkin.evaluation.executors).
    Stages: collect data, train, fit the TCM baseline, FK experiments, IK experiments, grids,
    timing; then results.json and report.md. Returns the results as written to results.json.
    `out` may hold a reproduction of the same settings (reused); one of other settings is refused
    unless `overwrite`, which replaces it (ctrkin.evaluation.repro_folder). device: where the models
    train (auto | cpu | cuda, ctrkin.training.device), not part of the settings a rerun must match.
    virtual: the virtual robot's effect magnitudes (default VirtualConfig(); `ctrkin reproduce
    --set`). Any robot: the protocols carry the paper robot's translations over to its geometry
    (ctrkin.acquisition.ranges)."""
    out = Path(out)
    virtual = VirtualConfig() if virtual is None else virtual
    resolve_device(device)              # cuda without one is refused before any work
    with folder_lock(out, OutputError, "reproduce"):
        claim(out, robot, scale, robot_seed, overwrite, virtual)
        return _reproduce(robot, scale, out, robot_seed, workers, log, executor, virtual, device)


def _reproduce(robot: Robot, scale: ReproScale, out: Path, robot_seed: int, workers: int,
               log: Callable[[str], None], executor: str, virtual: VirtualConfig,
               device: str) -> ReproResults:
    figures = out / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    st = _Stages(log)
    with st.stage("collect data on the virtual robot"):
        data, training = collect_training_data(robot, scale, out / "data", robot_seed, virtual)
    with st.stage("train models"):
        models = train_all(out / "data" / "paper", scale, out / "models", workers=workers, log=log,
                           executor=executor, device=device, training_dir=training)
    with st.stage("fit the TCM baseline's registration on training rows"):
        tcm = _tcm_baseline(robot, data, scale)
    with st.stage("calibrate the TCM on training rows (friction included)"):
        cal = _tcm_calibrated(robot, data, scale)
    ctx = Context(data=data, models=models, tcm=tcm, figures=figures, scale=scale, tcm_cal=cal.model)
    top: dict[str, Any] = {}
    experiments: dict[str, Any] = {}
    for exp in EXPERIMENTS:            # the typed table, in run order (ctrkin.evaluation.experiments)
        with st.stage(exp.stage):
            (top if exp.top_level else experiments)[exp.name] = exp.run(ctx, exp.rows)
    seconds, memory = st.total(), peak_rss_mb(workers if executor == "local" else 0)
    top["fk"][TCM_CALIBRATED_ROW.name]["calibration"] = cal.to_dict()
    results = _results(robot, scale, robot_seed, tcm, data, models, top["fk"], top["ik"], experiments,
                       top["grids"], top["timing"], seconds, memory, ctx.seconds_per_step)
    results = dataclasses.replace(results, virtual_settings=virtual_overrides(virtual))
    written = write_results(results, out / "results.json")
    write_report(written, out / "report.md")
    log(f"wrote {out / 'report.md'} and {out / 'results.json'} ({written.seconds['total']:.0f} s)")
    return written


def _tcm_baseline(robot: Robot, data: ReproData, scale: ReproScale) -> TCMBaseline:
    """The paper's TCM baseline: the nominal robot, registered to the tracker on training rows."""
    tcm = TCMBaseline(robot)
    train_rows = data.paper.get_split().train
    tcm.fit_registration(
        data.paper.joints()[train_rows],
        data.paper.poses()[train_rows],
        max_points=2000 if scale.name != "tiny" else 200,
    )
    return tcm


# rows of the point-wise fit and least-squares evaluations per scale (default: the full scale's)
CALIBRATION_BUDGET = {"tiny": (200, 8, 2_000), "quick": (1000, 30, 10_000)}


def _tcm_calibrated(robot: Robot, data: ReproData, scale: ReproScale) -> CalibrationResult:
    """`ctrkin calibrate` on (a seeded subsample of) the training rows: every group and μ."""
    rows_n, nfev, samples = CALIBRATION_BUDGET.get(scale.name, (2000, 60, 20_000))
    train = data.paper.get_split().train
    rows = np.sort(np.random.default_rng(0).choice(train, min(rows_n, len(train)), replace=False))
    return calibrate(data.paper, robot, (*GROUPS, FRICTION), rows=rows, max_nfev=nfev,
                     friction_samples=samples)


def _results(robot: Robot, scale: ReproScale, robot_seed: int, tcm: TCMBaseline, data: ReproData,
             models: dict[str, Kinematics], fk: dict[str, Any], ik: dict[str, Any],
             experiments: dict[str, Any], grid: dict[str, Any], lat: dict[str, Any],
             seconds: dict[str, float], memory: Memory,
             per_step: dict[str, list[float]]) -> ReproResults:
    """The results of every stage, as results.json holds them; per_step: seconds per prediction
    of the calibrated TCM's rows (Context.seconds_per_step)."""
    tcm_t = fk[TCM_ROW.name]["timing"]
    cal_us = {k: 1e6 * float(np.mean(v)) for k, v in per_step.items()}
    f = data.paper.frame
    return ReproResults(
        scale=scale,
        robot=robot.to_dict(),
        virtual_robot_seed=robot_seed,
        ctrkin_version=__version__,
        registration=tcm.registration.to_dict(),
        grids=grid,
        dataset=DatasetSummary(
            samples=len(f),
            sequences=int(f["sequence_id"].nunique()),
            snaps=int(f["snap"].sum()),
            outliers=int(f["outlier"].sum()),
            split=data.paper.get_split().sizes(),
        ),
        fk=fk,
        ik=ik,
        experiments=experiments,
        snapping=_snapping(experiments),
        recommended=Recommended(fk=f"models/{RECOMMENDED['fk'].folder}",
                                ik=f"models/{RECOMMENDED['ik'].folder}"),
        timing=Timing(
            fk_ms_mean=lat["fk"]["ms_mean"],
            fk_ms_std=lat["fk"]["ms_std"],
            fk_us_median=lat["fk"]["us_median"],
            fk_paper_us_median=lat["fk_paper"]["us_median"],
            ik_paper_us_median=lat["ik_paper"]["us_median"],
            ik_refined_us_median=lat["ik_refined"]["us_median"],
            ik_ms_mean=lat["ik"]["ms_mean"],
            ik_ms_std=lat["ik"]["ms_std"],
            ik_us_median=lat["ik"]["us_median"],
            tcm_ms_mean=tcm_t["ms_mean"],
            tcm_ms_std=tcm_t["ms_std"],
            tcm_us_median=tcm_t["us_median"],
            tcm_calibrated_us_mean=cal_us.get("tcm_calibrated"),
            tcm_calibrated_continued_us_mean=cal_us.get("tcm_calibrated_continued"),
        ),
        training={name: m.metrics.get("training", {}) for name, m in models.items()},
        notes=NOTES,
        seconds=seconds,
        memory=memory,
    )


def peak_rss_mb(workers: int) -> Memory:
    """Peak resident memory (MB): this process, the largest finished local training worker, and
    the bound of both at once (this process + `workers` such workers; Ray workers are not ours)."""
    main = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0       # Linux: kB
    child = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
    return Memory(peak_rss_mb_main=main, peak_rss_mb_worker=child, peak_rss_mb_bound=main + workers * child)


def _snapping(experiments: dict[str, Any]) -> Snapping:
    """Snap prediction per predictor on the sweeps (vs truth, per direction, and vs measured) and on
    the snap turns; the headline precision/recall are the recommended FK model's on the sweeps."""
    sweeps = experiments[SWEEPS.name]["snap_prediction"]
    head = sweeps[RECOMMENDED["fk"].name]
    return Snapping(
        precision=_zero_if_undefined(head["precision"], head["n_predicted"]),
        recall=_zero_if_undefined(head["recall"], head["n_reference"]),
        **{k: head[k] for k in Snapping.HEADLINE},
        model=RECOMMENDED["fk"].name,
        rule="T(L) step > 10 deg, matched within 2 steps, vs the noise-free truth, sweeps "
             "(per model also per direction, vs measured, and on the snap turns)",
        per_model={model: {**score, "precision": _zero_if_undefined(score["precision"], score["n_predicted"]),
                           "recall": _zero_if_undefined(score["recall"], score["n_reference"])}
                   for model, score in sweeps.items()},
        snap_turns=experiments[SNAP_TURNS.name]["snap_prediction"],
    )


def _zero_if_undefined(value: float, denominator: int) -> float:
    """Precision with no predicted snaps (or recall with none to find) is reported as 0, with the
    counts beside it, so the key stays a finite number."""
    return 0.0 if denominator == 0 or not np.isfinite(value) else float(value)
