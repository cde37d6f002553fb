"""Dense samples of a centerline graph with branch ids, scaled arc length and transported frames.

The wall builder bins lumen faces by (branch, arc position, angle around the axis); the checks
probe the lumen along the axis. Both need the graph resampled finely, split into branches (chains
between junctions and ends) and carrying a rotation-minimising frame, which this module provides.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from sim4endor.vessels.centerline import CenterlineGraph, points_along

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def branch_chains(graph: CenterlineGraph) -> list[list[int]]:
    """Splits the graph into chains of node indices between junctions and ends.

    Every edge belongs to exactly one chain. A cycle without junctions becomes one chain that
    starts and ends at the same node.
    """
    neighbours = graph.neighbours()
    degree = np.array([len(n) for n in neighbours])
    used: set[tuple[int, int]] = set()
    chains: list[list[int]] = []

    def walk(start: int, nxt: int) -> list[int]:
        chain = [start]
        prev, cur = start, nxt
        used.add((min(prev, cur), max(prev, cur)))
        while True:
            chain.append(cur)
            if degree[cur] != 2 or cur == start:
                return chain
            following = [n for n in neighbours[cur] if (min(cur, n), max(cur, n)) not in used]
            if not following:
                return chain
            prev, cur = cur, following[0]
            used.add((min(prev, cur), max(prev, cur)))

    key_nodes = [int(k) for k in np.flatnonzero(degree != 2)]
    for start in key_nodes:
        for nxt in neighbours[start]:
            if (min(start, nxt), max(start, nxt)) not in used:
                chains.append(walk(start, nxt))
    for i, j in graph.edges:  # pure cycles left over
        if (min(i, j), max(i, j)) not in used:
            chains.append(walk(int(i), int(j)))
    return chains


def _perpendicular(t: FloatArray) -> FloatArray:
    helper = np.array([1.0, 0.0, 0.0]) if abs(t[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    n = np.cross(t, helper)
    return n / np.linalg.norm(n)


@dataclass(frozen=True, eq=False)
class AxisSamples:
    """Points along every branch of a centerline graph.

    Attributes:
        points: (M, 3) sample positions (m).
        tangent: (M, 3) unit tangents along the branch direction.
        normal: (M, 3) unit normals of a rotation-minimising (parallel-transport) frame.
        binormal: (M, 3) ``tangent × normal``.
        radius: (M,) lumen radius (m), interpolated from the graph.
        branch: (M,) index of the branch (chain) of each sample.
        u: (M,) arc length along the branch divided by the local radius (dimensionless), so bins
            of constant ``u`` width are about a constant number of radii long.
        end_distance: (M,) arc length (m) from the sample to the nearest terminal node of the
            graph along its branch (``inf`` on branches without a terminal end).
    """

    points: FloatArray
    tangent: FloatArray
    normal: FloatArray
    binormal: FloatArray
    radius: FloatArray
    branch: IntArray
    u: FloatArray
    end_distance: FloatArray

    def tree(self) -> cKDTree:
        """Returns a KD-tree over the sample points."""
        return cKDTree(self.points)

    def locate(self, points: FloatArray) -> tuple[IntArray, FloatArray, FloatArray]:
        """Returns, for each point, the nearest sample, its angle around the axis and distance.

        The angle (radians in [0, 2π)) is measured in the sample's transported frame, so it is
        continuous along a branch.
        """
        dist, idx = self.tree().query(np.asarray(points, dtype=np.float64))
        idx = np.asarray(idx, dtype=np.int64)
        d = points - self.points[idx]
        d -= np.einsum("ij,ij->i", d, self.tangent[idx])[:, None] * self.tangent[idx]
        angle = np.arctan2(
            np.einsum("ij,ij->i", d, self.binormal[idx]),
            np.einsum("ij,ij->i", d, self.normal[idx]),
        )
        return idx, np.mod(angle, 2 * np.pi), np.asarray(dist, dtype=np.float64)


def sample_axis(graph: CenterlineGraph, spacing: float = 0.2) -> AxisSamples:
    """Resamples every branch of ``graph`` at ``spacing`` local radii.

    Args:
        graph: Centerline graph in metres.
        spacing: Sample spacing as a fraction of the local lumen radius.
    """
    degree = graph.degrees()
    chunks: dict[str, list[FloatArray]] = {k: [] for k in ("p", "t", "n", "b", "r", "br", "u", "e")}
    for branch_id, chain in enumerate(branch_chains(graph)):
        nodes = graph.nodes[chain]
        radii = graph.radii[chain]
        seg = np.linalg.norm(np.diff(nodes, axis=0), axis=1)
        arc = np.concatenate([[0.0], np.cumsum(seg)])
        if arc[-1] <= 0:
            continue
        # Sample densely enough for the thinnest part of the branch.
        step = spacing * float(radii.min())
        count = max(2, int(np.ceil(arc[-1] / step)) + 1)
        s = np.linspace(0.0, arc[-1], count)
        p, r = points_along(nodes, s), np.interp(s, arc, radii)
        t = np.gradient(p, axis=0)
        t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-30)
        n = np.empty_like(t)
        n[0] = _perpendicular(t[0])
        for k in range(1, len(t)):  # parallel transport: remove the tangential part, renormalise
            v = n[k - 1] - np.dot(n[k - 1], t[k]) * t[k]
            norm = np.linalg.norm(v)
            n[k] = v / norm if norm > 1e-9 else _perpendicular(t[k])
        b = np.cross(t, n)
        du = np.diff(s) / (0.5 * (r[1:] + r[:-1]))
        u = np.concatenate([[0.0], np.cumsum(du)])
        start_end = 0.0 if degree[chain[0]] == 1 else np.inf
        stop_end = 0.0 if degree[chain[-1]] == 1 else np.inf
        end = np.minimum(s + start_end, arc[-1] - s + stop_end)
        for key, value in zip(
            ("p", "t", "n", "b", "r", "br", "u", "e"),
            (p, t, n, b, r, np.full(len(s), branch_id), u, end),
            strict=True,
        ):
            chunks[key].append(value)
    return AxisSamples(
        points=np.vstack(chunks["p"]),
        tangent=np.vstack(chunks["t"]),
        normal=np.vstack(chunks["n"]),
        binormal=np.vstack(chunks["b"]),
        radius=np.concatenate(chunks["r"]),
        branch=np.concatenate(chunks["br"]).astype(np.int64),
        u=np.concatenate(chunks["u"]),
        end_distance=np.concatenate(chunks["e"]),
    )
