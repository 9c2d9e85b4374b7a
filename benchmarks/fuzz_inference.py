"""The inference classes of issue 27 (items 10-13, 16, 21, 24) for benchmarks/fuzz.py.

The areas fk_predict, fk_step and ik draw part of their inputs here (`fk_predict_input`,
`fk_step_input`, `ik_input`): labelled frames in another column order (read by name, or refused for
a missing column), ragged lists, interleaved sequence ids, empty batches, IK targets whose quaternion
is not unit, a follow IK's start joints with absurd angles, and the exported ONNX graph fed
non-finite rows and an empty batch (in a forked child: on the starting code ONNX Runtime aborted the
process). The area `interleaved` streams a sequence with other calls between its steps: batch
predicts of other sequences, a predict refused for its input, a step or a reset from a second
thread, a copy's stream; the stream must end as the uninterrupted one and the second thread must be
refused. Oracles raise `Silent`; an expected refusal is a CtrkinError (counted `clear`).
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import signal
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ctrkin.errors import CtrkinError
from ctrkin.inference import Kinematics, export_onnx
from ctrkin.training import TrainConfig, train

COUNTS = {"interleaved": 600}      # inputs at scale 1 of the area of this module
POSE = ["x", "y", "z", "q0", "qx", "qy"]


class Silent(Exception):
    """The oracle rejects a result that came back without a flag."""


def setup(ctx: dict[str, Any], seed: int) -> None:
    """A follow IK of two epochs and the FK and IK models' ONNX sessions (≈ 5 s)."""
    import onnxruntime as ort

    tmp: Path = ctx["tmp"]
    cfg = TrainConfig(task="ik", model="follow_mlp", max_epochs=2, threads=1, options={"structure": "|D16"},
                      seed=seed)
    with contextlib.redirect_stdout(io.StringIO()):
        train(ctx["dataset"], cfg, tmp / "follow", progress=False)
    ctx["follow"] = Kinematics.load(tmp / "follow")
    for name in ("fk", "ik"):
        path = export_onnx(ctx[name], tmp / f"{name}.onnx")
        ctx[f"{name}_onnx"] = path
        ctx[f"{name}_session"] = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    ctx["fk_seqs"] = [ctx["dataset"].joints()[a:b] for a, b in ctx["dataset"].sequence_bounds()]
    ctx["ik_seqs"] = [ctx["dataset"].poses()[a:b] for a, b in ctx["dataset"].sequence_bounds()]
    # every model's first batch and step compile numba kernels (seconds on a cold cache): done here,
    # so that no timed input pays for them (a cold cache made the first FK input a 10 s "hang")
    for name, data in (("fk", ctx["fk_seqs"][0][:4]), ("ik", ctx["ik_seqs"][0][:4]),
                       ("follow", ctx["ik_seqs"][0][:4])):
        kin = ctx[name]
        for rows in (data, np.ascontiguousarray(data)):    # numba compiles each memory layout apart
            kin.predict(rows)
            kin.reset()
            for row in rows:
                kin.step(row)
            kin.reset()


def _refused(what: str, fn: Any) -> str:
    """fn() must raise a CtrkinError (returns 'clear'); an answer is silent."""
    try:
        fn()
    except CtrkinError:
        return "clear"
    raise Silent(f"{what} was accepted")


def _interleaved_ids(rng: np.random.Generator, m: int) -> np.ndarray:
    """(m,) sequence ids in which some id starts again after another (m >= 3)."""
    k = int(rng.integers(2, max(3, m // 2) + 1))
    sid = np.sort(rng.integers(0, k, m))
    sid[0], sid[-2], sid[-1] = 0, max(sid[-2], 1), 0     # the first sequence comes back at the end
    if rng.random() < 0.5:
        sid = np.tile([0, 1], m)[:m]                      # the campaign's 0, 1, 0, 1, ...
    return sid


def _labelled(rng: np.random.Generator, raw: np.ndarray, names: list[str]) -> pd.DataFrame:
    """raw (T, W) as a DataFrame with its columns named and shuffled, maybe an extra column."""
    frame = pd.DataFrame(raw, columns=names)
    frame = frame[list(rng.permutation(names))]
    if rng.random() < 0.3:
        frame.insert(int(rng.integers(len(names) + 1)), "note", 1.0)
    return frame


def _run_in_child(fn: Any) -> int:
    """Run fn() in a forked child; its exit status (0: returned, 1: raised) or −signal if it died."""
    pid = os.fork()
    if pid == 0:                                                           # child
        code = 1
        try:
            fn()
            code = 0
        finally:
            os._exit(code)
    try:
        status = os.waitpid(pid, 0)[1]
    except BaseException:           # a hang: the child goes with it
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        raise
    return -os.WTERMSIG(status) if os.WIFSIGNALED(status) else os.WEXITSTATUS(status)


def _some_joints(rng: np.random.Generator, ctx: dict[str, Any]) -> np.ndarray:
    """(2N,) the joints of a random row of the dataset."""
    joints = ctx["dataset"].joints()
    return np.asarray(joints[int(rng.integers(len(joints)))])


# --- fk_predict ------------------------------------------------------------------------------------
def fk_predict_input(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    fk: Kinematics = ctx["fk"]
    Q = ctx["fk_seqs"][int(rng.integers(len(ctx["fk_seqs"])))][: int(rng.integers(3, 30))]
    names = list(fk.robot.joint_names())
    kind = int(rng.integers(7))
    if kind == 0:
        got = fk.predict(_labelled(rng, Q, names))
        if not np.array_equal(got, fk.predict(Q)):
            raise Silent("FK read a labelled DataFrame by position")
        return "ok"
    if kind == 1:
        frame = pd.DataFrame(Q, columns=names).drop(columns=[str(rng.choice(names))])
        return _refused("a DataFrame without a joint column", lambda: fk.predict(frame))
    if kind == 2:
        rows = [list(q) for q in Q]
        rows[int(rng.integers(len(rows)))] = rows[0][: int(rng.integers(0, len(names)))]
        return _refused("a ragged list", lambda: fk.predict(rows))
    if kind == 3:
        sid = _interleaved_ids(rng, len(Q))
        return _refused("interleaved sequence ids", lambda: fk.predict(Q, sequence_id=sid))
    if kind == 4:
        if fk.predict(Q[:0]).shape != (0, 6):
            raise Silent("an empty batch gave rows")
        return "ok"
    if kind == 5:
        return _onnx_rows(rng, ctx, "fk", Q)
    return _onnx_empty(ctx, "fk")


def _onnx_rows(rng: np.random.Generator, ctx: dict[str, Any], name: str, raw: np.ndarray) -> str:
    """Non-finite rows of the exported graph give NaN; the others what predict gives."""
    kin: Kinematics = ctx[name]
    windows = kin.feature_windows(raw).astype(np.float32)
    bad = rng.random(len(windows)) < 0.3
    for r in np.nonzero(bad)[0]:
        value = [math.nan, math.inf, -math.inf][int(rng.integers(3))]
        if rng.random() < 0.5:
            windows[r] = value
        else:
            windows[r, int(rng.integers(kin.ib)), int(rng.integers(windows.shape[2]))] = value
    out = ctx[f"{name}_session"].run(None, {"window": windows})[0].astype(np.float64)
    if np.isfinite(out[bad]).any():
        raise Silent(f"the ONNX graph gave a finite answer for {int(bad.sum())} non-finite window(s)")
    ref, scale = kin.predict(raw), 1.0
    if kin.task == "ik":            # the graph gives the network's joints; predict projects them
        ref, scale, out = ref.joints, kin.bundle.y_norm.span, kin.robot.project_joints(out)
    if np.abs((out[~bad] - ref[~bad]) / scale).max(initial=0.0) > 1e-3:
        raise Silent("the ONNX graph's finite rows differ from predict")
    return "flagged" if bad.any() else "ok"


def _onnx_empty(ctx: dict[str, Any], name: str) -> str:
    """An empty batch through the exported graph: an empty output, the process alive."""
    import onnxruntime as ort

    path = ctx[f"{name}_onnx"]
    kin: Kinematics = ctx[name]

    def run() -> None:
        sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
        out = sess.run(None, {"window": np.zeros((0, kin.ib, kin.layout.n_inputs), np.float32)})[0]
        if out.shape != (0, kin.layout.n_outputs):
            raise Silent(f"an empty ONNX batch gave shape {out.shape}")

    status = _run_in_child(run)
    if status < 0:
        raise RuntimeError(f"ONNX Runtime killed the process (signal {-status}) on an empty batch")
    if status:
        raise Silent("an empty ONNX batch failed or gave rows")
    return "ok"


# --- fk_step ---------------------------------------------------------------------------------------
def fk_step_input(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    fk: Kinematics = ctx["fk"]
    Q = ctx["fk_seqs"][int(rng.integers(len(ctx["fk_seqs"])))][: int(rng.integers(2, 20))]
    names = list(fk.robot.joint_names())
    fk.reset()
    clean = np.array([fk.step(q) for q in Q])
    if rng.random() < 0.6:
        frame = _labelled(rng, Q, names)
        fk.reset()
        got = np.array([fk.step(frame.iloc[t]) for t in range(len(Q))])
        if np.abs(got - clean).max() > 1e-9:
            raise Silent("FK step read a labelled row by position")
        return "ok"
    fk.reset()
    nested = [list(Q[0][:2]), list(Q[0][2:])] if rng.random() < 0.5 else [Q[0].tolist(), [1.0]]
    return _refused("a nested joint list", lambda: fk.step(nested))


# --- ik --------------------------------------------------------------------------------------------
def ik_input(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    ik: Kinematics = ctx["follow"] if rng.random() < 0.5 else ctx["ik"]
    seqs = ctx["ik_seqs"]
    T = seqs[int(rng.integers(len(seqs)))][: int(rng.integers(3, 12))].copy()
    follow = "start_joints" in ik.predictor.accepts["predict"]
    kind = int(rng.integers(6))
    if kind == 0:                                  # a quaternion that names no direction
        r = int(rng.integers(len(T)))
        T[r, 3:] = [(0.0, 0.0, 0.0), (1e-9, 0.0, 0.0), (0.5, 0.1, 0.0), (2.0, 0.0, 1.0)][int(rng.integers(4))]
        if rng.random() < 0.5:
            return _refused("an IK target without a unit quaternion", lambda: ik.predict(T))
        ik.reset()
        for t in range(r):
            ik.step(T[t])
        return _refused("an IK target without a unit quaternion (step)", lambda: ik.step(T[r]))
    if kind == 1:
        got = ik.predict(_labelled(rng, T, POSE)).joints
        if not np.array_equal(got, ik.predict(T).joints):
            raise Silent("IK read a labelled DataFrame by position")
        return "ok"
    if kind == 2 and follow:                       # start joints as every joint input is checked
        start = _some_joints(rng, ctx).copy()
        absurd = [1e300, -1e12, 1e10, math.nan, math.inf]
        start[int(rng.integers(ik.layout.n_tubes))] = absurd[int(rng.integers(len(absurd)))]
        what = "follow IK start joints with an absurd α"
        if rng.random() < 0.5:
            return _refused(what, lambda: ik.predict(T, start_joints=start))
        return _refused(f"{what} (reset)", lambda: ik.reset(start))
    if kind == 3 and len(T) >= 3:
        sid = _interleaved_ids(rng, len(T))
        return _refused("interleaved sequence ids", lambda: ik.predict(T, sequence_id=sid))
    if kind == 4:
        if ik.predict(T[:0]).joints.shape != (0, 2 * ik.layout.n_tubes):
            raise Silent("an empty IK batch gave rows")
        return "ok"
    return _onnx_rows(rng, ctx, "ik", T) if kind == 5 else "ok"


# --- interleaved calls -----------------------------------------------------------------------------
def _in_thread(fn: Any) -> object:
    out: list[object] = []

    def run() -> None:
        try:
            out.append(fn())
        except Exception as e:  # handed back
            out.append(e)

    t = threading.Thread(target=run)
    t.start()
    t.join()
    return out[0]


def case_interleaved(rng: np.random.Generator, ctx: dict[str, Any]) -> str:
    """Stream a sequence with other calls between its steps; it must end as the clean stream, and a
    second thread's step or reset must be refused."""
    kin: Kinematics = ctx[str(rng.choice(["fk", "ik", "follow"]))]
    seqs = ctx["fk_seqs"] if kin.task == "fk" else ctx["ik_seqs"]
    xs = seqs[int(rng.integers(len(seqs)))][: int(rng.integers(4, 16))]
    other = seqs[int(rng.integers(len(seqs)))][: int(rng.integers(1, 20))]

    def answer(x: np.ndarray) -> np.ndarray:
        r = kin.step(x)
        return np.asarray(r) if kin.task == "fk" else np.asarray(r.joints)

    kin.reset()
    clean = np.array([answer(x) for x in xs])
    kin.reset()
    got, done = [], []
    for x in xs:
        got.append(answer(x))
        op = int(rng.integers(6))
        if op == 0:
            kin.predict(other)
        elif op == 1 and "start_joints" in kin.predictor.accepts["predict"]:
            kin.predict(other, start_joints=_some_joints(rng, ctx))
        elif op == 2 and len(other) >= 3:
            with contextlib.suppress(CtrkinError):
                kin.predict(other, sequence_id=_interleaved_ids(rng, len(other)))
        elif op == 3:
            res = _in_thread(lambda: kin.step(other[0]))
            if not isinstance(res, CtrkinError):
                raise Silent(f"a second thread's step was taken into the stream ({type(res).__name__})")
        elif op == 4:
            if not isinstance(_in_thread(kin.reset), CtrkinError):
                raise Silent("a second thread reset the stream of another")
        else:                         # a second stream of the model (before issue 27: a second load)
            twin = kin.copy() if hasattr(type(kin), "copy") else Kinematics.load(kin.path)
            for y in other[:3]:
                twin.step(y)
        done.append(op)
    if np.abs(np.array(got) - clean).max() > 1e-9:
        raise Silent(f"the stream changed with calls {done} between its steps")
    return "ok"


CASES = {"interleaved": case_interleaved}
