"""The reproduction's training runs: the recommended FK trains with its scale's input buffer (issue
21: FK_MEMORY_IB, benchmarks/bench_fk_memory.py), the grids with their own,
and a results.json written before budgets had an IB reads back with the paper's IB 2."""

from __future__ import annotations

from pathlib import Path

from ctrkin.evaluation.scales import SCALES, ReproScale
from ctrkin.evaluation.table import FK_BRANCH, FK_PAPER
from ctrkin.evaluation.training_runs import TRAINED_WITH_EXCITATION, plan_runs, training_jobs
from tests.benchmark_scripts import load_benchmark

FK_BRANCH_MODEL = "lstm_mlp_branch"


def test_each_run_takes_its_budgets_input_buffer_and_the_grids_their_own() -> None:
    for scale in SCALES.values():
        runs = {r.name: r.config for r in plan_runs(scale)}
        assert runs[FK_BRANCH].ib == scale.branch.ib
        assert runs[FK_PAPER].ib == scale.main.ib == 2          # the paper's model stays the paper's
        assert [runs[f"grid_fk_ib{ib}"].ib for ib in scale.ib_grid] == list(scale.ib_grid)
        assert {runs[f"grid_fk_ib{ib}_S1"].ib for ib in scale.structure_ibs} == set(scale.structure_ibs)


def test_the_jobs_train_one_thread_each_the_recommended_models_on_the_excitation_folder(tmp_path) -> None:
    scale = SCALES["tiny"]
    runs = plan_runs(scale)
    paper, extra = tmp_path / "paper", tmp_path / "paper+excitation"
    jobs = training_jobs(runs, paper, scale, tmp_path / "models", "cpu", extra)
    assert [Path(job[3]) for job in jobs] == [tmp_path / "models" / r.name for r in runs]
    for run, (data_dir, n_seq, cfg, _) in zip(runs, jobs, strict=True):
        assert data_dir == str(extra if run.name in TRAINED_WITH_EXCITATION else paper)
        assert n_seq == (None if run.role == "main" else scale.grid_sequences)
        assert cfg == {**run.config.to_dict(), "threads": 1, "device": "cpu"}
    assert {job[0] for job in training_jobs(runs, paper, scale, tmp_path, "cpu")} == {str(paper)}


def test_a_scale_saved_before_budgets_had_an_input_buffer_reads_back_with_ib_2() -> None:
    d = SCALES["quick"].to_dict()
    for role in ("main", "branch", "follow", "compare", "grid"):
        del d[role]["ib"]
    assert ReproScale.from_dict(d).branch.ib == 2


def test_the_memory_benchmarks_arms_are_the_reproductions_recipe_with_their_ib_and_epochs() -> None:
    bench = load_benchmark("bench_fk_memory")
    quick = {r.name: r.config for r in plan_runs(SCALES["quick"])}[FK_BRANCH]
    ib4 = bench.arm_config("quick", "ib4")
    assert (ib4.ib, ib4.max_epochs, ib4.threads) == (4, quick.max_epochs, 1)
    same = {"ib": quick.ib, "threads": quick.threads, "device": quick.device}
    # the recommended FK's memory, field and fold scale
    assert quick.play_lags and quick.joint_field and quick.fold_scale
    field = {"joint_field": True, "fold_scale": True}    # an arm without f: no joint field; without g: g = 1
    assert ib4.to_dict() | same | {"play_lags": True} | field == quick.to_dict()    # without p: no lags
    assert not ib4.play_lags and not ib4.joint_field and not ib4.fold_scale
    assert bench.arm_config("quick", "ib2pgf").to_dict() | same == quick.to_dict()  # ib2pgf: the recipe
    assert bench.arm_config("quick", "ib2pf").to_dict() | same | field == quick.to_dict()
    assert bench.arm_config("quick", "ib2p").to_dict() | same | field == quick.to_dict()
    assert bench.arm_config("quick", "ib2ps3").seed == 3 and bench.arm_config("quick", "ib2pq").equivariant
    prior = bench.arm_config("quick", "ib2pts1")
    assert prior.tcm_prior and prior.play_lags and prior.seed == 1 and not quick.tcm_prior
    long = bench.arm_config("quick", "ib2e160")
    assert (long.ib, long.max_epochs, long.patience) == (2, 160, 160)
    tracker = bench.arm_config("quick", "ib2ptr")
    assert (tracker.model, tracker.target_frame, quick.target_frame) == (FK_BRANCH_MODEL, "tracker", "outer")
    assert tracker.to_dict() | same | {"tcm_prior": False, "target_frame": "outer"} | field == quick.to_dict()
    plain = bench.arm_config("quick", "ib2ptm")        # the paper's network, the same inputs and recipe
    assert (plain.model, plain.target_frame, plain.options) == ("lstm_mlp", "tracker", {"structure": "paper"})
    assert (plain.angle_encoding, plain.output_activation, plain.play_lags, plain.tcm_prior) == \
        (quick.angle_encoding, quick.output_activation, True, True)
    scaled = bench.arm_config("quick", "ib2pg")
    assert scaled.fold_scale and not scaled.joint_field
    assert scaled.to_dict() | same | field == quick.to_dict()
    offset = bench.arm_config("quick", "ib2ptro")          # the offset head form, on the prior, tracker frame
    assert offset.options == quick.options | {"heads": "offset"} and quick.options["heads"] == "separate"
    assert (offset.tcm_prior, offset.target_frame) == (True, "tracker")
