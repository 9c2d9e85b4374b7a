"""benchmarks/bench_gate_choice.py: the gate choice of a reproduction's recommended FK, read from its
folders (data/paper, models/fk_lstm_mlp_branch)."""

from __future__ import annotations

import json
import shutil

from tests.benchmark_scripts import load_benchmark


def test_the_benchmark_reports_the_choice_training_makes(model_dirs, sweeps, tmp_path, capsys) -> None:
    bench = load_benchmark("bench_gate_choice")
    repro = tmp_path / "repro"
    sweeps.save(repro / "data" / "paper")
    shutil.copytree(model_dirs["fk_branch"], repro / "models" / bench.FK)
    assert bench.main(["--repro", str(repro)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("reproduction") and str(repro) in lines[1]
    row = json.loads(lines[-1])[str(repro)]
    assert row["gate"] in ("fold", "learned") and row["gate_in_use"] == "fold"
    assert row["val_sequences"] == len(set(sweeps.frame["sequence_id"].to_numpy()[sweeps.get_split().val]))
    confident = row["p_learned_better"] >= row["level"] and row["val_sequences"] > 1
    assert (row["gate"] == "learned") == confident
