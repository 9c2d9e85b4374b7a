"""Learned FK at inference, against its floors (issue 26, goal 2; issue 8, goal 4): the streaming step,
the batch `predict` call, the network's multiply-adds as a bare matrix-vector chain in numba (the
floor) and ONNX Runtime on one thread, the old code beside the new in one run.

    python benchmarks/bench_streaming.py                       # a stand-in paper FK model (below)
    python benchmarks/bench_streaming.py --run out/reproduce   # the reproduction's fk_lstm_mlp
    python benchmarks/bench_streaming.py --run out/reproduce --all-models   # + the issue 8 table
    python benchmarks/bench_streaming.py --breakdown           # where the step's distance from its floor goes
    python benchmarks/bench_streaming.py --breakdown-predict 1024 --baseline dbab9a8 # predict call's pieces

The model: the paper's LSTM-MLP FK (L128|D64, IB 2, 85,376 multiply-adds a step) of a reproduction
(`--run`, made by code both trees read), or, without one, the same network trained for one epoch on
the demo sweeps by the baseline's code (the arithmetic does not depend on the weights' values).
Old and new: `--baseline REV` (default: main before issue 26) is extracted with `git archive` into a
folder of the temporary directory (kept, with its numba cache, for the next run); two worker
processes, one importing each tree, run the same measurements in alternating rounds (`--rounds`),
so that load falls on both alike; each figure is the median over rounds of the rounds' medians. One
torch and one ONNX Runtime thread.

Figures: `fk_step_us` (Kinematics.step, one sequence of test joints), `fk_floor_us` (float64 chain;
float32 beside it; each worker times its steps and the floor in alternating blocks of 50 calls, and
`*_step_to_floor` is the median of the rounds' step / floor ratios, which load does not move much),
`fk_floor_layout_us` (the same multiply-adds by the step's own product kernel,
ctrkin.models.engine._matvec: float32 weight matrices read four rows a pass, float64 sums; no
activation but the ReLU; `new_step_to_layout_floor` the step over it: the float64 floor reads 8-byte
weights one row a pass, which the step no longer does),
`onnx_step_us` (the exported graph on one window), predictions/s of `predict` on one sequence of B
rows for B = 1, 32, 1024, 65,536, and ONNX Runtime's on B windows (a third worker, in the same
alternating rounds; `*_to_onnx_b*`: the median of the rounds' ratios of predictions/s);
`predict_call_overhead_us`: the intercept of a least-squares line through predict's times at B = 1..16
(the cost of a call beyond its rows; the new code runs these rows through the fused step),
`predict_torch_call_overhead_us` the same at B = 32..256 (the batch path by chains in torch).
Prints a table with `uptime` and ends with one JSON line. `--breakdown`: only this tree's step, its
layers peeled off one at a time and the kernel's pieces alone, against the floor
(benchmarks/streaming_breakdown.py). `--breakdown-predict B`: only `predict` on B rows, split into
its pieces, the baseline's tree (one with the fused pass: dbab9a8 or later) and this one
(benchmarks/predict_breakdown.py). `--keep DIR`: the stand-in model trained into DIR once and reused.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from io import BytesIO
from pathlib import Path
from typing import Any

import numpy as np

REPO = Path(__file__).resolve().parents[1]
BASELINE = "0a0854f"               # main before issue 26
BATCHES = (1, 32, 1024, 65536)
FITS = {"": (1, 2, 4, 8, 16), "torch_": (32, 64, 128, 256)}   # the fixed cost's fits (new: two paths)
CALLS = {1: 400, 2: 300, 4: 300, 8: 200, 16: 200, 32: 100, 64: 60, 128: 40, 256: 20, 1024: 10, 65536: 2}
IK_MODELS = {"fk_paper": "fk_lstm_mlp", "fk_branch": "fk_lstm_mlp_branch", "ik_paper": "ik_lstm_mlp",
             "ik_refined": "ik_lstm_mlp_refined", "ik_follow": "ik_follow_mlp"}


# --- the worker: one tree's ctrkin, measurements on request ---------------------------------------
def _step_us(kin: Any, xs: np.ndarray, warmup: int = 200, step: Any = None) -> np.ndarray:
    """Per-step times (µs) of `step` (default kin.step) over xs after a warm-up, from a sequence
    start."""
    step = step or kin.step
    kin.reset()
    for x in xs[:warmup]:
        step(x)
    kin.reset()
    ns = np.empty(len(xs))
    clock = time.perf_counter_ns
    for k, x in enumerate(xs):
        t0 = clock()
        step(x)
        ns[k] = clock() - t0
    return ns / 1e3


def _step_and_floor_us(kin: Any, floor: Any, xs: np.ndarray, block: int = 50) -> tuple[float, float]:
    """Medians (µs) of kin.step over xs and of the floor chain, measured in alternating blocks of
    `block` calls (a load burst falls on both alike)."""
    _step_us(kin, xs[:block])
    steps, floors = [], []
    clock = time.perf_counter_ns
    kin.reset()
    for a in range(0, len(xs), block):
        for x in xs[a:a + block]:
            t0 = clock()
            kin.step(x)
            steps.append(clock() - t0)
        for _ in range(block):
            t0 = clock()
            floor()
            floors.append(clock() - t0)
    return float(np.median(steps)) / 1e3, float(np.median(floors)) / 1e3


def _predict_us(kin: Any, rows: np.ndarray, calls: int) -> float:
    """Median time (µs) of one predict call on the sequence `rows`."""
    kin.predict(rows)
    ns = np.empty(calls)
    for k in range(calls):
        t0 = time.perf_counter_ns()
        kin.predict(rows)
        ns[k] = time.perf_counter_ns() - t0
    return float(np.median(ns)) / 1e3


def onnx_worker(model: Path, inputs: Path) -> None:
    """ONNX Runtime (one thread) on the exported graph, as `worker` answers: "predict B" the median
    time (µs) of one run on B windows (3000 runs at B = 1: the step's figure)."""
    import onnxruntime as ort

    from ctrkin.inference import Kinematics, export_onnx

    kin = Kinematics.load(model)
    path = export_onnx(kin, inputs.parent / "fk.onnx")
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = opts.inter_op_num_threads = 1
    sess = ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])
    windows = kin.feature_windows(np.load(inputs)["long"]).astype(np.float32)
    print(json.dumps({"ready": "onnxruntime " + ort.__version__}), flush=True)
    for line in sys.stdin:
        b = int(line.split()[1])
        feed = {"window": np.ascontiguousarray(windows[:b])}
        sess.run(None, feed)
        ns = np.empty(CALLS[b] if b > 1 else 3000)
        for k in range(len(ns)):
            t0 = time.perf_counter_ns()
            sess.run(None, feed)
            ns[k] = time.perf_counter_ns() - t0
        print(json.dumps(float(np.median(ns)) / 1e3), flush=True)


def worker(model: Path, inputs: Path) -> None:
    """Answer one JSON line per request line on stdin: "step" or "predict B"."""
    import torch

    from ctrkin.inference import Kinematics

    torch.set_num_threads(1)
    kin = Kinematics.load(model)
    floor = floor_call(kin, np.float64)[0]
    data = np.load(inputs)
    steps, long = np.ascontiguousarray(data["steps"]), np.ascontiguousarray(data["long"])
    print(json.dumps({"ready": str(Path(sys.modules["ctrkin"].__file__ or "").parent)}), flush=True)
    for line in sys.stdin:
        what, *arg = line.split()
        if what == "step":
            out: Any = _step_and_floor_us(kin, floor, steps)
        elif what == "floor":
            out = [floor_us(model, np.float32)[0], floor_us(model, np.float64, layout=True)[0]]
        else:
            b = int(arg[0])
            out = _predict_us(kin, long[:b], CALLS[b])
        print(json.dumps(out), flush=True)


class Worker:
    """A worker process on one source tree (None: the installed ctrkin)."""

    def __init__(self, src: Path | None, model: Path, inputs: Path, kind: str = "--worker") -> None:
        env = dict(os.environ)
        if src is not None:
            env["PYTHONPATH"] = str(src)
        env["OMP_NUM_THREADS"] = "1"
        self.proc = subprocess.Popen([sys.executable, __file__, kind, str(model), str(inputs)],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)
        self.where = self._read()["ready"]

    def _read(self) -> Any:
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line:
            raise SystemExit(f"a benchmark worker failed (exit {self.proc.wait()})")
        return json.loads(line)

    def ask(self, request: str) -> Any:
        assert self.proc.stdin is not None
        self.proc.stdin.write(request + "\n")
        self.proc.stdin.flush()
        return self._read()

    def close(self) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.close()
        self.proc.wait()


def baseline_tree(rev: str) -> Path:
    """src/ of `rev` extracted once into the temporary directory (reused: its numba cache too)."""
    sha = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", rev], check=True,
                         capture_output=True, text=True).stdout.strip()
    root = Path(tempfile.gettempdir()) / f"ctrkin-bench-{sha}"
    if not (root / "src" / "ctrkin").is_dir():
        blob = subprocess.run(["git", "-C", str(REPO), "archive", sha, "src"], check=True,
                              capture_output=True).stdout
        part = Path(tempfile.mkdtemp(prefix=f".ctrkin-bench-{sha}-", dir=tempfile.gettempdir()))
        with tarfile.open(fileobj=BytesIO(blob)) as tar:
            tar.extractall(part, filter="data")
        part.rename(root)
    return root / "src"


# --- the floors ------------------------------------------------------------------------------------
def _floor_kernel() -> Any:
    from numba import njit

    @njit(cache=True, fastmath=True)
    def chain(x: np.ndarray, w_ih: np.ndarray, w_hh: np.ndarray, b: np.ndarray, h: np.ndarray,
              w1: np.ndarray, b1: np.ndarray, w2: np.ndarray, b2: np.ndarray, gates: np.ndarray,
              z: np.ndarray, hid: np.ndarray, out: np.ndarray) -> None:
        """The step's multiply-adds, nothing else: the LSTM's input and recurrent products for one new
        cell update (the other chain's input product is shared), the Dense layer on the flattened
        window z, the output layer."""
        for k in range(w_ih.shape[0]):
            s = b[k]
            for m in range(w_ih.shape[1]):
                s += w_ih[k, m] * x[m]
            for m in range(w_hh.shape[1]):
                s += w_hh[k, m] * h[m]
            gates[k] = s
        for k in range(w1.shape[0]):
            s = b1[k]
            for m in range(w1.shape[1]):
                s += w1[k, m] * z[m]
            hid[k] = max(s, 0.0)
        for k in range(w2.shape[0]):
            s = b2[k]
            for m in range(w2.shape[1]):
                s += w2[k, m] * hid[m]
            out[k] = s

    return chain


def _layout_floor_kernel() -> Any:
    from numba import njit

    from ctrkin.models.engine import _matvec

    @njit(cache=True, fastmath=True)
    def chain(x: np.ndarray, w_ih: np.ndarray, w_hh: np.ndarray, b: np.ndarray, h: np.ndarray,
              w1: np.ndarray, b1: np.ndarray, w2: np.ndarray, b2: np.ndarray, gates: np.ndarray,
              z: np.ndarray, hid: np.ndarray, out: np.ndarray) -> None:
        """The floor chain's products in the step's layout: the library's own product kernel
        (ctrkin.models.engine._matvec: float32 weights, float64 sums, four rows a pass), the biases
        and the ReLU, nothing else."""
        _matvec(w_ih, x, gates, False)
        _matvec(w_hh, h, gates, True)
        for k in range(gates.size):
            gates[k] += b[k]
        _matvec(w1, z, hid, False)
        for k in range(hid.size):
            hid[k] = max(hid[k] + b1[k], 0.0)
        _matvec(w2, hid, out, False)
        for k in range(out.size):
            out[k] += b2[k]

    return chain


def floor_call(kin: Any, dtype: type, layout: bool = False) -> tuple[Any, int]:
    """The bare chain in `dtype` (or the step's layout) on the weights of `kin` (a call without
    arguments), its multiply-adds."""
    chain, args, macs = floor_parts(kin, dtype, layout)
    return (lambda: chain(*args)), macs


def floor_parts(kin: Any, dtype: type, layout: bool = False) -> tuple[Any, tuple[np.ndarray, ...], int]:
    """The bare chain's compiled kernel, its arguments in `dtype` on the weights of `kin`, its
    multiply-adds. layout: the chain in the streaming step's layout instead (_layout_floor_kernel:
    float32 weight matrices, everything else float64)."""
    net = kin.net
    lstm, dense, out = net.seq[0], net.head[0], net.out
    w = [np.ascontiguousarray(t.detach().numpy(), dtype=dtype) for t in (lstm.weight_ih_l0, lstm.weight_hh_l0,
                                                                         lstm.bias_ih_l0, dense.weight,
                                                                         dense.bias, out.weight, out.bias)]
    if layout:
        w = [a.astype(np.float32) if a.ndim == 2 else a.astype(np.float64) for a in w]
        dtype = np.float64
    rng = np.random.default_rng(0)
    x, h = rng.random(w[0].shape[1]).astype(dtype), rng.random(w[1].shape[1]).astype(dtype)
    z = rng.random(w[3].shape[1]).astype(dtype)
    gates, hid, y = (np.empty(w[k].shape[0], dtype) for k in (0, 3, 5))
    args = (x, w[0], w[1], w[2], h, w[3], w[4], w[5], w[6], gates, z, hid, y)
    chain = _layout_floor_kernel() if layout else _floor_kernel()
    chain(*args)
    return chain, args, w[0].size + w[1].size + w[3].size + w[5].size


def floor_us(model: Path, dtype: type, calls: int = 1000, layout: bool = False) -> tuple[float, int]:
    """Median time (µs) of the bare chain in `dtype` (or the step's layout) with the model's weights,
    and its multiply-adds."""
    from ctrkin.inference import Kinematics

    call, macs = floor_call(Kinematics.load(model), dtype, layout)
    ns = np.empty(calls)
    for k in range(calls):
        t0 = time.perf_counter_ns()
        call()
        ns[k] = time.perf_counter_ns() - t0
    return float(np.median(ns)) / 1e3, macs


# --- the driver ------------------------------------------------------------------------------------
STAND_IN = """
import sys
from ctrkin import paper_robot
from ctrkin.acquisition.demo import sweep_dataset
from ctrkin.training import TrainConfig, train
ds = sweep_dataset(paper_robot(), translations=(8, 14, 20), outer_alphas=(0, 90), step_deg=4, seed=2)
train(ds, TrainConfig(task="fk", max_epochs=1, threads=1, batch_size=256), sys.argv[1], progress=False)
ds.save(sys.argv[1] + "_data")
"""


def stand_in_model(folder: Path, old_src: Path) -> tuple[Path, np.ndarray]:
    """The paper FK network trained one epoch on the demo sweeps (module docstring), and its joints;
    trained by the baseline's code, whose model folders both trees read."""
    from ctrkin.data.dataset import Dataset

    if not (folder / "fk_data").is_dir():
        subprocess.run([sys.executable, "-c", STAND_IN, str(folder / "fk")], check=True,
                       env={**os.environ, "PYTHONPATH": str(old_src)})
    return folder / "fk", Dataset.load(folder / "fk_data").joints()


def run_model(run: Path) -> tuple[Path, np.ndarray]:
    from ctrkin.data.dataset import Dataset

    ds = Dataset.load(run / "data" / "paper")
    return run / "models" / "fk_lstm_mlp", ds.joints()[ds.get_split().test]


def compare(model: Path, joints: np.ndarray, rounds: int, old_src: Path, folder: Path) -> dict[str, Any]:
    """Old and new in alternating rounds (module docstring); the floors and ONNX Runtime."""
    steps = joints[:3000]
    reps = -(-max(BATCHES) // len(joints))
    long = np.tile(joints, (reps, 1))[:max(BATCHES)]          # one valid sequence of 65,536 rows
    np.savez(folder / "inputs.npz", steps=steps, long=long)
    workers = {"old": Worker(old_src, model, folder / "inputs.npz"),
               "new": Worker(REPO / "src", model, folder / "inputs.npz"),
               "onnx": Worker(REPO / "src", model, folder / "inputs.npz", "--onnx-worker")}
    requests = ["step", "floor 32",
                *(f"predict {b}" for b in sorted({*FITS[""], *FITS["torch_"], *BATCHES}))]
    answers: dict[str, dict[str, list[float]]] = {w: {r: [] for r in requests} for w in workers}
    onnx_requests = {f"predict {b}" for b in BATCHES}
    try:
        for r in range(rounds):
            order = ("old", "new", "onnx") if r % 2 == 0 else ("onnx", "new", "old")
            for request in requests:
                for w in order:
                    if request.startswith("floor") and w == "old":
                        continue                    # the floor: measured once a round, beside the steps
                    if w == "onnx" and request not in onnx_requests:
                        continue
                    answers[w][request].append(workers[w].ask(request))
    finally:
        for w in workers.values():
            w.close()
    figures: dict[str, Any] = {}
    onnx = {k: float(np.median(v)) for k, v in answers["onnx"].items() if v}
    for b in BATCHES:
        figures[f"onnx_predictions_per_s_b{b}"] = b / onnx[f"predict {b}"] * 1e6
    figures["onnx_step_us"] = onnx["predict 1"]
    onnx_rounds = answers["onnx"]
    for w in ("old", "new"):             # predictions/s over ONNX Runtime's, round by round (median)
        for b in BATCHES:
            pair = np.array(onnx_rounds[f"predict {b}"]) / np.array(answers[w][f"predict {b}"])
            figures[f"{w}_to_onnx_b{b}"] = float(np.median(pair))
    for w in ("old", "new"):
        got = answers[w]
        pairs = np.array(got.pop("step"))                        # (rounds, 2): step, floor
        med = {k: float(np.median(v)) for k, v in got.items() if v}
        figures[f"{w}_step_to_floor"] = float(np.median(pairs[:, 0] / pairs[:, 1]))   # round by round
        figures[f"{w}_fk_step_us"] = float(np.median(pairs[:, 0]))
        figures[f"{w}_fk_floor_us"] = float(np.median(pairs[:, 1]))
        for b in BATCHES:
            figures[f"{w}_predictions_per_s_b{b}"] = b / med[f"predict {b}"] * 1e6
        for path, sizes in FITS.items():
            slope, intercept = np.polyfit(np.array(sizes, float), [med[f"predict {b}"] for b in sizes], 1)
            figures[f"{w}_predict_{path}call_overhead_us"] = float(intercept)
            figures[f"{w}_predict_{path}per_row_us"] = float(slope)
        figures[f"{w}_predict_b1_us"] = med["predict 1"]
    figures["fk_floor_us"] = figures["new_fk_floor_us"]
    floors = np.array(answers["new"]["floor 32"])                # (rounds, 2): f32, the step's layout
    figures["fk_floor_f32_us"] = float(np.median(floors[:, 0]))
    figures["fk_floor_layout_us"] = float(np.median(floors[:, 1]))
    figures["new_step_to_layout_floor"] = figures["new_fk_step_us"] / figures["fk_floor_layout_us"]
    figures["multiply_adds"] = floor_us(model, np.float64, calls=1)[1]
    figures["fk_step_us"] = figures["new_fk_step_us"]
    figures["predict_call_overhead_us"] = figures["new_predict_call_overhead_us"]
    figures["baseline"] = workers["old"].where
    return figures


def print_table(f: dict[str, Any], rev: str, load: str) -> None:
    print(f"load: {load}")
    print(f"{'':34s} {'old ' + rev:>14s} {'new':>12s} {'floor / ONNX':>14s}")
    print(f"{'FK step µs (median)':34s} {f['old_fk_step_us']:14.2f} {f['new_fk_step_us']:12.2f} "
          f"{f['fk_floor_us']:8.2f} f64 / {f['onnx_step_us']:.2f} ONNX")
    print(f"{'  to the f64 floor (round by round)':34s} {f['old_step_to_floor']:14.2f} "
          f"{f['new_step_to_floor']:12.2f}   (f32 floor {f['fk_floor_f32_us']:.2f} µs, "
          f"{f['multiply_adds']:,} multiply-adds)")
    print(f"{'  to the floor in the step layout':34s} {'':14s} {f['new_step_to_layout_floor']:12.2f}   "
          f"(float32 weights, f64 sums, 4 rows a pass: {f['fk_floor_layout_us']:.2f} µs)")
    for path, sizes in FITS.items():
        what = f"predict fixed cost µs (B={sizes[0]}..{sizes[-1]})"
        print(f"{what:34s} {f[f'old_predict_{path}call_overhead_us']:14.1f} "
              f"{f[f'new_predict_{path}call_overhead_us']:12.1f}   per row "
              f"{f[f'old_predict_{path}per_row_us']:.1f} / {f[f'new_predict_{path}per_row_us']:.1f} µs")
    print(f"{'predict B=1 call µs':34s} {f['old_predict_b1_us']:14.1f} {f['new_predict_b1_us']:12.1f}")
    for b in BATCHES:
        print(f"{f'predictions/s, B = {b:,}':34s} {f[f'old_predictions_per_s_b{b}']:14,.0f} "
              f"{f[f'new_predictions_per_s_b{b}']:12,.0f} {f[f'onnx_predictions_per_s_b{b}']:14,.0f}")
    for b in BATCHES:
        print(f"{f'  ÷ ONNX Runtime, B = {b:,} (by round)':34s} {f[f'old_to_onnx_b{b}']:14.2f} "
              f"{f[f'new_to_onnx_b{b}']:12.2f}")


def reproduction_table(run: Path, steps: int, rounds: int) -> dict[str, float]:
    """Issue 8's table: the streaming step of each learned model of a reproduction; for the FK
    models also the cost of the face (issue 27): the step through `Kinematics.step` and directly on
    its family's predictor in alternating rounds, and the median of the rounds' differences."""
    from ctrkin.data.dataset import Dataset
    from ctrkin.inference import Kinematics

    ds = Dataset.load(run / "data" / "paper")
    test = ds.get_split().test
    inputs = {"fk": ds.joints()[test], "ik": ds.poses()[test]}
    figures: dict[str, float] = {}
    print(f"{'model':28s} {'median µs':>10s} {'p95 µs':>10s} {'steps':>7s}")
    for key, name in IK_MODELS.items():
        if not (run / "models" / name).is_dir():
            print(f"{name:28s} (not in this run)")
            continue
        kin = Kinematics.load(run / "models" / name)
        n = steps // 5 if key == "ik_refined" else steps
        us = _step_us(kin, np.ascontiguousarray(inputs[kin.task][:n]))
        figures[f"{key}_step_us_median"] = float(np.median(us))
        figures[f"{key}_step_us_p95"] = float(np.quantile(us, 0.95))
        print(f"{name:28s} {np.median(us):10.1f} {np.quantile(us, 0.95):10.1f} {n:7d}")
        if kin.task == "fk" and rounds and hasattr(kin, "predictor"):
            xs = np.ascontiguousarray(inputs["fk"][:n])
            own = kin.predictor.step
            diffs = [float(np.median(_step_us(kin, xs)) - np.median(_step_us(kin, xs, step=own)))
                     for _ in range(rounds)]
            figures[f"{key}_face_us_median"] = float(np.median(diffs))
            print(f"{'':28s} through Kinematics: {np.median(diffs):+.2f} µs (median of {rounds} rounds)")
    return figures


def breakdown(model: Path, xs: np.ndarray, rounds: int) -> None:
    """The step's layers and the kernel's pieces against the floor (streaming_breakdown.py): a table
    and one JSON line."""
    from ctrkin.inference import Kinematics

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import streaming_breakdown as sb

    kin = Kinematics.load(model)
    chain, args, _ = floor_parts(kin, np.float64)
    load_before = os.getloadavg()
    us, ratio = sb.measure(sb.variants(kin, xs, lambda: chain(*args), args, chain), rounds)
    print("load:", subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip())
    figures = {"breakdown_us": sb.table(us, ratio), "step_to_floor": ratio["Kinematics.step"],
               "load_1min": [load_before[0], os.getloadavg()[0]]}
    print(json.dumps(figures))


def predict_breakdown_worker(model: Path, inputs: Path, b: int, rounds: int) -> None:
    """This process's tree: a predict call of b rows split into its pieces (predict_breakdown.py),
    one JSON line of µs by piece."""
    import torch

    from ctrkin.inference import Kinematics

    torch.set_num_threads(1)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import predict_breakdown as pb

    joints = np.load(inputs)["long"]
    rows = np.ascontiguousarray(np.tile(joints, (-(-b // len(joints)), 1))[:b])
    print(json.dumps(pb.measure(pb.variants(Kinematics.load(model), rows), rounds)), flush=True)


def predict_breakdown(model: Path, joints: np.ndarray, b: int, rounds: int, old_src: Path, folder: Path
                      ) -> None:
    """A predict call of b rows split into its pieces, the old tree's and this one's, each in a worker
    process, twice in alternation (predict_breakdown.py): a table and one JSON line."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import predict_breakdown as pb

    np.savez(folder / "inputs.npz", long=joints)
    load_before = os.getloadavg()
    runs: dict[str, list[dict[str, float]]] = {"old": [], "new": []}
    for order in (("old", "new"), ("new", "old")):
        for w in order:
            src = old_src if w == "old" else REPO / "src"
            env = {**os.environ, "PYTHONPATH": str(src), "OMP_NUM_THREADS": "1"}
            done = subprocess.run([sys.executable, __file__, "--predict-breakdown-worker", str(model),
                                   str(folder / "inputs.npz"), str(b), str(rounds)],
                                  env=env, capture_output=True, text=True)
            if done.returncode != 0:
                raise SystemExit(f"the {w} tree's breakdown worker failed ({src}):\n{done.stderr}")
            runs[w].append(json.loads(done.stdout.strip().splitlines()[-1]))
    us = {w: {k: float(np.median([r[k] for r in got])) for k in got[0]} for w, got in runs.items()}
    print("load:", subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip())
    figures = {"predict_breakdown_us": pb.table(us, b), "batch": b,
               "load_1min": [load_before[0], os.getloadavg()[0]]}
    print(json.dumps(figures))


def main() -> None:
    if len(sys.argv) == 4 and sys.argv[1] in ("--worker", "--onnx-worker"):
        (worker if sys.argv[1] == "--worker" else onnx_worker)(Path(sys.argv[2]), Path(sys.argv[3]))
        return
    if len(sys.argv) == 6 and sys.argv[1] == "--predict-breakdown-worker":
        predict_breakdown_worker(Path(sys.argv[2]), Path(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]))
        return
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", type=Path, default=None, help="a `ctrkin reproduce` folder (default: stand-in)")
    ap.add_argument("--baseline", default=BASELINE, help="the old code's git revision")
    ap.add_argument("--rounds", type=int, default=5,
                    help="alternating old/new rounds (and face / predictor rounds with --all-models)")
    ap.add_argument("--all-models", action="store_true", help="with --run: every model's step (issue 8)")
    ap.add_argument("--steps", type=int, default=3000, help="--all-models: steps per model")
    ap.add_argument("--keep", type=Path, default=None,
                    help="train the stand-in model into this folder once and reuse it in later runs")
    ap.add_argument("--breakdown", action="store_true",
                    help="only where the step's distance from its floor goes, this tree's code "
                         "(streaming_breakdown.py)")
    ap.add_argument("--breakdown-predict", type=int, default=None, metavar="B",
                    help="only where a predict call of B rows spends its time, the baseline's code "
                         "and this tree's (predict_breakdown.py)")
    args = ap.parse_args()
    import torch

    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory(prefix="bench_streaming_") as tmp:
        folder = Path(tmp)
        if args.run is not None and not (args.run / "models").is_dir():
            raise SystemExit(f"{args.run}/models not found: run `ctrkin reproduce --out {args.run}` first")
        old_src = baseline_tree(args.baseline)
        model, joints = (run_model(args.run) if args.run is not None
                         else stand_in_model(args.keep or folder, old_src))
        if args.breakdown:
            breakdown(model, np.ascontiguousarray(joints[:3000], dtype=np.float64), args.rounds)
            return
        if args.breakdown_predict is not None:
            predict_breakdown(model, np.ascontiguousarray(joints, dtype=np.float64), args.breakdown_predict,
                              args.rounds, old_src, folder)
            return
        figures: dict[str, Any] = {}
        if args.all_models and args.run is not None:
            figures.update(reproduction_table(args.run, args.steps, args.rounds))
        load_before = os.getloadavg()
        figures.update(compare(model, np.ascontiguousarray(joints, dtype=np.float64), args.rounds, old_src,
                               folder))
        load = os.getloadavg()
        uptime = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
        figures["load_1min"] = [load_before[0], load[0]]
        figures["fk_step_to_floor"] = figures["new_step_to_floor"]
        print_table(figures, args.baseline, uptime)
        print(json.dumps(figures))


if __name__ == "__main__":
    main()
