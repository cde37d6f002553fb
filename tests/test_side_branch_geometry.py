"""The side-branch geometry benchmark measures a junction as drawn (a synthetic fork)."""

from __future__ import annotations

import math
from types import ModuleType

import numpy as np
import pytest
from script_helpers import load_script

from sim4endor.vessels.centerline import CenterlineGraph


@pytest.fixture(scope="module")
def script() -> ModuleType:
    return load_script("experiments/benchmarks/side_branch_geometry.py")


def fork(angle_deg: float) -> CenterlineGraph:
    """A 3.5 mm vessel along x, forking at 10 mm into a 3.2 mm continuation and a 1.8 mm side
    branch ``angle_deg`` off it, nodes every 0.5 mm."""
    step = np.arange(1, 21) * 0.5e-3
    trunk = np.stack([np.arange(0, 21) * 0.5e-3, np.zeros(21), np.zeros(21)], axis=1)
    ahead = np.stack([10e-3 + step, np.zeros(20), np.zeros(20)], axis=1)
    a = math.radians(angle_deg)
    side = np.stack([10e-3 + step * math.cos(a), step * math.sin(a), np.zeros(20)], axis=1)
    nodes = np.vstack([trunk, ahead, side])
    radii = np.concatenate([np.full(21, 1.75e-3), np.full(20, 1.6e-3), np.full(20, 0.9e-3)])
    edges = ([(i, i + 1) for i in range(20)] + [(20, 21)] + [(i, i + 1) for i in range(21, 40)]
             + [(20, 41)] + [(i, i + 1) for i in range(41, 60)])
    return CenterlineGraph(nodes=nodes, radii=radii, edges=np.array(edges),
                           labels={"inlet": 0, "main": 40, "side": 60})


def test_a_side_branch_is_measured_at_its_fork(script: ModuleType) -> None:
    found = script.junction(fork(60.0), "side")
    assert found.parent_diameter_mm == pytest.approx(3.5)
    assert found.branch_diameter_mm == pytest.approx(1.8)
    assert found.angle_deg == pytest.approx(60.0, abs=0.5)
    assert found.ratio == pytest.approx(1.8 / 3.5)


def test_the_wider_daughter_is_no_side_branch(script: ModuleType) -> None:
    assert script.junction(fork(60.0), "main") is None


def test_the_table_bins_rows_by_ratio(script: ModuleType) -> None:
    narrow = script.Junction(3.5, 1.6, 70.0)
    wide = script.Junction(2.5, 2.0, 40.0)
    text = script.table("ratio", [(narrow, False), (wide, True)], "ratio", (0.0, 0.5, 0.6))
    assert "| 0.5-0.6 | 0/0 |" in text and "| 0-0.5 | 0/1 |" in text and "| >= 0.6 | 1/1 |" in text
