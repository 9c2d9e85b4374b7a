"""The virtual robot: the TCM of a perturbed ("true") robot behind imperfect actuation and sensing.

Data flow of one motion (joints are motor-side encoder values, the fixed joint convention):

    commanded motor joints m (T, 2N)
      -> play operator per joint (backlash + friction dead band, transmission.py)
      -> + encoder zero offset of each rotation (tube clamped into its gear by hand)
      -> clipped to the stages' travel                       = tube base joints b (T, 2N)
      -> TCM continuation on the true tubes (mechanics.follow: history, snaps, the friction
         between the tubes and its state, the clearance tilt)
      -> true tip pose (robot base frame)                    = true_* columns
      -> tracker: sensor offset, registration error, field warp, noise, mean of 5 readings
                                                             = measured x..qy columns
    encoder readings = m, with rare glitches (outlier = True)

One `VirtualRobot(nominal, config, seed)` is one reproducible piece of hardware: the same seed gives
the same true tubes, offsets and registration. Measurement noise is drawn from a generator passed in
per recording, so protocols decide how to seed (and parallelise) it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ctrkin.geometry import tip_pose
from ctrkin.mechanics import Equilibrium, follow, solve, solve_many
from ctrkin.mechanics.settings import DEFAULT_SETTINGS
from ctrkin.robots.robot import Robot
from ctrkin.virtual.config import VirtualConfig
from ctrkin.virtual.encoder import glitch
from ctrkin.virtual.field import FieldWarp
from ctrkin.virtual.hardware import perturb_robot
from ctrkin.virtual.tracker import Tracker
from ctrkin.virtual.transmission import clip_to_valid, curved_overlap, dead_band, play

WORKSPACE_POINTS = 64


def workspace(robot: Robot, rng: np.random.Generator, n: int = WORKSPACE_POINTS) -> np.ndarray:
    """(n, 3) mm: tips of the nominal robot at random valid joints (any rotation, translations
    across their travel), a sample of where the tracker will see the robot."""
    nt = robot.n_tubes
    q = np.zeros((n, 2 * nt))
    q[:, :nt] = rng.uniform(0.0, 360.0, (n, nt))
    # translations: the outer tube out by at least three quarters of its length, each inner one
    # anywhere between fully retracted into the next and flush with it
    lengths = robot.lengths
    q[:, 2 * nt - 1] = -rng.uniform(0.0, 0.25, n) * lengths[-1]
    for i in range(nt - 2, -1, -1):
        q[:, nt + i] = q[:, nt + i + 1] - rng.uniform(0.0, 1.0, n) * (lengths[i] - lengths[i + 1])
    return np.array([e.tip_position for e in solve_many(robot, robot.project_joints(q))])


@dataclass(frozen=True, eq=False)
class VirtualState:
    """Where the robot is between motions. equilibrium: the true robot's TCM state (its branch);
    play: (2N,) the play operators' outputs (motor-side deg, mm) before offsets and clipping."""

    equilibrium: Equilibrium
    play: np.ndarray


@dataclass(frozen=True, eq=False)
class Motion:
    """A motion of the virtual robot, T steps. commanded (T, 2N) motor joints (deg, mm); base (T, 2N)
    the tube-base joints the mechanics saw; true_poses (T, 6) in the robot base frame; snaps (T,)
    bool: a fold of the true robot's equilibrium branch was crossed on the way into the step;
    given_up (T,) bool: steps whose continuation follow gave up (its budget spent) and `move` solved
    again from the step before (the costly steps: benchmarks/bench_step_cost.py counts them)."""

    commanded: np.ndarray
    base: np.ndarray
    true_poses: np.ndarray
    snaps: np.ndarray
    given_up: np.ndarray


@dataclass(frozen=True, eq=False)
class Recording:
    """Sensor view of a motion. joints (T, 2N) encoder readings; outlier (T,) bool (a glitch);
    measured (T, 6) tracker poses registered to the robot base."""

    joints: np.ndarray
    outlier: np.ndarray
    measured: np.ndarray


class VirtualRobot:
    """nominal: the robot description a user would have; config: effect magnitudes;
    seed: draws the hardware (true tubes, encoder offsets, registration)."""

    def __init__(self, nominal: Robot, config: VirtualConfig | None = None, seed: int = 0) -> None:
        self.nominal = nominal
        self.config = config if config is not None else VirtualConfig()
        self.seed = int(seed)
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, 0x5EED]))
        shape_rng, field_rng = (np.random.default_rng(np.random.SeedSequence([self.seed, 0x5EED, k]))
                                for k in (1, 2))   # streams of their own: rng's draws stay put
        self.true_robot, self.tube_errors = perturb_robot(nominal, self.config, rng, shape_rng)
        self.alpha_offset = self.config.alpha_zero_error_deg * rng.standard_normal(nominal.n_tubes)
        c = self.config
        tracker = Tracker.draw(rng, c.registration_mm, c.registration_deg, c.sensor_offset_mm,
                               c.noise_mm, c.noise_deg, c.readings_per_sample)
        if c.em_distortion_mm > 0:
            warp = FieldWarp.draw(field_rng, c.em_distortion_mm, c.em_distortion_length_mm,
                                  workspace(nominal, field_rng))
            tracker = dataclasses.replace(tracker, warp=warp)
        self.tracker = tracker
        # the true robot's solver: its contacts' elastic slip is an effect of the robot
        self.settings = dataclasses.replace(DEFAULT_SETTINGS, stick_mm=c.presliding_mm)

    # --- actuation ------------------------------------------------------------------------------
    def base_joints(self, play_out: np.ndarray) -> np.ndarray:
        """Play outputs (T, 2N) -> tube-base joints (T, 2N): encoder offsets added, stops applied."""
        n = self.nominal.n_tubes
        b = np.array(play_out, dtype=float, copy=True)
        b[:, :n] += self.alpha_offset
        return clip_to_valid(self.true_robot, b)

    def rest(self, q: np.ndarray) -> VirtualState:
        """The robot at rest at motor joints q (2N,): play centred, the lowest-energy stable
        equilibrium (a point-wise solve: no history before the first motion)."""
        qa = self.nominal.check_joints(np.asarray(q, dtype=float))
        base = self.base_joints(qa[None, :])[0]
        return VirtualState(solve(self.true_robot, base, settings=self.settings), qa.copy())

    def move(self, state: VirtualState, Q: np.ndarray,
             progress: Callable[[int], None] | None = None) -> tuple[Motion, VirtualState]:
        """Drive the motors through Q (T, 2N) (deg, mm), starting from `state`."""
        Qa = self.nominal.check_joints(np.atleast_2d(np.asarray(Q, dtype=float)))
        width = dead_band(self.nominal, self.config, Qa)
        p = np.empty_like(Qa)
        play(Qa, width, state.play, p)
        base = self.base_joints(p)
        tr = follow(self.true_robot, base, start=state.equilibrium, settings=self.settings,
                    progress=progress)
        poses = tr.tip_poses
        # the equilibria solved again below; the others are made only where read (the last, and
        # those before a step solved again: making all of them cost ~20 µs a step, issue 26)
        redone: dict[int, Equilibrium] = {}

        def eq_at(t: int) -> Equilibrium:
            return redone[t] if t in redone else tr.equilibrium(t)

        for t in np.flatnonzero(~tr.converged).tolist():
            # follow gave up this step (its continuation budget, SolverSettings.max_search_steps,
            # spent; the inner reversals on three tubes that did this are now continued, but an
            # extreme robot may still): a real tube still has a pose, so the step is solved from
            # the equilibrium before it with its friction state (solve's snap recovery), else afresh
            before = eq_at(t - 1) if t > 0 else state.equilibrium
            eq = solve(self.true_robot, base[t], guess=before, state=before.friction_state,
                       settings=self.settings)
            if not eq.converged:   # no branch near it: the lowest-energy stable one, same friction state
                eq = solve(self.true_robot, base[t], state=before.friction_state, settings=self.settings)
            if not eq.converged:   # no equilibrium holds that friction state: the tubes slip, and the
                # step is the lowest-energy one from rest
                eq = solve(self.true_robot, base[t], settings=self.settings)
            if not eq.converged:   # none at all: the step stays unconverged (NaN pose), as follow said
                continue
            redone[t] = eq
            poses[t] = tip_pose(eq.tip_position[None, :], eq.tip_tangent[None, :])[0]
        motion = Motion(commanded=Qa, base=base, true_poses=poses, snaps=tr.snaps,
                        given_up=~tr.converged)
        return motion, VirtualState(eq_at(len(Qa) - 1), p[-1].copy())

    # --- sensing --------------------------------------------------------------------------------
    def record(self, motion: Motion, rng: np.random.Generator) -> Recording:
        """Encoder readings and tracker poses of a motion (noise drawn from rng)."""
        c = self.config
        joints, outlier = glitch(self.nominal, motion.commanded, c.glitch_rate, c.glitch_deg,
                                 c.glitch_mm, rng)
        return Recording(joints, outlier, self.tracker.measure(motion.true_poses, rng))

    def curved_overlap(self, Q: np.ndarray) -> np.ndarray:
        """(T,) mm of curved overlap of the nominal robot at joints Q (T, 2N)."""
        return curved_overlap(self.nominal, Q)

    def describe(self) -> dict[str, Any]:
        """Everything that defines this virtual robot, for the dataset meta."""
        return {"seed": self.seed, "config": self.config.to_dict(),
                "true_robot": self.true_robot.to_dict(), "tube_errors": self.tube_errors,
                "alpha_zero_offset_deg": self.alpha_offset.tolist(),
                "tracker": self.tracker.to_dict()}
