"""Test support: a straight-tube vessel folder written procedurally (no CoACD, < 10 ms).

The tube follows the vessel-folder contract (manifest.json, centerline.json, the vessel MJCF
with a ``vessel_wall`` class, a hull mesh file under ``hulls/``), so the scene builder treats
it like any built vessel. Walls are boxes whose inner faces are tangent to the lumen radius;
the far end is closed by a convex STL hull (exercises mesh paths relative to the folder).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import trimesh

from sim4endor import vessels
from sim4endor.vessels.centerline import CenterlineGraph
from sim4endor.vessels.manifest import Inlet, Manifest

WALL_CLASS = """
  <default>
    <default class="vessel_wall">
      <geom contype="2" conaffinity="1" condim="3" friction="0.1 0.005 0.0001"
            solref="0.004 1" solimp="0.99 0.999 0.0001 0.5 2" margin="0" group="3"/>
    </default>
  </default>"""


def write_tube_vessel(
    folder: Path, length: float = 0.06, radius: float = 0.002, wall: float = 0.0008,
    sectors: int = 12,
) -> vessels.Vessel:
    """Writes a straight tube along +x from the origin, capped at ``x = length``; loads it."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "hulls").mkdir(exist_ok=True)
    cap = trimesh.creation.box(extents=[wall, 2 * (radius + wall), 2 * (radius + wall)])
    cap.apply_translation([length + 0.5 * wall, 0.0, 0.0])
    cap.export(folder / "hulls" / "hull_000.stl")
    half_width = (radius + wall) * math.tan(math.pi / sectors)
    geoms = []
    for k in range(sectors):
        a = 2 * math.pi * k / sectors
        c = radius + 0.5 * wall
        geoms.append(
            f'<geom name="wall_{k + 1:03d}" class="vessel_wall" type="box" '
            f'size="{length / 2} {wall / 2} {half_width}" '
            f'pos="{length / 2} {c * math.cos(a)} {c * math.sin(a)}" '
            f'quat="{math.cos(a / 2)} {math.sin(a / 2)} 0 0"/>'
        )
    xml = f"""<mujoco model="tube">{WALL_CLASS}
  <asset><mesh name="hull_000" file="hulls/hull_000.stl"/></asset>
  <worldbody>
    <geom name="wall_000" class="vessel_wall" type="mesh" mesh="hull_000"/>
    {" ".join(geoms)}
    <site name="inlet" pos="0 0 0"/>
    <site name="target_A" pos="{length} 0 0"/>
  </worldbody>
</mujoco>
"""
    (folder / "tube.xml").write_text(xml)
    xs = np.linspace(0.0, length, 13)
    graph = CenterlineGraph(
        nodes=np.stack([xs, 0 * xs, 0 * xs], 1),
        radii=np.full(len(xs), radius),
        edges=np.stack([np.arange(12), np.arange(1, 13)], 1),
        labels={"inlet": 0, "A": 12},
    )
    graph.save(folder / vessels.CENTERLINE_FILE)
    Manifest(
        name="tube",
        source="tests/guidewire_helpers.py",
        units="m",
        mesh_to_model=tuple(tuple(row) for row in np.eye(4)),
        inlet=Inlet(position=(0.0, 0.0, 0.0), direction=(1.0, 0.0, 0.0), radius=radius),
        targets={"A": (length, 0.0, 0.0)},
        build={"wall_thickness": wall},
        hull_count=sectors + 1,
        mjcf="tube.xml",
    ).save(folder)
    return vessels.load(folder)
