"""Curved overlap of the paper robot's tubes (ctrkin.robots.overlap)."""

from __future__ import annotations

import pytest

from ctrkin.acquisition.protocols import config
from ctrkin.robots.overlap import curved_overlap


@pytest.mark.parametrize(("d", "overlap"), [(0.0, 0.0), (4.0, 0.0), (5.5, 0.0), (12.0, 6.5),
                                            (20.0, 14.5), (20.5, 14.5)])
def test_curved_overlap_of_the_paper_robot(robot, d, overlap):
    # inner curved part s in [beta1 + 57, beta1 + 72], outer in [beta2 + 37, beta2 + 51.5]
    q = config(2, 0.0, 0.0, -3.0, d)
    assert curved_overlap(robot, q[None, :])[0] == pytest.approx(overlap, abs=1e-12)
