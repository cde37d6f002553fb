"""Centerline extraction from a closed lumen mesh: voxels → distance transform → skeleton → graph.

1. The lumen is voxelised at ``median radius / voxels_per_radius`` (coarser if the grid would
   exceed ``max_voxels``) by ray parity along z, cropped to the mesh bounds.
2. ``scipy.ndimage.distance_transform_edt`` gives the radius at every voxel.
3. The skeleton is traced TEASAR-style (Sato et al. 2000, as in kimimaro): lumen voxels form a
   26-neighbourhood graph; from a root at a vessel end, shortest paths under a penalty that is
   large near the wall (relative to the local maximum radius, so thin and thick branches are
   treated alike) run to the farthest voxel not yet covered; voxels within
   ``invalidation_scale`` radii of a traced path are covered; repeat until all are covered.
   (``skimage.morphology.skeletonize`` was not used: in scikit-image 0.26 it deletes
   even-width tubes entirely.) Path ends that hook to the cap are trimmed where the radius drops
   below 90 % of the branch radius; spurs shorter than ``spur_length`` radii are pruned.
4. Each branch is resampled every ``node_spacing`` radii and smoothed; vessel ends are extended
   by their radius along the end tangent, because the trimmed paths stop short of a cap.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import trimesh
from numpy.typing import NDArray
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from sim4endor.errors import Sim4EndoRError
from sim4endor.vessels.axis import branch_chains
from sim4endor.vessels.centerline import CenterlineGraph, arc_lengths, points_along

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class SkeletonError(Sim4EndoRError, ValueError):
    """Raised when no usable centerline can be extracted; suggests giving one."""


@dataclass(frozen=True)
class SkeletonParams:
    """Centerline extraction settings.

    Attributes:
        voxels_per_radius: Voxels across the median lumen radius.
        max_voxels: Upper bound of the voxel grid size (memory); the pitch grows to fit.
        spur_length: Terminal branches shorter than this many radii are pruned.
        node_spacing: Node spacing of the output graph, in local radii.
        smoothing: Gaussian smoothing of each branch, sigma in local radii (removes the voxel
            staircase, which otherwise adds ~20 % to the length); ends stay in place.
        invalidation_scale: Voxels within this many local radii of a traced path are covered.
        penalty: ``(a, p)`` of the path cost per voxel step ``1 + a (1 - D / D_local)^p``, with
            ``D`` the distance to the wall and ``D_local`` its local maximum; it keeps paths
            central and stops them cutting the inside of bends.
    """

    voxels_per_radius: float = 6.0
    max_voxels: int = 40_000_000
    spur_length: float = 3.0
    node_spacing: float = 0.5
    smoothing: float = 1.0
    invalidation_scale: float = 3.0
    penalty: tuple[float, float] = (100.0, 2.0)


def voxelize(mesh: trimesh.Trimesh, pitch: float) -> tuple[NDArray[np.bool_], FloatArray]:
    """Returns the inside-voxel grid of a closed mesh and the centre of voxel (0, 0, 0)."""
    lo = mesh.bounds[0] - pitch
    # An irrational offset keeps voxel columns off mesh vertices and edges (parity stays exact).
    origin = lo + pitch * np.array([0.5 + 1e-4 * np.sqrt(2), 0.5 + 1e-4 * np.sqrt(3), 0.5])
    shape = np.ceil((mesh.bounds[1] + pitch - lo) / pitch).astype(int) + 1
    tri = mesh.triangles
    xy = tri[:, :, :2]
    i0 = np.ceil((xy[:, :, 0].min(1) - origin[0]) / pitch).astype(np.int64)
    i1 = np.floor((xy[:, :, 0].max(1) - origin[0]) / pitch).astype(np.int64)
    j0 = np.ceil((xy[:, :, 1].min(1) - origin[1]) / pitch).astype(np.int64)
    j1 = np.floor((xy[:, :, 1].max(1) - origin[1]) / pitch).astype(np.int64)
    ni, nj = np.maximum(i1 - i0 + 1, 0), np.maximum(j1 - j0 + 1, 0)
    count = ni * nj
    owner = np.repeat(np.arange(len(tri)), count)
    local = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
    ci = i0[owner] + local // nj[owner]
    cj = j0[owner] + local % nj[owner]
    px = origin[0] + ci * pitch
    py = origin[1] + cj * pitch
    a, b, c = tri[owner, 0], tri[owner, 1], tri[owner, 2]
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    valid = np.abs(det) > 1e-30
    safe = np.where(valid, det, 1.0)
    w1 = ((px - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (py - a[:, 1])) / safe
    w2 = ((b[:, 0] - a[:, 0]) * (py - a[:, 1]) - (px - a[:, 0]) * (b[:, 1] - a[:, 1])) / safe
    inside = valid & (w1 >= 0) & (w2 >= 0) & (w1 + w2 <= 1)
    z = a[:, 2] + w1 * (b[:, 2] - a[:, 2]) + w2 * (c[:, 2] - a[:, 2])
    ci, cj, z = ci[inside], cj[inside], z[inside]
    k = np.clip(np.ceil((z - origin[2]) / pitch).astype(np.int64), 0, shape[2] - 1)
    toggles = np.zeros(tuple(shape), dtype=np.uint8)
    np.add.at(toggles, (ci, cj, k), 1)
    toggles &= 1
    grid = np.bitwise_xor.accumulate(toggles, axis=2).astype(bool)
    return grid, origin


def _voxel_graph(coords: IntArray) -> coo_matrix:
    """Sparse 26-neighbourhood graph of skeleton voxels, weighted by distance (voxels)."""
    dims = coords.max(axis=0) + 3
    keys = np.ravel_multi_index(tuple((coords + 1).T), tuple(dims))
    order = np.argsort(keys)
    sorted_keys = keys[order]
    rows, cols, weights = [], [], []
    offsets = [o for o in np.ndindex(3, 3, 3) if o > (1, 1, 1)]  # half of the 26 neighbours
    for o in offsets:
        delta = np.array(o) - 1
        nkeys = np.ravel_multi_index(tuple((coords + 1 + delta).T), tuple(dims))
        pos = np.clip(np.searchsorted(sorted_keys, nkeys), 0, len(keys) - 1)
        hit = sorted_keys[pos] == nkeys
        rows.append(np.flatnonzero(hit))
        cols.append(order[pos[hit]])
        weights.append(np.full(int(hit.sum()), float(np.linalg.norm(delta))))
    n = len(coords)
    return coo_matrix(
        (np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
    )


def _prune(points: FloatArray, radii: FloatArray, edges: IntArray, spur_length: float) -> IntArray:
    """Removes terminal chains shorter than ``spur_length`` radii; returns the kept edges."""
    for _ in range(20):
        graph = CenterlineGraph(points, radii, edges)
        degree = graph.degrees()
        drop: set[tuple[int, int]] = set()
        for chain in branch_chains(graph):
            ends = degree[[chain[0], chain[-1]]]
            if not (1 in ends and ends.max() >= 3):
                continue
            junction = chain[0] if degree[chain[0]] >= 3 else chain[-1]
            length = float(np.linalg.norm(np.diff(points[chain], axis=0), axis=1).sum())
            if length < spur_length * radii[junction]:
                drop.update((min(a, b), max(a, b)) for a, b in itertools.pairwise(chain))
        if not drop:
            return edges
        edges = np.array([e for e in edges if (min(e), max(e)) not in drop], dtype=np.int64)
    return edges


def _smooth(values: FloatArray, sigma: float) -> FloatArray:
    """Gaussian smoothing along a chain (sigma in samples) with both ends kept in place."""
    if len(values) < 3 or sigma <= 0:
        return values.copy()
    out = ndimage.gaussian_filter1d(values, sigma, axis=0, mode="nearest")
    # Blend back to the original towards the ends so junctions and vessel ends do not move.
    ramp = np.minimum(np.arange(len(values)), np.arange(len(values))[::-1]) / max(sigma, 1.0)
    weight = np.clip(ramp, 0.0, 1.0).reshape(-1, *([1] * (values.ndim - 1)))
    return weight * out + (1.0 - weight) * values


def _assemble(
    points: FloatArray, radii: FloatArray, edges: IntArray, params: SkeletonParams, pitch: float
) -> CenterlineGraph:
    """Resamples and smooths every chain of a pruned skeleton into the output graph."""
    skeleton = CenterlineGraph(points, radii, edges)
    degree = skeleton.degrees()
    key_index: dict[int, int] = {}
    nodes: list[FloatArray] = []
    node_r: list[float] = []
    out_edges: list[tuple[int, int]] = []

    def key(v: int, position: FloatArray, radius: float) -> int:
        if v not in key_index:
            key_index[v] = len(nodes)
            nodes.append(position)
            node_r.append(radius)
        return key_index[v]

    for chain in branch_chains(skeleton):
        p, r = points[chain], radii[chain]
        # Extend vessel ends to the cap, along the direction over the last two radii (the last
        # voxel step alone is often diagonal).
        back = min(len(chain) - 1, max(1, round(2 * float(r.max()) / pitch)))
        for end, nbr in ((0, back), (-1, -1 - back)):
            if degree[chain[end]] == 1 and len(chain) > 1:
                t = p[end] - p[nbr]
                p[end] = p[end] + t / max(np.linalg.norm(t), 1e-30) * r[end] * 0.8
        # Voxel steps are ~1 pitch long, so sigma in samples is smoothing × radius / pitch.
        sigma = params.smoothing * float(np.median(r)) / pitch
        p, r = _smooth(p, sigma), _smooth(r, sigma)
        arc = arc_lengths(p)
        count = max(1, round(arc[-1] / (params.node_spacing * float(r.mean()))))
        s = np.linspace(0.0, arc[-1], count + 1)
        sp, sr = points_along(p, s), np.interp(s, arc, r)
        ids = [key(chain[0], sp[0], sr[0])]
        for k in range(1, count):
            nodes.append(sp[k])
            node_r.append(float(sr[k]))
            ids.append(len(nodes) - 1)
        ids.append(key(chain[-1], sp[-1], sr[-1]))
        out_edges.extend((a, b) for a, b in itertools.pairwise(ids) if a != b)
    return CenterlineGraph(np.array(nodes), np.array(node_r), np.array(out_edges, dtype=np.int64))


def _trim_hook(path: list[int], dbf: FloatArray) -> list[int]:
    """Drops the start of a path (at a vessel end) where it leaves the axis towards the cap."""
    values = dbf[path]
    window = values[: max(3, int(np.ceil(4 * values.max())))]
    keep_from = int(np.argmax(values >= 0.9 * window.max()))
    return path[keep_from:] if len(path) - keep_from >= 2 else path


def _trace(
    coords: IntArray, dbf: FloatArray, local_max: FloatArray, params: SkeletonParams
) -> IntArray:
    """Returns skeleton edges (pairs of voxel indices) traced TEASAR-style from a vessel end."""
    graph = _voxel_graph(coords).tocsr()
    plain = dijkstra(graph, directed=False, indices=0)
    root = int(np.argmax(np.where(np.isfinite(plain), plain, -1)))
    from_root = dijkstra(graph, directed=False, indices=root)
    penalty_scale, penalty_power = params.penalty
    penalty = 1.0 + penalty_scale * (1.0 - np.clip(dbf / local_max, 0, 1)) ** penalty_power
    weighted = graph.tocoo()
    weighted.data = weighted.data * 0.5 * (penalty[weighted.row] + penalty[weighted.col])
    _, pred = dijkstra(weighted.tocsr(), directed=False, indices=root, return_predecessors=True)
    reachable = np.isfinite(from_root)
    uncovered = reachable.copy()
    # The skeleton is what the paths traced so far keep: the first path's hook at the root is
    # trimmed off like any vessel end's, so the root itself may not be in it, and a later path
    # joined to it would hang on its own, apart from the tree.
    in_skeleton = np.zeros(len(coords), dtype=bool)
    tree = cKDTree(coords)
    edges: list[tuple[int, int]] = []
    first = True
    while uncovered.any():
        target = int(np.argmax(np.where(uncovered, from_root, -1.0)))
        path = [target]
        while path[-1] != root:
            path.append(int(pred[path[-1]]))
        if not first:
            # Join where the new path enters the lumen around the existing skeleton, not where
            # it first touches it: shortest paths run beside the skeleton for a long way.
            members = np.flatnonzero(in_skeleton)
            dist, nearest = cKDTree(coords[members]).query(coords[path])
            inside = dist <= np.maximum(dbf[members[nearest]], 1.5)
            cut = int(np.argmax(inside))
            path = path[: cut + 1]
            join = int(members[nearest[cut]])
            if cut > 0 and join != path[-1]:  # a voxel of the skeleton joins as itself
                path.append(join)
        path = _trim_hook(path, dbf)
        if first:  # the root is a vessel end too
            path = _trim_hook(path[::-1], dbf)[::-1]
            first = False
        if len(path) > 1:
            in_skeleton[path] = True
            edges.extend(itertools.pairwise(path))
        for v in path:
            covered = tree.query_ball_point(coords[v], params.invalidation_scale * dbf[v] + 1.5)
            uncovered[covered] = False
        uncovered[target] = False
    return np.asarray(edges, dtype=np.int64).reshape(-1, 2)


def extract_centerline(
    mesh: trimesh.Trimesh, params: SkeletonParams, *, radius_hint: float
) -> CenterlineGraph:
    """Extracts a centerline graph (m) from a closed lumen mesh (m).

    Args:
        mesh: Watertight lumen surface (open ends must be capped first).
        params: Extraction settings.
        radius_hint: Median lumen radius (m), sets the voxel pitch.
    """
    extent = mesh.bounds[1] - mesh.bounds[0]
    pitch = radius_hint / params.voxels_per_radius
    pitch = max(pitch, float(np.cbrt(np.prod(extent + 2 * pitch) / params.max_voxels)))
    grid, origin = voxelize(mesh, pitch)
    if grid.sum() < 8:
        raise SkeletonError(
            "The lumen mesh encloses no volume at this voxel size; is it closed? Pass a "
            "centerline (--centerline) instead."
        )
    dbf_grid = ndimage.distance_transform_edt(grid)
    size = 2 * int(np.ceil(dbf_grid.max())) + 1
    local_grid = ndimage.maximum_filter(dbf_grid, size=size)
    coords = np.argwhere(grid).astype(np.int64)
    dbf = dbf_grid[tuple(coords.T)]
    local_max = local_grid[tuple(coords.T)]
    del dbf_grid, local_grid, grid
    edges = _trace(coords, dbf, local_max, params)
    if len(edges) == 0:
        raise SkeletonError("Centerline extraction found no skeleton; pass --centerline.")
    points = origin + coords * pitch
    radii = dbf * pitch  # distance to the nearest outside voxel centre: >= 1 pitch
    used = np.unique(edges)
    remap = np.full(len(points), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    points, radii, edges = points[used], radii[used], remap[edges]
    edges = _prune(points, radii, edges, params.spur_length)
    used = np.unique(edges)
    remap = np.full(len(points), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return _assemble(points[used], radii[used], remap[edges], params, pitch)
