"""results.json and report.md of a reproduction: our figures beside the paper's."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from ctrkin.evaluation import paper_numbers as P
from ctrkin.util.files import atomic_write_text

REQUIRED_KEYS = (
    [
        f"fk.{m}.{k}"
        for m in ("lstm_mlp", "lstm_mlp_paper", "lstm_mlp_branch", "tcm", "mlp", "lstm", "cnn", "tcn",
                  "resnet")
        for k in ("position_rmse_mm", "orientation_rmse_deg", "position_rmse_true_mm")
    ]
    + [f"ik.{m}.{k}" for m in ("lstm_mlp", "lstm_mlp_paper", "lstm_mlp_refined", "follow_mlp")
       for k in ("joint_rmse_mm", "joint_rmse_deg", "tip_error_mm", "joint_alpha_median_deg")]
    + [f"snapping.{m}.{k}" for m in ("lstm_mlp_paper", "lstm_mlp_branch", "tcm", "tcm_continued")
       for k in ("precision", "recall", "timing_error_steps", "magnitude_error_deg")]
    + [f"experiments.{e}.within_1mm_fraction" for e in ("ik_random", "ik_square", "ik_triangle")]
    + ["recommended.fk", "recommended.ik"]
    + [
        f"experiments.{e}.position_rmse_mm"
        for e in ("sweeps", "random_points", "arbitrary", "ik_random", "ik_square", "ik_triangle")
    ]
    + [
        "snapping.precision",
        "snapping.recall",
        "timing.fk_ms_mean",
        "timing.fk_ms_std",
        "timing.ik_ms_mean",
        "timing.tcm_ms_mean",
        "dataset.samples",
        "dataset.sequences",
        "dataset.snaps",
    ]
)

# IK rows of the experiment table, in column order
IK_REPORT_ROWS = ("lstm_mlp_paper", "lstm_mlp_refined", "follow_mlp")


def lookup(results: dict[str, Any], dotted: str) -> Any:
    """results["a"]["b"]["c"] for "a.b.c"."""
    cur: Any = results
    for part in dotted.split("."):
        cur = cur[part]
    return cur


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


def write_results(results: dict[str, Any], path: Path) -> dict[str, Any]:
    """Write the nested results, plus every required key flattened under its dotted name (for
    tools that read flat keys); returns what was written."""
    out = _clean(results)
    for key in REQUIRED_KEYS:
        out[key] = lookup(out, key)
    atomic_write_text(path, json.dumps(out, indent=2))
    return out


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


def _budgets(scale: dict[str, Any]) -> str:
    """One paragraph: how this scale trained, against the paper's batch 32, lr 1e-3, ≤ 500 epochs."""
    roles = {"main": "paper FK/IK", "branch": "snap-aware FK", "follow": "follow IK",
             "compare": "baselines and ablation", "grid": "IB and structure grids"}
    parts = []
    for key, label in roles.items():
        b = scale.get(key)
        if isinstance(b, dict):
            sched = "cosine decay" if b["lr_schedule"] == "cosine" else "constant lr"
            parts.append(f"{label} batch {b['batch_size']}, lr {b['lr']:.2g} ({sched}), "
                         f"≤ {b['epochs']} epochs")
    return ("Training differs from the paper's (batch 32, lr 1e-3, up to 500 epochs with early "
            "stopping): " + "; ".join(parts) + " (docs/reproduction.md says why).")


def write_report(r: dict[str, Any], path: Path) -> None:
    fk, ik, ex, tm = r["fk"], r["ik"]["lstm_mlp"], r["experiments"], r["timing"]
    s: list[str] = [f"# ctrkin reproduction of the paper ({r['scale']['name']} scale)", ""]
    s.append(
        f"Robot: {r['robot']['name']} (paper Table I), virtual robot seed {r['virtual_robot_seed']}. "
        f"Training data: the paper protocol, {r['dataset']['samples']} samples in "
        f"{r['dataset']['sequences']} sequences ({r['dataset']['snaps']} snap samples), split by "
        f"sequence 70:15:15; errors are on held-out sequences unless stated. Wall time "
        f'{r["seconds"]["total"]:.0f} s. "Measured" is the virtual tracker (noise, registration, '
        f'sensor offset, like the paper\'s EM sensor); "truth" is the true tip seen by the tracker '
        "without noise, which hardware cannot give."
    )
    s += ["", _budgets(r["scale"])]
    rec = r.get("recommended", {})
    s += ["", "## Headline", "",
          f"Learned figures come from the recommended models: FK `{rec.get('fk')}` (the snap-aware "
          f"LSTM-MLP; the paper's own FK LSTM-MLP is the `lstm_mlp_paper` row below), IK "
          f"`{rec.get('ik')}` (the follow IK: joint changes from the robot's current joints; the paper's IK "
          f"network is the `lstm_mlp_paper` row, the IK refined on the learned FK `lstm_mlp_refined`).", ""]
    s.append(
        _table(
            ["quantity", "paper", "ours (vs measured)", "ours (vs truth)"],
            [
                [
                    "FK position RMSE (mm)",
                    _f(P.FK["position_rmse_mm"]),
                    _f(fk["lstm_mlp"]["position_rmse_mm"]),
                    _f(fk["lstm_mlp"]["position_rmse_true_mm"]),
                ],
                [
                    "FK orientation RMSE (deg)",
                    _f(P.FK["orientation_rmse_deg"]),
                    _f(fk["lstm_mlp"]["orientation_rmse_deg"]),
                    _f(fk["lstm_mlp"]["orientation_rmse_true_deg"]),
                ],
                [
                    "TCM position RMSE (mm)",
                    "8.55 / 10.94 (points / path)",
                    _f(fk["tcm"]["position_rmse_mm"]),
                    _f(fk["tcm"]["position_rmse_true_mm"]),
                ],
                ["IK joint RMSE β (mm)", _f(P.IK["joint_rmse_mm"]), _f(ik["joint_rmse_mm"]), ""],
                ["IK joint RMSE α (deg)", _f(P.IK["joint_rmse_deg"]), _f(ik["joint_rmse_deg"]), ""],
                [
                    "IK tip error through the robot (mm)",
                    "< 1 (via FK model)",
                    _f(ik["tip_error_mm"]),
                    f"via FK model: {_f(ik['tip_error_via_fk_mm'])}",
                ],
                [
                    "FK time per prediction (ms)",
                    f"{P.FK['ms_mean']} ± {P.FK['ms_std']}",
                    f"{_f(tm['fk_ms_mean'], 4)} ± {_f(tm['fk_ms_std'], 4)}",
                    "streaming, one core",
                ],
                [
                    "IK time per prediction (ms)",
                    f"{P.IK['ms_mean']} ± {P.IK['ms_std']}",
                    f"{_f(tm['ik_ms_mean'], 4)} ± {_f(tm['ik_ms_std'], 4)}",
                    "",
                ],
                [
                    "TCM time per point (ms)",
                    f"{P.TCM_MS['mean']:.0f} ± {P.TCM_MS['std']:.0f}",
                    f"{_f(tm['tcm_ms_mean'], 3)} ± {_f(tm['tcm_ms_std'], 3)}",
                    "",
                ],
                [
                    "snap prediction precision / recall (sweeps)",
                    "timing and magnitude shown (Fig. 10a)",
                    "",
                    f"{_f(r['snapping']['precision'])} / {_f(r['snapping']['recall'])}",
                ],
            ],
        )
    )
    s += [
        "",
        "## FK model comparison and Δα0 ablation (Fig. 5)",
        "",
        "Position/orientation RMSE on the held-out test sequences; 'at snap' is the two steps at each "
        "snap (where an input buffer lags), 'away' the rest.",
        "",
    ]
    rows = []
    for m, v in fk.items():
        if m == "lstm_mlp" or not isinstance(v, dict) or "position_rmse_mm" not in v:
            continue
        rows.append(
            [
                m,
                _f(v["position_rmse_mm"]),
                _f(v["orientation_rmse_deg"]),
                _f(v["position_rmse_true_mm"]),
                _f(v["away_from_snap"]["position_rmse_mm"]),
                _f((v.get("at_snap") or {}).get("position_rmse_mm")),
            ]
        )
    s.append(
        _table(
            [
                "model",
                "pos RMSE (mm)",
                "ori RMSE (deg)",
                "pos RMSE vs truth (mm)",
                "away from snap (mm)",
                "at snap (mm)",
            ],
            rows,
        )
    )
    ab = fk["ablation"]
    s += [
        "",
        f"Δα0 ablation: position MAE {_f(ab['position_mae_with_delta_mm'])} mm with Δα0, "
        f"{_f(ab['position_mae_without_delta_mm'])} mm without ({_f(ab['mae_decrease_pct'], 1)} % lower with "
        f"it; paper: MAE {P.ABLATION['mae_decrease_pct']} % lower, in normalised training MAE).",
        "",
    ]
    s += [
        "## Experiments (Fig. 10, 11, 12)",
        "",
        "Position RMSE (mm) / orientation RMSE (deg) against the measurement.",
        "",
    ]
    rows = []
    for name in ("sweeps", "random_points", "arbitrary", "snap_turns"):
        e = ex[name]
        pp = P.EXPERIMENTS.get(name, {})
        rows.append([name, _pair(pp.get("tcm")), _err(e["tcm"]), _pair(pp.get("lstm_mlp")),
                     _err(e["lstm_mlp_paper"]), _err(e["lstm_mlp_branch"])])
    s.append(_table(["experiment", "TCM paper", "TCM ours", "LSTM-MLP paper", "LSTM-MLP ours",
                     "snap-aware ours"], rows))
    s += ["", "IK: the tip the predicted joints reach on the virtual robot (RMSE vs the targets), the "
          "fraction of targets reached within 1 mm, and (in brackets) through the snap-aware FK model.",
          ""]
    rows = []
    for name in ("ik_random", "ik_square", "ik_triangle"):
        e = ex[name]
        pp = P.EXPERIMENTS.get(name, {})
        rows.append([name, _pair(pp.get("lstm_mlp"))]
                    + [f"{_err(e[m]['via_robot'])}, {_f(100 * e[m]['within_1mm_fraction'], 0)} % "
                       f"({_err(e[m]['via_fk_model'])})" for m in IK_REPORT_ROWS])
    ikh = r["ik"]
    rows.append(["held-out sequences", "–"]
                + [f"{_f(ikh[m]['tip_error_mm'])} mm, {_f(100 * ikh[m]['within_1mm_fraction'], 0)} %, "
                   f"α median {_f(ikh[m]['joint_alpha_median_deg'], 1)}°, {ikh[m]['flagged_jumps']} "
                   f"α jumps flagged" for m in IK_REPORT_ROWS])
    fs = ikh["follow_mlp"].get("from_robot_start")
    if fs:
        rows.append(["held-out, follow IK from the robot's start joints", "–", "", "",
                     f"{_f(fs['tip_error_mm'])} mm, {_f(100 * fs['within_1mm_fraction'], 0)} %, α median "
                     f"{_f(fs['joint_alpha_median_deg'], 1)}°"])
    s.append(_table(["IK experiment", "paper", "LSTM-MLP (paper's network)", "refined on the snap-aware FK",
                     "follow IK (recommended)"], rows))
    s += ["", "The follow IK starts each sequence from the joints of the nearest training target unless "
          "the robot's start joints are given (last row); its α can differ from the recorded α by the "
          "mirror solution (±α0) that puts the tip at the same pose, so its tip error is the measure.", ""]
    sw = ex["sweeps"].get("snapping_levels")
    if sw:
        for m in ("lstm_mlp_paper", "lstm_mlp_branch"):
            s += ["", f"Snapping sweeps, {m}: away from the snap {_err(sw[m + '_away_from_snap'])}"
                  f" (paper 0.8 mm, 4.2°); at the snap steps {_err(sw[m + '_at_snap'])}"
                  " (paper up to 12 mm, 20°)."]
    s += ["", "## Snap prediction (paper's rule: T(L) changes by more than 10° in one step)", "",
          "Against the noise-free truth (and, last column, the measurement); matched within ±2 steps. "
          "Position error vs truth on the two steps at each true snap and away from them.", ""]
    header = ["experiment", "predictor", "true snaps", "predicted", "matched", "precision", "recall",
              "forward P / R", "backward P / R", "timing (steps)", "magnitude (deg)", "pos at snap (mm)",
              "pos away (mm)", "P / R vs measured"]
    rows = []
    for exp in ("sweeps", "snap_turns"):
        for k, v in ex[exp]["snap_prediction"].items():
            fw, bw, vm = v["forward"], v["backward"], v["vs_measured"]
            rows.append([exp, k, _f(v["n_reference"], 0), _f(v["n_predicted"], 0), _f(v["n_matched"], 0),
                         _f(v["precision"]), _f(v["recall"]), f"{_f(fw['precision'])} / {_f(fw['recall'])}",
                         f"{_f(bw['precision'])} / {_f(bw['recall'])}", _f(v["timing_error_steps"]),
                         _f(v["magnitude_error_deg"]), _f(v["position_at_snap_true_mm"]),
                         _f(v["position_away_from_snap_true_mm"]),
                         f"{_f(vm['precision'])} / {_f(vm['recall'])}"])
    s.append(_table(header, rows))
    g = r["grids"]
    s += ["", "## Input buffer (Table II) and structures (Table III)", ""]
    s.append(
        _table(
            [
                "IB",
                "FK pos RMSE (mm)",
                "FK test loss",
                "paper FK test MAE",
                "IK β RMSE (mm)",
                "IK α RMSE (deg)",
                "paper IK test MAE",
            ],
            [
                [
                    ib,
                    _f(v["position_rmse_mm"]),
                    _f(v["test_loss"], 4),
                    _f(P.TABLE2_TEST_MAE["fk"].get(int(ib)), 4),
                    _f(g["ib"]["ik"][ib]["joint_rmse_mm"]),
                    _f(g["ib"]["ik"][ib]["joint_rmse_deg"]),
                    _f(P.TABLE2_TEST_MAE["ik"].get(int(ib)), 4),
                ]
                for ib, v in g["ib"]["fk"].items()
            ],
        )
    )
    s.append("")
    s.append(
        _table(
            ["IB, structure", "pos RMSE (mm)", "ori RMSE (deg)", "paper pos (mm)", "paper ori (deg)"],
            [
                [
                    k,
                    _f(v["position_rmse_mm"]),
                    _f(v["orientation_rmse_deg"]),
                    _f(_table3(k, 0)),
                    _f(_table3(k, 1)),
                ]
                for k, v in g["structure"].items()
            ],
        )
    )
    s += ["", "## Figures", ""]
    for f in sorted(Path(path).parent.joinpath("figures").glob("*.png")):
        s.append(f"![{f.stem}](figures/{f.name})")
    s += ["", "## Notes", "", *[f"- {n}" for n in r.get("notes", [])], ""]
    atomic_write_text(path, "\n".join(s))


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
