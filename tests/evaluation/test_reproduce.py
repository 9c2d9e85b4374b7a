"""The whole reproduction at tiny scale: every stage runs, every figure, key and section exists."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from ctrkin import paper_robot
from ctrkin.evaluation.datasets import TRAINING_FOLDER
from ctrkin.evaluation.reproduce import reproduce
from ctrkin.evaluation.results import ReproResults
from ctrkin.evaluation.scales import get_scale
from ctrkin.evaluation.training_runs import train_all
from ctrkin.inference import Kinematics

FIGURES = [
    "fig5a_model_comparison",
    "fig5b_delta_ablation",
    "fig6_delta_overlaps",
    "fig7_input_buffer",
    "fig8_structures",
    "fig9_training_curves",
    "fig10a_sweeps",
    "fig10b_random_points",
    "fig10c_arbitrary",
    "fig11_ik_random",
    "fig12_ik_square",
    "fig12_ik_triangle",
    "snap_turns",
]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    results = reproduce(paper_robot(), get_scale("tiny"), out, log=lambda _m: None)
    return out, results


@pytest.mark.slow
def test_results_json_is_the_results_and_every_headline_figure_is_finite(tiny_run) -> None:
    out, results = tiny_run
    on_disk = json.loads((out / "results.json").read_text())
    assert ReproResults.from_dict(on_disk) == results               # the nested tree reads back whole
    flat = results.flat()
    assert list(on_disk)[-len(flat):] == list(flat)                # the flat copies come last, in order
    for row in ("tcm_calibrated", "tcm_calibrated_continued"):     # the calibrated physics baseline
        assert f"fk.{row}.position_rmse_mm" in flat, row
    assert flat["timing.tcm_calibrated_continued_us_mean"] is not None
    for key, value in flat.items():
        assert on_disk[key] == value, key                          # for tools that read dotted keys
    for task, folder in (("fk", results.recommended.fk), ("ik", results.recommended.ik)):
        assert Kinematics.load(out / folder).task == task          # a model folder that loads
    undefined = set()      # a snap timing or magnitude error without a matched snap is undefined (None)
    for model, score in results.snapping.per_model.items():
        if score["n_matched"] == 0:
            undefined |= {f"snapping.{model}.timing_error_steps", f"snapping.{model}.magnitude_error_deg"}
    for key, value in flat.items():
        if key.startswith("recommended.") or (value is None and key in undefined):
            continue
        assert isinstance(value, (int, float)) and math.isfinite(value), key
    assert results.dataset.samples == 2 * 4 * 721  # tiny: 2 levels × 4 outer angles × 721


def test_fig6_and_fig9_counterparts_hold_their_figures(tiny_run) -> None:
    _out, results = tiny_run
    by_level = results.experiments["delta_overlaps"]["by_level"]
    assert 2 <= len(by_level) <= 3                                  # lowest, middle, highest sweep level
    for entry in by_level.values():
        assert set(entry) == {"lstm_mlp_paper_position_mae_mm", "lstm_mlp_no_delta_position_mae_mm"}
        assert all(math.isfinite(v) and v > 0 for v in entry.values())
    curves = results.experiments["training_curves"]
    assert {"fk_lstm_mlp_paper", "fk_lstm_mlp_branch", "ik_lstm_mlp_paper", "ik_follow_mlp"} <= set(curves)
    for entry in curves.values():
        assert 1 <= entry["best_epoch"] <= entry["epochs"]


@pytest.mark.slow
def test_report_has_every_section_and_figure(tiny_run) -> None:
    out, _ = tiny_run
    report = (out / "report.md").read_text()
    for section in (
        "## Headline",
        "## FK model comparison",
        "## Experiments",
        "## Snap prediction",
        "## Input buffer (Table II)",
        "## Figures",
        "## Notes",
    ):
        assert section in report
    assert "0.69" in report and "1.22" in report  # the paper's numbers beside ours
    for name in FIGURES:
        png = out / "figures" / f"{name}.png"
        assert png.is_file() and png.stat().st_size > 5_000, name
        assert f"figures/{name}.png" in report


@pytest.mark.slow
def test_the_recommended_models_alone_train_on_the_excitation_runs_too(tiny_run) -> None:
    """data/excitation beside data/paper; the snap-aware FK and the follow IK train on the paper rows
    and the excitation runs (data/paper+excitation), every other model on the paper rows alone; the
    validation and test rows are the paper's for all."""
    from ctrkin.data.dataset import Dataset
    from ctrkin.evaluation.training_runs import TRAINED_WITH_EXCITATION

    out, _results = tiny_run
    paper, extra = Dataset.load(out / "data" / "paper"), Dataset.load(out / "data" / "excitation")
    both = Dataset.load(out / "data" / "paper+excitation")
    assert extra.meta["protocol"] == "excitation" and len(both.frame) == len(paper.frame) + len(extra.frame)
    assert both.split.test.tolist() == paper.split.test.tolist()
    assert both.split.val.tolist() == paper.split.val.tolist()
    for folder in sorted((out / "models").glob("*/config.json")):
        if folder.parent.name == "ik_refined":
            continue
        samples = json.loads(folder.read_text())["data"]["samples"]
        want = len(both.frame) if folder.parent.name in TRAINED_WITH_EXCITATION else len(paper.frame)
        assert samples == want, folder.parent.name


@pytest.mark.slow
def test_rerun_reuses_data_and_models(tiny_run) -> None:
    out, first = tiny_run
    data_stamp = (out / "data" / "paper" / "data.parquet").stat().st_mtime_ns
    stamps = {name: (out / "data" / name / "data.parquet").stat().st_mtime_ns
              for name in ("excitation", "paper+excitation")}
    again = reproduce(paper_robot(), get_scale("tiny"), out, log=lambda _m: None)
    assert (out / "data" / "paper" / "data.parquet").stat().st_mtime_ns == data_stamp
    for name, stamp in stamps.items():
        assert (out / "data" / name / "data.parquet").stat().st_mtime_ns == stamp, name
    for name, info in first.training.items():  # no epoch trained again
        assert again.training[name]["epochs"] == info["epochs"]
        assert again.training[name]["seconds"] == info["seconds"]
    fk_first, fk_again = first.fk["lstm_mlp"], again.fk["lstm_mlp"]
    assert fk_again["position_rmse_mm"] == pytest.approx(fk_first["position_rmse_mm"])
    assert again.dataset == first.dataset


@pytest.mark.slow
def test_ray_executor_gives_the_local_results(tiny_run, tmp_path) -> None:
    """The executor changes where the runs train, nothing else: the same seeds give the same weights
    and the same held-out metrics (the experiments after training are the same code on the same
    models, checked by the rerun test; they are not run a third time here)."""
    pytest.importorskip("ray")
    out, _local = tiny_run
    train_all(out / "data" / "paper", get_scale("tiny"), tmp_path / "models", workers=2, executor="ray",
              log=lambda _m: None, training_dir=out / "data" / TRAINING_FOLDER)
    local_runs = sorted(p.parent.name for p in (out / "models").glob("*/weights.pt"))
    ray_runs = sorted(p.parent.name for p in (tmp_path / "models").glob("*/weights.pt"))
    assert local_runs and ray_runs == local_runs
    for name in local_runs:                                    # the same seeds: the same bytes
        local, on_ray = out / "models" / name, tmp_path / "models" / name
        assert (on_ray / "weights.pt").read_bytes() == (local / "weights.pt").read_bytes(), name
        assert _metrics(on_ray) == _metrics(local), name


def _metrics(folder: Path) -> dict[str, Any]:
    """A model folder's metrics.json less what depends on the clock (training seconds and CPU seconds,
    samples per second of each)."""
    metrics = json.loads((folder / "metrics.json").read_text())
    for key in ("seconds", "samples_per_s", "cpu_seconds", "samples_per_cpu_s"):
        del metrics["training"][key]
    return metrics


def test_local_reproduction_does_not_import_ray() -> None:
    code = ("import sys, ctrkin.cli.main, ctrkin.evaluation.reproduce, ctrkin.evaluation.executors; "
            "assert 'ray' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)
