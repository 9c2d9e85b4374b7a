"""A concentric tube robot: tubes innermost first, a transmission model, joint convention checks.

Joint vector (fixed convention): q = (α1..αN deg, β1..βN mm). βi is the base position of tube i
relative to the front plate (s = 0), βi ≤ 0; tube i occupies s ∈ [βi, βi + Li]. Valid joints satisfy
β1 ≤ β2 ≤ … ≤ βN ≤ 0 and β1 + L1 ≥ β2 + L2 ≥ … ≥ βN + LN ≥ 0.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import reprlib
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import tomli_w

from ctrkin.errors import JointError, RobotDescriptionError
from ctrkin.robots.tube import Tube
from ctrkin.util.files import atomic_write_text

Transmission = Literal["compliant", "rigid"]
JOINT_TOL = 1e-9  # mm: slack on the joint inequalities for round-off



def alpha_names(n_tubes: int) -> list[str]:
    """Names of the base rotations αi (deg), innermost tube first: alpha_1..alpha_N."""
    return [f"alpha_{i + 1}" for i in range(n_tubes)]


def beta_names(n_tubes: int) -> list[str]:
    """Names of the base translations βi (mm), innermost tube first: beta_1..beta_N."""
    return [f"beta_{i + 1}" for i in range(n_tubes)]


def joint_names(n_tubes: int) -> list[str]:
    """Joint vector order (fixed, docs/design.md: Conventions): α1..αN, β1..βN. These are the dataset's
    joint columns (ctrkin.data.schema) and the learned models' joint features."""
    return alpha_names(n_tubes) + beta_names(n_tubes)


def _lengths_mm(values: Any, n_tubes: int) -> tuple[float, ...]:
    """Robot.transmission_length as floats: empty, or one finite number >= 0 (mm) per tube. Anything
    else (text, lists, tables, booleans) is a RobotDescriptionError naming what was given."""
    what = (f"Robot.transmission_length needs {n_tubes} finite numbers >= 0 mm (one per tube) or "
            f"none, got {reprlib.repr(values)}")
    if isinstance(values, (str, bytes, dict)):
        raise RobotDescriptionError(what)
    try:
        items: tuple[Any, ...] = tuple(values)
    except TypeError:
        raise RobotDescriptionError(what) from None
    if not items:
        return ()
    ok = len(items) == n_tubes and all(
        isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))
        for v in items)
    try:
        out = tuple(float(v) for v in items) if ok else ()
    except OverflowError:       # an int beyond float range
        ok = False
    if not ok or not all(math.isfinite(v) and v >= 0 for v in out):
        raise RobotDescriptionError(what)
    return out


@dataclass(frozen=True)
class Robot:
    """A concentric tube robot: its tubes and how their bases are driven.

    Joints are q = (α1..αN deg, β1..βN mm), innermost tube first; βi ≤ 0 is the base of tube i
    relative to the front plate, and valid joints satisfy β1 ≤ … ≤ βN ≤ 0 and
    β1 + L1 ≥ … ≥ βN + LN ≥ 0 (`check_joints`; docs/design.md: Conventions).

    Parameters
    ----------
    tubes : tuple of Tube
        Innermost first; inner tubes at least as long as outer ones.
    transmission : {"compliant", "rigid"}
        "compliant": the part s < 0 inside the actuation unit is straight but twists
        (docs/mechanics.md: Model); "rigid": the tube's base angle is αi at s = 0.
    name : str
        A label (files and reports); not part of `mechanical_fingerprint`.
    transmission_length : tuple of float, optional
        (N,) mm of extra twisting length between each tube's actuator and its carriage, beyond the
        −βi inside the actuation unit (a calibrated parameter; empty: zeros).
    friction : float
        Coulomb coefficient μ between neighbouring tubes (0, the default: the frictionless TCM;
        docs/mechanics.md: Friction and clearance).
    clearance : float
        How much of the radial gap between neighbouring tubes (from their diameters) lets a tube
        tilt where it leaves the next one's tip (0, the default: concentric centrelines, the
        standard TCM; 1: the whole gap).

    Examples
    --------
    >>> import ctrkin
    >>> robot = ctrkin.paper_robot()
    >>> robot.n_tubes, robot.joint_names()
    (2, ['alpha_1', 'alpha_2', 'beta_1', 'beta_2'])
    """

    tubes: tuple[Tube, ...]
    transmission: Transmission = "compliant"
    name: str = "robot"
    transmission_length: tuple[float, ...] = ()
    friction: float = 0.0
    clearance: float = 0.0

    def __post_init__(self) -> None:
        try:
            tubes = tuple(self.tubes)
        except TypeError:
            raise RobotDescriptionError(
                f"Robot.tubes must be a sequence of Tube, innermost first, got {self.tubes!r}") from None
        object.__setattr__(self, "tubes", tubes)
        tl = _lengths_mm(self.transmission_length, len(tubes))
        object.__setattr__(self, "transmission_length", tl)
        for name, upper in (("friction", 2.0), ("clearance", 10.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not 0.0 <= v <= upper:
                raise RobotDescriptionError(
                    f"Robot.{name} must be a number in [0, {upper:g}] (0 switches it off), got {v!r}")
            object.__setattr__(self, name, float(v))
        if len(tubes) < 1:
            raise RobotDescriptionError("Robot needs at least one tube")
        for k, t in enumerate(tubes):
            if not isinstance(t, Tube):
                raise RobotDescriptionError(f"Robot.tubes[{k}] must be a Tube, got {type(t)}")
        if self.transmission not in ("compliant", "rigid"):
            raise RobotDescriptionError(
                f"Robot.transmission must be 'compliant' or 'rigid', got {self.transmission!r}")
        for k in range(len(tubes) - 1):
            inner, outer = tubes[k], tubes[k + 1]
            if inner.od > outer.id + 1e-12:
                raise RobotDescriptionError(
                    f"tube {k + 1} (od {inner.od} mm) does not fit inside tube {k + 2} "
                    f"(id {outer.id} mm): list tubes innermost first")
            if inner.length < outer.length:
                raise RobotDescriptionError(
                    f"tube {k + 1} ({inner.length} mm) is shorter than tube {k + 2} "
                    f"({outer.length} mm): inner tubes must be at least as long as outer ones")

    @property
    def n_tubes(self) -> int:
        """N, the number of tubes."""
        return len(self.tubes)

    @property
    def n_joints(self) -> int:
        """2N: a rotation and a translation per tube."""
        return 2 * len(self.tubes)

    @property
    def lengths(self) -> np.ndarray:
        """(N,) mm: each tube's total length L, innermost first."""
        return np.array([t.length for t in self.tubes])

    def joint_names(self) -> list[str]:
        """alpha_1..alpha_N, beta_1..beta_N: the dataset's joint columns, in joint order."""
        return joint_names(self.n_tubes)

    def project_joints(self, Q: np.ndarray) -> np.ndarray:
        """Project joints onto the valid set by moving translations only, as the mechanical stops would.

        βN ≤ 0 and βN + LN ≥ 0 first, then outward-in βi ≤ βi+1 and βi + Li ≥ βi+1 + Li+1; rotations
        are unlimited and unchanged.

        Parameters
        ----------
        Q : ndarray, shape (T, 2N)
            Joints (deg, mm).

        Returns
        -------
        ndarray, shape (T, 2N)
            A projected copy.
        """
        out = np.array(Q, dtype=float, copy=True)
        n = self.n_tubes
        lengths = self.lengths
        out[:, 2 * n - 1] = np.clip(out[:, 2 * n - 1], -lengths[-1], 0.0)
        for i in range(n - 2, -1, -1):
            outer = out[:, n + i + 1]
            lo = outer + lengths[i + 1] - lengths[i]
            out[:, n + i] = np.clip(out[:, n + i], lo, np.maximum(outer, lo))
        return out

    @functools.cached_property
    def _lengths(self) -> np.ndarray:
        out = self.lengths
        out.setflags(write=False)
        return out

    def _rule_message(self, rule: int) -> str:
        """The message of inequality `rule` (joint_check.joint_violations: 0 non-finite, 1.. the
        inequalities)."""
        n = self.n_tubes
        if rule == 1:
            return f"beta_{n} must be <= 0 mm (bases behind the front plate)"
        if rule == 2:
            return f"tube {n} tip beta_{n} + L_{n} must be >= 0 mm (no tube pulled behind the plate)"
        i = (rule - 3) // 2
        if rule % 2:
            return (f"beta_{i + 1} <= beta_{i + 2} is required (tube {i + 1} is inside "
                    f"tube {i + 2}, so its base is further back)")
        return (f"beta_{i + 1} + L_{i + 1} >= beta_{i + 2} + L_{i + 2} is required "
                f"(inner tubes reach further)")

    def check_joints(self, q: np.ndarray) -> np.ndarray:
        """Validate joints against the convention and the robot's limits.

        Parameters
        ----------
        q : array_like, shape (2N,) or (T, 2N)
            Joints (α deg, β mm).

        Returns
        -------
        ndarray
            The joints as floats, same shape.

        Raises
        ------
        JointError
            Naming the violated condition (and the row of a trajectory): a wrong shape, NaN, inf or
            complex values, or a translation the robot cannot take.
        """
        if np.iscomplexobj(q):
            raise JointError("joints must be real numbers (deg, mm), got complex values")
        try:
            qa = np.asarray(q, dtype=float)
        except (TypeError, ValueError) as e:
            raise JointError(f"joints must be numbers (alpha deg, beta mm): {e}") from None
        n = self.n_tubes
        if qa.shape[-1:] != (2 * n,) or qa.ndim not in (1, 2):
            raise JointError(f"joints must have shape (2N,) or (T, 2N) with 2N = {2 * n} "
                             f"(alpha_1..alpha_N deg, beta_1..beta_N mm), got {qa.shape}")
        rows = qa.reshape(-1, 2 * n)
        from ctrkin.robots.joint_check import joint_violations  # numba: loaded on first check

        codes, first = joint_violations(rows, self._lengths)
        if first < 0:
            return qa
        r = int(np.argmax(codes == first))
        if first == 0:
            raise JointError(f"joints contain NaN or inf at row {r}")
        where = f" (row {r}: {rows[r].tolist()})" if qa.ndim == 2 else f" (q = {rows[r].tolist()})"
        raise JointError(self._rule_message(first) + where)

    def is_valid(self, q: np.ndarray) -> np.ndarray:
        """Which rows of joints are valid, without raising for the invalid ones.

        Parameters
        ----------
        q : array_like, shape (2N,) or (T, 2N)
            Joints (deg, mm).

        Returns
        -------
        ndarray of bool, shape (T,)
        """
        if np.iscomplexobj(q):
            raise JointError("joints must be real numbers (deg, mm), got complex values")
        rows = np.atleast_2d(np.asarray(q, dtype=float))
        n = self.n_tubes
        if rows.ndim != 2 or rows.shape[1] != 2 * n:
            raise JointError(f"joints must have shape (2N,) or (T, 2N) with 2N = {2 * n}, got {rows.shape}")
        from ctrkin.robots.joint_check import joint_violations

        return joint_violations(rows, self._lengths)[0] < 0

    # --- serialisation -------------------------------------------------------------------------
    def to_dict(self) -> dict[str, object]:
        """The description as a dict, the layout of a robot TOML file (`ctrkin robot template`)."""
        d: dict[str, object] = {"name": self.name, "transmission": self.transmission}
        if any(self.transmission_length):
            d["transmission_length"] = list(self.transmission_length)
        for name in ("friction", "clearance"):
            if getattr(self, name):
                d[name] = getattr(self, name)
        d["tubes"] = [t.to_dict() for t in self.tubes]
        return d

    @classmethod
    def from_dict(cls, d: dict[str, object], source: str = "robot description") -> Robot:
        """A robot from the layout of `to_dict`, validated.

        Parameters
        ----------
        d : dict
            ``name``, ``transmission``, ``transmission_length`` and a ``tubes`` list of `Tube` fields.
        source : str
            Where `d` came from, for the messages (a file name).

        Raises
        ------
        RobotDescriptionError
            Naming the source, the tube and the field.
        """
        if not isinstance(d, dict) or "tubes" not in d:
            raise RobotDescriptionError(f"{source}: needs a 'tubes' list ([[tubes]] in TOML), "
                                        "innermost tube first")
        tubes_raw = d["tubes"]
        if not isinstance(tubes_raw, list) or not tubes_raw:
            raise RobotDescriptionError(f"{source}: 'tubes' must be a non-empty list")
        known = {"od", "id", "straight_length", "curved_length", "curvature", "youngs_modulus",
                 "poisson_ratio", "sections"}
        tubes = []
        for k, t in enumerate(tubes_raw):
            if not isinstance(t, dict):
                raise RobotDescriptionError(f"{source}: tubes[{k}] must be a table")
            unknown = set(t) - known
            if unknown:
                raise RobotDescriptionError(
                    f"{source}: tubes[{k}] has unknown field(s) {sorted(unknown)}; "
                    f"allowed: {sorted(known)}")
            try:
                if "sections" in t and "straight_length" not in t and "curved_length" not in t:
                    tubes.append(Tube.from_sections(
                        t["od"], t["id"], t["sections"],
                        t.get("youngs_modulus", 58.0), t.get("poisson_ratio", 0.33)))
                else:
                    missing = {"od", "id", "straight_length", "curved_length", "curvature"} - set(t)
                    if missing:
                        raise RobotDescriptionError(
                            f"{source}: tubes[{k}] is missing field(s) {sorted(missing)}")
                    args = dict(t)
                    if "sections" in args:
                        args["sections"] = tuple(tuple(s) for s in args["sections"])
                    tubes.append(Tube(**args))
            except RobotDescriptionError as e:
                raise RobotDescriptionError(f"{source}: tubes[{k}]: {e}") from None
            except (TypeError, KeyError) as e:
                raise RobotDescriptionError(f"{source}: tubes[{k}]: {e}") from None
        tl = d.get("transmission_length", ())
        if not isinstance(tl, list | tuple):
            raise RobotDescriptionError(f"{source}: transmission_length must be a list (mm, one per tube)")
        name = d.get("name", "robot")
        if not isinstance(name, str):
            raise RobotDescriptionError(f"{source}: 'name' must be a string, got {name!r}")
        contact = {key: d[key] for key in ("friction", "clearance") if key in d}
        return cls(tubes=tuple(tubes), transmission=d.get("transmission", "compliant"),  # type: ignore[arg-type]
                   name=name, transmission_length=tuple(tl), **contact)  # type: ignore[arg-type]

    def to_toml(self, path: str | Path) -> None:
        """Write the description as a TOML file (atomically)."""
        atomic_write_text(path, tomli_w.dumps(self.to_dict()))

    @classmethod
    def from_toml(cls, path: str | Path) -> Robot:
        """Read a robot TOML file.

        Raises
        ------
        RobotDescriptionError
            If the file is missing, not TOML, or not a valid description (naming the file).
        """
        p = Path(path)
        if not p.is_file():
            raise RobotDescriptionError(f"robot file {p} does not exist")
        try:
            d = tomllib.loads(p.read_text())
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
            raise RobotDescriptionError(f"robot file {p} is not valid TOML: {e}") from None
        except RecursionError:
            raise RobotDescriptionError(f"robot file {p} is nested too deeply to be a robot "
                                        "description ([[tubes]] tables of numbers)") from None
        return cls.from_dict(d, source=str(p))

    def fingerprint(self) -> str:
        """A short hash of the whole description, name included, stored with datasets and models to
        detect a description edited after the fact."""
        blob = json.dumps(self.to_dict(), sort_keys=True).encode()
        return hashlib.sha256(blob).hexdigest()[:16]

    def mechanical_fingerprint(self) -> str:
        """A short hash of what the kinematics depend on (tubes, transmission), not the name: two
        robots with the same one are the same hardware, whatever each file calls it."""
        d = self.to_dict()
        d.pop("name")
        return hashlib.sha256(json.dumps(d, sort_keys=True).encode()).hexdigest()[:16]
