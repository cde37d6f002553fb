"""Build checks: the lumen stays open and the wall is closed.

* Lumen open: the centerline is sampled every ``probe_spacing`` radii; a probe is open when no
  hull comes within ``clearance`` × R of it. The distance to a hull is bounded from below by
  ``max_i(n_i·p + d_i)`` over its half-spaces, so the check is conservative (it can only call a
  probe blocked that is open, never the reverse). Probes within ``end_margin`` radii of a
  terminal node are skipped: a capped vessel end is walled, and the graph's last node may sit
  on the cap.
* Wall closed: every lumen vertex and face centre is moved outward by half the wall's thickness
  there (:func:`~sim4endor.vessels.walls.wall_thickness`: thinner at a narrow carina);
  such a probe must lie inside some hull, otherwise a wire could slip between hulls there.
  Probes on the open inlet (faces without a wall) are skipped.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import trimesh
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from sim4endor.errors import Sim4EndoRError
from sim4endor.vessels.axis import AxisSamples, sample_axis
from sim4endor.vessels.centerline import CenterlineGraph
from sim4endor.vessels.manifest import REBUILD, below_acceptance
from sim4endor.vessels.meshio import boundary_loops, loop_perimeter
from sim4endor.vessels.walls import Hull, convex_hull, wall_thickness

if TYPE_CHECKING:
    from sim4endor.vessels import Vessel

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CheckParams:
    """Check settings (dimensionless, in local lumen radii unless named).

    Attributes:
        clearance: Radius of the sphere around each centerline probe that must stay hull-free.
        probe_spacing: Centerline probe spacing.
        end_margin: Probes this close to a terminal node (arc length) are skipped.
        min_lumen_open: Acceptance threshold for the open fraction.
        min_wall_closed: Acceptance threshold for the closed fraction.
    """

    clearance: float = 0.4
    probe_spacing: float = 0.25
    end_margin: float = 1.0
    min_lumen_open: float = 0.99
    min_wall_closed: float = 0.95


def _hull_spheres(hulls: Sequence[Hull]) -> tuple[FloatArray, FloatArray]:
    centres = np.array([h.vertices.mean(axis=0) for h in hulls])
    radii = np.array(
        [np.linalg.norm(h.vertices - c, axis=1).max() for h, c in zip(hulls, centres, strict=True)]
    )
    return centres, radii


def hull_distance_bound(hulls: Sequence[Hull], points: FloatArray, reach: float) -> FloatArray:
    """Returns, per point, a lower bound of the distance to the nearest hull (negative inside).

    Hulls farther than ``reach`` (m) from a point are ignored; such points get ``inf``.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    best = np.full(len(points), np.inf)
    if not hulls or len(points) == 0:
        return best
    centres, radii = _hull_spheres(hulls)
    tree = cKDTree(points)
    for hull, centre, radius in zip(hulls, centres, radii, strict=True):
        near = tree.query_ball_point(centre, radius + reach)
        if not near:
            continue
        idx = np.asarray(near, dtype=np.int64)
        side = points[idx] @ hull.equations[:, :3].T + hull.equations[:, 3]
        best[idx] = np.minimum(best[idx], side.max(axis=1))
    return best


@dataclass(frozen=True)
class LumenProbes:
    """The lumen-open check's centerline probes and what it found at each.

    Attributes:
        points: (P, 3) probe positions (m).
        radius: (P,) lumen radius at each (m).
        branch: (P,) branch chain of each (:func:`~sim4endor.vessels.axis.branch_chains`).
        end_distance: (P,) arc length to the branch's vessel end (m; ``inf`` on inner branches).
        open: (P,) no hull within the clearance.
    """

    points: FloatArray
    radius: FloatArray
    branch: NDArray[np.int64]
    end_distance: FloatArray
    open: NDArray[np.bool_]

    @property
    def open_fraction(self) -> float:
        """The fraction of open probes (1 without probes)."""
        return float(self.open.mean()) if len(self.open) else 1.0


def lumen_probes(hulls: Sequence[Hull], axis: AxisSamples, params: CheckParams) -> LumenProbes:
    """Probes the centerline every ``probe_spacing`` radii: open where no hull comes within
    ``clearance`` radii."""
    keep = axis.end_distance > params.end_margin * axis.radius
    # Axis samples are denser than the probe spacing; thin them by arc position in radii.
    bins = np.floor(axis.u / params.probe_spacing).astype(np.int64)
    key = np.column_stack([axis.branch, bins])
    _, first = np.unique(key, axis=0, return_index=True)
    chosen = np.zeros(len(axis.u), dtype=bool)
    chosen[first] = True
    chosen &= keep
    points, radii = axis.points[chosen], axis.radius[chosen]
    clear = np.ones(len(points), dtype=bool)
    if len(points):
        bound = hull_distance_bound(hulls, points, reach=params.clearance * float(radii.max()))
        clear = bound >= params.clearance * radii
    return LumenProbes(points, radii, axis.branch[chosen], axis.end_distance[chosen], clear)


@dataclass(frozen=True)
class BlockedPlace:
    """Where most of the lumen-open check's blocked probes lie: on one branch.

    Attributes:
        blocked: Blocked probes there.
        total_blocked: Blocked probes in all.
        point: A blocked probe in the middle of them (m).
        radius: (smallest, largest) lumen radius of the blocked probes there (m).
        from_end: Arc length from the farthest of them to the branch's vessel end (m; ``inf``
            on a branch without one).
        end: Where that vessel end is (m), if the branch has one.
    """

    blocked: int
    total_blocked: int
    point: FloatArray
    radius: tuple[float, float]
    from_end: float
    end: FloatArray | None

    def describe(self, scale: float, graph: CenterlineGraph) -> str:
        """One phrase naming the place, positions in input units (``scale`` m per unit)."""
        lo, hi = (round(r * 1e3, 2) for r in self.radius)
        where = np.round(self.point / scale, 2).tolist()
        of = f"{self.blocked} of the {self.total_blocked} blocked probes"
        if self.end is None or not np.isfinite(self.from_end):
            return (f"{of} lie on one branch near {where} (input units), lumen radius "
                    f"{lo}-{hi} mm")
        node = int(np.argmin(np.linalg.norm(graph.nodes - self.end, axis=1)))
        label = next((k for k, v in graph.labels.items() if v == node), None)
        end = np.round(self.end / scale, 2).tolist()
        name = (f"the branch to {label} (its end at {end})" if label
                else f"the branch ending at {end}")
        return (f"{of} lie in the last {self.from_end * 1e3:.3g} mm of {name}, around {where} "
                f"(input units), lumen radius {lo}-{hi} mm")


def blocked_place(probes: LumenProbes, axis: AxisSamples) -> BlockedPlace | None:
    """Returns the branch holding most blocked probes, or ``None`` if none is blocked."""
    blocked = np.flatnonzero(~probes.open)
    if not len(blocked):
        return None
    branches, counts = np.unique(probes.branch[blocked], return_counts=True)
    branch = int(branches[np.argmax(counts)])
    here = blocked[probes.branch[blocked] == branch]
    samples = np.flatnonzero(axis.branch == branch)
    ends = samples[axis.end_distance[samples] == 0.0]
    return BlockedPlace(
        blocked=len(here),
        total_blocked=len(blocked),
        point=probes.points[here[len(here) // 2]],
        radius=(float(probes.radius[here].min()), float(probes.radius[here].max())),
        from_end=float(probes.end_distance[here].max()),
        end=axis.points[ends[0]] if len(ends) else None,
    )


def wall_probes(
    vertices: FloatArray,
    faces: NDArray[np.int64],
    vertex_normals: FloatArray,
    face_normals: FloatArray,
    walled: NDArray[np.bool_],
    thickness: FloatArray,
) -> FloatArray:
    """Returns points half the wall's ``thickness`` (per vertex, m) outside the lumen surface
    of walled faces (a face centre takes its vertices' mean)."""
    faces = faces[walled]
    verts = np.unique(faces)
    centres = vertices[faces].mean(axis=1)
    return np.vstack(
        [
            vertices[verts] + 0.5 * thickness[verts, None] * vertex_normals[verts],
            centres + 0.5 * thickness[faces].mean(axis=1)[:, None] * face_normals[walled],
        ]
    )


def wall_closed_fraction(hulls: Sequence[Hull], probes: FloatArray, slack: float) -> float:
    """Returns the fraction of wall probes inside some hull (within ``slack`` metres)."""
    if len(probes) == 0:
        return 1.0
    bound = hull_distance_bound(hulls, probes, reach=slack)
    return float(np.mean(bound <= slack))


#: A centerline end this many radii of an opening from its centre, or nearer, ends there.
OPENING_REACH_RADII = 3.0


@dataclass(frozen=True)
class Opening:
    """A boundary loop of the lumen surface (an opening in it).

    Attributes:
        loop: Vertex indices of the loop, in order.
        centre: Mean of the loop's vertices (m).
        perimeter: Length of the loop (m).
        radius: Mean distance of the loop's vertices from its centre (m).
    """

    loop: NDArray[np.int64]
    centre: FloatArray
    perimeter: float
    radius: float


def openings(vertices: FloatArray, loops: Sequence[NDArray[np.int64]]) -> list[Opening]:
    """The openings of a lumen surface, one per boundary loop of ``vertices`` (m)."""
    out = []
    for loop in loops:
        points = vertices[loop]
        centre = points.mean(axis=0)
        radius = float(np.linalg.norm(points - centre, axis=1).mean())
        out.append(Opening(loop, centre, loop_perimeter(points), radius))
    return out


def stray_openings(
    vertices: FloatArray, loops: Sequence[NDArray[np.int64]], graph: CenterlineGraph,
    reach: float = OPENING_REACH_RADII,
) -> list[Opening]:
    """Returns the openings of the lumen that are not vessel ends.

    A vessel end is open where the centerline ends: a terminal node lies within ``reach``
    times the opening's radius (mean distance of its vertices from their centre) of it.
    Any other opening is a hole in the side wall, however it is shaped, and no wall hull
    covers it.
    """
    ends = graph.nodes[graph.terminal_nodes()]
    stray = []
    for opening in openings(vertices, loops):
        nearest = (float(np.linalg.norm(ends - opening.centre, axis=1).min()) if len(ends)
                   else np.inf)
        if nearest > reach * opening.radius:
            stray.append(opening)
    return stray


def inlet_cap(
    mesh: trimesh.Trimesh, position: FloatArray, direction: FloatArray, radius: float
) -> NDArray[np.bool_]:
    """Faces of the end cap at the inlet, which get no wall so a wire can enter a capped mesh."""
    offset = mesh.triangles_center - position
    along = offset @ direction
    lateral = np.linalg.norm(offset - along[:, None] * direction, axis=1)
    facing = np.abs(mesh.face_normals @ direction) > 0.5
    return np.asarray((along < 0.25 * radius) & (lateral < 1.5 * radius) & facing)


class VesselCheckError(Sim4EndoRError, ValueError):
    """Raised when a vessel folder's files cannot be read; the message names the file."""


def _mesh(path: Path) -> trimesh.Trimesh:
    try:
        mesh = trimesh.load(path, force="mesh")
    except Exception as exc:  # trimesh raises many unrelated types for unreadable files
        raise VesselCheckError(f"{path} is not a readable mesh ({type(exc).__name__}); "
                               f"{REBUILD}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise VesselCheckError(f"{path} holds no triangles; {REBUILD}")
    return mesh


def check_folder(vessel: Vessel, params: CheckParams | None = None) -> dict[str, Any]:
    """Re-runs the checks on a built vessel folder, from its files alone.

    Returns:
        ``lumen_open``, ``wall_closed``, ``hull_count``, ``compiles`` (MuJoCo loads
        ``scene.xml``; any warning counts as a failure), ``wall_holes`` (openings of the lumen
        that are not vessel ends, see :func:`stray_openings`) and ``passed``.
    """
    import mujoco

    from sim4endor.vessels import LUMEN_FILE
    from sim4endor.vessels.mjcf_writer import HULL_DIR

    params = params or CheckParams()
    # MuJoCo first: it opens every file the MJCF names, and says which one fails.
    try:
        model = mujoco.MjModel.from_xml_path(str(vessel.scene_path))
    except ValueError as exc:
        reason = str(exc).strip().splitlines()[0].removeprefix("Error: ")
        raise VesselCheckError(
            f"{vessel.root}: MuJoCo cannot load the folder ({reason}); {REBUILD}"
        ) from None
    hulls = [
        h
        for path in sorted((vessel.root / HULL_DIR).glob("*.stl"))
        if (h := convex_hull(np.asarray(_mesh(path).vertices))) is not None
    ]
    lumen = _mesh(vessel.root / LUMEN_FILE)
    inlet = vessel.manifest.inlet
    walled = ~inlet_cap(lumen, vessel.inlet_position, vessel.inlet_direction, inlet.radius)
    thickness = float(vessel.manifest.build.get("wall", {}).get("thickness", 0.8e-3))
    axis = sample_axis(vessel.centerline)
    lumen_open = lumen_probes(hulls, axis, params).open_fraction
    vertices, normals = np.asarray(lumen.vertices), np.asarray(lumen.vertex_normals)
    probes = wall_probes(
        vertices,
        np.asarray(lumen.faces),
        normals,
        np.asarray(lumen.face_normals),
        walled,
        wall_thickness(vertices, normals, vessel.centerline, thickness),
    )
    wall_closed = wall_closed_fraction(hulls, probes, slack=1e-3 * float(axis.radius.min()))
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    compiles = int(sum(w.number for w in data.warning)) == 0
    stray = stray_openings(np.asarray(lumen.vertices), boundary_loops(lumen), vessel.centerline)
    accepted = not below_acceptance({"lumen_open": lumen_open, "wall_closed": wall_closed},
                                    params.min_lumen_open, params.min_wall_closed)
    passed = accepted and compiles and not stray
    return {
        "lumen_open": lumen_open,
        "wall_closed": wall_closed,
        "hull_count": len(hulls),
        "compiles": compiles,
        "wall_holes": len(stray),
        "passed": bool(passed),
    }
