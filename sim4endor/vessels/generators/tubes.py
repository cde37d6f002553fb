"""A vessel tree as swept circular tubes: lumen surface (manifold3d union) and exact centerline.

Each branch is a polyline with a radius per point. Its tube is swept with rotation-minimising
frames (double reflection, Wang et al. 2008) and closed by hemispheres centred on its first and
last points, so the union of the tubes is the set of points within the local radius of the
axis: "farther from the centerline graph than the local radius" means "outside the lumen". The
hemisphere at a child's first point lies inside its parent's end ball, which closes the
junction without a crease. Only the inlet (first point of the root branch) is cut flat, so the
build pipeline can open it for the wire. Ring vertices lie on the circle (inscribed polygon),
so the faceted tube never reaches beyond the true radius.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import trimesh
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from sim4endor.errors import Sim4EndoRError
from sim4endor.vessels.centerline import CenterlineGraph

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


class LumenMeshError(Sim4EndoRError, RuntimeError):
    """Raised when the tube union is not a closed, single-component surface."""


@dataclass(frozen=True, eq=False)
class TubeBranch:
    """One branch of a vessel tree.

    Attributes:
        name: Branch name (stored in the centerline graph's ``branch_names``).
        points: (N, 3) axis samples (m); a child's first point equals its parent's last point.
        radii: (N,) lumen radius at each sample (m).
        parent: Index of the parent branch in the tree, ``None`` for the root.
    """

    name: str
    points: FloatArray
    radii: FloatArray
    parent: int | None = None

    @property
    def length(self) -> float:
        """Axis length (m)."""
        return float(np.linalg.norm(np.diff(self.points, axis=0), axis=1).sum())


def _tangents(points: FloatArray) -> FloatArray:
    segments = np.diff(points, axis=0)
    segments /= np.linalg.norm(segments, axis=1, keepdims=True)
    tangents = np.empty_like(points)
    tangents[0], tangents[-1] = segments[0], segments[-1]
    tangents[1:-1] = segments[:-1] + segments[1:]
    return tangents / np.linalg.norm(tangents, axis=1, keepdims=True)


def rotation_minimising_normals(points: FloatArray, tangents: FloatArray) -> FloatArray:
    """Returns unit normals transported along the polyline without twist (double reflection)."""
    first = np.cross(tangents[0], np.eye(3)[int(np.argmin(np.abs(tangents[0])))])
    normals = np.empty_like(points)
    normals[0] = first / np.linalg.norm(first)
    for i in range(len(points) - 1):
        v1 = points[i + 1] - points[i]
        c1 = v1 @ v1
        r_left = normals[i] - (2.0 / c1) * (v1 @ normals[i]) * v1
        t_left = tangents[i] - (2.0 / c1) * (v1 @ tangents[i]) * v1
        v2 = tangents[i + 1] - t_left
        c2 = v2 @ v2
        normal = r_left if c2 < 1e-20 else r_left - (2.0 / c2) * (v2 @ r_left) * v2
        normal -= (normal @ tangents[i + 1]) * tangents[i + 1]
        normals[i + 1] = normal / np.linalg.norm(normal)
    return normals


def sweep_tube(points: FloatArray, radii: FloatArray, segments: int, *,
               flat_start: bool = False) -> tuple[FloatArray, IntArray]:
    """Sweeps a closed tube along a polyline.

    Args:
        points: (N, 3) axis samples (m), N >= 2.
        radii: (N,) radius at each sample (m).
        segments: Vertices per ring (circumferential resolution).
        flat_start: Close the first end with a flat disc instead of a hemisphere.

    Returns:
        ``(vertices, faces)`` of a closed, outward-oriented triangle mesh.
    """
    tangents = _tangents(points)
    normals = rotation_minimising_normals(points, tangents)
    binormals = np.cross(tangents, normals)
    theta = 2.0 * np.pi * np.arange(segments) / segments
    cos, sin = np.cos(theta), np.sin(theta)
    cap_rings = max(2, segments // 4)
    polar = 0.5 * np.pi * np.arange(1, cap_rings) / cap_rings  # polar angles, equator excluded

    def ring(centre: FloatArray, radius: float, k: int) -> FloatArray:
        return centre + radius * (np.outer(cos, normals[k]) + np.outer(sin, binormals[k]))

    rings: list[FloatArray] = []
    if not flat_start:
        r0 = radii[0]
        rings += [ring(points[0] - r0 * np.cos(a) * tangents[0], r0 * np.sin(a), 0) for a in polar]
    rings += [ring(points[k], radii[k], k) for k in range(len(points))]
    r1 = radii[-1]
    rings += [
        ring(points[-1] + r1 * np.sin(a) * tangents[-1], r1 * np.cos(a), -1) for a in polar
    ]
    start_pole = points[0] - (0.0 if flat_start else radii[0]) * tangents[0]
    end_pole = points[-1] + r1 * tangents[-1]
    vertices = np.vstack([*rings, start_pole, end_pole])

    count = len(rings)
    j = np.arange(segments)
    a = np.arange(count - 1)[:, None] * segments + j
    b = np.arange(count - 1)[:, None] * segments + (j + 1) % segments
    c, d = a + segments, b + segments
    side = np.concatenate([np.stack([a, b, d], -1), np.stack([a, d, c], -1)]).reshape(-1, 3)
    first, last = j, (count - 1) * segments + j
    start_fan = np.stack([np.full(segments, count * segments), (j + 1) % segments, first], -1)
    last_next = (count - 1) * segments + (j + 1) % segments
    end_fan = np.stack([last, last_next, np.full(segments, count * segments + 1)], -1)
    faces = np.vstack([side, start_fan, end_fan]).astype(np.int64)
    return vertices, faces


def lumen_mesh(branches: Sequence[TubeBranch], segments: int) -> trimesh.Trimesh:
    """Returns the union of the branches' tubes: a watertight lumen surface (m).

    The root branch (the one without a parent) gets the flat inlet end; every other end is a
    hemisphere. Raises :class:`LumenMeshError` if the union is not one closed component.
    """
    import manifold3d

    parts = []
    for branch in branches:
        vertices, faces = sweep_tube(
            branch.points, branch.radii, segments, flat_start=branch.parent is None
        )
        mesh = manifold3d.Mesh64(
            vert_properties=np.ascontiguousarray(vertices, dtype=np.float64),
            tri_verts=np.ascontiguousarray(faces, dtype=np.uint32),
        )
        solid = manifold3d.Manifold(mesh)
        if solid.is_empty():
            raise LumenMeshError(
                f"Branch {branch.name!r} gave an invalid tube ({solid.status()}); its bends are "
                "probably tighter than its radius: increase the arc radii."
            )
        parts.append(solid)
    union = manifold3d.Manifold.batch_boolean(parts, manifold3d.OpType.Add)
    genus, components = union.genus(), len(union.decompose())
    if genus != 0 or components != 1:
        raise LumenMeshError(
            f"The tube union has genus {genus} and {components} component(s); "
            "a vessel tree must be one component of genus 0: branches touch each other away from "
            "their junctions. Increase the clearance or change the layout."
        )
    out = union.to_mesh64()
    return trimesh.Trimesh(
        np.asarray(out.vert_properties, dtype=np.float64)[:, :3],
        np.asarray(out.tri_verts, dtype=np.int64),
        process=False,
    )


def centerline_graph(branches: Sequence[TubeBranch], labels: Mapping[str, tuple[int, int]]
                     ) -> CenterlineGraph:
    """Returns the exact centerline graph of a tree.

    Args:
        branches: The tree, parents before children.
        labels: Name -> (branch index, point index within that branch; -1 for the last).
    """
    offsets: list[IntArray] = []
    nodes: list[FloatArray] = []
    radii: list[FloatArray] = []
    branch_ids: list[IntArray] = []
    edges: list[IntArray] = []
    count = 0
    for index, branch in enumerate(branches):
        if branch.parent is None:
            own = np.arange(len(branch.points)) + count
            new = slice(0, None)
        else:
            # The first point is the parent's last node, shared.
            junction = offsets[branch.parent][-1]
            own = np.concatenate([[junction], np.arange(len(branch.points) - 1) + count])
            new = slice(1, None)
        nodes.append(branch.points[new])
        radii.append(branch.radii[new])
        branch_ids.append(np.full(len(branch.points[new]), index))
        edges.append(np.stack([own[:-1], own[1:]], -1))
        offsets.append(own)
        count += len(branch.points[new])
    node_labels = {name: int(offsets[b][p]) for name, (b, p) in labels.items()}
    return CenterlineGraph(
        nodes=np.vstack(nodes),
        radii=np.concatenate(radii),
        edges=np.vstack(edges),
        labels=node_labels,
        branch=np.concatenate(branch_ids),
        branch_names=tuple(branch.name for branch in branches),
    )


def clearance_violations(graph: CenterlineGraph, gap: float, *,
                         nodes: IntArray | None = None, margin: float = 0.0) -> IntArray:
    """Finds places where two parts of the tree come too close away from their junctions.

    Two axis points ``p, q`` clash when their lumens are closer than ``gap`` (Euclidean
    distance < r_p + r_q + gap) while the way between them along the tree is much longer
    (geodesic > 4 (r_p + r_q + gap)), i.e. they are not simply neighbours on one branch or near
    the same junction (a >= 30° bifurcation separates its branches within that distance).

    Args:
        graph: The tree's centerline graph.
        gap: Smallest allowed wall-to-wall distance between lumens (m), e.g. two wall thicknesses.
        nodes: Only check pairs involving these nodes (default: all).
        margin: Widens both conditions by this much (m), so a tree that passes on a coarse
            sampling also passes on any finer one (use the coarse sample spacing).

    Returns:
        (K, 2) clashing node pairs (empty when the tree is clear).
    """
    tree = cKDTree(graph.nodes)
    query = np.arange(graph.num_nodes) if nodes is None else np.asarray(nodes, dtype=np.int64)
    reach = 2.0 * float(graph.radii.max()) + gap + margin
    pairs = [(int(i), int(j)) for i, near in zip(query, tree.query_ball_point(graph.nodes[query],
                                                                             reach), strict=True)
             for j in near if j != i]
    if not pairs:
        return np.zeros((0, 2), dtype=np.int64)
    p, q = np.asarray(pairs, dtype=np.int64).T
    allowed = graph.radii[p] + graph.radii[q] + gap
    close = np.linalg.norm(graph.nodes[p] - graph.nodes[q], axis=1) < allowed + margin
    p, q, allowed = p[close], q[close], allowed[close]
    if len(p) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    sources, inverse = np.unique(p, return_inverse=True)
    lengths = graph.edge_lengths()
    adjacency = coo_matrix(
        (np.maximum(lengths, 1e-12), (graph.edges[:, 0], graph.edges[:, 1])),
        shape=(graph.num_nodes, graph.num_nodes),
    ).tocsr()
    geodesic = dijkstra(adjacency, directed=False, indices=sources, limit=4.0 * allowed.max())
    far = geodesic[inverse, q] > 4.0 * allowed - margin
    return np.stack([p[far], q[far]], -1)
