"""The input-buffer and structure grids (paper Tables II and III, Fig. 7 and 8), and timing."""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ctrkin.evaluation.context import Context, summary, valid_rows
from ctrkin.evaluation.table import (
    FK_PAPER_ROW,
    IK_PAPER_ROW,
    IK_REFINED_ROW,
    RECOMMENDED,
    Experiment,
    Figure,
    Row,
)
from ctrkin.metrics import joint_errors, timing_stats
from ctrkin.viz import experiments as fig

FIG7 = Figure("fig7_input_buffer", "Fig. 7 and Table II: input buffer",
              "Errors on the held-out test sequences of the grid models against the input buffer IB: "
              "FK position RMSE and IK β RMSE share the mm colour scale, IK α RMSE (wrapped to ±180°) "
              "has its own deg scale. Darker is worse within a scale.")
FIG8 = Figure("fig8_structures", "Fig. 8 and Table III: structures",
              "FK position RMSE (mm) and orientation RMSE (deg), each on its own colour scale, of the "
              "structures S1–S5 (spelled out in the Table III section) at IB = 2 and 3, on the held-out "
              "test sequences. Darker is worse.")


def grids(ctx: Context, rows_: tuple[Row, ...] = ()) -> dict[str, Any]:
    """Test-split errors of every grid model; normalised test loss (MAE) as the paper's tables."""
    scale = ctx.scale
    ds = ctx.data.paper
    rows = valid_rows(ds, ds.get_split().test)
    measured, truth = ds.poses(), ctx.truth(ds)
    out: dict[str, Any] = {"ib": {"fk": {}, "ik": {}}, "structure": {}}
    for ib in scale.ib_grid:
        m = ctx.models[f"grid_fk_ib{ib}"]
        r = summary(ctx.fk(f"grid_fk_ib{ib}", ds)[rows], measured[rows], truth[rows])
        r["test_loss"] = m.metrics.get("test", {}).get("loss")
        out["ib"]["fk"][str(ib)] = r
        ik = ctx.models[f"grid_ik_ib{ib}"]
        je = joint_errors(ik.predict(ds).joints[rows], ds.joints()[rows], ds.n_tubes)
        out["ib"]["ik"][str(ib)] = {
            "joint_rmse_mm": je["beta_mm"]["rmse"],
            "joint_rmse_deg": je["alpha_deg"]["rmse"],
            "test_loss": ik.metrics.get("test", {}).get("loss"),
        }
    for ib in scale.structure_ibs:
        for s in scale.structure_grid:
            name = f"grid_fk_ib{ib}_{s}"
            r = summary(ctx.fk(name, ds)[rows], measured[rows], truth[rows])
            r["test_loss"] = ctx.models[name].metrics.get("test", {}).get("loss")
            out["structure"][f"ib{ib}_{s}"] = r
    ibs = [str(i) for i in scale.ib_grid]
    fig.grid_figure(
        ["FK position RMSE (mm)", "IK β RMSE (mm)", "IK α RMSE (deg)"],
        [f"IB={i}" for i in ibs],
        np.array(
            [
                [out["ib"]["fk"][i]["position_rmse_mm"] for i in ibs],
                [out["ib"]["ik"][i]["joint_rmse_mm"] for i in ibs],
                [out["ib"]["ik"][i]["joint_rmse_deg"] for i in ibs],
            ]
        ),
        ctx.figures / f"{FIG7.stem}.png",
        "Input buffer (Table II, Fig. 7): RMSE on the test sequences",
        "{:.2f}",
        units=["mm", "mm", "deg"],
    )
    fig.grid_figure(
        [f"{q} RMSE, IB={ib}" for q in ("position", "orientation") for ib in scale.structure_ibs],
        list(scale.structure_grid),
        np.array(
            [
                [out["structure"][f"ib{ib}_{s}"][key] for s in scale.structure_grid]
                for key in ("position_rmse_mm", "orientation_rmse_deg")
                for ib in scale.structure_ibs
            ]
        ),
        ctx.figures / f"{FIG8.stem}.png",
        "FK by structure (Table III, Fig. 8): RMSE on the test sequences",
        "{:.2f}",
        units=["mm"] * len(scale.structure_ibs) + ["deg"] * len(scale.structure_ibs),
    )
    return out


def timing(ctx: Context, rows_: tuple[Row, ...] = (), n_steps: int = 2000) -> dict[str, Any]:
    """Streaming single-step latency over a held-out sequence (one step a call, the control-loop
    case), in ms: "fk" / "ik" the recommended models (the IK with its refinement), "fk_paper" /
    "ik_paper" the paper's LSTM-MLP, "ik_refined" the IK refined on the learned FK (300 steps)."""
    ds = ctx.data.paper
    test = ds.get_split().test
    q = ds.joints()[test][:n_steps]
    p = ds.poses()[test][:n_steps]
    out: dict[str, Any] = {}
    models = {"fk": (RECOMMENDED["fk"], q), "ik": (RECOMMENDED["ik"], p), "fk_paper": (FK_PAPER_ROW, q),
              "ik_paper": (IK_PAPER_ROW, p), "ik_refined": (IK_REFINED_ROW, p[:300])}
    for name, (row, x) in models.items():
        model = ctx.models[str(row.folder)]
        model.reset()
        for v in x[:50]:  # warm-up (numba dispatch, caches)
            model.step(v)
        model.reset()
        t = np.empty(len(x))
        for k, v in enumerate(x):
            t0 = time.perf_counter()
            model.step(v)
            t[k] = time.perf_counter() - t0
        out[name] = timing_stats(t)
    return out


EXPERIMENTS = (
    Experiment("grids", "input buffer and structure grids (Tables II, III)", grids, figures=(FIG7, FIG8),
               top_level=True),
    Experiment("timing", "timing", timing, (RECOMMENDED["fk"], RECOMMENDED["ik"], FK_PAPER_ROW, IK_PAPER_ROW,
                                            IK_REFINED_ROW), top_level=True),
)
