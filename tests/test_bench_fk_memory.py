"""benchmarks/bench_fk_memory.py: where each true snap's nearest predicted snap lies, and the
validation snaps' jump error, what a wrong branch state costs."""

from __future__ import annotations

import numpy as np

from ctrkin.acquisition.demo import sweep_dataset
from ctrkin.families.snap_aware.labels import phase_deg, snap_events
from ctrkin.inference import Kinematics
from ctrkin.robots import paper_robot
from tests.benchmark_scripts import load_benchmark


def test_each_true_snap_gets_the_signed_steps_to_its_nearest_predicted_one_in_its_sequence() -> None:
    bench = load_benchmark("bench_fk_memory")
    bounds = [(0, 100), (100, 200)]
    true = np.array([30, 60, 105, 150])
    # 23: 7 early; 62 and 64: the nearer one, 2 late; 99 is in the other sequence than 105 and
    # nothing else is within reach of it; 150 has none within EVENT_REACH
    pred = np.array([23, 62, 64, 99, 190])
    assert bench.event_offsets(pred, true, bounds) == [-7, 2, None, None]
    assert bench.event_offsets(np.zeros(0, int), true, bounds) == [None] * 4



def test_a_validation_snap_scores_its_jump_only_when_predicted_late_early_or_short() -> None:
    """snap_jump_errors: the position change over ±JUMP_REACH steps around each recorded snap of the
    chosen sequences, predicted against true. A jump in time and of the right size scores 0; one
    JUMP_REACH + 1 steps late or of half the size scores the missing part; other sequences' snaps
    are not scored."""
    bench = load_benchmark("bench_fk_memory")
    ds = sweep_dataset(paper_robot(), translations=(20.0,), outer_alphas=(0.0, 90.0), step_deg=2)
    snap = ds.frame["snap"].to_numpy()
    bounds = ds.sequence_bounds()
    first = [int(t) for t in snap_events(snap, *bounds[0])]
    assert len(first) == 2 and len(snap_events(snap, *bounds[1])) == 2
    truth = np.zeros((len(snap), 6))
    for t in first:                                        # a 3 mm step in x at each of the first's snaps
        truth[t:bounds[0][1], 0] += 3.0
    rows = np.arange(*bounds[0])
    assert np.allclose(bench.snap_jump_errors(truth.copy(), truth, ds, rows), 0.0)
    late = np.zeros_like(truth)
    for t in first:
        late[t + bench.JUMP_REACH + 1:bounds[0][1], 0] += 3.0
    np.testing.assert_allclose(bench.snap_jump_errors(late, truth, ds, rows), [3.0, 3.0])
    short = truth.copy()
    short[:, 0] *= 0.5
    np.testing.assert_allclose(bench.snap_jump_errors(short, truth, ds, rows), [1.5, 1.5])
    assert len(bench.snap_jump_errors(late, truth, ds, np.arange(*bounds[1]))) == 2   # its own snaps
    assert len(bench.snap_jump_errors(late, truth, ds, np.zeros(0, int))) == 0


def test_a_wrong_state_costs_what_the_two_branches_differ_by_outside_the_band(model_dirs, sweeps) -> None:
    """wrong_state_cost: the median distance between the two branches' positions on the validation
    rows with |φ| > OUTSIDE_BAND_DEG; None for a model without a branch state."""
    bench = load_benchmark("bench_fk_memory")
    assert bench.wrong_state_cost(Kinematics.load(model_dirs["fk"]), sweeps) is None
    kin = Kinematics.load(model_dirs["fk_branch"])
    q, val = sweeps.joints(), sweeps.get_split().val
    far = val[np.abs(phase_deg(q[val, 0] - q[val, 1])) > bench.OUTSIDE_BAND_DEG]
    p0 = kin.predict(sweeps, branch_states=np.zeros(len(q)))[far, :3]
    p1 = kin.predict(sweeps, branch_states=np.ones(len(q)))[far, :3]
    want = float(np.median(np.linalg.norm(p1 - p0, axis=1)))
    assert len(far) > 10 and want > 0
    assert bench.wrong_state_cost(kin, sweeps) == want
