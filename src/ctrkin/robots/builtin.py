"""Built-in robots.

The paper robot (paper Table I): two nitinol tubes for vitreoretinal surgery. The paper gives no
elastic modulus; we use E = 58 GPa and ν = 0.33, typical of superelastic nitinol tubes in the CTR
literature (Webster, Romano, Cowan 2009: E ≈ 58 GPa measured on nitinol tubes; Rucker, Jones, Webster
2010 use ν = 0.33). In the unloaded TCM the kinematics depend only on stiffness *ratios*, so a common E
cancels; ν enters through GJ = EI / (1 + ν).
"""

from __future__ import annotations

from importlib import resources

from ctrkin.robots.robot import Robot
from ctrkin.robots.tube import Tube

NITINOL_E_GPA = 58.0
NITINOL_NU = 0.33


def paper_robot(transmission: str = "compliant") -> Robot:
    """The two-tube robot of paper Table I, innermost first.

    Inner: OD 0.4, ID 0.2 mm, straight 57 mm, curved 15 mm, radius 27 mm. Outer: OD 0.635, ID 0.48
    mm, straight 37 mm, curved 14.5 mm, radius 24 mm. E = 58 GPa, ν = 0.33 (module docstring).

    Parameters
    ----------
    transmission : {"compliant", "rigid"}
        The transmission model (`Robot`).

    Returns
    -------
    Robot
        Named "paper".
    """
    inner = Tube(od=0.4, id=0.2, straight_length=57.0, curved_length=15.0, curvature=1 / 27.0,
                 youngs_modulus=NITINOL_E_GPA, poisson_ratio=NITINOL_NU)
    outer = Tube(od=0.635, id=0.48, straight_length=37.0, curved_length=14.5, curvature=1 / 24.0,
                 youngs_modulus=NITINOL_E_GPA, poisson_ratio=NITINOL_NU)
    return Robot(tubes=(inner, outer), transmission=transmission, name="paper")  # type: ignore[arg-type]


def timclab_robot(transmission: str = "compliant") -> Robot:
    """The three-tube robot of the public C++ TCM of TIMClab-CAMI, innermost first.

    OD 1.524 / 1.8 / 2.35 mm, ID 1.3 / 1.62 / 2.06 mm, lengths 463 / 330.5 / 199 mm of which the
    last 50 mm are curved, curvature 0.010 / 0.005 / 0.007 1/mm, E = 58 GPa, ν = 0.3: long, stiff,
    mildly curved tubes (benchmarks/bench_mechanics.py).

    Parameters
    ----------
    transmission : {"compliant", "rigid"}
        The transmission model (`Robot`).

    Returns
    -------
    Robot
        Named "timclab".
    """
    spec = ((1.524, 1.3, 463.0, 0.010), (1.8, 1.62, 330.5, 0.005), (2.35, 2.06, 199.0, 0.007))
    tubes = tuple(Tube(od=od, id=idd, straight_length=length - 50.0, curved_length=50.0,
                       curvature=kap, youngs_modulus=NITINOL_E_GPA, poisson_ratio=0.3)
                  for od, idd, length, kap in spec)
    return Robot(tubes=tubes, transmission=transmission, name="timclab")  # type: ignore[arg-type]


BUILTIN = {"paper": paper_robot, "timclab": timclab_robot}


def load_robot(spec: str) -> Robot:
    """A built-in robot by name, or a robot TOML file.

    Parameters
    ----------
    spec : str
        "paper", "timclab", or the path of a robot file (`ctrkin robot template` writes one).

    Returns
    -------
    Robot

    Raises
    ------
    RobotDescriptionError
        If the file is missing or not a valid description.
    """
    if spec in BUILTIN:
        return BUILTIN[spec]()
    return Robot.from_toml(spec)


TEMPLATE_FILE = "robot_template.toml"


def robot_template() -> str:
    """The documented robot TOML template: the paper robot, every field commented with its unit.

    Returns
    -------
    str
        The text of the package's robots/data/robot_template.toml (`ctrkin robot template` writes it).
    """
    return (resources.files("ctrkin.robots") / "data" / TEMPLATE_FILE).read_text(encoding="utf-8")
