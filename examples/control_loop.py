"""A control-loop style use of a learned FK model: at a fixed rate, read the encoders, estimate the
tip from them with the streaming model, and compare with the tracker where one is fitted.

    python examples/control_loop.py --model models/fk-small              # 100 Hz, 2 s of motion
    python examples/control_loop.py --model models/fk-small --rate 500 --seconds 5

The "robot" is the virtual robot (the same hardware draw, robot seed 0, as the recording the model was
trained on). Each tick does what a controller thread would: command the next joints, read the
encoders and the tracker, `fk.step(joints)` (the model keeps its input buffer and history), and check
that the step met its deadline. On real hardware replace `VirtualRobot` by your drivers; the model's
side stays the same.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import ctrkin
from ctrkin.virtual import VirtualRobot


def trajectory(n_ticks: int) -> np.ndarray:
    """(T, 4) motor joints: the inner tube turning back and forth while both tubes translate slowly."""
    t = np.linspace(0.0, 1.0, n_ticks)
    return np.c_[120.0 * np.sin(2 * np.pi * t) + 120.0, 20.0 * t, -15.0 - 3.0 * np.sin(np.pi * t),
                 -2.0 * t]


def main(argv: list[str] | None = None) -> dict[str, object]:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", required=True, help="an FK model folder (train_and_stream.py, ctrkin train)")
    ap.add_argument("--rate", type=float, default=100.0, help="loop rate (Hz)")
    ap.add_argument("--seconds", type=float, default=2.0, help="length of the motion (s)")
    args = ap.parse_args(argv)

    fk = ctrkin.Kinematics.load(args.model)
    robot = VirtualRobot(fk.robot, seed=0)           # stands in for the hardware drivers
    rng = np.random.default_rng(0)
    period = 1.0 / args.rate
    commands = trajectory(max(int(args.seconds * args.rate), 2))
    state = robot.rest(commands[0])
    fk.reset()                                        # a new sequence: the buffer starts empty
    step_s, errors, late = [], [], 0
    deadline = time.perf_counter()
    for q_cmd in commands:
        deadline += period
        motion, state = robot.move(state, q_cmd[None, :])         # the motors move one tick
        reading = robot.record(motion, rng)                      # encoders and tracker
        t0 = time.perf_counter()
        tip = fk.step(reading.joints[0])                         # the learned FK, one step
        step_s.append(time.perf_counter() - t0)
        errors.append(float(np.linalg.norm(tip[:3] - reading.measured[0, :3])))
        slack = deadline - time.perf_counter()
        if slack < 0:
            late += 1                                            # this tick overran its period
        else:
            time.sleep(slack)
    step_us = 1e6 * np.array(step_s)
    print(f"{len(commands)} ticks at {args.rate:g} Hz: FK step median {np.median(step_us):.0f} µs, "
          f"max {step_us.max():.0f} µs; {late} ticks late (the robot simulation shares the period); "
          f"tip vs tracker {np.mean(errors):.2f} mm mean")
    return {"ticks": len(commands), "late": late, "step_us_median": float(np.median(step_us)),
            "tip_error_mm_mean": float(np.mean(errors))}


if __name__ == "__main__":
    main()
