"""benchmarks/bench_train_stage.py's machinery: a worker's start-up, gaps and idle tail, the pool's
list schedule, the comparison of two model folders timing apart, and one timed job whose phases
cover its wall time."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest
import torch

from tests.benchmark_scripts import load_benchmark
from tests.small_models import small_configs

bench = load_benchmark("bench_train_stage")


def test_worker_idle_counts_start_up_gaps_and_the_tail_until_the_last_job_ends() -> None:
    recs = [{"pid": 1, "start": 2.0, "end": 5.0}, {"pid": 1, "start": 6.0, "end": 9.0},
            {"pid": 2, "start": 3.0, "end": 10.0}]
    idle = bench.worker_idle(recs, 0.0, 10.0)
    assert idle[1] == {"startup": 2.0, "gaps": 1.0, "tail": 1.0, "busy": 6.0, "jobs": 2}
    assert idle[2] == {"startup": 3.0, "gaps": 0.0, "tail": 0.0, "busy": 7.0, "jobs": 1}


def test_list_schedule_hands_each_job_to_the_first_free_worker() -> None:
    assert bench.list_schedule([1.0, 1.0, 4.0], 2) == (5.0, 4.0)     # the long job last: a worker waits
    assert bench.list_schedule([4.0, 1.0, 1.0], 2) == (4.0, 2.0)     # longest first
    assert bench.list_schedule([5.0, 3.0, 3.0, 1.0], 2) == (6.0, 0.0)
    assert bench.list_schedule([2.0, 2.0], 1) == (4.0, 0.0)


def _folder(path, weight: float, seconds: float):
    path.mkdir()
    torch.save({"w": torch.tensor([1.0, weight])}, path / "weights.pt")
    (path / "metrics.json").write_text(json.dumps({"test": {"rmse": 1.5}, "training": {
        "epochs": 3, "seconds": seconds, "cpu_seconds": seconds, "samples_per_s": 1 / seconds}}))
    (path / "history.csv").write_text(f"epoch,train_loss,val_loss,seconds\n1,0.5,0.6,{seconds}\n")
    return path


def test_model_differences_ignore_the_clocks_and_see_one_bit_of_a_weight(tmp_path) -> None:
    a = _folder(tmp_path / "a", 2.0, 1.0)
    assert bench.model_differences(a, _folder(tmp_path / "b", 2.0, 7.0)) == []
    c = _folder(tmp_path / "c", float(torch.nextafter(torch.tensor(2.0), torch.tensor(3.0))), 1.0)
    assert bench.model_differences(a, c) == ["weights.pt"]
    d = _folder(tmp_path / "d", 2.0, 1.0)
    (d / "metrics.json").write_text(json.dumps({"test": {"rmse": 1.6}, "training": {"epochs": 3}}))
    assert bench.model_differences(a, d) == ["metrics.json"]


@pytest.mark.slow
def test_a_timed_jobs_phases_cover_its_wall_time_and_hold_the_epoch_loop(sweeps, tmp_path) -> None:
    sweeps.save(tmp_path / "data")
    log = tmp_path / "log"
    log.mkdir()
    cfg = {**replace(small_configs()["fk"], max_epochs=2).to_dict(), "device": "cpu"}
    bench.timed_job(str(log), str(tmp_path / "data"), None, cfg, str(tmp_path / "models" / "fk"))
    rec = json.loads((log / "fk.json").read_text())
    walls = [rec[p]["wall"] for p in bench.PHASES]
    assert all(w >= 0 for w in walls)
    assert sum(walls) == pytest.approx(rec["end"] - rec["start"], abs=1e-6)
    assert rec["epochs"]["wall"] >= rec["metrics_seconds"]           # the loop holds what metrics.json times
    assert bench.model_differences(tmp_path / "models" / "fk", tmp_path / "models" / "fk") == []
