"""benchmarks/bench_fk_memory.py: where each true snap's nearest predicted snap lies."""

from __future__ import annotations

import numpy as np

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

