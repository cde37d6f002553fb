"""Writes a vessel folder's MJCF: hull meshes, the vessel model and its ``scene.xml``.

The vessel model is built with ``mujoco.MjSpec`` starting from ``mjcf/vessel_defaults.xml``,
so the default classes are copied into the vessel file and the folder stays self-contained
(it can live anywhere). Names the rest of sim4endor relies on are constants here.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from pathlib import Path

import mujoco
import numpy as np
import trimesh

from sim4endor import assets
from sim4endor.vessels import LUMEN_FILE
from sim4endor.vessels.remesh import display_parts
from sim4endor.vessels.walls import Hull

DEFAULTS_FILE = "vessel_defaults.xml"
WALL_CLASS = "vessel_wall"
VISUAL_CLASS = "vessel_visual"
HULL_DIR = "hulls"
LUMEN_GEOM = "lumen"
#: Where a lumen decimated for the wall keeps its full-resolution surface, for display, in
#: parts under MuJoCo's faces-per-mesh limit (``part_000.stl``...).
DISPLAY_DIR = "lumen_full"
INLET_SITE = "inlet"
TARGET_SITE_PREFIX = "target_"


def hull_mesh_name(index: int) -> str:
    """Returns the MJCF mesh name of hull ``index`` (``hull_000``...)."""
    return f"hull_{index:03d}"


def wall_geom_name(index: int) -> str:
    """Returns the MJCF geom name of hull ``index`` (``wall_000``...)."""
    return f"wall_{index:03d}"


def target_site_name(target: str) -> str:
    """Returns the MJCF site name of a target (``target_A``)."""
    return f"{TARGET_SITE_PREFIX}{target}"


def display_part_file(index: int) -> str:
    """Returns the path, in a vessel folder, of part ``index`` of the full-resolution lumen."""
    return f"{DISPLAY_DIR}/part_{index:03d}.stl"


def write_meshes(folder: Path, hulls: Sequence[Hull], lumen: trimesh.Trimesh,
                 display: trimesh.Trimesh | None = None) -> int:
    """Writes ``hulls/hull_XXX.stl`` (binary), the lumen the wall was built from and, when it
    was decimated from one or is over MuJoCo's faces-per-mesh limit, the lumen to display
    (``display``, else ``lumen``) in parts (:data:`DISPLAY_DIR`).

    Returns:
        The number of display parts written (0: the lumen itself is displayed).
    """
    (folder / HULL_DIR).mkdir(parents=True, exist_ok=True)
    for k, hull in enumerate(hulls):
        hull.to_trimesh().export(folder / HULL_DIR / f"{hull_mesh_name(k)}.stl", file_type="stl")
    lumen.export(folder / LUMEN_FILE, file_type="stl")
    parts = display_parts(lumen if display is None else display)
    if display is None and len(parts) == 1:
        return 0
    (folder / DISPLAY_DIR).mkdir()
    for k, part in enumerate(parts):
        part.export(folder / display_part_file(k), file_type="stl")
    return len(parts)


def write_vessel_mjcf(
    folder: Path,
    *,
    name: str,
    hull_count: int,
    inlet: np.ndarray,
    targets: Mapping[str, np.ndarray],
    display_part_count: int = 0,
) -> Path:
    """Writes ``<name>.xml`` into ``folder`` (whose meshes must exist) and returns its path.

    The lumen is displayed from :data:`LUMEN_FILE` (geom ``lumen``) or
    from its ``display_part_count`` full-resolution parts (geoms ``lumen_000``...).
    """
    spec = mujoco.MjSpec.from_file(str(assets.mjcf_path(DEFAULTS_FILE)))
    spec.modelname = name
    spec.modelfiledir = str(folder)
    spec.meshdir = "."
    wall = spec.find_default(WALL_CLASS)
    visual = spec.find_default(VISUAL_CLASS)
    body = spec.worldbody
    for k in range(hull_count):
        spec.add_mesh(
            default=wall, name=hull_mesh_name(k), file=f"{HULL_DIR}/{hull_mesh_name(k)}.stl"
        )
        body.add_geom(default=wall, name=wall_geom_name(k), meshname=hull_mesh_name(k))
    shown = ([(LUMEN_GEOM, LUMEN_FILE)] if display_part_count == 0 else
             [(f"{LUMEN_GEOM}_{k:03d}", display_part_file(k)) for k in range(display_part_count)])
    for geom, file in shown:
        spec.add_mesh(default=visual, name=geom, file=file)
        body.add_geom(default=visual, name=geom, meshname=geom)
    body.add_site(
        name=INLET_SITE,
        pos=np.asarray(inlet, dtype=float),
        size=[2e-4, 0, 0],
        rgba=[0.1, 0.4, 1, 1],
    )
    for target, pos in targets.items():
        body.add_site(
            name=target_site_name(target),
            pos=np.asarray(pos, dtype=float),
            size=[3e-4, 0, 0],
            rgba=[0.1, 0.9, 0.2, 1],
        )
    spec.compile()  # fails loudly here, inside the staging folder, on any bad mesh
    path = folder / f"{name}.xml"
    path.write_text(spec.to_xml())
    return path


def write_scene(
    folder: Path, *, name: str, vessel_file: str, extent: float, centre: np.ndarray
) -> Path:
    """Writes ``scene.xml``: the vessel MJCF plus a light and a camera looking at the vessel."""
    root = ET.Element("mujoco", model=f"{name}_scene")
    ET.SubElement(root, "include", file=vessel_file)
    ET.SubElement(
        root, "statistic", center=" ".join(f"{c:.6g}" for c in centre), extent=f"{extent:.6g}"
    )
    visual = ET.SubElement(root, "visual")
    ET.SubElement(
        visual, "headlight", diffuse="0.6 0.6 0.6", ambient="0.3 0.3 0.3", specular="0 0 0"
    )
    world = ET.SubElement(root, "worldbody")
    top = np.asarray(centre) + np.array([0.0, 0.0, 2.0 * extent])
    ET.SubElement(world, "light", name="top", pos=" ".join(f"{c:.6g}" for c in top), dir="0 0 -1")
    ET.SubElement(
        world,
        "camera",
        name="overview",
        pos=" ".join(f"{c:.6g}" for c in top),
        xyaxes="1 0 0 0 1 0",
        fovy="60",
    )
    ET.indent(root)
    path = folder / "scene.xml"
    path.write_text(ET.tostring(root, encoding="unicode") + "\n")
    return path
