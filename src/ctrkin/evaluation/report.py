"""report.md of a reproduction: our figures beside the paper's, from the results as written to
results.json (ctrkin.evaluation.results)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ctrkin.errors import CtrkinError
from ctrkin.evaluation import paper_numbers as P
from ctrkin.evaluation.experiments import EXPERIMENTS, FIGURES
from ctrkin.evaluation.experiments_fk import SNAPPING_ROWS, SWEEPS
from ctrkin.evaluation.figure_captions import figure_section
from ctrkin.evaluation.results import ReproResults
from ctrkin.evaluation.scales import BUDGET_ROLES, ReproScale
from ctrkin.evaluation.table import (
    FK_BRANCH_ROW,
    FK_PAPER_ROW,
    HEADLINE,
    IK_FOLLOW_ROW,
    IK_ROWS,
    TCM_CALIBRATED_CONTINUED_ROW,
    TCM_CALIBRATED_ROW,
    TCM_ROW,
    labels,
)
from ctrkin.models.seqnet import STRUCTURES
from ctrkin.robots.builtin import paper_robot
from ctrkin.robots.robot import Robot
from ctrkin.util.files import atomic_write_text

CAL_CONT = TCM_CALIBRATED_CONTINUED_ROW.name   # the calibrated TCM continued: headline and Fig. 10 column
IK_REPORT_ROWS = tuple(r.name for r in IK_ROWS)     # the columns of the IK experiments' table


def write_report(r: ReproResults, path: Path) -> None:
    """report.md from the results as written to results.json: one named stage per section, in the
    order a reader needs them (what ran, headline, each paper figure's table, figures, notes)."""
    sections = (
        _title(r),
        _setup(r),
        _headline(r),
        _fk_comparison(r),
        _fk_experiments(r),
        _ik_experiments(r),
        _snap_prediction(r),
        _grids(r),
        figure_section(Path(path).parent / "figures", FIGURES),
        _notes(r),
    )
    atomic_write_text(path, "\n\n".join("\n".join(lines) for lines in sections) + "\n")


def _title(r: ReproResults) -> list[str]:
    """The heading, and for the tiny scale a warning that its numbers mean nothing."""
    name = r.scale.name
    lines = [f"# ctrkin reproduction of the paper ({name} scale)"]
    if name == "tiny":
        lines += ["", TINY_WARNING]
    return lines


TINY_WARNING = (
    "> **Tiny scale: a smoke test, not a result.** Every model trained for one or two epochs on a few "
    "thousand samples, so the numbers and figures below only show that every stage runs; they say "
    "nothing about how well any model works. Run `ctrkin reproduce --scale quick` (minutes) or "
    "`--scale full` for results."
)


def _setup(r: ReproResults) -> list[str]:
    """What ran: robot, data, split, what "measured" and "truth" mean, and the training budgets."""
    d = r.dataset
    return [
        f"Robot: {robot_title(r.robot)}, virtual robot seed {r.virtual_robot_seed}{_effects(r)}. "
        f"Training data: the paper protocol, {d.samples} samples in {d.sequences} sequences "
        f"({d.snaps} snap samples), split by sequence 70:15:15; errors are on held-out sequences "
        f"unless stated. Wall time {r.seconds['total']:.0f} s. \"Measured\" is the virtual tracker "
        "(noise, registration, sensor offset, like the paper's EM sensor); \"truth\" is the true tip "
        "seen by the tracker without noise, which hardware cannot give.",
        "",
        _budgets(r.scale),
    ]


def robot_title(robot: dict[str, Any]) -> str:
    """The robot's name from its description, with "(paper Table I)" only where its tubes are the
    paper robot's."""
    try:
        same = Robot.from_dict(robot).fingerprint() == paper_robot().fingerprint()
    except CtrkinError:                 # a trimmed description (a name only): not known to be it
        same = False
    return f"{robot['name']}{' (paper Table I)' if same else ''}"


def _effects(r: ReproResults) -> str:
    """The virtual robot's effects where `--set` changed them ("" for the default)."""
    if not r.virtual_settings:
        return ""
    return " with " + ", ".join(f"{k} = {v}" for k, v in r.virtual_settings.items())


def _budgets(scale: ReproScale) -> str:
    """One paragraph: how this scale trained, against the paper's batch 32, lr 1e-3, ≤ 500 epochs."""
    labels = ("paper FK/IK", "snap-aware FK", "follow IK", "baselines and ablation", "IB and structure grids")
    parts = []
    for role, label in zip(BUDGET_ROLES, labels, strict=True):
        b = getattr(scale, role)
        sched = "cosine decay" if b.lr_schedule == "cosine" else "constant lr"
        parts.append(f"{label} batch {b.batch_size}, lr {b.lr:.2g} ({sched}), ≤ {b.epochs} epochs")
    return ("Training differs from the paper's (batch 32, lr 1e-3, up to 500 epochs with early "
            "stopping): " + "; ".join(parts) + " (docs/reproduction.md says why).")


def _headline(r: ReproResults) -> list[str]:
    """Three tables whose columns each hold one kind of number: FK accuracy (vs the measurement and
    vs the truth), IK accuracy, and time per prediction."""
    fk, ik, tm = r.fk, r.ik[HEADLINE], r.timing
    head, tcm = fk[HEADLINE], fk[TCM_ROW.name]
    rec = r.recommended
    snap = r.snapping
    snap_meas = snap.per_model.get(snap.model, {}).get("vs_measured", {})
    lines = ["## Headline", "",
             f"Learned figures come from the recommended models: FK `{rec.fk}` (the snap-aware "
             f"LSTM-MLP; the paper's own FK LSTM-MLP is the `lstm_mlp_paper` row of the next section), IK "
             f"`{rec.ik}` (the follow IK: joint changes from the robot's current joints; the paper's "
             "IK network is the `lstm_mlp_paper` column of the IK table, the IK refined on the learned FK "
             "`lstm_mlp_refined`).", "",
             "Forward kinematics, RMSE on the held-out sequences:", ""]
    lines.append(_table(
        ["quantity", "paper", "ours vs measured", "ours vs truth"],
        [["FK position RMSE (mm)", _f(P.FK["position_rmse_mm"]), _f(head["position_rmse_mm"]),
          _f(head["position_rmse_true_mm"])],
         ["FK orientation RMSE (deg)", _f(P.FK["orientation_rmse_deg"]),
          _f(head["orientation_rmse_deg"]), _f(head["orientation_rmse_true_deg"])],
         ["TCM (point-wise) position RMSE (mm)", "8.55 (random points), 10.94 (path)",
          _f(tcm["position_rmse_mm"]), _f(tcm["position_rmse_true_mm"])],
         *([[f"calibrated TCM with friction, continued, position RMSE (mm; μ = "
             f"{_f(_mu(fk), 3)})", "–", _f(fk[CAL_CONT]["position_rmse_mm"]),
             _f(fk[CAL_CONT]["position_rmse_true_mm"])]] if CAL_CONT in fk else []),
         ["snap prediction precision / recall (sweeps)", "– (shown in Fig. 10a, not scored)",
          f"{_f(snap_meas.get('precision'))} / {_f(snap_meas.get('recall'))}",
          f"{_f(snap.precision)} / {_f(snap.recall)}"]]))
    lines += ["", "Inverse kinematics on the held-out sequences (joint errors against the recorded joints, "
              "α wrapped to ±180°; tip errors against the target poses):", ""]
    lines.append(_table(
        ["quantity", "paper", "ours"],
        [["IK joint RMSE β (mm)", _f(P.IK["joint_rmse_mm"]), _f(ik["joint_rmse_mm"])],
         ["IK joint RMSE α (deg)", _f(P.IK["joint_rmse_deg"]), _f(ik["joint_rmse_deg"])],
         ["IK tip RMSE through the learned FK model (mm)", "< 1 (Fig. 11, 20 points)",
          _f(ik["tip_error_via_fk_mm"])],
         ["IK tip RMSE driving the robot to the joints (mm)", "– (not reported)", _f(ik["tip_error_mm"])]]))
    lines += ["", "Time per prediction (the paper's on its own computer: compare orders of magnitude):", ""]
    lines.append(_table(
        ["quantity", "paper", "ours", "how ours was timed"],
        [["FK time per prediction (ms)", f"{P.FK['ms_mean']} ± {P.FK['ms_std']}",
          f"{_f(tm.fk_ms_mean, 4)} ± {_f(tm.fk_ms_std, 4)}",
          "recommended FK, streaming: one step a call"],
         ["IK time per prediction (ms)", f"{P.IK['ms_mean']} ± {P.IK['ms_std']}",
          f"{_f(tm.ik_ms_mean, 4)} ± {_f(tm.ik_ms_std, 4)}",
          "recommended IK, streaming: one step a call"],
         ["TCM time per point (ms)", f"{P.TCM_MS['mean']:.0f} ± {P.TCM_MS['std']:.0f}",
          f"{_f(tm.tcm_ms_mean, 3)} ± {_f(tm.tcm_ms_std, 3)}",
          "point-wise solve on the test rows (compiled shooting)"],
         *([["calibrated TCM with friction, continued, time per step (ms)", "–",
             _f(tm.tcm_calibrated_continued_us_mean / 1e3, 3),
             "mean over whole sequences, the friction state carried"]]
           if tm.tcm_calibrated_continued_us_mean is not None else [])]))
    return lines


def _mu(fk: dict[str, Any]) -> float | None:
    """μ of the calibrated TCM (its calibration table), None without one."""
    rows = fk.get(TCM_CALIBRATED_ROW.name, {}).get("calibration", {}).get("parameters", [])
    return next((r["value"] for r in rows if r["name"] == "friction_mu"), None)


def _fk_comparison(r: ReproResults) -> list[str]:
    """Fig. 5: every FK predictor on the test sequences, and the Δα0 ablation."""
    fk = r.fk
    names = labels()
    rows = [[f"{names.get(m, m)} (`{m}`)", _f(v["position_rmse_mm"]), _f(v["position_mae_mm"]),
             _f(v["orientation_rmse_deg"]), _f(v["position_rmse_true_mm"]),
             _f(v["away_from_snap"]["position_rmse_mm"]),
             _f((v.get("at_snap") or {}).get("position_rmse_mm"))]
            for m, v in fk.items()
            if m != HEADLINE and isinstance(v, dict) and "position_rmse_mm" in v]
    ab = fk["ablation"]
    return [
        "## FK model comparison and Δα0 ablation (Fig. 5)", "",
        "Errors on the held-out test sequences against the measurement (and, one column, the truth); "
        "'at snap' is the two steps at each snap (where an input buffer lags), 'away' the rest. "
        "Fig. 5a plots the position MAE per relative translation.", "",
        _table(["model", "pos RMSE (mm)", "pos MAE (mm)", "ori RMSE (deg)", "pos RMSE vs truth (mm)",
                "away from snap, pos RMSE (mm)", "at snap, pos RMSE (mm)"], rows),
        "",
        f"Δα0 ablation: position MAE {_f(ab['position_mae_with_delta_mm'])} mm with Δα0, "
        f"{_f(ab['position_mae_without_delta_mm'])} mm without ({_f(ab['mae_decrease_pct'], 1)} % lower "
        f"with it; paper: MAE {P.ABLATION['mae_decrease_pct']} % lower, in normalised training MAE).",
    ]


def _fk_experiments(r: ReproResults) -> list[str]:
    """Fig. 10: sweeps, random points, the arbitrary path and the snap turns, TCM beside learned."""
    ex = r.experiments
    rows = []
    for name in (e.name for e in EXPERIMENTS if e.section == "fk"):
        e, pp = ex[name], P.EXPERIMENTS.get(name, {})
        cal = e.get(CAL_CONT)
        rows.append([name, _pair(pp.get("tcm")), _err(e[TCM_ROW.name]), _err(cal) if cal else "–",
                     _pair(pp.get("lstm_mlp")), _err(e[FK_PAPER_ROW.name]), _err(e[FK_BRANCH_ROW.name])])
    lines = ["## Experiments (Fig. 10, 11, 12)", "",
             "Position RMSE (mm) / orientation RMSE (deg) against the measurement.", "",
             _table(["experiment", "TCM, paper", "TCM, ours", "calibrated TCM with friction (continued), "
                     "ours", "LSTM-MLP, paper", "LSTM-MLP (paper's), ours", "snap-aware LSTM-MLP, ours"],
                    rows)]
    sw = ex[SWEEPS.name].get("snapping_levels")
    for m in SNAPPING_ROWS if sw else ():
        lines += ["", f"Snapping sweeps, {labels()[m]}: away from the snap {_err(sw[m + '_away_from_snap'])}"
                  f" (paper 0.8 mm, 4.2°); at the snap steps {_err(sw[m + '_at_snap'])}"
                  " (paper up to 12 mm, 20°)."]
    return lines


def _ik_experiments(r: ReproResults) -> list[str]:
    """Fig. 11, 12: IK at random poses and along the square and triangle, and on held-out sequences."""
    ex, ikh = r.experiments, r.ik
    rows = []
    for name in (e.name for e in EXPERIMENTS if e.section == "ik"):
        e = ex[name]
        rows.append([name, _pair(P.EXPERIMENTS.get(name, {}).get("lstm_mlp"))]
                    + [f"{_err(e[m]['via_robot'])}, {_f(100 * e[m]['within_1mm_fraction'], 0)} % "
                       f"({_err(e[m]['via_fk_model'])})" for m in IK_REPORT_ROWS])
    rows.append(["held-out sequences", "–"]
                + [f"{_f(ikh[m]['tip_error_mm'])} mm, {_f(100 * ikh[m]['within_1mm_fraction'], 0)} %, "
                   f"α median {_f(ikh[m]['joint_alpha_median_deg'], 1)}°, {ikh[m]['flagged_jumps']} "
                   f"α jumps flagged" for m in IK_REPORT_ROWS])
    tube = ikh[IK_FOLLOW_ROW.name].get("joint_alpha_median_tube_deg")
    if tube is not None:
        rows.append(["held-out, follow IK, α median of the outer tube's angle (the play removed)", "–",
                     "", "", f"{_f(tube, 1)}°"])
    fs = ikh[IK_FOLLOW_ROW.name].get("from_robot_start")
    if fs:
        rows.append(["held-out, follow IK from the robot's start joints", "–", "", "",
                     f"{_f(fs['tip_error_mm'])} mm, {_f(100 * fs['within_1mm_fraction'], 0)} %, α median "
                     f"{_f(fs['joint_alpha_median_deg'], 1)}°"])
    return [
        "IK: the tip the predicted joints reach on the virtual robot (RMSE vs the targets), the "
        "fraction of targets reached within 1 mm, and (in brackets) through the snap-aware FK model.", "",
        _table(["IK experiment", "paper", "LSTM-MLP (paper's network)", "refined on the snap-aware FK",
                "follow IK (recommended)"], rows),
        "",
        "The follow IK starts each sequence from the joints of the nearest training target unless "
        "the robot's start joints are given (last row); its α can differ from the recorded α by the "
        "mirror solution (±α0) that puts the tip at the same pose, so its tip error is the measure.",
    ]


def _snap_prediction(r: ReproResults) -> list[str]:
    """Snap events per predictor on the sweeps and snap turns, by the paper's 10° T(L) rule."""
    ex = r.experiments
    rows = []
    for exp in (e.name for e in EXPERIMENTS if "snap_prediction" in ex.get(e.name, {})):
        for k, v in ex[exp]["snap_prediction"].items():
            fw, bw, vm = v["forward"], v["backward"], v["vs_measured"]
            rows.append([exp, k, _f(v["n_reference"], 0), _f(v["n_predicted"], 0), _f(v["n_matched"], 0),
                         _f(v["precision"]), _f(v["recall"]), f"{_f(fw['precision'])} / {_f(fw['recall'])}",
                         f"{_f(bw['precision'])} / {_f(bw['recall'])}", _f(v["timing_error_steps"]),
                         _f(v["magnitude_error_deg"]), _f(v["position_at_snap_true_mm"]),
                         _f(v["position_away_from_snap_true_mm"]),
                         f"{_f(vm['precision'])} / {_f(vm['recall'])}"])
    return [
        "## Snap prediction (paper's rule: T(L) changes by more than 10° in one step)", "",
        "Against the noise-free truth (and, last column, the measurement); matched within ±2 steps. "
        "Position error vs truth on the two steps at each true snap and away from them.", "",
        _table(["experiment", "predictor", "true snaps", "predicted", "matched", "precision", "recall",
                "forward P / R", "backward P / R", "timing (steps)", "magnitude (deg)", "pos at snap (mm)",
                "pos away (mm)", "P / R vs measured"], rows),
    ]


def _grids(r: ReproResults) -> list[str]:
    """Tables II and III: the input-buffer grid and the structure grid, S1–S5 spelled out."""
    g = r.grids
    ib_rows = [[ib, _f(v["position_rmse_mm"]), _f(v["test_loss"], 4),
                _f(P.TABLE2_TEST_MAE["fk"].get(int(ib)), 4), _f(g["ib"]["ik"][ib]["joint_rmse_mm"]),
                _f(g["ib"]["ik"][ib]["joint_rmse_deg"]), _f(g["ib"]["ik"][ib].get("test_loss"), 4),
                _f(P.TABLE2_TEST_MAE["ik"].get(int(ib)), 4)]
               for ib, v in g["ib"]["fk"].items()]
    st_rows = [[k, _f(v["position_rmse_mm"]), _f(v["orientation_rmse_deg"]), _f(_table3(k, 0)),
                _f(_table3(k, 1))] for k, v in g["structure"].items()]
    names = sorted({k.split("_", 1)[1] for k in g["structure"]})
    return [
        "## Input buffer (Table II) and structures (Table III)", "",
        "Table II is not like with like. The paper's columns are its test MAE of the outputs "
        "normalised to [0, 1], on its random 70:15:15 split of its hardware data with its own "
        "normalisation ranges and training. Our \"test MAE\" columns are the same kind of number (MAE "
        "of the [0, 1]-normalised outputs, the training loss) on held-out sequences of virtual-robot "
        "data, with our ranges and this scale's training budget, so only the trend across IB is "
        "comparable, not the values. The errors in mm and deg are ours alone (the paper gives none "
        "per IB).", "",
        _table(["IB", "FK pos RMSE (mm)", "FK test MAE, normalised", "paper FK test MAE, normalised",
                "IK β RMSE (mm)", "IK α RMSE (deg)", "IK test MAE, normalised",
                "paper IK test MAE, normalised"], ib_rows),
        "",
        "Structures (Table III): FK errors against the measurement on the held-out sequences, the "
        "paper's beside them (its random split and hardware: the trend, not the values, compares). "
        "Each structure is a stack of layers applied per step of the input buffer, then flattened, "
        "then Dense layers, then Dense(6) (`ctrkin.models.seqnet`):", "",
        _table(["structure", "layers"], [[s, describe_structure(s)] for s in names]),
        "",
        _table(["IB, structure", "pos RMSE (mm)", "ori RMSE (deg)", "paper pos (mm)", "paper ori (deg)"],
               st_rows),
    ]


def _notes(r: ReproResults) -> list[str]:
    return ["## Notes", "", *[f"- {n}" for n in r.notes]]


def describe_structure(name: str) -> str:
    """'S1' -> 'LSTM 64 → LSTM 64 → flatten → Dense 32 (ReLU) → Dense 6', from the structure's spec."""
    spec = STRUCTURES.get(name, name)
    seq, head = spec.split("|")
    layer = {"L": "LSTM {}", "D": "Dense {} (ReLU)"}
    parts = [layer[t[0]].format(t[1:]) for t in filter(None, seq.split(","))]
    parts.append("flatten")
    parts += [layer[t[0]].format(t[1:]) for t in filter(None, head.split(","))]
    return " → ".join([*parts, "Dense 6"])


def _f(x: Any, nd: int = 2) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "–"
    if isinstance(x, (int,)) and not isinstance(x, bool):
        return str(x)
    return f"{x:.{nd}f}"


def _table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def _pair(p: Any) -> str:
    if p is None:
        return "–"
    return f"{_f(p[0])} mm / {_f(p[1])}°"


def _err(d: dict[str, Any]) -> str:
    """RMSE position / orientation of a summary dict."""
    return _pair((d["position_rmse_mm"], d["orientation_rmse_deg"]))


def _table3(key: str, k: int) -> float | None:
    ib, s = key.split("_")
    entry = P.TABLE3.get(int(ib[2:]), {}).get(s)
    return entry[k] if entry else None
