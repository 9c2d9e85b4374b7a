"""Record a protocol on the virtual robot (the TCM of perturbed tubes behind backlash, friction and
an imperfect tracker) into a dataset folder, and compare the nominal TCM with what it recorded.

    python examples/record_virtual_robot.py --out data/sweeps
    python examples/record_virtual_robot.py --protocol paper --scale tiny --out data/paper-tiny
    python examples/record_virtual_robot.py --levels 4,20 --set friction_deg_per_mm=0 --out data/nofriction
"""

from __future__ import annotations

import argparse

from ctrkin.acquisition import protocols
from ctrkin.acquisition.recorder import record
from ctrkin.acquisition.summary import nominal_error, sweep_hysteresis
from ctrkin.data import Dataset
from ctrkin.robots import paper_robot
from ctrkin.virtual import VirtualConfig, VirtualRobot


def main(argv: list[str] | None = None) -> dict[str, object]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--protocol", choices=["sweeps", "paper"], default="sweeps")
    ap.add_argument("--scale", choices=protocols.SCALES, default="tiny", help="size of the paper protocol")
    ap.add_argument("--levels", help="relative translations d (mm), comma-separated")
    ap.add_argument("--set", dest="settings", action="append", default=[], metavar="KEY=VALUE",
                    help="a VirtualConfig field, e.g. noise_mm=0.1 (repeatable)")
    ap.add_argument("--robot-seed", type=int, default=0, help="the virtual hardware draw")
    ap.add_argument("--seed", type=int, default=1, help="measurement noise and glitches")
    ap.add_argument("--out", required=True, help="dataset folder to write")
    args = ap.parse_args(argv)

    robot = paper_robot()
    config = VirtualConfig(**{k: float(v) for k, v in (s.split("=", 1) for s in args.settings)})
    virtual = VirtualRobot(robot, config, seed=args.robot_seed)     # one "robot": keep its seed
    kw = {} if args.levels is None else {"levels": tuple(float(v) for v in args.levels.split(","))}
    plan = protocols.build(args.protocol, robot, scale=args.scale, **kw)
    ds = record(plan, virtual, seed=args.seed, workers=1, progress=False)
    ds.save(args.out)
    back = Dataset.load(args.out)                   # the folder: data.parquet + meta.json
    print(f"{args.protocol}: {len(back.frame)} samples in {back.frame['sequence_id'].nunique()} sequences, "
          f"{int(back.frame['snap'].sum())} snap samples -> {args.out}")
    print(sweep_hysteresis(back).to_string(index=False, float_format=lambda v: f"{v:.2f}"))
    err = nominal_error(back, every=10)
    print(f"nominal TCM vs measured: {err['position_mean_mm_vs_measured']:.2f} mm, "
          f"vs true tip: {err['position_mean_mm_vs_true']:.2f} mm (mean)")
    return {**err, "samples": len(back.frame), "snap_samples": int(back.frame["snap"].sum())}


if __name__ == "__main__":
    main()
