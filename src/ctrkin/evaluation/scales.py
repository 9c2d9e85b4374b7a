"""How big a reproduction is (data sizes and training budgets of `ctrkin reproduce --scale`), and the
typed configuration of a reproduction (`ctrkin reproduce` is generated from it). A light module: the
command line reads it without importing the networks."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, Literal, get_args

from ctrkin.acquisition.protocols import PAPER_SIZES
from ctrkin.errors import CtrkinError
from ctrkin.training.config import DEVICES, FK_MEMORY_IB, IK_EPOCHS, Device, LrSchedule, scaled_lr
from ctrkin.virtual.config import SETTINGS_HELP, VirtualConfig


@dataclass(frozen=True)
class Budget:
    """Training budget of one role of model: epochs (max), early-stopping patience, batch size,
    learning rate and its schedule (TrainConfig.lr_schedule), smoothing of the val loss for early
    stopping (TrainConfig.val_smoothing), Adam's fused kernel (TrainConfig.fused_adam; with it the fused
    window LSTM, TrainConfig.fused_lstm: off, a budget trains the weights it did before), and the input
    buffer IB (TrainConfig.ib: the memory the window gives; the grids set their own)."""

    epochs: int
    patience: int
    batch_size: int
    lr: float = 1e-3
    lr_schedule: LrSchedule = "constant"
    val_smoothing: float = 0.0
    fused_adam: bool = True
    ib: int = 2


@dataclass(frozen=True)
class ReproScale:
    """paper_levels / paper_outer_step_deg: the training protocol (None: the protocol's own; the
    quick and tiny sizes are acquisition.protocols.PAPER_SIZES, which `ctrkin collect` records);
    main: the LSTM-MLP FK and IK models (the paper's); branch: the snap-aware FK model
    (lstm_mlp_branch, the recommended FK); follow: the follow IK (follow_mlp, the recommended IK,
    ctrkin.families.follow.features); compare: baselines and the Δα0 ablation; grid: the IB and
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
    # The snap-aware FK: quick's cosine schedule at batch 1024 (lr 2e-3 at 256 by the same rule), and
    # quick's input buffer (FK_MEMORY_IB), 80 epochs (14,640 steps, about quick's 16,240): at 40 it
    # under-fit (best epoch the last, training loss 98 % of validation's), and 80 lowered the validation
    # loss on the default robot and on three-tube-central (docs/reproduction.md: The full scale's FK budget).
    "full": ReproScale(
        "full",
        "full",
        None,
        None,
        main=Budget(60, 10, 1024, scaled_lr(1024), val_smoothing=0.5),
        branch=Budget(80, 80, 1024, scaled_lr(1024, 2e-3, 256), "cosine", ib=FK_MEMORY_IB),
        follow=Budget(40, 40, 512, 2e-3, "cosine", fused_adam=False),
        compare=Budget(25, 6, 1024, scaled_lr(1024), val_smoothing=0.5),
        grid=Budget(12, 4, 1024, scaled_lr(1024), val_smoothing=0.5),
        grid_sequences=None,
    ),
    # the README's main job, ~6 minutes on two quiet cores at the defaults (342 s measured 2026-12-07,
    # training 247 of them; 36 min at load 3.5 on an earlier host):
    # 4 levels × 18 outer angles × 721 samples;
    # the snap-aware FK gets a fixed cosine schedule (no early stopping: the gate keeps improving
    # after the pose loss flattens) and a window of FK_MEMORY_IB steps (issue 21: IB 8 measured and
    # not adopted, training.config). Adam's default kernel: the same weights, bit for
    # bit, as before issue 11 (the fused one rounds differently, and a run stopped early lands elsewhere).
    "quick": ReproScale(
        "quick", "quick", PAPER_SIZES["quick"].levels_mm, PAPER_SIZES["quick"].outer_step_deg,
        main=Budget(150, 15, 64, fused_adam=False),
        branch=Budget(80, 80, 256, 2e-3, "cosine", fused_adam=False, ib=FK_MEMORY_IB),
        follow=Budget(IK_EPOCHS, IK_EPOCHS, 512, 2e-3, "cosine", fused_adam=False),
        compare=Budget(40, 8, 128, fused_adam=False), grid=Budget(15, 5, 128, fused_adam=False),
        grid_sequences=None,
    ),
    # the CI test of the whole pipeline: every step and key, seconds of training (the recommended FK
    # with its window, so that its streaming, export and the refined IK on it run as at quick scale)
    "tiny": ReproScale(
        "tiny",
        "quick",   # with the tiny size's levels and step: the key of reproductions recorded before
        PAPER_SIZES["tiny"].levels_mm,
        PAPER_SIZES["tiny"].outer_step_deg,
        main=Budget(2, 2, 256),
        branch=Budget(2, 2, 256, 2e-3, "cosine", ib=FK_MEMORY_IB),
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


Scale = Literal["full", "quick", "tiny"]
Executor = Literal["local", "ray"]


def _help(text: str) -> dict[str, str]:
    """A field's metadata: its meaning, which is also its `ctrkin reproduce --help` text."""
    return {"help": text}


@dataclass(frozen=True)
class ReproduceConfig:
    """What a reproduction runs on (`ctrkin reproduce` has one option per field, ctrkin.cli.from_config)."""

    scale: Scale = field(default="quick", metadata=_help(
        "quick: ~6 min on 2 quiet cores on the default robot (36 at load 3.5 on a slower host); full: "
        "the paper's protocol (~208k samples), batch 1024 with early stopping (the paper: batch 32, up "
        "to 500 epochs), ~30 min on 2 cores at the central values; tiny: a smoke test of every step."))
    robot: str = field(default="paper", metadata=_help(
        "Built-in robot name (paper, timclab) or path to a robot TOML file."))
    robot_seed: int = field(default=0, metadata=_help("The virtual hardware draw."))
    workers: int = field(default=2, metadata=_help(
        "Models trained in parallel (one thread each); with --executor ray and no RAY_ADDRESS, the CPUs "
        "of the local Ray instance."))
    executor: Executor = field(default="local", metadata=_help(
        "local: spawned processes; ray: one Ray task per training, on the cluster at RAY_ADDRESS or a "
        "local instance (pip install 'ctrkin[ray]')."))
    device: Device = field(default="auto", metadata=_help(
        "Where the models train: auto (CUDA where torch sees a GPU, else the CPU, and says which), cpu, "
        "or cuda (an error without one). Not part of the settings a rerun must match."))
    virtual: VirtualConfig = field(default_factory=VirtualConfig, metadata={
        **_help(SETTINGS_HELP), "key_values": True, "name": "--set", "metavar": "KEY=VALUE"})
    out: str = field(default="out/reproduce", metadata={**_help(
        "Output folder. A rerun with the same settings reuses its data and models; one with other "
        "settings is refused unless --overwrite."), "path": "out"})

    def __post_init__(self) -> None:
        get_scale(self.scale)
        if self.executor not in get_args(Executor):
            raise CtrkinError(f"executor must be one of {get_args(Executor)}, got {self.executor!r}")
        if self.device not in DEVICES:
            raise CtrkinError(f"device must be one of {DEVICES}, got {self.device!r}")
        if self.device == "cuda" and self.executor == "ray":
            raise CtrkinError("--device cuda with --executor ray: the Ray tasks reserve CPUs only; pass "
                              "--device cpu, or use the local executor to train on a GPU")
        if not isinstance(self.workers, int) or self.workers < 1:
            raise CtrkinError(f"workers must be an integer >= 1, got {self.workers!r}")
        if not isinstance(self.virtual, VirtualConfig):
            raise CtrkinError(f"virtual must be a VirtualConfig, got {type(self.virtual).__name__}")
