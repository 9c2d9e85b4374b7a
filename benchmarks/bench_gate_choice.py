"""Benchmark: which gate the snap-aware FK switches branches by, chosen on validation (issue 21, goal 2;
docs/learned_kinematics.md: The gate chosen on validation).

    python benchmarks/bench_gate_choice.py --repro out/gen/design-b out/gen/default-top

For each finished reproduction (or any folder with data/paper and models/fk_lstm_mlp_branch) this
makes the choice training makes (ctrkin.families.snap_aware.gate_choice) on the recommended FK as it
is: the fold gate's and the learned gate's position RMSE on the validation sequences of data/paper
against the poses the model learned, the share of bootstrap resamples of those sequences in which the
learned gate is better, and the choice; beside them, for reference only, the same two on the test
sequences (not used to choose) and the gate the folder uses now (an older folder: the fold gate).
Ends with one JSON line of the figures.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np

import ctrkin
from ctrkin.data.dataset import Dataset
from ctrkin.families.snap_aware.gate_choice import LEVEL, choose_gate, gate_positions
from ctrkin.models.recipe import inputs_and_targets

FK = "fk_lstm_mlp_branch"


def figures(repro: Path) -> dict[str, Any]:
    """The choice and the reference figures of one reproduction."""
    ds = Dataset.load(repro / "data" / "paper")
    kin = ctrkin.Kinematics.load(repro / "models" / FK)
    model = kin.predictor
    target = inputs_and_targets(ds, "fk", kin.config.pose_source)[1]
    split = ds.get_split()
    fold, learned = gate_positions(model, ds)          # each gate once, judged on two row sets
    sequence = ds.frame["sequence_id"].to_numpy()

    def on(rows: np.ndarray) -> Any:
        rows = np.sort(rows)
        return choose_gate(fold[rows], learned[rows], target[rows, :3], sequence[rows])

    choice, on_test = on(split.val), on(split.test)
    return {**choice.to_dict(), "test_position_rmse_fold_mm": on_test.fold_mm,
            "test_position_rmse_learned_mm": on_test.learned_mm,
            "gate_in_use": "fold" if model.fold_gate is not None else "learned"}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repro", nargs="+", type=Path, required=True,
                    help="reproduction folders (data/paper, models/fk_lstm_mlp_branch)")
    args = ap.parse_args(argv)
    out = {str(r): figures(r) for r in args.repro}
    rows = [[r, f"{f['val_position_rmse_fold_mm']:.3f}", f"{f['val_position_rmse_learned_mm']:.3f}",
             f"{f['p_learned_better']:.3f}", f["gate"], f"{f['test_position_rmse_fold_mm']:.3f}",
             f"{f['test_position_rmse_learned_mm']:.3f}", f["gate_in_use"]] for r, f in out.items()]
    cells = [["reproduction", "val fold", "val learned", "P(learned better)", f"chosen (P ≥ {LEVEL})",
              "test fold", "test learned", "folder uses"], *rows]
    widths = [max(len(c[i]) for c in cells) for i in range(len(cells[0]))]
    for c in cells:
        print("  ".join(v.ljust(w) for v, w in zip(c, widths, strict=True)), flush=True)
    print("(position RMSE, mm, against the poses the model learned; test: for reference, not chosen on)")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
