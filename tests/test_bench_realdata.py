"""benchmarks/bench_realdata.py: the learned FK on the calibrated TCM (its prior arms), the recommended FK."""

from __future__ import annotations

import dataclasses

import numpy as np

from tests.benchmark_scripts import load_benchmark


def test_the_prior_arms_train_on_the_split_and_score_each_seed(sweeps) -> None:
    bench = load_benchmark("bench_realdata")
    ds = dataclasses.replace(sweeps, split=sweeps.get_split(seed=0))
    arms = bench.prior_fk(ds, max_epochs=1, encoding="sincos", seeds=2)
    assert set(arms) == {None, "residual", "input", "tcm"}
    for mode, (test, seeds, val) in arms.items():
        assert np.isfinite(test) and np.isfinite(val) and test > 0
        assert len(seeds) == (0 if mode == "tcm" else 2)
    # the TCM calibrated on the training rows of these sweeps (the nominal robot plus noise) is close
    # to them; a network trained for one epoch is not
    assert arms["tcm"][0] < 1.0 < arms[None][0]


def test_the_recommended_fk_row_trains_a_selection_per_seed(sweeps, tmp_path) -> None:
    bench = load_benchmark("bench_realdata")
    ds = dataclasses.replace(sweeps, split=sweeps.get_split(seed=0))
    test, seeds, kept = bench.recommended_fk(ds, tmp_path, seeds=2, max_epochs=1)
    assert np.isfinite(test) and test > 0 and len(seeds) == 2 and all(np.isfinite(seeds))
    assert all(k in ("requested", "paper") for k in kept) and len(kept) == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"fk_optitrack_recommended_seed{s}" for s in (0, 1)]
