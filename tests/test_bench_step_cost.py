"""benchmarks/bench_step_cost.py (issue 21, goal 4): a case's effects with overrides on top, the
segments it drives, and its figures."""

from __future__ import annotations

import json

from tests.benchmark_scripts import load_benchmark


def test_it_drives_the_first_segments_of_a_case_with_an_effect_overridden(capsys) -> None:
    bench = load_benchmark("bench_step_cost")
    case = bench.ROBOTS["default-top"]
    figures = bench.step_cost("default-top", {"tube_friction": 0.2}, n_runs=1, n_segments=2)
    assert figures["effects"] == {**case.settings, "tube_friction": 0.2}
    assert figures["segments"] == 2
    plan = bench.protocols.build("paper", bench._robot(case), scale="quick", seed=0)
    assert figures["steps"] == sum(seg.q.shape[0] for seg in plan.runs[0].segments[:2])
    assert figures["given_up_share"] == 0.0      # the paper robot's steps all continue
    assert 0 < figures["segment_us_p50"] <= figures["segment_us_p90"] <= figures["segment_us_max"]
    out = capsys.readouterr().out.splitlines()
    assert "tube_friction 0.2" in out[0] and "given up" in out[1]
    assert json.loads(out[-1]) == figures


def test_against_drives_the_same_segments_again_and_measures_the_tip_difference(capsys) -> None:
    bench = load_benchmark("bench_step_cost")
    same = bench.step_cost("default-top", {}, n_runs=1, n_segments=2,
                           against={"presliding_mm": bench.VirtualConfig().presliding_mm})
    assert same["tip_diff_max_mm"] == 0.0                      # the same robot: the same motion
    assert same["against_given_up_share"] == 0.0 and same["against_us_per_step"] > 0
    other = bench.step_cost("default-top", {}, n_runs=1, n_segments=2, against={"tube_friction": 0.2})
    assert other["against"] == {"tube_friction": 0.2}
    assert 0 < other["tip_diff_rms_mm"] <= other["tip_diff_p99_mm"] <= other["tip_diff_max_mm"]
    out = capsys.readouterr().out.splitlines()
    assert out[-2].startswith("against {'tube_friction': 0.2}")
    assert json.loads(out[-1]) == other


def test_the_moving_path_moves_every_joint_each_step_within_the_stops(capsys) -> None:
    import numpy as np

    bench = load_benchmark("bench_step_cost")
    for name in ("default-top", "three-tube"):
        robot = bench._robot(bench.ROBOTS[name])
        plan = bench.protocols.build("paper", robot, scale="quick", seed=0)
        Q = bench.moving_path(robot, plan, 400)
        assert Q.shape == (400, 2 * robot.n_tubes)
        robot.check_joints(Q)                                    # raises on a joint past a stop
        assert (np.diff(Q, axis=0) != 0).all()                   # every joint, every step
        np.testing.assert_array_equal(Q, bench.moving_path(robot, plan, 400))    # seeded
    figures = bench.moving_cost("default-top", {}, 60, repeats=2)
    assert figures["steps"] == 60 and figures["repeats"] == 2 and figures["given_up_share"] == 0.0
    assert 0 < figures["us_per_step_min"] <= figures["us_per_step"]
    assert json.loads(capsys.readouterr().out.splitlines()[-1]) == figures
