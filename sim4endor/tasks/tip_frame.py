"""What the wire tip sees in its own frame: the path ahead, the lumen around it, its motion.

These are the entries of the ``generalist`` observation set (:mod:`sim4endor.observations`).
Every vector is expressed in the **tip frame**: the body frame of the wire's distal segment,
origin at the tip end. Its axes turn with the segment, so they carry both the tip's heading
and its roll. Rotating or translating the anatomy together with the wire therefore leaves
every entry unchanged (tested): a policy that sees only these cannot memorise where a
target is in one patient's coordinates. The scalars (distances, radius, forces) are
invariant by nature.

The path ahead follows the shortest route along the centerline graph from the tip's
projection onto the graph to the target, so at a bifurcation the points already bend into the
branch to take: that is where the branch choice is encoded.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim4endor.observations import PATH_POINTS, PATH_SPACING
from sim4endor.vessels.centerline import CenterlineGraph, Projection, points_along

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class PathToTarget:
    """The shortest route from any point of a centerline graph to one target node.

    Attributes:
        graph: The vessel's centerline graph (m).
        node_distances: Geodesic distance of every node to the target (m).
        next_node: For each node, the neighbour one step closer to the target (-1 at the
            target).
    """

    graph: CenterlineGraph
    node_distances: FloatArray
    next_node: NDArray[np.int64]

    @classmethod
    def to_node(cls, graph: CenterlineGraph, target: int) -> PathToTarget:
        """Runs Dijkstra from ``target`` once and records each node's next hop."""
        distances = graph.geodesic_from(target)
        lengths = graph.edge_lengths()
        next_node = np.full(graph.num_nodes, -1, dtype=np.int64)
        best = np.full(graph.num_nodes, np.inf)
        # An edge (i, j) is a step towards the target from whichever end is farther.
        for (i, j), length in zip(graph.edges, lengths, strict=True):
            for near, far in ((i, j), (j, i)):
                via = distances[near] + length
                if distances[far] > distances[near] and via < best[far]:
                    best[far], next_node[far] = via, near
        return cls(graph, distances, next_node)

    def route(self, start: int) -> list[int]:
        """The nodes from ``start`` to the target, both included, one step each."""
        nodes = [start]
        while self.next_node[nodes[-1]] >= 0:
            nodes.append(int(self.next_node[nodes[-1]]))
        return nodes

    def points_ahead(self, proj: Projection, count: int = PATH_POINTS,
                     spacing: float = PATH_SPACING) -> FloatArray:
        """Returns ``count`` points at ``spacing``, 2 ``spacing``, ... along the route from
        ``proj`` (m, world frame), shape (count, 3); points beyond the target repeat it."""
        graph = self.graph
        i, j = (int(n) for n in graph.edges[proj.edge])
        length = float(np.linalg.norm(graph.nodes[j] - graph.nodes[i]))
        # Leave the edge by the end the route does (as CenterlineGraph.distance_at chooses).
        toward_i = proj.fraction * length + self.node_distances[i]
        toward_j = (1.0 - proj.fraction) * length + self.node_distances[j]
        node = i if toward_i <= toward_j else j
        # Along the route the node distances fall by exactly the edge lengths, so the walk
        # follows indices only (it runs every control step, over ~0.5 mm node spacing).
        route = [node]
        left = count * spacing - math.dist(proj.point, graph.nodes[node])
        start, next_node = self.node_distances[node], self.next_node
        while next_node[node] >= 0 and start - self.node_distances[node] < left:
            node = int(next_node[node])
            route.append(node)
        vertices = np.vstack([proj.point, graph.nodes[route]])
        return points_along(vertices, spacing * np.arange(1, count + 1))


@dataclass(frozen=True)
class TipView:
    """The ``generalist`` entries of one state, in the tip frame (see the module doc).

    Attributes:
        path_ahead: (PATH_POINTS, 3) route points ahead of the tip (m).
        axis_offset: (3,) from the tip to its projection onto the centerline, in lumen radii.
        lumen_radius: Lumen radius at that projection (m).
        tip_velocity: (3,) tip velocity (m/s).
    """

    path_ahead: FloatArray
    axis_offset: FloatArray
    lumen_radius: float
    tip_velocity: FloatArray


def tip_view(path: PathToTarget, tip: FloatArray, frame: FloatArray, velocity: FloatArray,
             proj: Projection | None = None) -> TipView:
    """Expresses the route, the lumen axis and the tip velocity in the tip frame.

    Args:
        path: The route to the current target.
        tip: Tip position (m, world).
        frame: (3, 3) rotation of the tip frame: its columns are the frame's axes in world
            coordinates (MuJoCo's ``xmat`` of the distal segment, reshaped).
        velocity: Tip velocity (m/s, world).
        proj: ``tip``'s projection onto the graph, if already known.
    """
    proj = proj or path.graph.project(tip)
    radius = path.graph.radius_at_projection(proj)
    # Row vectors times the frame = each vector's coordinates along the frame's axes.
    ahead = (path.points_ahead(proj) - tip) @ frame
    return TipView(
        path_ahead=ahead,
        axis_offset=((proj.point - tip) @ frame) / radius,
        lumen_radius=radius,
        tip_velocity=velocity @ frame,
    )
