"""Whether two vessel folders hold the same anatomy, up to floating-point rounding.

A rebuild on another machine (other CPU, other numpy build) reproduces a vessel folder's
geometry but not always its bytes: the float64 arithmetic of the build differs in the last
bits, and the files store it rounded (float32 in STL, six digits in ``scene.xml``), so one
rounding may fall the other way. :func:`folder_differences` compares what the folder *means*:
the manifest and centerline as data, the lumen and every wall hull as geometry, the vessel MJCF
as the model MuJoCo compiles from it. Each tolerance follows from how the value is stored or
computed (see :class:`Tolerances`), not from one machine's observed differences.

Example:
    >>> from sim4endor.vessels.compare import folder_differences
    >>> folder_differences("vessels/simplified_phantom", "/tmp/rebuilt")  # doctest: +SKIP
    []
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from numpy.typing import NDArray

from sim4endor.vessels import CENTERLINE_FILE, LUMEN_FILE, SCENE_FILE, Vessel, load
from sim4endor.vessels.manifest import MANIFEST_FILE
from sim4endor.vessels.mjcf_writer import HULL_DIR

FloatArray = NDArray[np.float64]

#: Manifest entries that differ between identical builds by design.
_VOLATILE = {("content_hash",), ("checks", "build_time_s")}


@dataclass(frozen=True)
class Tolerances:
    """How far two values may differ and still be the same.

    Attributes:
        float64_rel: Relative tolerance of values stored as float64 (JSON): a build's float64
            arithmetic differs between machines by a few ulps per operation (~1e-16), so
            1e-9 leaves a wide margin and still resolves 0.1 nm on a 0.1 m phantom.
        float64_abs: Absolute floor for float64 values near zero (m or dimensionless).
        float32_ulps: Float32 ulps (of the mesh's largest coordinate) two STL vertices may
            differ by: a float64 value a few ulps away rounds to the neighbouring float32 at
            most one ulp off; four leave room for the normals and offsets derived from it.
        printed_rel: Relative tolerance of numbers printed with six significant digits
            (``scene.xml``): one unit in the sixth digit.
    """

    float64_rel: float = 1e-9
    float64_abs: float = 1e-12
    float32_ulps: float = 4.0
    printed_rel: float = 1e-5


def folder_differences(
    expected: str | Path | Vessel, actual: str | Path | Vessel, tol: Tolerances | None = None
) -> list[str]:
    """Returns the differences between two vessel folders; empty when they are the same.

    Args:
        expected: The reference folder (a name, path or loaded vessel).
        actual: The folder to compare with it.
        tol: Tolerances (defaults: :class:`Tolerances`).

    Returns:
        One line per difference, naming the file and the entry.
    """
    tol = tol or Tolerances()
    a = expected if isinstance(expected, Vessel) else load(expected)
    b = actual if isinstance(actual, Vessel) else load(actual)
    found: list[str] = []
    for name in (MANIFEST_FILE, CENTERLINE_FILE):
        left, right = (json.loads((v.root / name).read_text()) for v in (a, b))
        found += [f"{name}: {d}" for d in _json_differences(left, right, (), tol)]
    found += _mesh_differences(a.root / LUMEN_FILE, b.root / LUMEN_FILE, tol)
    found += _hull_differences(a.root / HULL_DIR, b.root / HULL_DIR, tol)
    found += _model_differences(a, b, tol)
    found += [f"{SCENE_FILE}: {d}" for d in _xml_differences(
        ET.parse(a.root / SCENE_FILE).getroot(), ET.parse(b.root / SCENE_FILE).getroot(), tol)]
    return found


def _close(x: float, y: float, rel: float, abs_tol: float) -> bool:
    return math.isclose(x, y, rel_tol=rel, abs_tol=abs_tol)


def _json_differences(x: Any, y: Any, path: tuple[str, ...], tol: Tolerances) -> Iterator[str]:
    where = ".".join(path) or "(top level)"
    if path in _VOLATILE:
        return
    if isinstance(x, dict) and isinstance(y, dict):
        for key in sorted(set(x) | set(y)):
            if key not in x or key not in y:
                yield f"{where}: entry {key!r} only in the {'actual' if key in y else 'expected'}"
            else:
                yield from _json_differences(x[key], y[key], (*path, key), tol)
    elif isinstance(x, list) and isinstance(y, list):
        if len(x) != len(y):
            yield f"{where}: {len(x)} items expected, {len(y)} found"
            return
        for k, (u, v) in enumerate(zip(x, y, strict=True)):
            yield from _json_differences(u, v, (*path, str(k)), tol)
    elif isinstance(x, float | int) and isinstance(y, float | int) and not isinstance(x, bool):
        if not _close(float(x), float(y), tol.float64_rel, tol.float64_abs):
            yield f"{where}: {x!r} expected, {y!r} found"
    elif x != y:
        yield f"{where}: {x!r} expected, {y!r} found"


def _float32_tolerance(*meshes: FloatArray, tol: Tolerances) -> float:
    largest = max(float(np.abs(m).max()) for m in meshes)
    return tol.float32_ulps * float(np.spacing(np.float32(largest)))


def _read(path: Path) -> trimesh.Trimesh:
    mesh = trimesh.load(path, force="mesh", process=False)
    assert isinstance(mesh, trimesh.Trimesh)  # force="mesh" gives one or raises
    return mesh


def _mesh_differences(left: Path, right: Path, tol: Tolerances) -> list[str]:
    a, b = _read(left), _read(right)
    if a.faces.shape != b.faces.shape or not np.array_equal(a.faces, b.faces):
        return [f"{left.name}: the triangles differ ({len(a.faces)} expected, {len(b.faces)} "
                "found, or other vertex indices)"]
    atol = _float32_tolerance(a.vertices, b.vertices, tol=tol)
    error = float(np.abs(a.vertices - b.vertices).max())
    if error > atol:
        return [f"{left.name}: vertices moved by up to {error:.3g} m (tolerance {atol:.3g} m)"]
    return []


def _hull_differences(left: Path, right: Path, tol: Tolerances) -> list[str]:
    names = sorted(p.name for p in left.glob("*.stl"))
    others = sorted(p.name for p in right.glob("*.stl"))
    if names != others:
        only = sorted(set(names) ^ set(others))[:3]
        return [f"{HULL_DIR}/: {len(names)} hull files expected, {len(others)} found "
                f"(not in both: {only})"]
    found = []
    for name in names:
        a, b = (np.asarray(_read(d / name).vertices, dtype=np.float64) for d in (left, right))
        # The same convex set: qhull may list near-coplanar points differently after a rounding
        # change, so the hulls are compared by containment, each within the other's faces.
        atol = _float32_tolerance(a, b, tol=tol)
        gap = max(_outside(a, b), _outside(b, a))
        if gap > atol:
            found.append(f"{HULL_DIR}/{name}: the hulls differ by {gap:.3g} m (tolerance "
                         f"{atol:.3g} m)")
    return found


def _outside(points: FloatArray, hull_vertices: FloatArray) -> float:
    """How far the farthest of ``points`` lies outside the convex hull of ``hull_vertices``."""
    from scipy.spatial import ConvexHull

    equations = ConvexHull(hull_vertices).equations
    return float(np.max(points @ equations[:, :3].T + equations[:, 3]))


def _model_differences(a: Vessel, b: Vessel, tol: Tolerances) -> list[str]:
    """The vessel MJCF as compiled: the same geoms, meshes and sites in the same places."""
    import mujoco

    ma, mb = (mujoco.MjModel.from_xml_path(str(v.mjcf_path)) for v in (a, b))
    name = a.mjcf_path.name
    found = []
    for kind, count in (("geom", "ngeom"), ("mesh", "nmesh"), ("site", "nsite")):
        na, nb = getattr(ma, count), getattr(mb, count)
        names_a = [getattr(ma, kind)(i).name for i in range(na)]
        names_b = [getattr(mb, kind)(i).name for i in range(nb)]
        if names_a != names_b:
            found.append(f"{name}: the {kind} names differ ({na} expected, {nb} found)")
    if found:
        return found
    for field in ("geom_type", "geom_contype", "geom_conaffinity", "geom_group",
                  "geom_friction", "geom_solref", "geom_solimp", "geom_dataid"):
        if not np.array_equal(getattr(ma, field), getattr(mb, field)):
            found.append(f"{name}: {field} differs")
    da, db = mujoco.MjData(ma), mujoco.MjData(mb)
    mujoco.mj_kinematics(ma, da)
    mujoco.mj_kinematics(mb, db)
    atol = _float32_tolerance(ma.mesh_vert, mb.mesh_vert, da.geom_xpos, tol=tol)
    # MuJoCo recentres each mesh on its own centroid; a geom's placement is where that lands.
    moved = np.abs(da.geom_xpos - db.geom_xpos).max(axis=1)
    for geom in np.flatnonzero(moved > atol)[:5]:
        found.append(f"{name}: geom {ma.geom(geom).name} placed {moved[geom]:.3g} m apart")
    site_gap = np.abs(da.site_xpos - db.site_xpos).max(initial=0.0)
    if site_gap > tol.float64_abs + tol.float64_rel * float(np.abs(da.site_xpos).max(initial=0)):
        found.append(f"{name}: sites moved by up to {site_gap:.3g} m")
    return found


def _xml_differences(x: ET.Element, y: ET.Element, tol: Tolerances) -> Iterator[str]:
    if x.tag != y.tag or set(x.attrib) != set(y.attrib) or len(x) != len(y):
        yield f"<{x.tag}> and <{y.tag}> differ in tag, attributes or children"
        return
    for key, value in x.attrib.items():
        if not _same_text(value, y.attrib[key], tol.printed_rel):
            yield f"<{x.tag} {key}>: {value!r} expected, {y.attrib[key]!r} found"
    for u, v in zip(x, y, strict=True):
        yield from _xml_differences(u, v, tol)


def _same_text(u: str, v: str, rel: float) -> bool:
    """Equal strings, or equal-length lists of numbers within ``rel`` of their largest."""
    if u == v:
        return True
    try:
        a, b = np.array(u.split(), dtype=np.float64), np.array(v.split(), dtype=np.float64)
    except ValueError:
        return False
    scale = max(float(np.abs(a).max(initial=0.0)), float(np.abs(b).max(initial=0.0)), 1e-300)
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= rel * scale))
