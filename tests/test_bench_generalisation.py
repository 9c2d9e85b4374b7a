"""benchmarks/bench_generalisation.py's machinery (issue 21, goal 4) without a reproduction: the
reversal protocol on every robot of the benchmark, the goal-1 figures read from a results.json, the
output rule, and the whole report path (`--reuse`) on one robot whose reproduction folder is made of
the tests' trimmed tiny results, a small trained snap-aware FK and a sweep dataset."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.benchmark_scripts import load_benchmark

TINY_RESULTS = Path(__file__).resolve().parent / "evaluation" / "tiny_results.json"


@pytest.fixture(scope="module")
def bench():
    return load_benchmark("bench_generalisation")


def test_reversal_plan_reverses_mid_turn_inside_each_robot(bench) -> None:
    for case in bench.ROBOTS.values():
        robot = bench._robot(case)
        plan = bench.reversals_plan(robot)
        assert len(plan.runs) == len(bench.REVERSAL_OUTER)
        for run in plan.runs:
            q = run.segments[0].q
            robot.check_joints(q)                        # raises on a joint the robot cannot take
            turn = np.sign(np.diff(q[:, 0]))
            assert np.count_nonzero(np.diff(turn)) == len(bench.REVERSAL_TURNS_DEG) - 2   # 3 reversals
            assert np.ptp(q[:, robot.n_tubes:], axis=0).max() == 0.0                      # β held


def test_small_moves_go_back_and_forth_in_small_steps_inside_each_robot(bench) -> None:
    for case in bench.ROBOTS.values():
        robot = bench._robot(case)
        plan, kinds = bench.small_moves_plan(robot)
        assert kinds == list(bench.SMALL_KINDS) * len(bench.REVERSAL_OUTER)
        for run, kind in zip(plan.runs, kinds, strict=True):
            q = run.segments[0].q
            robot.check_joints(q)
            n = robot.n_tubes
            moving = {"outer": q[:, n - 1], "inner": q[:, 0], "d": q[:, 2 * n - 1] - q[:, n]}[kind]
            step = np.abs(np.diff(moving))
            assert 0 < step.max() <= (bench.SMALL_STEP_DEG if kind != "d" else bench.SMALL_STEP_MM) + 1e-9
            assert np.count_nonzero(np.diff(np.sign(np.diff(moving)))) == 2        # back and forth
            a0 = q[:, 0] - q[:, n - 1]
            assert np.ptp(a0) == (0.0 if kind != "inner" else bench.SMALL_ANGLE_DEG)


def test_figures_of_reads_the_goal_figures_and_marks_misses(bench) -> None:
    res = json.loads(TINY_RESULTS.read_text())
    f = bench.figures_of(res)
    fk = res["fk"]["lstm_mlp"]
    assert f["fk_true_mm"] == fk["position_rmse_true_mm"]
    assert f["tcm_ratio"] == pytest.approx(res["fk"]["tcm"]["position_rmse_mm"] / fk["position_rmse_mm"])
    assert f["tcm_calibrated_mm"] is None                 # this trimmed file predates the calibrated TCM
    assert f["ik_random_within_1mm"] == res["experiments"]["ik_random"]["lstm_mlp"]["within_1mm_via_robot"]
    turns = res["snapping"]["snap_turns"][res["snapping"]["model"]]
    assert f["turns_recall"] == min(turns["forward"]["recall"], turns["backward"]["recall"])
    cells = bench.table_row({"robot": "r", "wall_s": 1.0, **f})
    assert len(cells) == len(bench.HEADER)
    assert cells[1] == f"{f['fk_true_mm']:.2f}*"           # 7.3 mm misses the 0.5 mm goal: marked


def test_a_non_empty_out_is_refused_without_overwrite(bench, tmp_path, capsys) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert bench.main(["--robots", "default-top", "--scale", "tiny", "--out", str(out)]) == 1
    assert "--overwrite" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["keep.txt"]


@pytest.mark.slow
def test_reuse_reports_one_robot_end_to_end(bench, tmp_path, capsys, model_dirs, sweeps) -> None:
    out = tmp_path / "gen"
    folder = out / "default-top"
    res = json.loads(TINY_RESULTS.read_text())
    folder.mkdir(parents=True)
    (folder / "results.json").write_text(json.dumps(res))
    shutil.copytree(model_dirs["fk_branch"], folder / res["recommended"]["fk"])
    sweeps.save(folder / "data" / "paper")
    sweeps.save(folder / "data" / "sweeps")
    assert bench.main(["--robots", "default-top", "--out", str(out), "--overwrite", "--reuse"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    row = json.loads(lines[-1])["rows"][0]
    assert "errors" not in row, row.get("errors")
    assert row["robot"] == "default-top" and row["wall_s"] == res["seconds"]["total"]
    assert np.isfinite(row["reversal_rmse_true_mm"]) and row["reversal_samples"] == 3 * 881
    assert all(np.isfinite(row[f"small_{k}_rmse_true_mm"]) for k in bench.SMALL_KINDS)
    snaps = int(sweeps.frame["snap"].sum())
    assert 0 < row["gate_snaps"] <= snaps and row["gate_snaps"] == row["sweeps_gate_snaps"]
    assert row["gate_residual_rms_deg"] >= 0 and row["gate_residual_max_deg"] >= row["gate_residual_rms_deg"]
    assert "ik_floor_mm" not in row           # sweeps of the nominal robot: no virtual robot to drive
    assert any(line.startswith("default-top") for line in lines)                # the table's row
    assert json.loads((out / "rows.jsonl").read_text())["robot"] == "default-top"


@pytest.fixture(scope="module")
def fold_bench(bench):
    return sys.modules["bench_fold_gate"]            # imported by bench_generalisation, beside it


def test_the_fold_gate_matches_the_nominal_robot_it_assumes(fold_bench, sweeps) -> None:
    """On sweeps of the nominal robot itself (follow, no effects) the gate's assumption holds: its
    offsets vanish, every snap lies on the nominal fold within one 4° step, and its switches are
    exactly the snaps."""
    r = fold_bench.measure(sweeps, sweeps)
    assert r["sweeps_recorded_snaps"] > 0 and r["sweeps_gate_no_fold_snaps"] == 0
    assert abs(r["widen_deg"]) < 2.0
    assert r["sweeps_gate_residual_max_deg"] < 2.0
    assert r["sweeps_gate_precision"] == 1.0 and r["sweeps_gate_recall"] == 1.0


def test_the_play_form_scores_beside_the_gate(fold_bench, sweeps) -> None:
    """The play-operator form, identified on the same snaps, is scored beside the fold gate on every
    held-out dataset; on the nominal robot's own sweeps it switches at the snaps as the gate does."""
    r = fold_bench.measure(sweeps, sweeps, sweeps)
    for where in ("sweeps", "turns"):
        assert r[f"{where}_pi_recorded_snaps"] == r[f"{where}_recorded_snaps"] > 0
        assert r[f"{where}_pi_gate_precision"] == 1.0 and r[f"{where}_pi_gate_recall"] == 1.0
        assert r[f"{where}_pi_residual_max_deg"] < 2.0
    assert r["pi_cv_runs"] >= 1 and all(w >= 0 for w in r["pi_slide_weights"])
    assert "pix_widen_deg" not in r                                  # no excitation runs given


def test_the_history_probe_and_the_excitation_runs(fold_bench) -> None:
    """On the nominal robot (no effects, no memory) every history of the probe gives the same snaps;
    the excitation runs record their start, so that the slide before each turn is in the joint path
    the play operators follow (and a move of both tubes together is no slide)."""
    from ctrkin.families.snap_aware import play
    from ctrkin.robots import load_robot
    from ctrkin.virtual import VirtualRobot
    from ctrkin.virtual.config import VirtualConfig

    robot = load_robot("paper")
    virtual = VirtualRobot(robot, VirtualConfig().ideal(), seed=0)
    probe = fold_bench.history_probe(robot, virtual, 1)
    assert list(probe) == list(fold_bench.HISTORIES)
    assert len(probe["rest"]) == 2 and all(v == probe["rest"] for v in probe.values())
    ex = fold_bench.excitation(robot, virtual, 1, "quick")          # the library's protocol
    assert ex.meta["protocol"] == "excitation" and ex.frame["run"].nunique() == 10
    slide = play.dataset_lags(ex).slide
    runs = ex.frame["run"].to_numpy()
    slid = {int(r) for r in np.unique(runs) if np.abs(slide[runs == r]).max() > 0.99}
    assert len(slid) >= 5                                          # slides of one tube against the other


def test_the_snap_form_is_chosen_on_held_out_excitation_runs(fold_bench) -> None:
    """The excitation runs split by run into identification and validation halves; on the nominal
    robot (its snaps on the nominal folds, whatever the history) the fold gate and the play form
    identified with the excitation runs and the fold gate with a fitted scale of the folds all switch
    at the validation snaps, and a tie keeps the fold gate."""
    from ctrkin.acquisition import protocols
    from ctrkin.acquisition.recorder import record
    from ctrkin.robots import load_robot
    from ctrkin.virtual import VirtualRobot
    from ctrkin.virtual.config import VirtualConfig

    robot = load_robot("paper")
    virtual = VirtualRobot(robot, VirtualConfig().ideal(), seed=0)
    paper = record(protocols.build("paper", robot, scale="tiny", outer_step_deg=180.0), virtual, seed=0,
                   workers=1, progress=False)
    ex = fold_bench.excitation(robot, virtual, 1, "quick")
    ident, val = fold_bench.split_runs(ex)
    assert set(ident.frame["run"]).isdisjoint(val.frame["run"])
    assert len(ident.frame) + len(val.frame) == len(ex.frame) and len(val.frame) > 0
    r = fold_bench.choose_on_validation(paper, ex, {})
    assert r["xv_val_runs"] == r["xv_id_runs"] == 5
    assert r["val_xv_recorded_snaps"] > 0
    for p in ("xv", "pxv", "sxv"):          # the scaled folds too: this robot snaps on the nominal folds
        assert r[f"val_{p}_gate_precision"] == 1.0 and r[f"val_{p}_gate_recall"] == 1.0, p
    # the paper rows' own gate is reported beside them (its fold table spans only the translations of
    # those rows: here βN 0 and −2.5 mm, fewer than the excitation runs reach)
    assert r["val_pv_recorded_snaps"] == r["val_xv_recorded_snaps"]
    assert set(r["xv_val_f1"]) == {"fold gate", "play", "fold gate (paper rows)", "scaled folds"}
    assert r["xv_chosen"] == "fold gate"
