"""The tests' small dataset and training settings, made in one place: the session fixtures of
tests/conftest.py and the docs test's fixtures (tests/cli/test_doc_commands.py) both call these."""

from __future__ import annotations

from typing import Any

from ctrkin.robots import paper_robot


def six_sweeps() -> Any:
    """6 rotation sweeps of the paper robot (d = 8, 14, 20 mm; outer α 0, 90°) at 4° steps, 0.02 mm
    tracker noise (a `Dataset`)."""
    from ctrkin.acquisition.demo import sweep_dataset

    return sweep_dataset(paper_robot(), translations=(8, 14, 20), outer_alphas=(0, 90), step_deg=4,
                         noise_mm=0.02, seed=2)


def small_configs() -> dict[str, Any]:
    """`TrainConfig` of each small model, by name: few epochs, a small LSTM."""
    from ctrkin.training import TrainConfig

    return {
        "fk": TrainConfig(task="fk", max_epochs=3, threads=1, options={"structure": "L16|D16"}),
        "ik": TrainConfig(task="ik", ib=3, max_epochs=3, threads=1, options={"structure": "L16|D16"}),
        "fk_cnn": TrainConfig(task="fk", model="cnn", max_epochs=1, threads=1, options={"channels": 8}),
        "fk_default": TrainConfig(task="fk", max_epochs=1, threads=1),
        "fk_branch": TrainConfig(task="fk", model="lstm_mlp_branch", max_epochs=3, threads=1,
                                 options={"structure": "L16|D16", "gate_units": 8}),
    }


def with_position_field(kin: Any) -> Any:
    """kin (a Kinematics of a model with an outer frame) with a position field of degree 3 in its frame
    (ctrkin.models.field; as a joint field leaves it), set after loading: the fused step follows."""
    from dataclasses import replace

    import numpy as np

    from ctrkin.models.field import PositionField, exponents

    assert kin.frame is not None
    exps = exponents(3)
    coef = np.random.default_rng(11).normal(0.0, 0.3, (len(exps), 3))
    field = PositionField(np.array([0.0, 0.0, 90.0]), 30.0, exps, coef, 0.0, 0.1, 0.2)
    kin.predictor.frame = replace(kin.frame, field=field)
    return kin
