"""The FK streaming step in one numba call (issue 8, goal 4: an FK step ≤ 30 µs on one core).

Why: an FK step on the reference path (FKPredictor.step) runs the input guards, the features, the engine's
kernels (one call per layer), the fold gate and the frame rotation as a dozen Python-level calls.
Each costs 0.5–5 µs of dispatch, attribute look-ups and small allocations; together they cost more
than the network's arithmetic (profile, paper robot, one core: engine 19 µs of which the LSTM
kernel 9 µs, to_world_one 4.6 µs, guards 3.8 µs, fold gate 1.4 µs). Here the whole step of an
LSTM-MLP FK model (the paper's fk_lstm_mlp, the snap-aware fk_lstm_mlp_branch) is one compiled
function that calls the same kernels in the same order on the same state:
engine._lstm_rows, engine._push_history, engine._dense_rows, relay.gate_step, frame.pose_to_world.
It therefore returns the reference path's numbers to the last bit (tests/models/test_fused.py).

Scope: an FK model whose network is one LSTM layer followed by one or more Dense layers (the "Lh|Dk…"
structures, the paper's L128|D64 included), minmax or phase angle encoding, with or without the
outer-tube frame, a model with a branch state from a tabulated relay (the snap-aware model's fold
gate, ctrkin.models.relay, with its slide memory where it has one) or from its learned gate, with or
without play-lag inputs (ctrkin.models.play_lags; not with equivariant inputs), with or without the
frame's position field (ctrkin.models.field: added after the compiled step, by the kernel the
reference path adds it with).
Other models, and any step
that the fast checks do not pass (a joint the robot cannot take, a rotation outside the trained
range, NaN), go through the reference path, which raises with its message; a declined step has
touched nothing.

State: the streaming state stays where the reference path keeps it (FKPredictor: previous joints,
whole-turn shift, relay state; StreamingEngine: the LSTM chains, their history and the branch state;
the play operators' outputs are PlayState's buffer, a piece of this one's),
so both paths can alternate within one sequence and `probe()` sees the same history.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from ctrkin.models.engine import StreamingEngine, _dense_rows, _lstm_rows, _push_history
from ctrkin.models.feature_row import paper_feature_row
from ctrkin.models.frame import OuterFrame, pose_to_world
from ctrkin.models.guards import MAX_ABS_ALPHA_DEG, TURN_DEG, FKGuard
from ctrkin.models.play_lags import input_operators, play_step, slide_operators
from ctrkin.models.relay import GateTables, gate_step
from ctrkin.models.seqnet import UNKNOWN_STATE
from ctrkin.models.store import ModelBundle
from ctrkin.robots.robot import JOINT_TOL

GATE_NONE, GATE_FOLD, GATE_LEARNED = 0, 1, 2
DECLINED = -2          # the step's status when the fast checks fail (nothing was changed)


class Clip(NamedTuple):
    """The step-change feature columns and their trained range (FKPredictor.clip_deltas)."""

    columns: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


class Relay(NamedTuple):
    """A tabulated relay for the branch state (ctrkin.models.relay): its grid and (c, κ, band) deg."""

    tables: GateTables
    widen_deg: float
    outer_lag_deg: float
    band_deg: float
    slide_weights: tuple[float, ...] = ()     # a fold gate's slide memory u (deg), () none


@njit(cache=True)
def _joints_ok(raw: np.ndarray, shift: np.ndarray, n: int, lengths: np.ndarray, alpha_lo: np.ndarray,
               alpha_hi: np.ndarray) -> bool:
    """FKGuard._fast_ok with Robot._valid_single: finite joints the robot can take (βN ≤ 0, tips
    ahead of the plate, tubes nested), |α| ≤ 1e9 and α − shift within the trained range ± a turn."""
    for v in raw:
        if not math.isfinite(v):
            return False
    if raw[2 * n - 1] > JOINT_TOL or raw[2 * n - 1] + lengths[n - 1] < -JOINT_TOL:
        return False
    for i in range(n - 1):
        if not (raw[n + i] <= raw[n + i + 1] + JOINT_TOL
                and raw[n + i] + lengths[i] >= raw[n + i + 1] + lengths[i + 1] - JOINT_TOL):
            return False
    for i in range(n):
        if abs(raw[i]) > MAX_ABS_ALPHA_DEG or not (alpha_lo[i] <= raw[i] - shift[i] <= alpha_hi[i]):
            return False
    return True


# The constants and the state of one model reach the kernel as four flat buffers (`_Packed`): a numba
# call unboxes each array argument and types each tuple element, which for the three dozen arrays of a
# step cost as much as the network's arithmetic (issue 26: 2.2 of 15 µs quiet, 7.7 of 35 µs at load
# 7), and each array it allocates costs an allocation and a free. Piece k of a buffer is
# buf[o:o + d0·d1·d2] as shape (d0[, d1[, d2]]), with (o, d0, d1, d2) = directory[4k:4k + 4]; every
# view is C-contiguous, so the kernels run the same specialisations (and give the same bits) as on the
# engine's own arrays. The int64 buffer starts with the model's settings (cfg) and the four
# directories, then its own pieces.
# constants (float64): guard, normalisation, the network's biases, gate tables, registration, the play
# operators' widths and inputs (ctrkin.models.play_lags.input_operators), the fold gate's slide memory
# (its play operators' widths and inputs, its weights u); head layer l's biases at HEAD_B + l
(LENGTHS, ALPHA_LO, ALPHA_HI, XLO, XSPAN, CLIP_LO, CLIP_HI, YLO, YSPAN, BIAS, OUT_B,
 GATE_W0, GATE_W1, GATE_B0, GATE_B1, T_AXES, T_FORWARD, T_BACKWARD, ROT, TRANS, GATE_CONSTS, TRAIN_LO,
 TRAIN_HI, PLAY_W, PLAY_SRC, GATE_PLAY_W, GATE_PLAY_SRC, GATE_SLIDE_U, HEAD_B) = range(29)
# the weight matrices (float32, as the engine keeps them: ctrkin.models.engine._f32): the LSTM's
# input and recurrent weights, the output layer's, head layer l's at W_HEAD + l
(W_IH, W_HH, OUT_W, W_HEAD) = range(4)
# the streaming state (float64; the engine's arrays are views of it), the step's previous joints as
# the network saw them, its result and its scratch (predict's rows: SHIFT, PREV_IN), the play
# operators' outputs and at-rest flag (PlayState's buffer), the slide memory's likewise and its lags'
# scratch; head layer l's output buffer at HEAD_OUT + l
(H, C, H2, C2, G, T, HIST, X, PREV, Q, Y, LOCAL, YN, ZS, G1, G2, SHIFT, PREV_IN, PLAY_Y, GATE_PLAY_Y,
 GATE_LAGS, HEAD_OUT) = range(22)
# the int64 buffer's pieces: the gate tables' start and size, the sigmoid's scratch
T_START, T_SIZE, BITS = range(3)
# the model's settings at the int64 buffer's start, then where each directory starts (C_DIR, S_DIR,
# W_DIR, I_DIR) and ends (END_DIR)
(N_TUBES, PHASE, DELTA, FLATTEN, RELU_OUT, GATE_KIND, OUTER_FRAME, HAS_LAG, LAGGED_INPUTS, N_PLAY,
 N_GATE_PLAY, N_HEAD, C_DIR, S_DIR, W_DIR, I_DIR, END_DIR, N_CFG) = range(18)


# explicit signatures: one compiled version each, not one per piece number (numba would otherwise
# specialise on each literal k)
@njit(["float64[::1](float64[::1], int64[::1], int64)", "float32[::1](float32[::1], int64[::1], int64)",
       "int64[::1](int64[::1], int64[::1], int64)"], cache=True)
def _piece(buf, where, k):
    """The flat view of piece k of buf (its shape: `where` at 4k + 1..3)."""
    o = where[4 * k]
    return buf[o:o + where[4 * k + 1] * where[4 * k + 2] * where[4 * k + 3]]


@njit(["float64[:, ::1](float64[::1], int64[::1], int64)",
       "float32[:, ::1](float32[::1], int64[::1], int64)"], cache=True)
def _v2(buf, where, k):
    return _piece(buf, where, k).reshape((where[4 * k + 1], where[4 * k + 2]))


@njit(["float64[:, :, ::1](float64[::1], int64[::1], int64)",
       "float32[:, :, ::1](float32[::1], int64[::1], int64)"], cache=True)
def _v3(buf, where, k):
    return _piece(buf, where, k).reshape((where[4 * k + 1], where[4 * k + 2], where[4 * k + 3]))


@njit(cache=True)
def _fk_step(raw, shift, prev, consts, weights, state, ints, started, fresh, branch, gate_state, motion,
             outer_prev, lag):
    """One FK step: joints raw (2N,) (deg, mm, as given) -> the (6,) tracker-frame pose in the state
    buffer's piece Y. Returns (gate state, m_N, αN, branch state) or a gate state DECLINED (nothing
    changed).

    shift (2N,): the sequence's whole turns; prev (2N,): the previous shifted joints (if `started`);
    the state's piece PREV receives this step's (as the network sees them). consts, weights, state,
    ints: the flat buffers (module comment above); cfg (the start of ints): N, phase, delta, flatten,
    relu output, gate kind, outer frame, its lag, its lagged inputs, Dense layers, the directories.
    The constants: the guard (lengths, α lo, α hi), normalisation (x lo, x span, clip lo, clip hi,
    y lo, y span), the LSTM's bias b, per Dense layer the biases (B, out) for B branches and the
    output layer's likewise (the weights: the LSTM's w_ih, w_hh, as the StreamingEngine's, per Dense
    layer (B, out, in) and the output layer likewise), the learned gate's two layers, the fold
    gate's GateTables and (c, κ, band), the outer frame's registration (rot, trans). The state: the
    LSTM chains h, c (scratch h2, c2, g, t, bits), the history hist and the input row x (1, F) of the
    StreamingEngine; fresh: the sequence's first step. lag: the outer frame's λ(β) (deg) here."""
    cwhere, swhere = ints[ints[C_DIR]:ints[S_DIR]], ints[ints[S_DIR]:ints[W_DIR]]
    wwhere, iwhere = ints[ints[W_DIR]:ints[I_DIR]], ints[ints[I_DIR]:ints[END_DIR]]
    n, gate_kind = ints[N_TUBES], ints[GATE_KIND]
    phase, delta = ints[PHASE] != 0, ints[DELTA] != 0
    flatten, relu_out = ints[FLATTEN] != 0, ints[RELU_OUT] != 0
    outer_frame, has_lag, lagged_inputs = ints[OUTER_FRAME] != 0, ints[HAS_LAG] != 0, ints[LAGGED_INPUTS] != 0
    if not _joints_ok(raw, shift, n, _piece(consts, cwhere, LENGTHS), _piece(consts, cwhere, ALPHA_LO),
                      _piece(consts, cwhere, ALPHA_HI)):
        return DECLINED, motion, outer_prev, branch
    xlo, xspan = _piece(consts, cwhere, XLO), _piece(consts, cwhere, XSPAN)
    clip_lo, clip_hi = _piece(consts, cwhere, CLIP_LO), _piece(consts, cwhere, CLIP_HI)
    ylo, yspan = _piece(consts, cwhere, YLO), _piece(consts, cwhere, YSPAN)
    q = _piece(state, swhere, Q)
    for j in range(q.size):
        q[j] = raw[j] - shift[j]
    a0_cmd = q[0] - q[n - 1]                    # the commanded α0: the fold gate's input
    # m_N from αN as given (FKPredictor._motion_after), followed by the fold gate or the lagged frame
    if gate_kind == GATE_FOLD or has_lag:
        a_n = raw[n - 1]
        if not math.isnan(outer_prev) and abs(a_n - outer_prev) > 1e-9:
            motion = 1 if a_n > outer_prev else -1
        outer_prev = a_n
    outer = q[n - 1] - lag * motion if has_lag else q[n - 1]    # the frame's angle (FKPredictor._step_angle)
    if lagged_inputs:                           # the network sees it as αN (OuterFrame.network_joints)
        q[n - 1] = outer
    # features (ctrkin.models.features: α, β, α0, [sin α0, cos α0], Δα0), clipped and normalised
    x = _v2(state, swhere, X)
    f = x[0]
    prev_a0 = prev[0] - prev[n - 1] if started else 0.0
    paper_feature_row(q, n, prev_a0, started, phase, delta, f)
    n_play = ints[N_PLAY]
    if n_play:                  # the play lags of the joints as given (PlayState.after, then advance)
        play_step(raw, n, _piece(consts, cwhere, PLAY_W), _piece(consts, cwhere, PLAY_SRC),
                  _piece(state, swhere, PLAY_Y), f[f.size - n_play:])
    _piece(state, swhere, PREV)[:] = q
    for j in range(f.size):
        f[j] = (min(max(f[j], clip_lo[j]), clip_hi[j]) - xlo[j]) / xspan[j]
    if gate_kind == GATE_FOLD:          # the relay on the shifted joints (SnapAwarePredictor._fold_step)
        gc = _piece(consts, cwhere, GATE_CONSTS)
        widen = gc[0]
        n_slide = ints[N_GATE_PLAY]
        if n_slide:             # the slide memory: w = c − Σ u_k |ℓ_k| (FoldGate.widen, same order)
            ell = _piece(state, swhere, GATE_LAGS)
            play_step(raw, n, _piece(consts, cwhere, GATE_PLAY_W), _piece(consts, cwhere, GATE_PLAY_SRC),
                      _piece(state, swhere, GATE_PLAY_Y), ell)
            u = _piece(consts, cwhere, GATE_SLIDE_U)
            total = 0.0
            for k in range(n_slide):
                total += u[k] * abs(ell[k])
            widen = gc[0] - total
        gate_state = gate_step(gate_state, a0_cmd, q[n:], float(motion), _piece(consts, cwhere, T_AXES),
                               _piece(ints, iwhere, T_START), _piece(ints, iwhere, T_SIZE),
                               _piece(consts, cwhere, T_FORWARD), _piece(consts, cwhere, T_BACKWARD),
                               widen, gc[1], gc[2])
        branch = 1.0 if gate_state > 0.5 else 0.0
    # the engine (StreamingEngine.step, one LSTM layer): a fresh sequence feeds its first step IB times
    w_ih, w_hh, b = _v2(weights, wwhere, W_IH), _v2(weights, wwhere, W_HH), _piece(consts, cwhere, BIAS)
    h, c = _v2(state, swhere, H), _v2(state, swhere, C)
    h2, c2 = _v2(state, swhere, H2), _v2(state, swhere, C2)
    g, t, bits = _v2(state, swhere, G), _v2(state, swhere, T), _piece(ints, iwhere, BITS)
    hist = _v3(state, swhere, HIST)
    ib = hist.shape[0]
    for live in range(1 if fresh else ib, ib + 1):     # a sequence's start: IB updates, chain by chain
        _lstm_rows(x, True, w_ih, w_hh, b, h, c, h2, c2, g, t, bits, live)
        _push_history(hist, h, False)
    window = hist[ib - 1]
    z = window.reshape((1, window.size)) if flatten else window[ib - 1:]
    if gate_kind == GATE_LEARNED:                                    # StreamingEngine._head
        zs, g1, g2 = _v2(state, swhere, ZS), _v2(state, swhere, G1), _v2(state, swhere, G2)
        zs[0, :-1] = z[0]
        zs[0, -1] = branch
        _dense_rows(zs, _v2(consts, cwhere, GATE_W0), _piece(consts, cwhere, GATE_B0), g1, True)
        _dense_rows(g1, _v2(consts, cwhere, GATE_W1), _piece(consts, cwhere, GATE_B1), g2, False)
        branch = 1.0 if g2[0, 0] > 0 else 0.0
    head = int(branch) if gate_kind != GATE_NONE else 0
    for layer in range(ints[N_HEAD]):
        hw, hb = _v3(weights, wwhere, W_HEAD + layer), _v2(consts, cwhere, HEAD_B + layer)
        buf = _v2(state, swhere, HEAD_OUT + layer)
        _dense_rows(z, hw[head], hb[head], buf, True)
        z = buf
    out_w, out_b = _v3(weights, wwhere, OUT_W), _v2(consts, cwhere, OUT_B)
    yn = _v2(state, swhere, YN)
    _dense_rows(z, out_w[head], out_b[head], yn, relu_out)
    local, y = _piece(state, swhere, LOCAL), _piece(state, swhere, Y)
    for j in range(local.size):
        local[j] = yn[0, j] * yspan[j] + ylo[j]
    if outer_frame:                              # at αN less the lag (FKPredictor._step_angle)
        pose_to_world(local, outer, _v2(consts, cwhere, ROT), _piece(consts, cwhere, TRANS), y)
    else:
        y[:] = local
        nq = math.sqrt(y[3] * y[3] + y[4] * y[4] + y[5] * y[5])
        if nq > 1e-12:
            y[3:6] /= nq
    return gate_state, motion, outer_prev, branch


@njit(cache=True)
def _first_shift(first, n, lo, hi, shift):
    """FKGuard.shift in numba: shift (2N,) <- the whole turns (deg) that bring each α of a sequence's
    first step `first` (2N,) into the trained range [lo, hi] (N,) (±inf: a sin/cos encoding)."""
    shift[:] = 0.0
    for i in range(n):
        a = first[i]
        if lo[i] <= a <= hi[i]:
            continue
        centre = 0.5 * (lo[i] + hi[i])
        shift[i] = TURN_DEG * math.floor((a - centre) / TURN_DEG + 0.5)


@njit(cache=True)
def _fk_rows(rows, consts, weights, state, ints, out):
    """Each row of one sequence rows (T, 2N) as a step from a sequence start (reset() defaults: no
    branch state, the outer tube at rest) -> out (T, 6), as `_fk_step` would give them one by one.
    Returns T, or the first declined row (its checks failed: nothing is to be trusted)."""
    gate_state, motion, outer_prev, branch = -1, 0, math.nan, UNKNOWN_STATE
    cwhere, swhere = ints[ints[C_DIR]:ints[S_DIR]], ints[ints[S_DIR]:ints[W_DIR]]
    for v in rows[0]:
        if not math.isfinite(v):
            return 0
    shift, prev = _piece(state, swhere, SHIFT), _piece(state, swhere, PREV_IN)
    _first_shift(rows[0], ints[N_TUBES], _piece(consts, cwhere, TRAIN_LO), _piece(consts, cwhere, TRAIN_HI),
                 shift)
    prev_out, y = _piece(state, swhere, PREV), _piece(state, swhere, Y)
    play = _piece(state, swhere, PLAY_Y)
    play[play.size - 1] = 1.0                   # the play operators start at rest
    for r in range(rows.shape[0]):
        gate_state, motion, outer_prev, branch = _fk_step(
            rows[r], shift, prev, consts, weights, state, ints, r > 0, r == 0, branch, gate_state, motion,
            outer_prev, 0.0)
        if gate_state == DECLINED:
            return r
        out[r] = y
        prev[:] = prev_out
    return rows.shape[0]


class _Packed:
    """Arrays laid end to end in one flat buffer of `dtype`, and the directory `where` (int64,
    4 entries per piece: offset, shape padded with 1s to three dimensions) that `_piece` reads."""

    def __init__(self, arrays: list[np.ndarray], dtype: type, head: int = 0) -> None:
        """head: entries kept free at the buffer's start (the int64 buffer's settings and directories)."""
        where, offset = [], head
        for a in arrays:
            shape = (*a.shape, 1, 1, 1)[:3]
            where.extend([offset, *shape])
            offset += a.size
        self.buf: np.ndarray = np.zeros(offset, dtype=dtype)
        self.where = np.array(where, dtype=np.int64)
        for k, a in enumerate(arrays):
            self.view(k, a.shape)[...] = a

    def view(self, k: int, shape: tuple[int, ...]) -> np.ndarray:
        """Piece k as an array of `shape` sharing the buffer."""
        o, d0, d1, d2 = (int(v) for v in self.where[4 * k:4 * k + 4])
        return self.buf[o:o + d0 * d1 * d2].reshape(shape)


def _float32_weights(engine: StreamingEngine) -> bool:
    """Whether every weight matrix of the engine is float32 (a net trained in float32; one trained in
    float64 keeps its float64 weights and goes through the reference path)."""
    mats = [engine.seq[0][1][0], engine.seq[0][1][1]]
    mats += [w for head, out in engine.heads for w in [*(lw for lw, _ in head), out[0]]]
    return all(m.dtype == np.float32 for m in mats)


class FusedFK:
    """The constants of one FK model laid out for `_fk_step`, and its call. `build` returns None for a
    model outside the scope of the module docstring."""

    def __init__(self, bundle: ModelBundle, engine: StreamingEngine, guard: FKGuard, clip: Clip,
                 frame: OuterFrame | None, relay: Relay | None) -> None:
        layout = bundle.layout
        n = layout.n_tubes
        w_ih, w_hh, b = engine.seq[0][1]
        self.engine = engine
        self.field = None if frame is None else frame.field     # added after the step (PositionField)
        lo = np.full(n, -np.inf) if guard.periodic_only else np.asarray(guard._lo, float)
        hi = np.full(n, np.inf) if guard.periodic_only else np.asarray(guard._hi, float)
        self.guard = (np.asarray(bundle.robot.lengths, float), lo, hi)
        # the trained α range, for predict's whole-turn shifts (FKGuard.shift)
        self.trained = ((np.full(n, -np.inf), np.full(n, np.inf)) if guard.periodic_only
                        else (np.asarray(guard.lo, float), np.asarray(guard.hi, float)))
        f = layout.n_inputs
        clip_lo, clip_hi = np.full(f, -np.inf), np.full(f, np.inf)
        clip_lo[clip.columns], clip_hi[clip.columns] = clip.lo, clip.hi
        self.norm = tuple(np.ascontiguousarray(a, dtype=np.float64) for a in (
            bundle.x_norm.lo, bundle.x_norm.span, clip_lo, clip_hi, bundle.y_norm.lo, bundle.y_norm.span))
        self.lstm = (w_ih, w_hh, b)
        heads = engine.heads
        n_layers = len(heads[0][0])
        self.head_w = tuple(np.stack([hd[0][i][0] for hd in heads]) for i in range(n_layers))
        self.head_b = tuple(np.stack([hd[0][i][1] for hd in heads]) for i in range(n_layers))
        self.out_w = np.stack([hd[1][0] for hd in heads])
        self.out_b = np.stack([hd[1][1] for hd in heads])
        gate_kind = GATE_NONE
        self.gate_w: tuple[np.ndarray, np.ndarray] = (np.zeros((1, 1)), np.zeros((1, 1)))
        self.gate_b: tuple[np.ndarray, np.ndarray] = (np.zeros(1), np.zeros(1))
        self.tables: tuple[np.ndarray, ...] = (np.zeros(1), np.zeros(1, np.int64), np.zeros(1, np.int64),
                                               np.zeros(1), np.zeros(1))
        self.gate_consts = (0.0, 0.0, 0.0)
        self.slide: tuple[np.ndarray, ...] = (np.ones(1), np.full(1, 2.0), np.zeros(1))   # widths, inputs, u
        if relay is not None:
            gate_kind = GATE_FOLD
            tb = relay.tables
            self.tables = (tb.axes, tb.start, tb.size, tb.forward, tb.backward)
            self.gate_consts = (float(relay.widen_deg), float(relay.outer_lag_deg), float(relay.band_deg))
            if any(u > 0 for u in relay.slide_weights):
                widths, inputs = slide_operators()
                self.slide = (widths, inputs, np.asarray(relay.slide_weights, float))
        elif engine.gate:
            gate_kind = GATE_LEARNED
            self.gate_w = (engine.gate[0][0], engine.gate[1][0])
            self.gate_b = (engine.gate[0][1], engine.gate[1][1])
        reg = frame.registration if frame is not None else None
        self.rot = np.eye(3) if reg is None else np.ascontiguousarray(reg.rotation, dtype=np.float64)
        self.trans = np.zeros(3) if reg is None else np.ascontiguousarray(reg.translation, dtype=np.float64)
        widths, source = input_operators()
        self.play = (widths, source.astype(float)) if layout.play else (np.ones(1), np.zeros(1))
        self.cfg = (n, layout.angle_encoding == "phase", layout.delta, engine.pooling == "flatten",
                    engine.relu_out, gate_kind, reg is not None, frame is not None and frame.has_lag,
                    frame is not None and frame.lags_inputs, len(widths) if layout.play else 0,
                    int(self.slide[2].any()) * len(self.slide[0]))
        self.prev = np.zeros(2 * n)        # the last step's shifted joints (FKPredictor._prev)
        self._none = np.zeros(2 * n)
        self._pack(n_layers)

    def _pack(self, n_layers: int) -> None:
        """The flat buffers `_fk_step` reads (module comment above it); the engine's state arrays
        become views of the state buffer, so the reference path and this one share them."""
        w_ih, w_hh, b = self.lstm
        self.consts = _Packed([*self.guard, *self.norm, b, self.out_b, *self.gate_w,
                               *self.gate_b, self.tables[0], self.tables[3], self.tables[4], self.rot,
                               self.trans, np.array(self.gate_consts, float), *self.trained, *self.play,
                               *self.slide, *self.head_b], np.float64)
        self.weights = _Packed([w_ih, w_hh, self.out_w, *self.head_w], np.float32)
        e = self.engine
        n_out = self.out_w.shape[1]
        width = e._hist.shape[2] * (e.ib if e.pooling == "flatten" else 1)
        scratch = [np.zeros(len(self.prev)), np.zeros(len(self.prev)), np.zeros(6), np.zeros(n_out),
                   np.zeros((1, n_out)), np.zeros((1, width + 1)), np.zeros((1, self.gate_w[0].shape[0])),
                   np.zeros((1, 1)), np.zeros(len(self.prev)), np.zeros(len(self.prev)),
                   np.r_[np.zeros(len(self.play[0])), 1.0], np.r_[np.zeros(len(self.slide[0])), 1.0],
                   np.zeros(len(self.slide[0])),
                   *(np.zeros((1, self.head_w[i].shape[1])) for i in range(n_layers))]
        self.state = _Packed([*self._engine_state(), *scratch], np.float64)
        ints = [self.tables[1], self.tables[2], e._bits[0]]
        c_dir = N_CFG
        s_dir = c_dir + len(self.consts.where)
        w_dir = s_dir + len(self.state.where)
        i_dir = w_dir + len(self.weights.where)
        end = i_dir + 4 * len(ints)
        self.ints = _Packed(ints, np.int64, head=end)
        self.ints.buf[:end] = [*self.cfg, n_layers, c_dir, s_dir, w_dir, i_dir, end, *self.consts.where,
                               *self.state.where, *self.weights.where, *self.ints.where]
        self._share_state()
        # whether a step depends on nothing before the sequence's start (no branch state, no outer
        # lag): then `rows` gives what `step` gives from a reset()
        self.stateless = bool(self.cfg[GATE_KIND] == GATE_NONE and not self.cfg[HAS_LAG])

    def _engine_state(self) -> list[np.ndarray]:
        """The engine's state arrays, in the state buffer's order (H, C, H2, C2, G, T, HIST, X)."""
        e = self.engine
        return [e._h[0], e._c[0], e._h2[0], e._c2[0], e._g[0], e._t[0], e._hist, e._x]

    def _share_state(self) -> None:
        """Point the engine's state arrays at views of the buffers (they hold the same values), and
        keep views of the step's previous joints and its result."""
        e = self.engine
        e._h[0], e._c[0], e._h2[0], e._c2[0], e._g[0], e._t[0], e._hist, e._x = (
            self.state.view(k, a.shape) for k, a in enumerate(self._engine_state()))
        e._bits[0] = self.ints.view(BITS, e._bits[0].shape)
        self.prev = self.state.view(PREV, self.prev.shape)
        self._y = self.state.view(Y, (6,))
        self.play_state = self.state.view(PLAY_Y, (len(self.play[0]) + 1,))  # PlayState's buffer
        self.slide_state = self.state.view(GATE_PLAY_Y, (len(self.slide[0]) + 1,))   # the slide memory's
        self._bufs = (self.consts.buf, self.weights.buf, self.state.buf, self.ints.buf)

    def __setstate__(self, state: dict[str, Any]) -> None:
        """After a deep copy or unpickling the engine's arrays are copies of their own, no longer views
        of the buffers: share them again, so that both paths keep seeing one state."""
        self.__dict__.update(state)
        self._share_state()

    @classmethod
    def build(cls, bundle: ModelBundle, engine: StreamingEngine | None, guard: FKGuard, clip: Clip,
              frame: OuterFrame | None, relay: Relay | None = None) -> FusedFK | None:
        """The fused step of an FK model (`bundle` with its streaming engine, input guard, step-change
        clip and outer frame; the branch state from `relay` where given), or None where it does not
        apply (module docstring)."""
        eng = engine
        if (eng is None or bundle.layout.angle_encoding not in ("minmax", "phase")
                or bundle.layout.equivariant
                or len(eng.seq) != 1 or eng.seq[0][0] != "lstm" or not eng.heads[0][0]
                or len(eng.heads) > 2 or not _float32_weights(eng)):
            return None
        return cls(bundle, eng, guard, clip, frame, relay)

    def step(self, raw: np.ndarray, shift: np.ndarray, prev: np.ndarray | None, gate_state: int,
             outer_motion: int, outer_prev: float, lag: float = 0.0) -> tuple[np.ndarray, tuple[Any, ...]]:
        """One step: raw (2N,) joints as given, shift (2N,) the sequence's whole turns, prev the
        previous shifted joints (None at a start), the fold gate's state and m_N, lag the outer frame's
        λ(β) (deg) -> the (6,) pose and the new state (gate state, m_N, αN, branch state; DECLINED:
        nothing changed, take the reference path)."""
        consts, weights, state, ints = self._bufs
        e = self.engine
        res = _fk_step(raw, shift, self._none if prev is None else prev, consts, weights, state, ints,
                       prev is not None, e._fresh, e.state, gate_state, outer_motion, outer_prev, lag)
        y = self._y.copy()
        if self.field is not None and res[0] != DECLINED:
            self.field.apply_one(y)
        return y, res

    def rows(self, raw: np.ndarray) -> np.ndarray | None:
        """The steps of one whole sequence raw (T, 2N) (as given, C-contiguous) from a sequence start,
        shifted by the whole turns of its first step: (T, 6) poses equal to `step`'s, on this
        object's state (a model's own copy, never the stream's: FKPredictor.predict); None where a
        row fails the fast checks. Only for a `stateless` model."""
        out = np.empty((len(raw), 6))
        if _fk_rows(raw, *self._bufs, out) != len(raw):
            return None
        return out if self.field is None else self.field.apply_rows(out)
