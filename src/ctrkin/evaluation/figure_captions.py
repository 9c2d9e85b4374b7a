"""The figures of a reproduction in reading order, each with a title and the caption that report.md
puts under it (what is plotted, in which units, against what, and how to read it)."""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple


class Figure(NamedTuple):
    stem: str       # file name in OUT/figures without .png
    title: str
    caption: str


_TURNS = (
    "Solid lines and filled dots: forward (α0 increasing); dashed lines and open dots: backward, so "
    "the gap between a predictor's two curves is its hysteresis. Black crosses: the snaps flagged in "
    "the data. The point-wise TCM has no history, so its forward and "
    "backward points coincide; the continued TCM follows the equilibrium branch and snaps at its "
    "folds. The snap-aware model's gate ablations are scored in the snap-prediction table, not drawn."
)

FIGURES = (
    Figure("fig5a_model_comparison", "Fig. 5a: FK model comparison",
           "Position MAE (mm, lower is better) of every FK model and the point-wise TCM on the "
           "held-out test sequences, per relative translation d of the paper protocol. The paper "
           "plotted normalised training MAE; the table above gives RMSE and MAE over all levels."),
    Figure("fig5b_delta_ablation", "Fig. 5b: the directional parameter Δα0",
           "Position MAE (mm) of the paper's LSTM-MLP trained with and without Δα0 among its inputs, "
           "per relative translation d, on the held-out test sequences."),
    Figure("fig7_input_buffer", "Fig. 7 and Table II: input buffer",
           "Errors on the held-out test sequences of the grid models against the input buffer IB: "
           "FK position RMSE and IK β RMSE share the mm colour scale, IK α RMSE (wrapped to ±180°) "
           "has its own deg scale. Darker is worse within a scale."),
    Figure("fig8_structures", "Fig. 8 and Table III: structures",
           "FK position RMSE (mm) and orientation RMSE (deg), each on its own colour scale, of the "
           "structures S1–S5 (spelled out in the Table III section) at IB = 2 and 3, on the held-out "
           "test sequences. Darker is worse."),
    Figure("fig10a_sweeps", "Fig. 10a: rotation sweeps",
           "T(L), the tip azimuth measured from the outer tube's base rotation (deg), against the "
           "relative rotation α0 = α1 − αN (deg), for full inner rotations 0 → 360 → 0° at each "
           "relative translation d (one panel each, low nonlinearity to snapping). " + _TURNS),
    Figure("snap_turns", "Snap turns (beyond the paper)",
           "As Fig. 10a, for full turns at full overlap at outer angles αN and translations βN that "
           "the training data never recorded (one panel each). " + _TURNS),
    Figure("fig10b_random_points", "Fig. 10b: random points",
           "The 20 random targets, numbered in the order visited: measured tip, the snap-aware "
           "LSTM-MLP's and the point-wise TCM's predictions in the x–y and x–z planes (mm), and each "
           "point's position error against the measurement."),
    Figure("fig10c_arbitrary", "Fig. 10c: arbitrary path",
           "The paper's simultaneous trajectory: measured tip, snap-aware LSTM-MLP and point-wise "
           "TCM in the x–y and x–z planes (mm), and the distribution of their position errors "
           "against the measurement."),
    Figure("fig11_ik_random", "Fig. 11: IK at random poses",
           "The recommended IK at the 20 random poses: predicted (×) and recorded (○) α and β per "
           "point (a mirror solution may differ in α and still reach the pose), and the targets "
           "with the tips the predicted joints reach through the learned FK model and by driving "
           "the virtual robot (x–y, mm)."),
    Figure("fig12_ik_square", "Fig. 12: IK along a square",
           "The recommended IK along a square of 10 target poses: targets and the tips reached "
           "through the learned FK model and by driving the virtual robot (3-D, mm), and the "
           "predicted joints per point."),
    Figure("fig12_ik_triangle", "Fig. 12: IK along a triangle",
           "As the square (Fig. 12 above), along a triangle of 10 target poses: targets, tips reached "
           "and predicted joints."),
)


def figure_section(folder: Path) -> list[str]:
    """The report's figure section: each figure present in `folder`, in FIGURES order, under its
    title with its caption beneath; a figure FIGURES does not know is listed by its file name."""
    lines = ["## Figures"]
    known = {f.stem for f in FIGURES}
    for f in FIGURES:
        if (folder / f"{f.stem}.png").is_file():
            lines += ["", f"### {f.title}", "", f"![{f.title}](figures/{f.stem}.png)", "", f"*{f.caption}*"]
    for png in sorted(p for p in folder.glob("*.png") if p.stem not in known):
        lines += ["", f"### {png.stem}", "", f"![{png.stem}](figures/{png.name})"]
    return lines
