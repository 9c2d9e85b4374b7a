"""A rig description: the robot, its drives, its tracker, in one TOML file (docs/hardware.md).

    name = "paper-rig"
    robot = "paper"                       # built-in name or robot TOML (relative to this file)
    home = [0, 0, -20, 0]                 # joints (deg, mm) the rig goes to after homing
    home_every_run = true                 # home before every protocol run (its state from rest)

    [actuator]
    kind = "canopen"                      # canopen | virtual | replay
    interface = "socketcan"               # python-can interface (socketcan, pcan, kvaser, ixxat, virtual)
    channel = "can0"
    bitrate = 1000000

    [[actuator.drives]]                   # one per joint, any order
    joint = "alpha_1"
    node_id = 1
    counts_per_turn = 4096                # encoder increments per motor turn (1024 CPT, quadrature)
    gear_ratio = 35                       # motor turns per output turn (or per lead-screw turn)
    min = -720.0                          # joint limits (deg or mm)
    max = 720.0
    max_velocity = 60.0                   # deg/s or mm/s: the cap no move exceeds
    # translation drives also: lead_mm = 2.0 (mm per lead-screw turn)

    [tracker]
    kind = "ndi"                          # ndi | virtual | replay
    device = "aurora"                     # aurora | polaris | vega
    port = "/dev/ttyUSB0"                 # serial port (or host = "192.168.0.2" for a Vega)
    readings = 5                          # averaged per sample (the paper: five)

Joint value = zero + direction · counts / (counts per joint unit), with counts per unit =
counts_per_turn · gear_ratio / 360 for a rotation (deg) and counts_per_turn · gear_ratio / lead_mm
for a translation (mm). Every error names the file, the table and the key, and says what to change.
"""

from __future__ import annotations

import hashlib
import json
import math
import tomllib
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ctrkin.errors import CtrkinError, JointError
from ctrkin.geometry import RigidTransform
from ctrkin.hardware.interfaces import OK, STATUSES
from ctrkin.robots.robot import Robot, joint_names

ACTUATOR_KINDS = ("canopen", "virtual", "replay")
TRACKER_KINDS = ("ndi", "virtual", "replay")
NDI_DEVICES = ("aurora", "polaris", "vega")
VELOCITY_UNITS = ("rpm", "counts/s")


class RigError(CtrkinError, ValueError):
    """A rig description is malformed or not physical."""


class _Table:
    """Typed reads of one TOML table with messages 'FILE: [table] key: what to change'."""

    def __init__(self, d: object, where: str) -> None:
        if not isinstance(d, Mapping):
            raise RigError(f"{where}: must be a table, got {d!r}")
        self.d, self.where = dict(d), where
        self.used: set[str] = set()

    def _get(self, key: str, default: Any, what: str = "") -> Any:
        self.used.add(key)
        if key not in self.d:
            if default is _REQUIRED:
                raise RigError(f"{self.where}: needs {key} = ...{what}")
            return default
        return self.d[key]

    def number(self, key: str, default: Any = None, positive: bool = False, what: str = "") -> float:
        if key not in self.d and default is not _REQUIRED:
            self.used.add(key)
            return float(default)
        v = self._get(key, default, what)
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise RigError(f"{self.where} {key}: must be a finite number{what}, got {v!r}")
        if positive and v <= 0:
            raise RigError(f"{self.where} {key}: must be > 0{what}, got {v!r}")
        return float(v)

    def integer(self, key: str, default: Any = None, lo: int | None = None, what: str = "") -> int:
        v = self._get(key, default, what)
        if isinstance(v, bool) or not isinstance(v, int) or (lo is not None and v < lo):
            bound = f" >= {lo}" if lo is not None else ""
            raise RigError(f"{self.where} {key}: must be a whole number{bound}{what}, got {v!r}")
        return int(v)

    def text(self, key: str, default: Any = None, choices: tuple[str, ...] | None = None) -> str:
        v = self._get(key, default)
        if not isinstance(v, str) or (choices is not None and v not in choices):
            allowed = f" one of {list(choices)}" if choices else " text"
            raise RigError(f"{self.where} {key}: must be{allowed}, got {v!r}")
        return v

    def flag(self, key: str, default: bool) -> bool:
        v = self._get(key, default)
        if not isinstance(v, bool):
            raise RigError(f"{self.where} {key}: must be true or false, got {v!r}")
        return v

    def raw(self, key: str, default: Any = None) -> Any:
        return self._get(key, default)

    def done(self) -> None:
        unknown = sorted(set(self.d) - self.used)
        if unknown:
            raise RigError(f"{self.where}: unknown key(s) {unknown}; allowed: {sorted(self.used)}")


_REQUIRED = object()


@dataclass(frozen=True)
class Drive:
    """One joint's motor, gear and encoder (module docstring). Values in deg or mm of the joint."""

    joint: str
    node_id: int = 0
    counts_per_turn: float = 4096.0
    gear_ratio: float = 1.0
    lead_mm: float | None = None
    direction: int = 1
    zero: float = 0.0
    min: float = -math.inf
    max: float = math.inf
    max_velocity: float = 30.0
    velocity: float = 10.0
    homing_method: int = 37
    home_offset_counts: int = 0
    velocity_unit: str = "rpm"

    @property
    def is_rotation(self) -> bool:
        return self.joint.startswith("alpha_")

    @property
    def counts_per_unit(self) -> float:
        """Encoder counts per deg (rotation) or per mm (translation)."""
        if self.is_rotation:
            return self.counts_per_turn * self.gear_ratio / 360.0
        return self.counts_per_turn * self.gear_ratio / float(self.lead_mm or 1.0)

    def to_counts(self, value: float) -> int:
        return round(self.direction * (value - self.zero) * self.counts_per_unit)

    def from_counts(self, counts: float) -> float:
        return self.zero + self.direction * float(counts) / self.counts_per_unit

    def drive_velocity(self, v: float) -> int:
        """A joint speed (deg/s or mm/s) in the drive's velocity unit (motor rpm or counts/s),
        at least 1 (a drive refuses a zero profile velocity)."""
        counts_per_s = abs(v) * self.counts_per_unit
        value = counts_per_s / self.counts_per_turn * 60.0 if self.velocity_unit == "rpm" else counts_per_s
        return max(1, round(value))


@dataclass(frozen=True)
class ActuatorSpec:
    kind: str
    drives: tuple[Drive, ...] = ()
    interface: str = "socketcan"
    channel: str = "can0"
    bitrate: int = 1_000_000
    eds: str | None = None
    simulate: bool = False
    simulation_speedup: float = 1.0
    timeout_s: float = 60.0
    settle_s: float = 0.0
    log: str | None = None


@dataclass(frozen=True)
class TrackerSpec:
    kind: str
    device: str = "aurora"
    port: str | None = None
    host: str | None = None
    network_port: int = 8765
    tools: tuple[str, ...] = ()
    sensor_tool: int = 1
    reference_tool: int = 0
    orientation: str = "tangent"
    readings: int = 5
    max_bad_readings: int = 20
    accept: tuple[str, ...] = (OK,)
    volume_min: tuple[float, ...] = ()
    volume_max: tuple[float, ...] = ()
    registration: dict[str, Any] | None = None
    settle_s: float = 0.0
    log: str | None = None


@dataclass(frozen=True, eq=False)
class RigDescription:
    """A parsed rig file. home: (2N,) joints of the home configuration; limits and velocity caps
    per joint come from the drives (the robot's own validity is checked as well)."""

    name: str
    robot: Robot
    home: np.ndarray
    actuator: ActuatorSpec
    tracker: TrackerSpec
    home_every_run: bool = True
    virtual: dict[str, Any] = field(default_factory=dict)
    source: str = "rig"
    folder: Path = Path(".")

    @property
    def n_joints(self) -> int:
        return self.robot.n_joints

    def drive(self, joint: str) -> Drive | None:
        return next((d for d in self.actuator.drives if d.joint == joint), None)

    def limits(self) -> tuple[np.ndarray, np.ndarray]:
        """(2N,) lower and upper joint limits (deg, mm) of the drives (±inf where none is given)."""
        lo = np.full(self.n_joints, -np.inf)
        hi = np.full(self.n_joints, np.inf)
        for k, name in enumerate(self.robot.joint_names()):
            d = self.drive(name)
            if d is not None:
                lo[k], hi[k] = d.min, d.max
        return lo, hi

    def max_velocity(self) -> np.ndarray:
        """(2N,) velocity caps (deg/s, mm/s); without drives 30 deg/s and 5 mm/s."""
        out = np.array([30.0] * self.robot.n_tubes + [5.0] * self.robot.n_tubes)
        for k, name in enumerate(self.robot.joint_names()):
            d = self.drive(name)
            if d is not None:
                out[k] = d.max_velocity
        return out

    def velocity(self) -> np.ndarray:
        """(2N,) default move velocities (deg/s, mm/s), never above the caps."""
        out = 0.5 * self.max_velocity()
        for k, name in enumerate(self.robot.joint_names()):
            d = self.drive(name)
            if d is not None:
                out[k] = min(d.velocity, d.max_velocity)
        return out

    def check(self, q: np.ndarray) -> None:
        """Refuse joints q (2N,) outside the drives' limits or the robot's valid set (JointError
        naming the joint and the limit)."""
        qa = np.asarray(q, dtype=float)
        lo, hi = self.limits()
        bad = np.nonzero((qa < lo - 1e-9) | (qa > hi + 1e-9))[0]
        if bad.size:
            k = int(bad[0])
            name = self.robot.joint_names()[k]
            raise JointError(f"{name} = {qa[k]:g} is outside the rig's limits [{lo[k]:g}, {hi[k]:g}] "
                             f"({self.source} [[actuator.drives]] joint = {name!r})")
        self.robot.check_joints(qa)

    def path(self, value: str) -> Path:
        """A file named in the rig file, relative to the rig file's folder."""
        p = Path(value).expanduser()
        return p if p.is_absolute() else self.folder / p

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "robot": self.robot.to_dict(), "home": self.home.tolist(),
                "home_every_run": self.home_every_run,
                "actuator": {**asdict(self.actuator), "drives": [asdict(d) for d in self.actuator.drives]},
                "tracker": asdict(self.tracker), "virtual": self.virtual, "source": self.source}

    def fingerprint(self) -> str:
        """Hash of everything that decides what the rig records (not the file's name)."""
        d = {k: v for k, v in self.to_dict().items() if k != "source"}
        blob = json.dumps(d, sort_keys=True, default=str).encode()
        return hashlib.sha256(blob).hexdigest()[:16]

    @classmethod
    def from_toml(cls, path: str | Path) -> RigDescription:
        p = Path(path)
        if not p.is_file():
            raise RigError(f"rig file {p} does not exist")
        try:
            d = tomllib.loads(p.read_text())
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
            raise RigError(f"{p}: not valid TOML: {e}") from None
        return parse_rig(d, source=str(p), folder=p.parent)


def _robot(value: object, where: str, folder: Path) -> Robot:
    from ctrkin.robots import load_robot

    if not isinstance(value, str):
        raise RigError(f"{where} robot: a built-in robot name or a robot TOML file, got {value!r}")
    candidate = folder / value
    return load_robot(str(candidate) if value.endswith(".toml") and candidate.is_file() else value)


def _drive(d: object, where: str, names: list[str], kind: str) -> Drive:
    t = _Table(d, where)
    joint = t.text("joint", _REQUIRED)
    if joint not in names:
        raise RigError(f"{where} joint: {joint!r} is not a joint of this robot; joints: {names}")
    w = f"{where} ({joint})"
    t.where = w
    rotation = joint.startswith("alpha_")
    node_id = t.integer("node_id", 0 if kind != "canopen" else _REQUIRED, lo=0,
                        what=" (the drive's CANopen node id, 1..127)")
    if kind == "canopen" and not 1 <= node_id <= 127:
        raise RigError(f"{w} node_id: a CANopen node id is 1..127, got {node_id}")
    lead = None
    if not rotation:
        lead = t.number("lead_mm", _REQUIRED, positive=True, what=" (mm per lead-screw turn)")
    elif "lead_mm" in t.d:
        raise RigError(f"{w} lead_mm: a rotation joint has no lead screw; remove lead_mm")
    direction = t.integer("direction", 1)
    if direction not in (1, -1):
        raise RigError(f"{w} direction: +1 or -1 (the sign of counts per joint unit), got {direction}")
    lo = t.number("min", -math.inf if rotation else _REQUIRED, what=" (deg or mm)")
    hi = t.number("max", math.inf if rotation else _REQUIRED, what=" (deg or mm)")
    if not lo < hi:
        raise RigError(f"{w}: min ({lo:g}) must be below max ({hi:g})")
    vmax = t.number("max_velocity", 30.0 if rotation else 5.0, positive=True, what=" (deg/s or mm/s)")
    v = t.number("velocity", vmax / 2, positive=True, what=" (deg/s or mm/s)")
    if v > vmax:
        raise RigError(f"{w} velocity: {v:g} is above max_velocity {vmax:g}; lower it or raise the cap")
    drive = Drive(joint=joint, node_id=node_id,
                  counts_per_turn=t.number("counts_per_turn", 4096.0, positive=True,
                                           what=" (encoder increments per motor turn)"),
                  gear_ratio=t.number("gear_ratio", 1.0, positive=True,
                                      what=" (motor turns per output or lead-screw turn)"),
                  lead_mm=lead, direction=direction, zero=t.number("zero", 0.0), min=lo, max=hi,
                  max_velocity=vmax, velocity=v, homing_method=t.integer("homing_method", 37),
                  home_offset_counts=t.integer("home_offset_counts", 0),
                  velocity_unit=t.text("velocity_unit", "rpm", VELOCITY_UNITS))
    t.done()
    return drive


def _actuator(d: object, where: str, names: list[str]) -> ActuatorSpec:
    t = _Table(d, where)
    kind = t.text("kind", _REQUIRED, ACTUATOR_KINDS)
    raw = t.raw("drives", [])
    if not isinstance(raw, list):
        raise RigError(f"{where} drives: a list of [[actuator.drives]] tables")
    drives = tuple(_drive(x, f"{where.split(':')[0]}: [[actuator.drives]] {k + 1}", names, kind)
                   for k, x in enumerate(raw))
    seen = [dr.joint for dr in drives]
    dup = sorted({j for j in seen if seen.count(j) > 1})
    if dup:
        raise RigError(f"{where}: joint(s) {dup} have two drives; give each joint one")
    if kind == "canopen":
        missing = [j for j in names if j not in seen]
        if missing:
            raise RigError(f"{where}: no [[actuator.drives]] for joint(s) {missing}; a CANopen rig "
                           "needs a drive for every joint")
        ids = [dr.node_id for dr in drives]
        if len(set(ids)) != len(ids):
            raise RigError(f"{where}: two drives share a node_id ({ids}); each drive needs its own")
    spec = ActuatorSpec(
        kind=kind, drives=drives, interface=t.text("interface", "socketcan"),
        channel=str(t.raw("channel", "can0")),
        bitrate=t.integer("bitrate", 1_000_000, lo=10_000),
        eds=t.raw("eds", None), simulate=t.flag("simulate", False),
        simulation_speedup=t.number("simulation_speedup", 1.0, positive=True),
        timeout_s=t.number("timeout_s", 60.0, positive=True, what=" (s a move may take)"),
        settle_s=t.number("settle_s", 0.0, what=" (s to wait after a move)"),
        log=t.raw("log", None))
    if spec.settle_s < 0:
        raise RigError(f"{where} settle_s: must be >= 0, got {spec.settle_s}")
    if kind == "replay" and not isinstance(spec.log, str):
        raise RigError(f"{where}: a replay actuator needs log = \"readings.csv\" (a recorded rig log)")
    t.done()
    return spec


def _vector(value: object, n: int, where: str) -> tuple[float, ...]:
    if (not isinstance(value, list) or len(value) != n
            or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in value)):
        raise RigError(f"{where}: needs {n} numbers, got {value!r}")
    return tuple(float(v) for v in value)


def _tracker(d: object, where: str) -> TrackerSpec:
    t = _Table(d, where)
    kind = t.text("kind", _REQUIRED, TRACKER_KINDS)
    device = t.text("device", "aurora", NDI_DEVICES)
    tools = t.raw("tools", [])
    if not isinstance(tools, list) or not all(isinstance(x, str) for x in tools):
        raise RigError(f"{where} tools: a list of tool definition (.rom) files, got {tools!r}")
    if kind == "ndi" and device in ("polaris", "vega") and not tools:
        raise RigError(f"{where} tools: a {device} tracks passive or active tools described by .rom "
                       "files; list them (tools = [\"tip.rom\", \"reference.rom\"])")
    accept = t.raw("accept", [OK])
    if not isinstance(accept, list) or not accept or any(a not in STATUSES for a in accept):
        raise RigError(f"{where} accept: tool statuses to accept, from {list(STATUSES)}, got {accept!r}")
    vol = t.raw("volume_mm", None)
    vmin: tuple[float, ...] = ()
    vmax: tuple[float, ...] = ()
    if vol is not None:
        vt = _Table(vol, f"{where} volume_mm")
        vmin = _vector(vt.raw("min", _REQUIRED), 3, f"{where} volume_mm.min")
        vmax = _vector(vt.raw("max", _REQUIRED), 3, f"{where} volume_mm.max")
        vt.done()
        if not all(a < b for a, b in zip(vmin, vmax, strict=True)):
            raise RigError(f"{where} volume_mm: min must be below max on every axis")
    reg = t.raw("registration", None)
    if reg is not None:
        try:
            RigidTransform.from_dict(reg)
        except Exception as e:
            raise RigError(f"{where} registration: {{rotation = [[3x3]], translation_mm = [x, y, z]}} "
                           f"(tracker <- robot base), got {reg!r}: {e}") from None
    spec = TrackerSpec(
        kind=kind, device=device, port=t.raw("port", None), host=t.raw("host", None),
        network_port=t.integer("network_port", 8765, lo=1), tools=tuple(tools),
        sensor_tool=t.integer("sensor_tool", 1, lo=1, what=" (1-based tool index of the tip sensor)"),
        reference_tool=t.integer("reference_tool", 0, lo=0, what=" (0: none)"),
        orientation=t.text("orientation", "tangent", ("tangent", "marker")),
        readings=t.integer("readings", 5, lo=1, what=" (readings averaged per sample)"),
        max_bad_readings=t.integer("max_bad_readings", 20, lo=0,
                                   what=" (consecutive unusable readings before the rig stops)"),
        accept=tuple(accept), volume_min=vmin, volume_max=vmax, registration=reg,
        settle_s=t.number("settle_s", 0.0), log=t.raw("log", None))
    if kind == "ndi" and device == "vega" and not spec.host:
        raise RigError(f"{where}: a vega is reached over the network; give host = \"IP or name\"")
    if spec.reference_tool == spec.sensor_tool:
        raise RigError(f"{where}: reference_tool and sensor_tool are the same tool")
    if kind == "replay" and not isinstance(spec.log, str):
        raise RigError(f"{where}: a replay tracker needs log = \"readings.csv\" (a recorded rig log)")
    t.done()
    return spec


def parse_rig(d: Mapping[str, Any], source: str = "rig", folder: Path = Path(".")) -> RigDescription:
    """A RigDescription from a parsed TOML document (errors name `source`)."""
    t = _Table(d, source)
    name = t.text("name", "rig")
    robot = _robot(t.raw("robot", "paper"), source, folder)
    names = joint_names(robot.n_tubes)
    actuator = _actuator(t.raw("actuator", _REQUIRED), f"{source}: [actuator]", names)
    tracker = _tracker(t.raw("tracker", _REQUIRED), f"{source}: [tracker]")
    simulated = actuator.kind == "virtual" or (actuator.kind == "canopen" and actuator.simulate)
    if (actuator.kind == "virtual" and tracker.kind != "virtual") or (tracker.kind == "virtual"
                                                                        and not simulated):
        raise RigError(f"{source}: the virtual tracker reads the virtual robot, which only a virtual "
                       "actuator or simulated CANopen drives ([actuator] simulate = true) move; set "
                       "both kinds to \"virtual\", or use a real tracker")
    if (actuator.kind == "replay") != (tracker.kind == "replay"):
        raise RigError(f"{source}: a replay plays one recorded log as both actuator and tracker; set both "
                       "kinds to \"replay\" with the same log")
    home_raw = t.raw("home", None)
    home = (np.array(_vector(home_raw, robot.n_joints, f"{source} home"))
            if home_raw is not None else robot.project_joints(np.zeros(robot.n_joints))[0])
    virtual = t.raw("virtual", {})
    if not isinstance(virtual, Mapping):
        raise RigError(f"{source}: [virtual] must be a table (seed, robot_seed, settings)")
    rig = RigDescription(name=name, robot=robot, home=home, actuator=actuator, tracker=tracker,
                         home_every_run=t.flag("home_every_run", True), virtual=dict(virtual),
                         source=source, folder=folder)
    t.done()
    try:
        rig.check(home)
    except JointError as e:
        raise RigError(f"{source} home: {e}") from None
    return rig
