"""Robot description: nesting, joint convention, TOML round trip and malformed files."""

from __future__ import annotations

import numpy as np
import pytest

from ctrkin.errors import JointError, RobotDescriptionError
from ctrkin.robots import Robot, Tube, load_robot, paper_robot


def test_paper_robot_table_one() -> None:
    r = paper_robot()
    inner, outer = r.tubes
    assert (inner.od, inner.id, inner.straight_length, inner.curved_length) == (0.4, 0.2, 57.0, 15.0)
    assert (outer.od, outer.id, outer.straight_length, outer.curved_length) == (0.635, 0.48, 37.0, 14.5)
    assert 1 / inner.curvature == pytest.approx(27.0) and 1 / outer.curvature == pytest.approx(24.0)
    assert r.joint_names() == ["alpha_1", "alpha_2", "beta_1", "beta_2"]


def test_tubes_must_nest_innermost_first() -> None:
    inner, outer = paper_robot().tubes
    with pytest.raises(RobotDescriptionError, match="innermost first"):
        Robot((outer, inner))
    with pytest.raises(RobotDescriptionError, match="transmission"):
        Robot((inner, outer), transmission="springy")  # type: ignore[arg-type]


def test_joint_limits() -> None:
    r = paper_robot()
    ok = np.array([[0, 0, -20.5, 0], [10, 20, -10, -10], [0, 0, -51.5, -51.5]])
    assert r.is_valid(ok).all()
    r.check_joints(ok)
    bad = np.array([[0, 0, -21.0, 0], [0, 0, -10, -11], [0, 0, -52, -52.0], [0, 0, 0.1, 0.1]])
    assert not r.is_valid(bad).any()
    with pytest.raises(JointError, match="row 1"):
        r.check_joints(np.vstack([ok[0], bad[0]]))



def _first_violation(lengths: np.ndarray, beta: np.ndarray) -> str | None:
    """The joint inequalities written out one by one (docs/design.md: Conventions), in the order
    check_joints reports them; None if all hold."""
    n, tol = len(lengths), 1e-9
    tips = beta + lengths
    if beta[-1] > tol:
        return f"beta_{n} must be <= 0"
    if tips[-1] < -tol:
        return f"tube {n} tip"
    for i in range(n - 1):
        if beta[i] > beta[i + 1] + tol:
            return f"beta_{i + 1} <= beta_{i + 2} is required"
        if tips[i] < tips[i + 1] - tol:
            return f"beta_{i + 1} \\+ L_{i + 1} >= beta_{i + 2} \\+ L_{i + 2} is required"
    return None


def test_one_joint_check_agrees_with_the_inequalities(rng) -> None:
    """is_valid, check_joints on a row and on a trajectory are one vectorised check: they agree
    with the inequalities written out, and the error names the first violated one (seeded draws,
    half of them on the boundaries, where the 1e-9 mm slack decides)."""
    from ctrkin.robots import timclab_robot

    for r in (paper_robot(), timclab_robot()):
        n, lengths = r.n_tubes, r.lengths
        for _ in range(300):
            beta = -rng.uniform(0, 1.2 * lengths) + rng.uniform(0, 5, n) * (rng.random(n) < 0.1)
            if rng.random() < 0.5:  # snap some translations onto a limit, ± round-off or ± 2e-9
                i = rng.integers(n)
                beta[i] = [0.0, -lengths[i], beta[min(i + 1, n - 1)],
                           beta[min(i + 1, n - 1)] + lengths[min(i + 1, n - 1)] - lengths[i]
                           ][rng.integers(4)] + rng.choice([0.0, 2e-9, -2e-9])
            q = np.r_[rng.uniform(-400, 400, n), beta]
            expect = _first_violation(lengths, beta)
            assert bool(r.is_valid(q[None])[0]) is (expect is None)
            if expect is None:
                r.check_joints(q)
                continue
            with pytest.raises(JointError, match=expect):
                r.check_joints(q)
            with pytest.raises(JointError, match="row 1"):
                r.check_joints(np.vstack([np.r_[np.zeros(n), -lengths], q]))  # row 0 valid
        assert not r.is_valid(np.r_[np.zeros(n), np.full(n, np.nan)][None])[0]
        with pytest.raises(JointError, match="NaN or inf at row 0"):
            r.check_joints(np.r_[np.inf, np.zeros(2 * n - 1)])

def test_toml_round_trip(tmp_path) -> None:
    r = Robot((Tube.from_sections(0.5, 0.3, [(40, 0.0), (10, 0.01), (10, 0.03)]),
               Tube(0.9, 0.6, 20, 15, 1 / 40, youngs_modulus=60, poisson_ratio=0.3)),
              transmission="rigid", name="custom")
    path = tmp_path / "robot.toml"
    r.to_toml(path)
    back = Robot.from_toml(path)
    assert back == r and back.fingerprint() == r.fingerprint()
    assert load_robot(str(path)) == r
    assert load_robot("paper") == paper_robot()


@pytest.mark.parametrize(("text", "message"), [
    ("this is = not toml [", "not valid TOML"),
    ("name = 'x'\n", "tubes"),
    ("[[tubes]]\nod = 1.0\nid = 0.5\n", "missing field"),
    ("[[tubes]]\nod = 1.0\nid = 0.5\nstraight_length = 1\ncurved_length = 1\ncurvature = 0.1\n"
     "colour = 'red'\n", "unknown field"),
    ("[[tubes]]\nod = 1.0\nid = 1.5\nstraight_length = 1\ncurved_length = 1\ncurvature = 0.1\n", "id"),
    # issue 9 item 6: each a RobotDescriptionError naming the field (was ValueError / RecursionError)
    ("[[tubes]]\nod = 1.0\nid = 0.5\nsections = [[10.0]]\n", r"tubes\[0\].*sections\[0\] must be a pair"),
    ("[[tubes]]\nod = 1.0\nid = 0.5\nsections = 3\n", r"tubes\[0\]"),
    ("x = " + "[" * 5000 + "]" * 5000 + "\n", "nested too deeply|not valid TOML"),
    ("name = 5\n[[tubes]]\nod = 1.0\nid = 0.5\nstraight_length = 1\ncurved_length = 1\n"
     "curvature = 0.1\n", "'name' must be a string"),
    ("[[tubes]]\nod = 1.0\nid = 0.5\nstraight_length = 1e10\ncurved_length = 1\ncurvature = 0.1\n",
     r"straight_length must be <= 10000 mm"),
])
def test_malformed_robot_file(tmp_path, text: str, message: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(RobotDescriptionError, match=message):
        Robot.from_toml(path)


def test_missing_robot_file(tmp_path) -> None:
    with pytest.raises(RobotDescriptionError, match="does not exist"):
        load_robot(str(tmp_path / "nope.toml"))


def test_fingerprint_differs_between_robots() -> None:
    assert paper_robot().fingerprint() != paper_robot("rigid").fingerprint()


def test_transmission_length_takes_numbers_only() -> None:
    """Issue 27 item 15: `transmission_length = ["abc", "d"]`, `[[1], [2]]`, `[{a = 1}]` crashed with
    ValueError / TypeError and `[true, false]` was accepted as [1.0, 0.0]."""
    d = paper_robot().to_dict()
    for bad in (["abc", "d"], [[1], [2]], [{"a": 1}], [True, False], "12", 5, [1.0], [1.0, -2.0],
                [1.0, float("nan")], [1, 2**2000]):
        with pytest.raises(RobotDescriptionError, match="transmission_length"):
            Robot.from_dict({**d, "transmission_length": bad})
    assert Robot.from_dict({**d, "transmission_length": [1, 2.5]}).transmission_length == (1.0, 2.5)
