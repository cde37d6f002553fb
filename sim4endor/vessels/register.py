"""Registers a given centerline onto the lumen of the given surface (a documented repair).

Centerline curves are often made on another surface than the one imported: 3D Slicer's curves
of the shared stEVE_bench anatomy were extracted on a finer surface, and its collision OBJ is a
heavy decimation of it (median edge 6.3 mm for vessels of 0.55–16 mm radius), so some curve
points lie outside this lumen, many close to its wall, and curve ends run past its capped
vessel ends. The checks and the tasks need the axis of the lumen the simulation actually uses,
so each given point is moved:

1. candidates are sampled in the point's cross-section plane (perpendicular to the curve; a
   ball at junctions) within ``max(search_radius × R, min_search)`` of it, then refined
   around the best one on ever finer grids;
2. the best candidate maximises ``clearance − offset_penalty × offset``, where ``clearance`` is
   the signed distance to the surface (positive inside; the sign comes from the angle-weighted
   pseudonormal of the closest feature, exact on a closed surface). With a penalty below 1 the
   optimum of a round lumen is its centre; the penalty only breaks ties towards the given
   point, so a point does not jump into a wider neighbouring vessel;
3. runs of points at a vessel end whose best clearance stays below ``end_clearance`` given radii
   (drawn past the end, or into its cap) are trimmed; any other point without an inside
   candidate is searched again in a ball;
4. the offsets are smoothed along every branch (a moving average over ``smooth_nodes`` nodes
   each side), where that keeps at least ``smooth_keep`` of the point's clearance;
5. the radius becomes ``min(given R, clearance)``: the largest sphere at the point that fits in
   this lumen.

A point that still has no candidate inside the lumen raises
:class:`CenterlineRegistrationError` naming its curve (the branch name: the ``.mrk.json`` file
stem) and position. :func:`register_centerline` returns a :class:`RegistrationReport`, which the
build logs and stores in the manifest, with the raw curves' lumen-open figure beside it.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import trimesh
from numpy.typing import NDArray

from sim4endor.errors import Sim4EndoRError
from sim4endor.vessels.axis import branch_chains
from sim4endor.vessels.centerline import CenterlineGraph
from sim4endor.vessels.ends import end_runs, without_nodes

logger = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class CenterlineRegistrationError(Sim4EndoRError, ValueError):
    """Raised when a given centerline point cannot be placed inside the lumen."""


@dataclass(frozen=True)
class RegistrationParams:
    """Settings of :func:`register_centerline` (lengths in metres or local radii as named).

    Attributes:
        search_radius: Search radius around each given point, in its given radii.
        min_search: Smallest search radius (m), for thin vessels drawn on another surface.
        rings: Rings of the first (coarse) candidate grid.
        angles: Directions per ring of the coarse grid.
        refinements: Refinement steps around the best candidate, each at half the spacing.
        offset_penalty: Metres of clearance one metre of offset must buy (below 1).
        smooth_nodes: Half-width of the moving average of the offsets along a branch (nodes).
        smooth_keep: A smoothed point is kept only if it keeps this fraction of its clearance.
        end_clearance: Curve ends are trimmed back to the first node whose best clearance is
            at least this many given radii (ends drawn past a vessel end, or into its cap).
    """

    search_radius: float = 1.0
    min_search: float = 3e-3
    rings: int = 4
    angles: int = 12
    refinements: int = 3
    offset_penalty: float = 0.25
    smooth_nodes: int = 2
    smooth_keep: float = 0.9
    end_clearance: float = 0.5


@dataclass(frozen=True)
class RegistrationReport:
    """What :func:`register_centerline` changed (stored in the manifest under ``build``).

    Attributes:
        points: Centerline nodes registered (after trimming).
        trimmed_points: Nodes dropped from curve ends that run past a vessel end or into its
            cap (curves made on a longer surface); see ``end_clearance``.
        trimmed_length_mm: Centerline length dropped with them (mm).
        given_outside: Given nodes outside the lumen (before trimming).
        given_within_clearance: Given nodes (before trimming) inside but within
            ``clearance`` given radii of the surface (the lumen-open check's sphere).
        moved: Nodes moved by more than 1 % of their given radius.
        offset_median_mm: Median displacement (mm).
        offset_p95_mm: 95th-percentile displacement (mm).
        offset_median_r: Median displacement in given radii.
        offset_p95_r: 95th-percentile displacement in given radii.
        radius_reduced: Nodes whose radius became the (smaller) measured clearance.
        radius_ratio_median: Median of new radius / given radius.
    """

    points: int
    trimmed_points: int
    trimmed_length_mm: float
    given_outside: int
    given_within_clearance: int
    moved: int
    offset_median_mm: float
    offset_p95_mm: float
    offset_median_r: float
    offset_p95_r: float
    radius_reduced: int
    radius_ratio_median: float


def signed_distance(mesh: trimesh.Trimesh, points: FloatArray) -> FloatArray:
    """Returns the exact distance of ``points`` to the closed surface ``mesh``, positive inside.

    libigl's pseudonormal test: the sign comes from the angle-weighted pseudonormal of the
    closest feature (face, edge or vertex; Bærentzen & Aanæs 2005), which is exact for a closed
    surface, where trimesh's ray-parity test miscounts on coarse, sharp-edged meshes. The faces
    are turned outward first (by the sign of the enclosed volume), so the winding of ``mesh``
    does not matter.
    """
    import igl  # libigl: imported here, as only building a vessel needs it

    points = np.ascontiguousarray(points, dtype=np.float64).reshape(-1, 3)
    vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    triangles = vertices[faces]
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    if np.einsum("ij,ij->", triangles[:, 0], cross) < 0:  # 6 × signed volume: wound inward
        faces = faces[:, ::-1]
    distance = igl.signed_distance(
        points, vertices, np.ascontiguousarray(faces), igl.SIGNED_DISTANCE_TYPE_PSEUDONORMAL
    )[0]
    return -np.asarray(distance, dtype=np.float64)  # libigl counts outside as positive


def _frames(graph: CenterlineGraph) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Returns each node's (first, second, tangent) axes (N, 3, 3) and the junction mask."""
    tangent = np.zeros((graph.num_nodes, 3))
    for node, adjacent in enumerate(graph.neighbours()):
        if len(adjacent) == 1:
            tangent[node] = graph.nodes[adjacent[0]] - graph.nodes[node]
        elif len(adjacent) == 2:
            tangent[node] = graph.nodes[adjacent[1]] - graph.nodes[adjacent[0]]
    junction = (graph.degrees() > 2) | (np.linalg.norm(tangent, axis=1) == 0)
    tangent[junction] = [0.0, 0.0, 1.0]
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    helper = np.where(np.abs(tangent[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    first = np.cross(tangent, helper)
    first /= np.linalg.norm(first, axis=1, keepdims=True)
    return np.stack([first, np.cross(tangent, first), tangent], axis=1), junction


def _directions(angles: int, sphere: bool) -> FloatArray:
    """Unit directions: ``angles`` in a plane (x, y), or about 3 × ``angles`` over a sphere."""
    if not sphere:
        theta = 2 * np.pi * np.arange(angles) / angles
        return np.column_stack([np.cos(theta), np.sin(theta), np.zeros(angles)])
    count = 3 * angles  # Fibonacci sphere
    z = 1 - (2 * np.arange(count) + 1) / count
    phi = np.pi * (3 - np.sqrt(5)) * np.arange(count)
    ring = np.sqrt(1 - z**2)
    return np.column_stack([ring * np.cos(phi), ring * np.sin(phi), z])


def _search(
    mesh: trimesh.Trimesh,
    origins: FloatArray,
    axes: FloatArray,
    reach: FloatArray,
    sphere: bool,
    params: RegistrationParams,
) -> tuple[FloatArray, FloatArray]:
    """Returns the best point near each origin and its clearance (coarse grid, refinements).

    Args:
        mesh: The closed lumen surface.
        origins: (n, 3) given points.
        axes: (n, 3, 3) per point the two in-plane axes and the tangent.
        reach: (n,) search radius (m).
        sphere: Search a ball instead of the cross-section plane.
        params: Registration settings.
    """
    best = origins.copy()
    best_clear = signed_distance(mesh, best)
    best_score = best_clear.copy()
    step = reach / params.rings
    plan = [(np.arange(1, params.rings + 1), params.angles)]
    plan += [(np.array([1]), 8)] * params.refinements
    n = len(origins)
    for level, (rings, angles) in enumerate(plan):
        centre = best.copy()
        if level:
            step = step / 2
        unit = np.einsum("dk,nkj->ndj", _directions(angles, sphere), axes)  # (n, D, 3)
        offsets = rings[None, :, None, None] * step[:, None, None, None] * unit[:, None]
        candidates = (centre[:, None, None] + offsets).reshape(n, -1, 3)
        clear = signed_distance(mesh, candidates.reshape(-1, 3)).reshape(n, -1)
        moved = np.linalg.norm(candidates - origins[:, None], axis=-1)
        score = clear - params.offset_penalty * moved
        index = score.argmax(axis=1)
        top = score[np.arange(n), index]
        better = top > best_score
        best[better] = candidates[better, index[better]]
        best_clear[better] = clear[better, index[better]]
        best_score[better] = top[better]
    return best, best_clear


def _place(
    mesh: trimesh.Trimesh, graph: CenterlineGraph, params: RegistrationParams
) -> tuple[FloatArray, FloatArray]:
    """Searches the cross-section plane (a ball at junctions) of every node of ``graph``."""
    axes, junction = _frames(graph)
    reach = np.maximum(params.search_radius * graph.radii, params.min_search)
    points = np.empty_like(graph.nodes)
    clear = np.empty(graph.num_nodes)
    for sphere in (False, True):
        rows = np.flatnonzero(junction == sphere)
        if len(rows):
            points[rows], clear[rows] = _search(
                mesh, graph.nodes[rows], axes[rows], reach[rows], sphere, params
            )
    return points, clear


def _smoothed(graph: CenterlineGraph, offsets: FloatArray, half_width: int) -> FloatArray:
    """Returns the offsets averaged over ``half_width`` nodes each side along every branch."""
    out = offsets.copy()
    if half_width <= 0:
        return out
    for chain in branch_chains(graph):
        inner = chain[1:-1]  # junctions and ends keep their own offsets
        values = offsets[chain]
        for position, node in enumerate(inner, start=1):
            lo, hi = max(0, position - half_width), min(len(chain), position + half_width + 1)
            out[node] = values[lo:hi].mean(axis=0)
    return out


def _curve_name(graph: CenterlineGraph, node: int) -> str:
    branch = int(graph.branch[node]) if graph.branch is not None else -1
    if 0 <= branch < len(graph.branch_names):
        return f"curve {graph.branch_names[branch]!r}"
    return "the centerline"


def register_centerline(
    graph: CenterlineGraph,
    lumen: trimesh.Trimesh,
    params: RegistrationParams = RegistrationParams(),
    clearance: float = 0.4,
) -> tuple[CenterlineGraph, RegistrationReport]:
    """Moves every node of ``graph`` onto the axis of ``lumen``; see the module docstring.

    Args:
        graph: The given centerline (m), e.g. from :func:`.slicer.read_slicer_centerline`.
        lumen: The closed lumen surface (m), normals out of the lumen.
        params: Registration settings.
        clearance: Sphere of the lumen-open check, in radii (only for the report).

    Returns:
        The registered graph (same topology, labels and branch names, less trimmed curve
        ends) and the report.

    Raises:
        CenterlineRegistrationError: A node has no point inside the lumen within its search
            radius; the message names the curve and the point.
    """
    given_clear = signed_distance(lumen, graph.nodes)
    given_outside = int(np.sum(given_clear < 0))
    given_close = int(np.sum((given_clear >= 0) & (given_clear < clearance * graph.radii)))
    points, point_clear = _place(lumen, graph, params)
    trim = end_runs(graph, point_clear < params.end_clearance * graph.radii)
    trimmed_length = float(graph.edge_lengths()[trim[graph.edges].any(axis=1)].sum())
    if trim.any():
        kept = ~trim
        graph = without_nodes(graph, trim)
        points, point_clear = points[kept], point_clear[kept]
    lost = np.flatnonzero(point_clear <= 0)
    if len(lost):  # not at a vessel end: look around in 3D before giving up
        axes, _ = _frames(graph)
        reach = np.maximum(params.search_radius * graph.radii[lost], params.min_search)
        points[lost], point_clear[lost] = _search(
            lumen, graph.nodes[lost], axes[lost], reach, True, params
        )
        lost = lost[point_clear[lost] <= 0]
    if len(lost):
        node = int(lost[0])
        limit = max(params.search_radius * float(graph.radii[node]), params.min_search)
        raise CenterlineRegistrationError(
            f"{_curve_name(graph, node)}: {len(lost)} point(s) lie outside the lumen surface "
            f"with no inside point within {limit * 1e3:.3g} mm, e.g. node {node} at "
            f"{np.round(graph.nodes[node] * 1e3, 2).tolist()} mm (model frame). Check that the "
            "curves belong to this mesh and share its frame (--mesh-frame) and units, or pass "
            "the centerline as given (--no-register)."
        )
    offsets = _smoothed(graph, points - graph.nodes, params.smooth_nodes)
    smooth = graph.nodes + offsets
    smooth_clear = signed_distance(lumen, smooth)
    keep = smooth_clear >= params.smooth_keep * point_clear
    points = np.where(keep[:, None], smooth, points)
    point_clear = np.where(keep, smooth_clear, point_clear)
    radii = np.minimum(graph.radii, point_clear)
    registered = CenterlineGraph(
        points, radii, graph.edges, graph.labels, graph.branch, graph.branch_names
    )
    moved = np.linalg.norm(points - graph.nodes, axis=1)
    in_radii = moved / graph.radii
    report = RegistrationReport(
        points=graph.num_nodes,
        trimmed_points=int(trim.sum()),
        trimmed_length_mm=round(trimmed_length * 1e3, 3),
        given_outside=given_outside,
        given_within_clearance=given_close,
        moved=int(np.sum(in_radii > 0.01)),
        offset_median_mm=round(float(np.median(moved)) * 1e3, 4),
        offset_p95_mm=round(float(np.percentile(moved, 95)) * 1e3, 4),
        offset_median_r=round(float(np.median(in_radii)), 4),
        offset_p95_r=round(float(np.percentile(in_radii, 95)), 4),
        radius_reduced=int(np.sum(point_clear < graph.radii)),
        radius_ratio_median=round(float(np.median(radii / graph.radii)), 4),
    )
    logger.info(
        "centerline registered onto the lumen: %d curve-end points past a vessel end or in "
        "its cap trimmed (%.3g mm); %d of %d points moved (median %.3g mm = %.3g R, "
        "95th pct %.3g mm = %.3g R); given: %d outside the lumen, %d within %.2g R of the wall; "
        "%d radii reduced to the clearance",
        report.trimmed_points,
        report.trimmed_length_mm,
        report.moved,
        report.points,
        report.offset_median_mm,
        report.offset_median_r,
        report.offset_p95_mm,
        report.offset_p95_r,
        report.given_outside,
        report.given_within_clearance,
        clearance,
        report.radius_reduced,
    )
    return registered, report
