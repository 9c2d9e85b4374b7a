"""Train a small forward-kinematics model and run it both ways: batch over a sequence, and streaming
one step at a time as a controller would (the model keeps its input buffer itself).

    python examples/record_virtual_robot.py --levels 4,12,20 --out data/sweeps
    python examples/train_and_stream.py --data data/sweeps --out models/fk-small
    python examples/train_and_stream.py --data data/sweeps --out models/fk-small --epochs 200   # better

This trains the paper's LSTM-MLP (`lstm_mlp`) for a few epochs: a demonstration of the API, not the
accuracy of the recommended models (docs/tutorial.md and docs/reproduction.md for those).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import ctrkin
from ctrkin.data import Dataset
from ctrkin.metrics import pose_errors
from ctrkin.training import TrainConfig, train


def main(argv: list[str] | None = None) -> dict[str, object]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, help="a dataset folder (ctrkin collect, or the record example)")
    ap.add_argument("--out", required=True, help="the model folder to write")
    ap.add_argument("--epochs", type=int, default=20)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args(argv)

    ds = Dataset.load(args.data)
    cfg = TrainConfig(task="fk", model="lstm_mlp", max_epochs=args.epochs, batch_size=64,
                      threads=args.threads, seed=0)
    result = train(ds, cfg, args.out, overwrite=True, progress=False)
    epochs = len(result.history)
    print(f"trained {cfg.model} for {epochs} epochs -> {args.out}")

    fk = ctrkin.Kinematics.load(args.out)
    test = ds.get_split().test                              # held-out rows: whole sequences
    seq = ds.frame.iloc[test]["sequence_id"].to_numpy()
    rows = test[seq == seq[0]]                              # the first held-out sequence
    Q = ds.joints()[rows]                                   # (T, 2N) deg, mm
    measured = ds.poses()[rows]                             # (T, 6)

    batch = fk.predict(Q)                                   # (T, 6): the whole sequence at once
    fk.reset()                                              # a new sequence starts
    times, stream = [], []
    for q in Q:                                             # one step at a time
        t0 = time.perf_counter()
        stream.append(fk.step(q))
        times.append(time.perf_counter() - t0)
    stream_arr = np.array(stream)
    gap = float(np.abs(stream_arr - batch).max())
    rmse = pose_errors(batch, measured)["position_mm"]["rmse"]
    print(f"held-out sequence of {len(Q)} steps: position error {rmse:.2f} mm RMSE; streaming equals "
          f"batch to {gap:.1e}; one step {1e6 * np.median(times):.0f} µs (median)")
    return {"epochs": epochs, "steps": len(Q), "rmse_mm": rmse, "stream_vs_batch": gap,
            "step_us": 1e6 * float(np.median(times))}


if __name__ == "__main__":
    main()
