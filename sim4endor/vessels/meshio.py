"""Reading, validating and repairing lumen (blood-pool) surface meshes.

Documented repairs (each is counted in :class:`RepairReport` and logged):

* vertices closer than trimesh's merge tolerance are merged (OBJ/STL files often duplicate them);
* degenerate faces (repeated vertices or zero area) and duplicate faces are removed;
* small holes in the side wall (a boundary loop whose perimeter is below
  ``max_hole_perimeter`` lumen radii and whose adjacent faces lie in the loop's plane) are closed
  with a fan around the loop centroid;
* with ``keep_largest=True`` every connected component but the largest is dropped;
* a lumen of more faces than ``RemeshParams.max_faces`` is decimated, and edges longer than
  ``RemeshParams.max_edge_fraction`` lumen radii are subdivided (:mod:`.remesh`); the full
  mesh is kept for display.

Everything else that makes a mesh unusable raises :class:`MeshInputError` naming the file and the
fix: an empty or unreadable file, large holes, several components (without ``keep_largest``), or
an absurd lumen radius for the declared units.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import trimesh
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from sim4endor.errors import Sim4EndoRError
from sim4endor.vessels.remesh import RemeshParams, decimate, faces_for

logger = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]
Units = Literal["um", "mm", "m"]

SUPPORTED_SUFFIXES = (".stl", ".obj", ".ply", ".off")
UNIT_SCALE: dict[str, float] = {"um": 1e-6, "mm": 1e-3, "m": 1.0}
#: Plausible lumen radii (m) of vessels a guidewire navigates: small coronary to large aorta.
PLAUSIBLE_RADIUS = (0.2e-3, 30e-3)
#: Plausible sizes (m, bounding-box diagonal) of a vessel mesh: from a few millimetres of one
#: narrow vessel to a whole body's arterial tree. Checked before any heavy work, so a mesh in
#: the wrong units fails at once; the radius check after the repairs is the finer one.
PLAUSIBLE_EXTENT = (1e-3, 3.0)


class MeshInputError(Sim4EndoRError, ValueError):
    """Raised for an input mesh that cannot be turned into a vessel; names the file and fix."""


@dataclass(frozen=True)
class RepairReport:
    """What :func:`prepare_lumen` changed in the input mesh.

    Attributes:
        merged_vertices: Duplicate vertices merged.
        removed_faces: Degenerate or duplicate faces removed.
        filled_holes: Small side-wall holes closed.
        dropped_components: Face counts of components dropped by ``keep_largest``.
        open_ends: Number of boundary loops kept open as vessel ends.
        decimated_from: Faces of the repaired lumen before decimation (0: not decimated).
        subdivided_from: Faces of the repaired lumen before its faces with edges over the
            remeshing limit were subdivided (0: none were).
    """

    merged_vertices: int = 0
    removed_faces: int = 0
    filled_holes: int = 0
    dropped_components: tuple[int, ...] = ()
    open_ends: int = 0
    decimated_from: int = 0
    subdivided_from: int = 0


@dataclass(frozen=True, eq=False)
class PreparedLumen:
    """A validated lumen mesh in model metres.

    Attributes:
        mesh: The repaired lumen surface (m), normals pointing out of the lumen.
        scale: Factor from input units to metres.
        radius_estimate: Median lumen radius (m) estimated from the surface.
        end_loops: Vertex index loops of the open vessel ends.
        report: The repairs made.
        display: The repaired lumen at full resolution (m) when ``mesh`` was decimated from
            it, for display; None when ``mesh`` is the full lumen.
    """

    mesh: trimesh.Trimesh
    scale: float
    radius_estimate: float
    end_loops: list[NDArray[np.int64]] = field(default_factory=list)
    report: RepairReport = field(default_factory=RepairReport)
    display: trimesh.Trimesh | None = None


def read_mesh(path: Path) -> trimesh.Trimesh:
    """Reads a surface mesh file (STL, OBJ, PLY or OFF) without changing it."""
    path = Path(path)
    if path.is_dir():
        meshes = sorted(p.name for p in path.iterdir() if p.suffix.lower() in SUPPORTED_SUFFIXES)
        found = f" (it holds {', '.join(meshes[:5])})" if meshes else ""
        raise MeshInputError(f"{path} is a folder, not a mesh file{found}. Pass the lumen "
                             "surface mesh (STL/OBJ/PLY) itself.")
    if not path.is_file():
        raise MeshInputError(f"{path}: no such file. Pass the lumen surface mesh (STL/OBJ/PLY).")
    if path.suffix.lower() not in SUPPORTED_SUFFIXES:
        raise MeshInputError(
            f"{path}: unsupported mesh format {path.suffix!r}; export the lumen surface as one of "
            f"{', '.join(SUPPORTED_SUFFIXES)}."
        )
    if path.stat().st_size == 0:
        raise MeshInputError(f"{path} is empty; export the lumen surface mesh again.")
    try:
        loaded = trimesh.load(path, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many unrelated types for unparsable files
        raise MeshInputError(
            f"{path} could not be read as a {path.suffix[1:].upper()} mesh ({exc}); check that "
            "it is a triangle surface mesh file."
        ) from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise MeshInputError(f"{path} holds no triangles; export the lumen surface mesh again.")
    return loaded


#: Vertices closer than this fraction of the mesh's median edge are one vertex
#: (:func:`merge_close_vertices`).
MERGE_FRACTION = 1e-4


def merge_close_vertices(mesh: trimesh.Trimesh) -> None:
    """Merges (in place) the vertices of ``mesh`` that meet on a grid of at most
    :data:`MERGE_FRACTION` of its median edge, a power of ten.

    trimesh's own merge rounds coordinates to a fixed 1e-8 in the mesh's units, so one lumen
    merged differently in metres, millimetres and micrometres: marching-cubes vertices a few
    nanometres apart were merged in metres only, and in millimetres the decimation then broke
    the lumen ("non-manifold boundary"). On a grid set by the mesh's own edges (and the mesh
    in metres, as :func:`prepare_lumen` has it), the same points merge in any unit; for a
    lumen of sub-millimetre edges in metres the grid is trimesh's own, so the shipped phantoms
    rebuild bit for bit.

    Only a mesh that is not closed after merging its identical vertices is merged on the grid:
    a closed marching-cubes lumen has distinct vertices closer than that where the surface
    passes a voxel corner, and merging them pinched its edges (6 non-manifold edges, then 60
    boundary edges once the collapsed faces went, on a 136,178-face tree: "non-manifold
    boundary", issue 78).
    """
    _merge_identical_vertices(mesh)
    if mesh.is_watertight:
        return
    edges = mesh.edges_unique_length
    edges = edges[edges > 0]
    if not edges.size:
        return
    digits = int(-math.floor(math.log10(MERGE_FRACTION * float(np.median(edges)))))
    mesh.merge_vertices(merge_tex=True, merge_norm=True, digits_vertex=digits)


def _merge_identical_vertices(mesh: trimesh.Trimesh) -> None:
    """Merges (in place) vertices with bit-identical coordinates, as a triangle soup has."""
    unique, inverse = np.unique(np.asarray(mesh.vertices), axis=0, return_inverse=True)
    if len(unique) < len(mesh.vertices):
        faces = inverse.reshape(-1)[np.asarray(mesh.faces)]
        mesh.vertices = unique
        mesh.faces = faces


def degenerate_faces(mesh: trimesh.Trimesh) -> NDArray[np.bool_]:
    """Mask of the faces the importer removes: zero height or area relative to the mesh size."""
    scale = float(mesh.scale)
    return ~(mesh.nondegenerate_faces(height=1e-10 * scale)
             & (mesh.area_faces > 1e-12 * scale**2))


def without_degenerate_faces(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """``mesh`` less its :func:`degenerate_faces`, closed if it was closed.

    Marching cubes leaves zero-area slivers where the surface passes a voxel corner; deleting
    them opened a closed 136,178-face lumen with 64 boundary edges and pinched vertices that
    the build then refused as a "non-manifold boundary" (issue 78). In a closed mesh each
    sliver's shortest edge is collapsed instead, which takes the sliver and its neighbour
    across that edge; should that not leave the mesh closed, the slivers are deleted as in an
    open one.
    """
    if mesh.is_watertight:
        collapsed = _collapse_degenerate_faces(mesh)
        if collapsed.is_watertight:
            return collapsed
    out = mesh.copy()
    out.update_faces(~degenerate_faces(out))
    return out


def _collapse_degenerate_faces(mesh: trimesh.Trimesh, rounds: int = 5) -> trimesh.Trimesh:
    vertices, faces = np.asarray(mesh.vertices), np.asarray(mesh.faces)
    for _ in range(rounds):
        current = trimesh.Trimesh(vertices, faces, process=False)
        bad = np.flatnonzero(degenerate_faces(current))
        if not len(bad):
            break
        corners = faces[bad]
        edges = np.stack([corners[:, [0, 1]], corners[:, [1, 2]], corners[:, [2, 0]]], axis=1)
        lengths = np.linalg.norm(vertices[edges[..., 0]] - vertices[edges[..., 1]], axis=2)
        shortest = edges[np.arange(len(bad)), lengths.argmin(axis=1)]
        # Every vertex joined by collapsed edges becomes the first of its group.
        joined = coo_matrix((np.ones(len(shortest)), (shortest[:, 0], shortest[:, 1])),
                            shape=(len(vertices), len(vertices)))
        _, group = connected_components(joined, directed=False)
        first = np.full(group.max() + 1, len(vertices))
        np.minimum.at(first, group, np.arange(len(vertices)))
        target = first[group]
        faces = target[faces]
        faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2])
                      & (faces[:, 2] != faces[:, 0])]
    out = trimesh.Trimesh(vertices, faces, process=False)
    out.update_faces(out.unique_faces())
    out.remove_unreferenced_vertices()
    return out


def boundary_loops(mesh: trimesh.Trimesh) -> list[NDArray[np.int64]]:
    """Returns the closed loops of boundary edges (edges with one face) as vertex index arrays."""
    edges = mesh.edges_sorted
    groups = trimesh.grouping.group_rows(edges, require_count=1)
    if len(groups) == 0:
        return []
    # Directed boundary edges, in face order, so each loop is walked consistently.
    directed = mesh.edges[np.asarray(groups).ravel()]
    successor: dict[int, int] = {int(a): int(b) for a, b in directed}
    loops: list[NDArray[np.int64]] = []
    seen: set[int] = set()
    for start in successor:
        if start in seen:
            continue
        loop = [start]
        seen.add(start)
        cur = successor[start]
        while cur != start and cur in successor and cur not in seen:
            loop.append(cur)
            seen.add(cur)
            cur = successor[cur]
        loops.append(np.asarray(loop, dtype=np.int64))
    return loops


def loop_perimeter(points: FloatArray) -> float:
    """Length of the closed polygon through ``points`` (in their units)."""
    return float(np.linalg.norm(points - np.roll(points, 1, axis=0), axis=1).sum())


def _loop_is_side_hole(mesh: trimesh.Trimesh, loop: NDArray[np.int64]) -> bool:
    """True when the loop lies in the surface (a hole), False when it is a tube cross-section."""
    points = mesh.vertices[loop]
    centred = points - points.mean(axis=0)
    plane_normal = np.linalg.svd(centred, full_matrices=False)[2][-1]
    faces = np.unique(
        np.concatenate([mesh.vertex_faces[v][mesh.vertex_faces[v] >= 0] for v in loop])
    )
    alignment = np.abs(mesh.face_normals[faces] @ plane_normal)
    return bool(np.median(alignment) > 0.5)


def _units_hint(raw: float, plausible: tuple[float, float] = PLAUSIBLE_RADIUS) -> str:
    """Names the units in which a length of ``raw`` (input units) would be ``plausible``."""
    fitting = [u for u, k in UNIT_SCALE.items() if plausible[0] <= raw * k <= plausible[1]]
    if fitting:
        return f"If the mesh is in {fitting[0]}, pass --units {fitting[0]}."
    return (f"No supported unit ({', '.join(UNIT_SCALE)}) makes it plausible: check the mesh's "
            "scale.")


def estimate_radius(mesh: trimesh.Trimesh, samples: int = 256, seed: int = 0) -> float:
    """Estimates the median lumen radius: half the distance across the lumen along the normal.

    Rays are cast inwards from a seeded sample of faces; works for open and capped meshes.
    The median is over the surface's area, not its face count: a coarsely triangulated
    capped cylinder has as many cap triangles as side triangles, and the caps' rays cross the
    whole length.
    """
    rng = np.random.default_rng(seed)
    faces = rng.choice(len(mesh.faces), size=min(samples, len(mesh.faces)), replace=False)
    origins = mesh.triangles_center[faces]
    directions = -mesh.face_normals[faces]
    scale = float(mesh.scale)
    locations, ray_idx, tri_idx = mesh.ray.intersects_location(
        origins + directions * 1e-6 * scale, directions, multiple_hits=True
    )
    if len(ray_idx) == 0:
        return float(2.0 * abs(mesh.volume) / max(mesh.area, 1e-30))
    dist = np.linalg.norm(locations - origins[ray_idx], axis=1)
    valid = tri_idx != faces[ray_idx]
    nearest = np.full(len(faces), np.inf)
    np.minimum.at(nearest, ray_idx[valid], dist[valid])
    hit = np.isfinite(nearest)
    if not np.any(hit):
        return float(2.0 * abs(mesh.volume) / max(mesh.area, 1e-30))
    order = np.argsort(nearest[hit])
    weight = np.cumsum(mesh.area_faces[faces[hit]][order])
    return float(0.5 * nearest[hit][order][np.searchsorted(weight, 0.5 * weight[-1])])


def _fill_loop(mesh: trimesh.Trimesh, loop: NDArray[np.int64]) -> trimesh.Trimesh:
    centre = mesh.vertices[loop].mean(axis=0)
    new_index = len(mesh.vertices)
    # Boundary edges run with the faces; the fan runs against them so the patch matches winding.
    fan = np.column_stack([np.roll(loop, -1), loop, np.full(len(loop), new_index)])
    return trimesh.Trimesh(
        vertices=np.vstack([mesh.vertices, centre]),
        faces=np.vstack([mesh.faces, fan]),
        process=False,
    )


def _fill_loops(mesh: trimesh.Trimesh, loops: list[NDArray[np.int64]]) -> trimesh.Trimesh:
    for loop in loops:
        mesh = _fill_loop(mesh, loop)
    return mesh


def close_openings(prepared: PreparedLumen, loops: list[NDArray[np.int64]]) -> PreparedLumen:
    """Returns ``prepared`` with some of its open ends (``loops``, from ``end_loops``) filled.

    For small openings found to be holes only once the centerline is known (see
    :func:`sim4endor.vessels.checks.stray_openings`); they count as filled holes in the report.
    Filling appends vertices, so the indices of the other loops stay valid.
    """
    mesh = _fill_loops(prepared.mesh, loops)
    closed = {id(loop) for loop in loops}
    report = dataclasses.replace(
        prepared.report,
        filled_holes=prepared.report.filled_holes + len(loops),
        open_ends=prepared.report.open_ends - len(loops),
    )
    return dataclasses.replace(
        prepared, mesh=mesh, report=report,
        end_loops=[loop for loop in prepared.end_loops if id(loop) not in closed],
    )


def closed(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Returns ``mesh`` with every boundary loop closed by a fan (a folder's lumen, whose
    vessel ends are open)."""
    return _fill_loops(mesh, boundary_loops(mesh))


def capped(prepared: PreparedLumen) -> trimesh.Trimesh:
    """Returns the lumen with its open ends closed by fans (for voxelisation)."""
    return _fill_loops(prepared.mesh, prepared.end_loops)


def _faces_inward(mesh: trimesh.Trimesh, samples: int = 256, seed: int = 0) -> bool:
    """Whether a lumen surface's faces point into the lumen.

    A closed surface says so by its signed volume. An open one (a lumen with open vessel
    ends, or one that merging, repair or decimation left with a stray edge) by rays: from a
    seeded sample of faces, a ray against the normal of an outward surface crosses the lumen
    and meets the wall again, one along it leaves the vessel; inward, the other way round.
    """
    if mesh.is_watertight:
        return bool(mesh.volume < 0)
    rng = np.random.default_rng(seed)
    faces = rng.choice(len(mesh.faces), size=min(samples, len(mesh.faces)), replace=False)
    origins, normals = mesh.triangles_center[faces], mesh.face_normals[faces]
    hits = []
    for direction in (-normals, normals):
        triangles, rays = mesh.ray.intersects_id(origins, direction, multiple_hits=True)[:2]
        hits.append(len(np.unique(rays[triangles != faces[rays]])))  # not its own face
    across, away = hits
    return away > across


def _outward(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """``mesh`` with its winding made consistent and outward."""
    mesh = mesh.copy()
    trimesh.repair.fix_winding(mesh)
    if _faces_inward(mesh):
        # A new mesh, not Trimesh.invert(): in trimesh 5.2 invert() leaves the cached face
        # normals pointing against the new winding, and the wall would then grow into the lumen.
        mesh = trimesh.Trimesh(mesh.vertices, np.ascontiguousarray(mesh.faces[:, ::-1]),
                               process=False)
    return mesh


def prepare_lumen(
    mesh: trimesh.Trimesh,
    *,
    units: Units,
    source: str = "<mesh>",
    keep_largest: bool = False,
    max_hole_perimeter: float = 3.0,
    resolution: RemeshParams | None = None,
) -> PreparedLumen:
    """Validates and repairs a lumen mesh, brings it to the wall's resolution and converts it
    to metres.

    Args:
        mesh: The lumen surface in input units.
        units: Units of ``mesh`` (``"um"``, ``"mm"`` or ``"m"``).
        source: Name of the input (file path) used in error messages.
        keep_largest: Drop every connected component but the largest instead of failing.
        max_hole_perimeter: Side-wall holes whose perimeter is below this many lumen radii are
            filled; larger ones are errors.
        resolution: When to decimate the lumen or subdivide its long edges (:mod:`.remesh`;
            None: the defaults).
    """
    if units not in UNIT_SCALE:
        raise MeshInputError(f"units must be one of {list(UNIT_SCALE)}, got {units!r}.")
    # A copy: the caller's mesh stays in its units.
    work = trimesh.Trimesh(vertices=np.array(mesh.vertices, dtype=np.float64),
                           faces=np.array(mesh.faces), process=False)
    if len(work.faces) == 0:
        raise MeshInputError(f"{source} holds no triangles.")
    if not np.all(np.isfinite(work.vertices)):
        raise MeshInputError(f"{source} has non-finite vertex coordinates; re-export the mesh.")
    extent = float(np.linalg.norm(np.ptp(work.vertices, axis=0)))
    if not PLAUSIBLE_EXTENT[0] <= extent * UNIT_SCALE[units] <= PLAUSIBLE_EXTENT[1]:
        raise MeshInputError(
            f"{source}: with units={units!r} the mesh is {extent * UNIT_SCALE[units] * 1e3:.4g} mm "
            f"across, absurd for a vessel (expected {PLAUSIBLE_EXTENT[0] * 1e3:g} mm to "
            f"{PLAUSIBLE_EXTENT[1]:g} m). {_units_hint(extent, PLAUSIBLE_EXTENT)}"
        )
    # In metres from here on, and every tolerance relative to the lumen: the same mesh in mm,
    # m or um is repaired the same.
    scale = UNIT_SCALE[units]
    work.apply_scale(scale)
    n_vertices = len(work.vertices)
    merge_close_vertices(work)
    merged = n_vertices - len(work.vertices)
    n_faces = len(work.faces)
    work = without_degenerate_faces(work)
    work.update_faces(work.unique_faces())
    work.remove_unreferenced_vertices()
    removed = n_faces - len(work.faces)
    if len(work.faces) < 4:
        raise MeshInputError(f"{source} has fewer than 4 usable triangles; it is not a vessel.")

    components = work.split(only_watertight=False)
    dropped: tuple[int, ...] = ()
    if len(components) > 1:
        sizes = sorted((len(c.faces) for c in components), reverse=True)
        if not keep_largest:
            raise MeshInputError(
                f"{source} has {len(components)} disconnected parts (faces per part: {sizes}). "
                "Export only the vessel lumen, or pass --keep-largest (keep_largest=True) to keep "
                "the largest part."
            )
        work = max(components, key=lambda c: len(c.faces))
        dropped = tuple(sizes[1:])
        logger.info("%s: kept the largest component, dropped parts of %s faces", source, dropped)

    work = _outward(work)
    resolution = resolution or RemeshParams()
    decimated = len(work.faces) > resolution.max_faces
    # On a decimated copy for a large lumen: the ray casts took 19 s on 1.1 M faces.
    radius = estimate_radius(decimate(work, resolution.max_faces) if decimated else work)
    if not PLAUSIBLE_RADIUS[0] <= radius <= PLAUSIBLE_RADIUS[1]:
        raise MeshInputError(
            f"{source}: with units={units!r} the median lumen radius is {radius * 1e3:.4g} mm, "
            f"absurd for a vessel (expected {PLAUSIBLE_RADIUS[0] * 1e3:g}–"
            f"{PLAUSIBLE_RADIUS[1] * 1e3:g} mm). {_units_hint(radius / scale)}"
        )
    full = work
    if decimated:
        # From the full mesh in one pass: decimating the copy further left non-manifold edges.
        target = min(resolution.max_faces, faces_for(work, resolution.edge_fraction * radius))
        work = decimate(work, target)
        logger.info("%s: decimated from %d to %d faces for the wall (edges of about %g lumen "
                    "radii); the full mesh is kept for display", source, len(full.faces),
                    len(work.faces), resolution.edge_fraction)
    max_edge = resolution.max_edge_fraction * radius
    subdivided_from = 0
    if work.edges_unique_length.max() > max_edge:
        subdivided_from = len(work.faces)
        vertices, faces = trimesh.remesh.subdivide_to_size(work.vertices, work.faces, max_edge)
        work = trimesh.Trimesh(vertices, faces, process=False)
        work.merge_vertices()
        logger.info("%s: subdivided the faces with edges longer than %.3g mm (%g lumen radii): "
                    "%d faces, from %d", source, max_edge * 1e3, resolution.max_edge_fraction,
                    len(work.faces), subdivided_from)

    filled = 0
    end_loops: list[NDArray[np.int64]] = []
    for loop in boundary_loops(work):
        if len(loop) < 3:
            raise MeshInputError(f"{source} has a non-manifold boundary; repair it in a mesh tool.")
        points = work.vertices[loop]
        perimeter = loop_perimeter(points)
        if _loop_is_side_hole(work, loop):
            if perimeter > max_hole_perimeter * radius:
                raise MeshInputError(
                    f"{source} has a hole in the vessel wall ({perimeter * 1e3:.3g} mm around, "
                    f"near {np.round(points.mean(axis=0) / scale, 3).tolist()} in input units). "
                    "Close it in the segmentation or a mesh tool (holes below "
                    f"{max_hole_perimeter:g} lumen radii around are filled automatically)."
                )
            work = _fill_loop(work, loop)
            filled += 1
        else:
            end_loops.append(loop)
    if filled:
        logger.info("%s: filled %d small hole(s) in the wall", source, filled)
    if removed or merged:
        logger.info("%s: merged %d vertices, removed %d bad faces", source, merged, removed)
    report = RepairReport(
        merged_vertices=merged,
        removed_faces=removed,
        filled_holes=filled,
        dropped_components=dropped,
        open_ends=len(end_loops),
        decimated_from=len(full.faces) if decimated else 0,
        subdivided_from=subdivided_from,
    )
    return PreparedLumen(
        mesh=work, scale=scale, radius_estimate=radius, end_loops=end_loops, report=report,
        display=full if decimated else None,
    )
