"""Centerline graph of a vessel tree: sampled lumen axis points, radii and their connections.

The graph is the discrete stand-in for the vascular manifold of the paper: the manifold
(geodesic) distance between two points in the lumen is the shortest path along it. All
lengths are in metres.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra

from sim4endor._atomic import atomic_write_text
from sim4endor._checks import check_schema_version
from sim4endor.errors import Sim4EndoRError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

SCHEMA_VERSION = 1
#: The label of the inlet node of every vessel's graph (the build and the generators set it;
#: the tasks measure the path to a target from it).
INLET_LABEL = "inlet"


def arc_lengths(points: FloatArray) -> FloatArray:
    """Returns the arc length (m) from the first of ``points`` (N, 3) to each, along the
    polyline through them."""
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(steps)])


def points_along(points: FloatArray, stations: NDArray[np.floating]) -> FloatArray:
    """The polyline through ``points`` (N, D) at arc lengths ``stations`` from its first point
    (m), shape (len(stations), D); stations beyond either end give that end."""
    arc = arc_lengths(points)
    return np.stack([np.interp(stations, arc, points[:, k]) for k in range(points.shape[1])],
                    axis=1)


class CenterlineError(Sim4EndoRError, ValueError):
    """Raised for a malformed centerline graph; the message names the problem."""


@dataclass(frozen=True)
class Projection:
    """Closest point on the graph to a query point.

    Attributes:
        edge: Index of the closest edge.
        fraction: Position along that edge, 0 at ``edges[edge, 0]`` and 1 at ``edges[edge, 1]``.
        point: The closest point on the graph (m).
        distance: Euclidean distance from the query point to ``point`` (m).
    """

    edge: int
    fraction: float
    point: FloatArray
    distance: float


@dataclass(frozen=True, eq=False)
class CenterlineGraph:
    """An undirected graph of lumen-axis samples.

    Attributes:
        nodes: (N, 3) node positions in model metres.
        radii: (N,) lumen radius at each node in metres.
        edges: (E, 2) node index pairs.
        labels: Named nodes, e.g. ``{"inlet": 0, "A": 57, "B": 112}``.
        branch: (N,) integer branch id of each node (``-1`` where unknown).
        branch_names: Name of each branch id.
    """

    nodes: FloatArray
    radii: FloatArray
    edges: IntArray
    labels: Mapping[str, int] = field(default_factory=dict)
    branch: IntArray | None = None
    branch_names: tuple[str, ...] = ()
    # Derived in __post_init__: per-edge terms of the point-to-segment projection.
    _edge_start: FloatArray = field(init=False, repr=False)
    _edge_vector: FloatArray = field(init=False, repr=False)
    _projector: FloatArray = field(init=False, repr=False)
    _abab: FloatArray = field(init=False, repr=False)
    _half_inv_abab: FloatArray = field(init=False, repr=False)
    _edge_radius_start: FloatArray = field(init=False, repr=False)
    _edge_radius_change: FloatArray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        nodes = np.asarray(self.nodes, dtype=np.float64).reshape(-1, 3)
        radii = np.asarray(self.radii, dtype=np.float64).reshape(-1)
        edges = np.asarray(self.edges, dtype=np.int64).reshape(-1, 2)
        branch = (
            np.full(len(nodes), -1, dtype=np.int64)
            if self.branch is None
            else np.asarray(self.branch, dtype=np.int64).reshape(-1)
        )
        if len(nodes) < 2 or len(edges) < 1:
            raise CenterlineError("A centerline graph needs at least two nodes and one edge.")
        if len(radii) != len(nodes) or len(branch) != len(nodes):
            raise CenterlineError(
                f"radii ({len(radii)}) and branch ({len(branch)}) must have one entry per node "
                f"({len(nodes)})."
            )
        if not (np.all(np.isfinite(nodes)) and np.all(np.isfinite(radii))):
            raise CenterlineError("Centerline nodes and radii must be finite.")
        if np.any(radii <= 0):
            raise CenterlineError("Centerline radii must be positive (metres).")
        if edges.min() < 0 or edges.max() >= len(nodes) or np.any(edges[:, 0] == edges[:, 1]):
            raise CenterlineError("Centerline edges must join two different existing nodes.")
        for name, index in self.labels.items():
            if not 0 <= int(index) < len(nodes):
                raise CenterlineError(f"Label {name!r} points at missing node {index}.")
        arrays = (("nodes", nodes), ("radii", radii), ("edges", edges), ("branch", branch))
        for attr, value in arrays:
            value.setflags(write=False)
            object.__setattr__(self, attr, value)
        object.__setattr__(self, "labels", {k: int(v) for k, v in self.labels.items()})
        object.__setattr__(self, "branch_names", tuple(self.branch_names))
        # Per-edge terms of the point-to-segment projection, computed once: the task projects
        # the wire tip every control step, hundreds of times per second.
        a = nodes[edges[:, 0]]
        ab = nodes[edges[:, 1]] - a
        abab = np.einsum("ij,ij->i", ab, ab)
        # One (2E, 4) matrix maps the homogeneous point [p, 1] to 2(p - a)·ab and |a|^2 - 2 a·p
        # for every edge at once.
        projector = np.concatenate(
            [
                np.column_stack([2.0 * ab, -2.0 * np.einsum("ij,ij->i", a, ab)]),
                np.column_stack([-2.0 * a, np.einsum("ij,ij->i", a, a)]),
            ]
        )
        object.__setattr__(self, "_edge_start", a)
        object.__setattr__(self, "_edge_vector", ab)
        object.__setattr__(self, "_projector", projector)
        object.__setattr__(self, "_abab", abab)
        object.__setattr__(self, "_half_inv_abab", 0.5 / np.maximum(abab, 1e-30))
        object.__setattr__(self, "_edge_radius_start", radii[edges[:, 0]])
        object.__setattr__(self, "_edge_radius_change", radii[edges[:, 1]] - radii[edges[:, 0]])

    # ----------------------------------------------------------------------------- geometry
    @property
    def num_nodes(self) -> int:
        """Number of nodes."""
        return len(self.nodes)

    def edge_lengths(self) -> FloatArray:
        """Returns the Euclidean length of every edge (m)."""
        a, b = self.nodes[self.edges[:, 0]], self.nodes[self.edges[:, 1]]
        return np.linalg.norm(b - a, axis=1)

    def total_length(self) -> float:
        """Returns the summed length of all edges (m)."""
        return float(self.edge_lengths().sum())

    def degrees(self) -> IntArray:
        """Returns the number of edges at every node."""
        return np.bincount(self.edges.ravel(), minlength=self.num_nodes)

    def terminal_nodes(self) -> IntArray:
        """Returns the nodes with exactly one edge (vessel ends)."""
        return np.flatnonzero(self.degrees() == 1)

    def num_components(self) -> int:
        """Returns the number of connected components (1 for a proper vessel tree)."""
        return int(self.components().max()) + 1

    def components(self) -> IntArray:
        """Returns each node's connected component (0, 1, ...)."""
        return np.asarray(
            connected_components(self._adjacency(self.edge_lengths()), directed=False)[1],
            dtype=np.int64,
        )

    def neighbours(self) -> list[list[int]]:
        """Returns, for every node, the nodes it shares an edge with (in edge order)."""
        neighbours: list[list[int]] = [[] for _ in range(self.num_nodes)]
        for i, j in self.edges:
            neighbours[i].append(int(j))
            neighbours[j].append(int(i))
        return neighbours

    def node_curvature(self) -> FloatArray:
        """Returns the discrete curvature (1/m) at every node; 0 at ends and junctions."""
        curvature = np.zeros(self.num_nodes)
        for k, adjacent in enumerate(self.neighbours()):
            if len(adjacent) != 2:
                continue
            a, b, c = self.nodes[adjacent[0]], self.nodes[k], self.nodes[adjacent[1]]
            u, v = b - a, c - b
            nu, nv = np.linalg.norm(u), np.linalg.norm(v)
            if nu == 0 or nv == 0:
                continue
            # atan2(|u x v|, u.v), not arccos of the cosine: arccos is ill-conditioned near 0,
            # where a rounding error of 1e-16 in the cosine gives a turn of ~1e-8 rad on a
            # straight line; atan2 keeps the turn's relative error at rounding level.
            turn = np.arctan2(np.linalg.norm(np.cross(u, v)), np.dot(u, v))
            curvature[k] = turn / (0.5 * (nu + nv))
        return curvature

    # ---------------------------------------------------------------------------- distances
    def edge_weights(self, curvature_weight: float = 0.0) -> FloatArray:
        """Returns edge weights for shortest paths.

        Args:
            curvature_weight: Dimensionless gain ``w``; an edge of length ``l`` whose end nodes
                have mean curvature ``k`` weighs ``l * (1 + w * k * r)`` where ``r`` is the mean
                lumen radius, so tortuous segments count as longer. 0 gives plain arc length.
        """
        lengths = self.edge_lengths()
        if curvature_weight == 0.0:
            return lengths
        if curvature_weight < 0:
            raise ValueError(f"curvature_weight must be >= 0, got {curvature_weight}.")
        kappa = self.node_curvature()
        i, j = self.edges[:, 0], self.edges[:, 1]
        bend = 0.5 * (kappa[i] + kappa[j]) * 0.5 * (self.radii[i] + self.radii[j])
        return lengths * (1.0 + curvature_weight * bend)

    def _adjacency(self, weights: FloatArray) -> coo_matrix:
        n = self.num_nodes
        # Zero-length edges would vanish from a sparse matrix; keep them as tiny weights.
        w = np.maximum(weights, 1e-12)
        return coo_matrix((w, (self.edges[:, 0], self.edges[:, 1])), shape=(n, n))

    def geodesic_from(self, node: int, curvature_weight: float = 0.0) -> FloatArray:
        """Returns the shortest-path distance (m) from ``node`` to every node (Dijkstra)."""
        adjacency = self._adjacency(self.edge_weights(curvature_weight)).tocsr()
        return np.asarray(dijkstra(adjacency, directed=False, indices=int(node)), dtype=np.float64)

    def project(self, point: FloatArray) -> Projection:
        """Returns the closest point of the graph's edges to ``point``."""
        p = np.asarray(point, dtype=np.float64).reshape(3)
        # Few numpy calls (ufuncs, no Python-level wrappers such as np.clip): right after a
        # physics step the CPU caches are cold and each call, not the arithmetic, is what costs.
        both = self._projector @ np.array([*p.tolist(), 1.0])
        edges = len(self._abab)
        along2, base = both[:edges], both[edges:]
        t = np.minimum(np.maximum(along2 * self._half_inv_abab, 0.0), 1.0)
        # |p - (a + t ab)|^2 - |p|^2 = |a|^2 - 2 a·p - 2 t (p - a)·ab + t^2 |ab|^2
        k = int((base + t * (t * self._abab - along2)).argmin())
        fraction = float(t[k])
        closest = self._edge_start[k] + fraction * self._edge_vector[k]
        return Projection(
            edge=k, fraction=fraction, point=closest, distance=math.dist(p, closest)
        )

    def tube_excess(self, point: FloatArray) -> float:
        """Returns how far ``point`` lies outside the union of the edges' tubes (m; < 0 inside).

        Each edge is a tube (a truncated cone) of its nodes' radii; the lumen is their union.
        Not the nearest edge's tube alone: near a junction a small branch's axis can be nearer
        to a point inside the large parent than the parent's own axis (measured on a
        generated left coronary tree: a tip 1.94 mm from the axis of a 2.31 mm left main was
        1.88 mm from a 1.2 mm branch, read as 0.68 mm outside).
        """
        return float(self.tube_excesses(np.asarray(point, dtype=np.float64).reshape(1, 3))[0])

    def tube_excesses(self, points: FloatArray, chunk: int = 1024) -> FloatArray:
        """:meth:`tube_excess` of each of ``points`` (N, 3), ``chunk`` points at a time (the
        work array holds ``chunk`` x 2 x edges numbers)."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.empty(len(points))
        for first in range(0, len(points), chunk):
            out[first:first + chunk] = self.edge_excesses(points[first:first + chunk]).min(axis=1)
        return out

    def edge_excesses(self, points: FloatArray) -> FloatArray:
        """Returns how far each of ``points`` (N, 3) lies outside each edge's tube: (N, edges),
        m, negative inside. Holds N x 2 x edges numbers: pass points in chunks."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        edges = len(self._abab)
        # Few numpy calls (ufuncs, no Python-level wrappers such as np.clip): right after a
        # physics step the CPU caches are cold and each call, not the arithmetic, is what
        # costs (the navigation task reads one point every step).
        both = np.hstack([p, np.ones((len(p), 1))]) @ self._projector.T
        along2, base = both[:, :edges], both[:, edges:]
        t = np.minimum(np.maximum(along2 * self._half_inv_abab, 0.0), 1.0)
        squared = np.maximum(base + t * (t * self._abab - along2)
                             + np.einsum("ij,ij->i", p, p)[:, None], 0.0)
        radii = self._edge_radius_start + t * self._edge_radius_change
        return np.asarray(np.sqrt(squared) - radii)

    def radius_at_projection(self, proj: Projection) -> float:
        """Returns the lumen radius (m) interpolated at a projection onto the graph."""
        i, j = self.edges[proj.edge]
        return float((1.0 - proj.fraction) * self.radii[i] + proj.fraction * self.radii[j])

    def distance_along(self, point: FloatArray, node_distances: FloatArray) -> float:
        """Returns the manifold distance from ``point`` to the source of ``node_distances``.

        ``point`` is projected onto the graph; the distance is the arc length from the
        projection to the better end of its edge plus that end's precomputed distance.

        Args:
            point: Query point (m), e.g. the wire tip.
            node_distances: Output of :meth:`geodesic_from` for the target node.
        """
        return self.distance_at(self.project(point), node_distances)

    def distance_at(
        self,
        proj: Projection,
        node_distances: FloatArray,
        edge_weights: FloatArray | None = None,
    ) -> float:
        """Returns the manifold distance from a point already projected onto the graph.

        Args:
            proj: The point's projection (:meth:`project`).
            node_distances: Output of :meth:`geodesic_from` for the target node.
            edge_weights: The weights ``node_distances`` was computed with
                (:meth:`edge_weights`); None means arc length.
        """
        i, j = self.edges[proj.edge]
        if edge_weights is None:
            weight = float(np.linalg.norm(self.nodes[j] - self.nodes[i]))
        else:
            weight = float(edge_weights[proj.edge])
        return float(
            min(
                proj.fraction * weight + node_distances[i],
                (1.0 - proj.fraction) * weight + node_distances[j],
            )
        )

    def resampled_points(self, spacing: float) -> FloatArray:
        """Returns points along every edge at about ``spacing`` metres (nodes included)."""
        pieces = [self.nodes]
        for (i, j), length in zip(self.edges, self.edge_lengths(), strict=True):
            count = int(np.floor(length / spacing))
            if count >= 1:
                t = np.arange(1, count + 1)[:, None] / (count + 1)
                pieces.append(self.nodes[i] + t * (self.nodes[j] - self.nodes[i]))
        return np.vstack(pieces)

    def radius_at(self, points: FloatArray) -> FloatArray:
        """Returns the lumen radius interpolated at the projections of ``points`` (m)."""
        query = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        return np.array([self.radius_at_projection(self.project(p)) for p in query])

    def transformed(self, matrix: FloatArray) -> CenterlineGraph:
        """Returns the graph moved by a 4×4 similarity transform (radii scaled with it)."""
        m = np.asarray(matrix, dtype=np.float64).reshape(4, 4)
        scale = float(np.cbrt(abs(np.linalg.det(m[:3, :3]))))
        nodes = self.nodes @ m[:3, :3].T + m[:3, 3]
        return CenterlineGraph(
            nodes, self.radii * scale, self.edges, self.labels, self.branch, self.branch_names
        )

    # ----------------------------------------------------------------------------------- io
    def to_json_dict(self) -> dict[str, object]:
        """Returns the ``centerline.json`` content (SI units)."""
        return {
            "schema_version": SCHEMA_VERSION,
            "units": "m",
            "nodes": np.round(self.nodes, 9).tolist(),
            "radii": np.round(self.radii, 9).tolist(),
            "edges": self.edges.tolist(),
            "labels": dict(self.labels),
            "branch": self.branch.tolist() if self.branch is not None else None,
            "branch_names": list(self.branch_names),
        }

    def save(self, path: Path) -> None:
        """Writes the graph as ``centerline.json`` (atomically)."""
        atomic_write_text(Path(path), json.dumps(self.to_json_dict(), indent=1) + "\n")

    @classmethod
    def from_json_dict(cls, data: Mapping[str, object], source: str = "<dict>") -> CenterlineGraph:
        """Builds a graph from ``centerline.json`` content."""
        check_schema_version(data, SCHEMA_VERSION, source, CenterlineError)
        missing = [k for k in ("nodes", "radii", "edges") if k not in data]
        if missing:
            raise CenterlineError(f"{source}: missing keys {missing}.")
        if data.get("units", "m") != "m":
            raise CenterlineError(f"{source}: units must be 'm', got {data.get('units')!r}.")
        try:
            return cls(
                nodes=np.asarray(data["nodes"], dtype=np.float64),
                radii=np.asarray(data["radii"], dtype=np.float64),
                edges=np.asarray(data["edges"], dtype=np.int64),
                labels=dict(data.get("labels") or {}),  # type: ignore[call-overload]
                branch=None if data.get("branch") is None else np.asarray(data["branch"]),
                branch_names=tuple(data.get("branch_names") or ()),  # type: ignore[arg-type]
            )
        except CenterlineError as exc:
            raise CenterlineError(f"{source}: {exc}") from None

    @classmethod
    def load(cls, path: Path) -> CenterlineGraph:
        """Reads ``centerline.json``."""
        path = Path(path)
        try:
            data = json.loads(path.read_text())
        except FileNotFoundError:
            raise CenterlineError(f"No centerline file at {path}.") from None
        except json.JSONDecodeError as exc:
            raise CenterlineError(f"{path} is not valid JSON: {exc}") from None
        return cls.from_json_dict(data, source=str(path))
