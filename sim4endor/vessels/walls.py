"""Convex wall hulls around a lumen surface.

CoACD on a whole tube shell fills the lumen (its threshold is relative to the bounding-box
diagonal), so the wall is cut into small pieces first:

1. every lumen face is located on the centerline (branch, arc position in radii, angle around
   the axis in a rotation-minimising frame) and binned by (branch, ``arc_bin`` radii,
   ``sectors`` angular sectors, and whether it faces along the axis as end caps do);
2. a piece is a closed solid: its lumen faces, the same faces offset outward by the wall
   thickness along the vertex normals, and side walls along the piece boundary. Neighbouring
   pieces share their boundary, so the wall is closed by construction. Where the lumen comes
   back within a wall thickness (the carina between a parent and a branch, two vessels
   running side by side) the wall there is half the gap (:func:`wall_thickness`), so the
   walls of both sides meet and neither enters the other's lumen;
3. fast path: if the piece's convex hull intrudes into the lumen by at most
   ``intrusion_tolerance`` radii (the exit distance of an inward ray from every lumen vertex of
   the piece through the hull's half-spaces), the hull is used as is. Most tube pieces take this
   path, which is why a ~100k-face tree builds in a minute or two;
4. the other pieces (bifurcations, tight bends) are bisected along their longer extent (arc or
   angle) and the halves are treated again, down to single faces, whose prisms are convex;
5. with ``use_coacd`` (the default) a piece whose bisection needs three hulls or more also goes
   to CoACD (``pca=True``, preprocessing off since the piece solid is closed, a shallow search,
   ``coacd_threshold`` 0.2 of the piece's bounding-box diagonal), and CoACD's hulls replace the
   bisection's when they keep the lumen open (step 3's test) and are fewer. Measured: CoACD at
   threshold 0.05 with its default search cut a 48-face phantom piece into 80-113 hulls in
   10-20 s; at 0.2 with the shallow search into 2-3 hulls in 0.1-0.2 s. It saves 5-10 % of the
   phantoms' hulls and none on a ~100k-face coronary tree, where it doubles the wall time
   (docs/vessels.md has the figures).

Faces of the end cap at the inlet get no wall, so a wire can enter a capped mesh.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import multiprocessing.pool
import signal
import sys
import types
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import trimesh
from numpy.typing import NDArray
from scipy.spatial import ConvexHull, QhullError

from sim4endor.errors import Sim4EndoRError
from sim4endor.vessels.axis import AxisSamples
from sim4endor.vessels.centerline import CenterlineGraph

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class WallParamsError(Sim4EndoRError, ValueError):
    """Raised for an impossible wall setting; the message names the field."""


@dataclass(frozen=True)
class WallParams:
    """How the wall is cut and decomposed (lengths in metres or in lumen radii as named).

    Attributes:
        thickness: Wall thickness (m). 0.8 mm is the guidewire spike's measured setting: thick
            enough that a mass-scaled wire does not tunnel through at 1 ms steps.
        arc_bin: Piece length along the axis, in local lumen radii.
        sectors: Angular sectors around the axis.
        intrusion_tolerance: Largest accepted intrusion of a hull into the lumen, in local
            lumen radii.
        use_coacd: Also decompose pieces that bisection splits into three or more hulls with
            CoACD, and keep its hulls where they are fewer.
        coacd_threshold: CoACD concavity threshold (relative to the piece's bbox diagonal).
        coacd_mcts_iterations: CoACD search iterations (fewer is faster).
        coacd_resolution: CoACD sampling resolution.
        max_split_depth: Bisection depth limit per piece.
        workers: Processes for the pieces (they are independent). They are spawned, so a
            script building with workers > 1 needs an ``if __name__ == "__main__":`` guard.
    """

    thickness: float = 0.8e-3
    arc_bin: float = 1.5
    sectors: int = 8
    intrusion_tolerance: float = 0.15
    use_coacd: bool = True
    coacd_threshold: float = 0.2
    coacd_mcts_iterations: int = 5
    coacd_resolution: int = 100
    max_split_depth: int = 12
    workers: int = 2

    def __post_init__(self) -> None:
        positive = {"thickness": self.thickness, "arc_bin": self.arc_bin,
                    "coacd_threshold": self.coacd_threshold}
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0):
                raise WallParamsError(f"WallParams.{name} must be a positive number, got {value}.")
        if not (math.isfinite(self.intrusion_tolerance) and self.intrusion_tolerance >= 0):
            raise WallParamsError("WallParams.intrusion_tolerance must be >= 0, got "
                                  f"{self.intrusion_tolerance}.")
        counts = {"sectors": (self.sectors, 1), "workers": (self.workers, 1),
                  "max_split_depth": (self.max_split_depth, 0),
                  "coacd_mcts_iterations": (self.coacd_mcts_iterations, 1),
                  "coacd_resolution": (self.coacd_resolution, 1)}
        for name, (count, least) in counts.items():
            if count < least:
                raise WallParamsError(f"WallParams.{name} must be >= {least}, got {count}.")


@dataclass(frozen=True, eq=False)
class Hull:
    """One convex wall hull.

    Attributes:
        vertices: (V, 3) hull vertices (m).
        faces: (F, 3) outward-oriented triangles.
        equations: (P, 4) half-spaces ``n·x + d <= 0`` with unit ``n``.
    """

    vertices: FloatArray
    faces: IntArray
    equations: FloatArray

    def to_trimesh(self) -> trimesh.Trimesh:
        """Returns the hull as a trimesh."""
        return trimesh.Trimesh(self.vertices, self.faces, process=False)


#: A hull whose volume is below this fraction of the cube of its longest extent is flat: a
#: sliver that stops nothing (one of 2.8e-19 m^3, 1e-9 of its cube, came out of a decomposed
#: junction).
FLAT_VOLUME_FRACTION = 1e-6


def convex_hull(points: FloatArray) -> Hull | None:
    """Returns the convex hull of ``points``, or None when they are (nearly) flat
    (:data:`FLAT_VOLUME_FRACTION`) or have fewer than four vertices as a hull mesh stores
    them (float32, the STL's precision): two vertices distinct in float64 but equal in float32
    left a four-vertex hull with three, which MuJoCo refuses to compile ("at least 4 vertices
    required"). Every other hull is the one qhull gives for the points as they are, so that
    builds stay bit for bit what they were.
    """
    try:
        qh = ConvexHull(points)
    except (QhullError, ValueError):
        return None
    if qh.volume <= FLAT_VOLUME_FRACTION * float(np.ptp(points, axis=0).max()) ** 3:
        return None
    if len(np.unique(points[qh.vertices].astype(np.float32), axis=0)) < 4:
        return None
    used = np.unique(qh.simplices)
    remap = np.full(len(points), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    faces = remap[qh.simplices]
    verts = points[used]
    # Orient every triangle outward using qhull's facet normals.
    tri = verts[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flip = np.einsum("ij,ij->i", normal, qh.equations[:, :3]) < 0
    faces[flip] = faces[flip][:, ::-1]
    return Hull(verts, faces, np.asarray(qh.equations, dtype=np.float64))


def intrusion(hull: Hull, points: FloatArray, inward: FloatArray, slack: float) -> FloatArray:
    """Returns how far an inward ray from each lumen point runs inside ``hull`` (m).

    Points outside the hull (by more than ``slack``) get 0: the hull does not cover them.
    """
    a, d = hull.equations[:, :3], hull.equations[:, 3]
    side = points @ a.T + d  # (N, P), <= 0 inside
    inside = side.max(axis=1) <= slack
    rate = inward @ a.T  # how fast the ray approaches each plane
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(rate > 1e-12, -side / rate, np.inf)
    exit_distance = np.clip(t.min(axis=1), 0.0, None)
    return np.where(inside, exit_distance, 0.0)


#: The thinnest wall, as a fraction of the wall's thickness (1/32: 25 um of the default 0.8 mm).
MIN_WALL_FRACTION = 1.0 / 32.0


def wall_thickness(vertices: FloatArray, normals: FloatArray, graph: CenterlineGraph,
                   thickness: float, samples: int = 16) -> FloatArray:
    """Returns the wall's thickness (m) at each lumen vertex: ``thickness``, or half the gap
    where the vertex's outward normal runs into another part of the lumen within it.

    Walls offset by a full thickness from both sides of a narrow carina overlap: in a vessel
    folder of a generated right coronary tree the parent's wall came within 0.34 mm of the
    axis of a 0.83 mm acute marginal, 2.7 mm past its ostium, at the place the scripted
    expert never entered (docs/tasks/coronary.md, 2026-11-29). The normal is sampled at
    ``samples`` steps out to ``thickness``; a step is in another part of the lumen when it
    lies a tenth of ``thickness`` inside an edge's tube (:meth:`CenterlineGraph.edge_excesses`)
    and that much deeper in it than the vertex itself. The second condition is what leaves the
    vertex's own vessel out: an axis extracted from a tortuous tube's mesh cuts the inside of
    a tight bend by 0.3 mm (2.2 mm bend radius, 1.2 mm lumen), so the lumen surface there lies
    0.23 mm inside the axis's own tube, and counting the tube alone thinned the wall to the
    floor on the inside of every tight bend (issue 78: probes 0.4 mm outside the true lumen
    found no hull at 1.3 % of the wall). Stepping out of its own vessel a point only gets
    shallower in that vessel's tube; into another vessel's it gets deeper.

    Args:
        vertices: (V, 3) lumen vertices (m).
        normals: (V, 3) unit vertex normals pointing out of the lumen.
        graph: The lumen's centerline.
        thickness: The wall's thickness where nothing is near (m).
        samples: Steps along each normal.
    """
    out = np.full(len(vertices), thickness)
    tolerance = 0.1 * thickness
    floor = MIN_WALL_FRACTION * thickness
    chunk = max(1, 2_000_000 // max(len(graph.edges), 1))  # (chunk, edges) work arrays
    for first in range(0, len(vertices), chunk):
        index = np.arange(first, min(first + chunk, len(vertices)))
        # A step counts inside an edge's tube only below this depth.
        depth = np.minimum(graph.edge_excesses(vertices[index]), 0.0) - tolerance
        for distance in thickness * np.arange(1, samples + 1) / samples:
            excess = graph.edge_excesses(vertices[index] + distance * normals[index])
            hit = (excess < depth).any(axis=1)
            # The lumen starts about ``tolerance`` before the step that is that far inside it.
            out[index[hit]] = max(0.5 * (distance - tolerance), floor)
            index, depth = index[~hit], depth[~hit]
            if not len(index):
                break
    return out


def piece_solid(
    vertices: FloatArray, triangles: IntArray, normals: FloatArray, thickness: FloatArray
) -> trimesh.Trimesh:
    """Returns the closed wall solid over lumen ``triangles``: inner, outer skin, side walls.

    Args:
        vertices: (V, 3) lumen vertices (m).
        triangles: (F, 3) the piece's lumen triangles (indices into ``vertices``).
        normals: (V, 3) unit vertex normals pointing out of the lumen.
        thickness: (V,) wall thickness at each vertex (m, :func:`wall_thickness`).
    """
    verts, local = np.unique(triangles, return_inverse=True)
    local = local.reshape(-1, 3)
    inner = vertices[verts]
    outer = inner + normals[verts] * thickness[verts, None]
    n = len(verts)
    # Lumen normals point out of the lumen, into the wall: the inner skin is reversed.
    skins = [local[:, ::-1], local + n]
    directed = np.vstack([local[:, [0, 1]], local[:, [1, 2]], local[:, [2, 0]]])
    key = np.sort(directed, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    border = directed[counts[inv.reshape(-1)] == 1]
    a, b = border[:, 0], border[:, 1]
    sides = np.vstack([np.column_stack([b, a, a + n]), np.column_stack([b, a + n, b + n])])
    return trimesh.Trimesh(np.vstack([inner, outer]), np.vstack([*skins, sides]), process=False)


@dataclass(frozen=True, eq=False)
class _Piece:
    faces: IntArray  # lumen face indices
    depth: int


@dataclass(frozen=True, eq=False)
class WallContext:
    """The lumen data the hull builder needs, as plain arrays (cheap to send to a worker).

    Attributes:
        vertices: (V, 3) lumen vertices (m).
        faces: (F, 3) lumen triangles.
        vertex_normals: (V, 3) unit normals out of the lumen.
        face_normals: (F, 3) unit normals out of the lumen.
        face_radius: (F,) local lumen radius (m).
        face_u: (F,) arc position along the branch (radii).
        face_angle: (F,) angle around the axis (rad).
        vertex_thickness: (V,) wall thickness at each vertex (m, :func:`wall_thickness`).
        params: Wall parameters.
    """

    vertices: FloatArray
    faces: IntArray
    vertex_normals: FloatArray
    face_normals: FloatArray
    face_radius: FloatArray
    face_u: FloatArray
    face_angle: FloatArray
    vertex_thickness: FloatArray
    params: WallParams

    def subset(self, faces: IntArray) -> WallContext:
        """Returns the context restricted to ``faces`` (re-indexed from 0)."""
        verts, local = np.unique(self.faces[faces], return_inverse=True)
        return WallContext(
            vertices=self.vertices[verts],
            faces=local.reshape(-1, 3).astype(np.int64),
            vertex_normals=self.vertex_normals[verts],
            face_normals=self.face_normals[faces],
            face_radius=self.face_radius[faces],
            face_u=self.face_u[faces],
            face_angle=self.face_angle[faces],
            vertex_thickness=self.vertex_thickness[verts],
            params=self.params,
        )


def _accept(hulls: list[Hull], ctx: WallContext, faces: IntArray) -> bool:
    verts = np.unique(ctx.faces[faces])
    centres = ctx.vertices[ctx.faces[faces]].mean(axis=1)
    points = np.vstack([ctx.vertices[verts], centres])
    inward = -np.vstack([ctx.vertex_normals[verts], ctx.face_normals[faces]])
    radius = float(ctx.face_radius[faces].min())
    slack = 1e-3 * radius
    limit = ctx.params.intrusion_tolerance * radius
    return all(float(intrusion(h, points, inward, slack).max()) <= limit for h in hulls)


def _solid_hull(ctx: WallContext, faces: IntArray) -> Hull | None:
    solid = piece_solid(ctx.vertices, ctx.faces[faces], ctx.vertex_normals,
                        ctx.vertex_thickness)
    return convex_hull(np.asarray(solid.vertices))


def _coacd_hulls(ctx: WallContext, faces: IntArray) -> list[Hull]:
    import coacd  # heavy import, only needed for non-convex pieces

    solid = piece_solid(ctx.vertices, ctx.faces[faces], ctx.vertex_normals,
                        ctx.vertex_thickness)
    solid.merge_vertices()
    coacd.set_log_level("error")
    # The piece solid is closed by construction, so CoACD's manifold check and remeshing are
    # skipped. A shallow search (5 nodes, depth 2) gave the same hull counts as CoACD's
    # defaults on phantom pieces at a fraction of the time.
    parts = coacd.run_coacd(
        coacd.Mesh(np.asarray(solid.vertices), np.asarray(solid.faces)),
        threshold=ctx.params.coacd_threshold,
        preprocess_mode="off",
        mcts_iterations=ctx.params.coacd_mcts_iterations,
        resolution=ctx.params.coacd_resolution,
        mcts_nodes=5,
        mcts_max_depth=2,
        pca=True,
        seed=0,
    )
    hulls = [convex_hull(np.asarray(v, dtype=np.float64)) for v, _ in parts]
    return [h for h in hulls if h is not None]


def _bisect(ctx: WallContext, faces: IntArray) -> tuple[IntArray, IntArray]:
    radius = ctx.face_radius[faces]
    u = ctx.face_u[faces] * radius  # arc positions in metres
    angle = np.unwrap(np.sort(ctx.face_angle[faces]))
    angle_span = (angle.max() - angle.min()) * float(radius.mean())
    if float(np.ptp(u)) >= angle_span:
        order = np.argsort(u, kind="stable")
    else:  # rotate angles so the largest gap is the cut-free seam, then sort
        raw = ctx.face_angle[faces]
        sorted_raw = np.sort(raw)
        gaps = np.diff(np.concatenate([sorted_raw, [sorted_raw[0] + 2 * np.pi]]))
        seam = sorted_raw[(int(np.argmax(gaps)) + 1) % len(sorted_raw)]
        order = np.argsort(np.mod(raw - seam, 2 * np.pi), kind="stable")
    half = len(faces) // 2
    return faces[order[:half]], faces[order[half:]]


def _bisected(ctx: WallContext, faces: IntArray) -> list[Hull]:
    """Returns hulls of ``faces`` split in halves until each hull keeps the lumen open."""
    out: list[Hull] = []
    stack = [_Piece(faces, 0)]
    while stack:
        piece = stack.pop()
        hull = _solid_hull(ctx, piece.faces)
        if hull is not None and (_accept([hull], ctx, piece.faces) or len(piece.faces) == 1):
            out.append(hull)
            continue
        if len(piece.faces) == 1 or piece.depth >= ctx.params.max_split_depth:
            if hull is not None:
                out.append(hull)
            continue
        first, second = _bisect(ctx, piece.faces)
        stack.extend([_Piece(second, piece.depth + 1), _Piece(first, piece.depth + 1)])
    return out


def hulls_for_piece(ctx: WallContext, faces: IntArray) -> list[Hull]:
    """Returns convex hulls covering the wall over ``faces`` that keep the lumen open.

    With ``use_coacd``, a piece whose bisection needs three hulls or more also goes to CoACD,
    and CoACD's hulls are taken when they keep the lumen open and are fewer.
    """
    # _bisected tries the whole piece's hull first: a piece it accepts comes back as one hull.
    split = _bisected(ctx, faces)
    if ctx.params.use_coacd and len(split) >= 3 and len(faces) > 8:
        parts = _coacd_hulls(ctx, faces)
        if parts and len(parts) < len(split) and _accept(parts, ctx, faces):
            return parts
    return split


def _worker(ctx: WallContext) -> list[Hull]:
    return hulls_for_piece(ctx, np.arange(len(ctx.faces)))


def bin_faces(
    mesh: trimesh.Trimesh, axis: AxisSamples, params: WallParams
) -> tuple[list[IntArray], FloatArray, FloatArray, FloatArray]:
    """Groups lumen faces into wall pieces.

    Returns:
        The pieces (face index arrays, deterministic order), and per face its local radius (m),
        arc position (radii) and angle (rad).
    """
    idx, angle, _ = axis.locate(mesh.triangles_center)
    radius = axis.radius[idx]
    u = axis.u[idx]
    arc_bin = np.floor(u / params.arc_bin).astype(np.int64)
    sector = np.minimum((angle / (2 * np.pi) * params.sectors).astype(np.int64), params.sectors - 1)
    # End caps face along the axis; binned with the side wall their hull would fill the lumen.
    cap = np.abs(np.einsum("ij,ij->i", mesh.face_normals, axis.tangent[idx])) > 0.7
    keys = np.column_stack([axis.branch[idx], arc_bin, sector, cap])
    _, inverse = np.unique(keys, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    order = np.argsort(inverse, kind="stable")
    splits = np.flatnonzero(np.diff(inverse[order])) + 1
    pieces = [np.asarray(p, dtype=np.int64) for p in np.split(order, splits)]
    return pieces, radius, u, angle


@contextlib.contextmanager
def _worker_pool(workers: int) -> Iterator[multiprocessing.pool.Pool]:
    """A pool of spawned workers that a Ctrl-C stops at once.

    Spawned, not forked: CoACD runs OpenMP, and a child forked after this process's OpenMP
    pool started (any earlier CoACD call here) hangs in its first parallel region. SIGINT is
    blocked while the workers start, and they inherit the blocked signal, so a Ctrl-C reaches
    only this process (after the start, if it came during it): it leaves the ``with`` block
    and the pool is terminated, instead of each worker dying mid-import or mid-task while this
    process waits on it (which hung 3 of 11 interrupted builds).
    """
    spawn = multiprocessing.get_context("spawn")
    block = hasattr(signal, "pthread_sigmask")
    if block:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        with _main_script_hidden():
            pool = spawn.Pool(workers)
    finally:
        if block:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    try:
        yield pool
        pool.close()
    finally:
        pool.terminate()
        pool.join()


@contextlib.contextmanager
def _main_script_hidden() -> Iterator[None]:
    """Workers spawned inside the block start without re-running the main script.

    A spawned worker re-runs its parent's main script (as ``__mp_main__``) before its first
    task, and the wall's workers need none of it: their tasks are this module's functions.
    Re-run, a script without an ``if __name__ == "__main__":`` guard loaded again in every
    worker (a coronary tree's first ``suite.load`` waited forever there, on the build lock
    its own parent held), and a script piped in (``python - < script.py``) has no file to
    re-run, so every worker died on start and the pool replaced it forever. A bare module
    stands in for ``__main__`` while the workers start (they read it then, in this thread).
    """
    main = sys.modules["__main__"]
    sys.modules["__main__"] = types.ModuleType("__main__")
    try:
        yield
    finally:
        sys.modules["__main__"] = main


def _can_spawn() -> bool:
    """Whether this process can start the spawned worker pool: a daemonic process (a
    multiprocessing pool's or a collector's worker that draws a tree not built yet) may not
    start children, and builds in series."""
    return not multiprocessing.current_process().daemon


def build_hulls(
    ctx: WallContext,
    pieces: list[IntArray],
    progress: Callable[[Iterator[list[Hull]], int], Iterator[list[Hull]]] | None = None,
) -> list[Hull]:
    """Returns the hulls of all pieces, in piece order (deterministic for any worker count)."""
    jobs = [ctx.subset(p) for p in pieces]
    if ctx.params.workers > 1 and len(pieces) > 1 and _can_spawn():
        with _worker_pool(ctx.params.workers) as pool:
            results: Iterator[list[Hull]] = pool.imap(_worker, jobs, chunksize=8)
            if progress is not None:
                results = progress(results, len(jobs))
            return [h for hulls in results for h in hulls]
    serial: Iterator[list[Hull]] = map(_worker, jobs)
    if progress is not None:
        serial = progress(serial, len(jobs))
    return [h for hulls in serial for h in hulls]
