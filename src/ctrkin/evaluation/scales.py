"""How big a reproduction is: data sizes and training budgets of `ctrkin reproduce --scale`."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from ctrkin.acquisition.protocols import PAPER_SIZES
from ctrkin.errors import CtrkinError
from ctrkin.training.config import LrSchedule, scaled_lr


@dataclass(frozen=True)
class Budget:
    """Training budget of one role of model: epochs (max), early-stopping patience, batch size,
    learning rate and its schedule (TrainConfig.lr_schedule), smoothing of the val loss for early
    stopping (TrainConfig.val_smoothing), Adam's fused kernel (TrainConfig.fused_adam)."""

    epochs: int
    patience: int
    batch_size: int
    lr: float = 1e-3
    lr_schedule: LrSchedule = "constant"
    val_smoothing: float = 0.0
    fused_adam: bool = True


@dataclass(frozen=True)
class ReproScale:
    """paper_levels / paper_outer_step_deg: the training protocol (None: the protocol's own; the
    quick and tiny sizes are acquisition.protocols.PAPER_SIZES, which `ctrkin collect` records);
    main: the LSTM-MLP FK and IK models (the paper's); branch: the snap-aware FK model
    (lstm_mlp_branch, the recommended FK); follow: the follow IK (follow_mlp, the recommended IK,
    ctrkin.models.follow); compare: baselines and the Δα0 ablation; grid: the IB and
    structure grids (Tables II, III); grid_sequences: how many training sequences the grid and
    comparison models see (None: all); ib_grid / structure_grid: what the grids cover."""

    name: str
    protocol_scale: str
    paper_levels: tuple[float, ...] | None
    paper_outer_step_deg: float | None
    main: Budget
    branch: Budget
    follow: Budget
    compare: Budget
    grid: Budget
    grid_sequences: int | None
    ib_grid: tuple[int, ...] = (1, 2, 3, 4, 5)
    structure_grid: tuple[str, ...] = ("S1", "S2", "S3", "S4", "S5")
    structure_ibs: tuple[int, ...] = (2, 3)

    def to_dict(self) -> dict[str, object]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ReproScale:
        """Inverse of to_dict (as read back from results.json: lists for the tuples)."""
        levels = d["paper_levels"]
        return cls(**{**d, **{role: Budget(**d[role]) for role in BUDGET_ROLES},
                      "paper_levels": None if levels is None else tuple(levels),
                      **{k: tuple(d[k]) for k in ("ib_grid", "structure_grid", "structure_ibs")}})


BUDGET_ROLES = ("main", "branch", "follow", "compare", "grid")   # the ReproScale fields that are a Budget


SCALES = {
    # the paper's protocol and data; training within an hour on two cores (issue 11): batch 1024
    # with the square-root lr rule (5.7e-3; the paper: batch 32, 1e-3, up to 500 epochs), early
    # stopping on a smoothed val loss, fixed epoch caps (seeded: reproducible, unlike a time budget).
    # The snap-aware FK: quick's cosine schedule at batch 1024 (lr 2e-3 at 256 by the same rule).
    "full": ReproScale(
        "full",
        "full",
        None,
        None,
        main=Budget(60, 10, 1024, scaled_lr(1024), val_smoothing=0.5),
        branch=Budget(40, 40, 1024, scaled_lr(1024, 2e-3, 256), "cosine"),
        follow=Budget(40, 40, 512, 2e-3, "cosine", fused_adam=False),
        compare=Budget(25, 6, 1024, scaled_lr(1024), val_smoothing=0.5),
        grid=Budget(12, 4, 1024, scaled_lr(1024), val_smoothing=0.5),
        grid_sequences=None,
    ),
    # the README's main job, ~12 minutes on two cores: 4 levels × 18 outer angles × 721 samples;
    # the snap-aware FK gets a fixed cosine schedule (no early stopping: the gate keeps improving
    # after the pose loss flattens). Adam's default kernel: the same weights, bit for bit, as before
    # issue 11 (the fused one rounds differently, and a run stopped early lands elsewhere).
    "quick": ReproScale(
        "quick", "quick", PAPER_SIZES["quick"].levels_mm, PAPER_SIZES["quick"].outer_step_deg,
        main=Budget(150, 15, 64, fused_adam=False),
        branch=Budget(80, 80, 256, 2e-3, "cosine", fused_adam=False),
        follow=Budget(40, 40, 512, 2e-3, "cosine", fused_adam=False),
        compare=Budget(40, 8, 128, fused_adam=False), grid=Budget(15, 5, 128, fused_adam=False),
        grid_sequences=None,
    ),
    # the CI test of the whole pipeline: every step and key, seconds of training
    "tiny": ReproScale(
        "tiny",
        "quick",   # with the tiny size's levels and step: the key of reproductions recorded before
        PAPER_SIZES["tiny"].levels_mm,
        PAPER_SIZES["tiny"].outer_step_deg,
        main=Budget(2, 2, 256),
        branch=Budget(2, 2, 256, 2e-3, "cosine"),
        follow=Budget(2, 2, 512, 2e-3, "cosine"),
        compare=Budget(1, 1, 512),
        grid=Budget(1, 1, 512),
        grid_sequences=4,
    ),
}


def get_scale(name: str) -> ReproScale:
    if name not in SCALES:
        raise CtrkinError(f"unknown scale {name!r}; choose one of {sorted(SCALES)}")
    return SCALES[name]
