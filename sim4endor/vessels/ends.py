"""Vessel ends of a centerline: runs of nodes from an end inward, and trimming narrow ends.

A segmented distal branch often ends narrower than any guidewire can use: a real patient's
mesh was refused at lumen open 0.9764 because 40 of its 41 blocked probes lay in the last 6 mm
of one branch of 0.22-0.28 mm radius (a lumen 0.5 mm across for a 0.36 mm wire; issue 78).
Trimming the centerline there (``BuildParams.trim_ends_below``, ``--trim-ends-below``) takes
such an end out of the checks and the targets; the lumen and its wall stay as they are.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

import numpy as np
import trimesh
from numpy.typing import NDArray

from sim4endor.vessels.axis import branch_chains
from sim4endor.vessels.centerline import CenterlineGraph

BoolArray = NDArray[np.bool_]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class TrimmedEnd:
    """A vessel end cut off the centerline.

    Attributes:
        end: Where the dropped end was (m).
        length: Centerline length dropped (m).
        radius: Largest lumen radius of the dropped part (m).
    """

    end: tuple[float, float, float]
    length: float
    radius: float


def end_runs(graph: CenterlineGraph, flagged: BoolArray, whole_chains: bool = False) -> BoolArray:
    """Returns the nodes on runs of ``flagged`` nodes that start at a vessel end and go inward
    along its branch, never past a junction.

    A branch flagged from end to end is left alone (nothing of it would be left), unless
    ``whole_chains``: then all of it goes but the junction it hangs from.
    """
    degree = graph.degrees()
    run_nodes = np.zeros(graph.num_nodes, dtype=bool)
    for chain in branch_chains(graph):
        whole = bool(flagged[chain].all())
        if whole and not whole_chains:
            continue
        for run in (chain, chain[::-1]):
            if degree[run[0]] != 1:
                continue
            for node in run[:-1]:
                if not flagged[node]:
                    break
                run_nodes[node] = True
    return run_nodes


def without_nodes(graph: CenterlineGraph, drop: BoolArray) -> CenterlineGraph:
    """Returns ``graph`` less the ``drop`` nodes and their edges (labels of dropped nodes go)."""
    keep = np.flatnonzero(~drop)
    index = _inverse(keep, graph.num_nodes)
    edges = index[graph.edges]
    labels = {k: int(index[v]) for k, v in graph.labels.items() if index[v] >= 0}
    branch = None if graph.branch is None else graph.branch[keep]
    return CenterlineGraph(
        graph.nodes[keep],
        graph.radii[keep],
        edges[(edges >= 0).all(axis=1)],
        labels,
        branch,
        graph.branch_names,
    )


def trim_narrow_ends(graph: CenterlineGraph, min_radius: float, keep: Collection[int] = ()
                     ) -> tuple[CenterlineGraph, list[TrimmedEnd], NDArray[np.int64]]:
    """Cuts every vessel end back to its first node of ``min_radius`` (m) or more.

    A branch narrower than that from its junction to its end goes whole, and the branch it
    hangs from is then trimmed in turn if its own end is narrow. Runs holding a ``keep`` node
    (the inlet) stay.

    Returns:
        The trimmed graph, the ends cut, and each old node's index in the new graph (-1 where
        dropped).
    """
    index = np.arange(graph.num_nodes)
    trimmed: list[TrimmedEnd] = []
    kept = np.zeros(graph.num_nodes, dtype=bool)
    kept[list(keep)] = True
    while True:
        narrow = (graph.radii < min_radius) & ~kept[index]
        drop = end_runs(graph, narrow, whole_chains=True)
        if not drop.any():
            return graph, trimmed, _inverse(index, len(kept))
        cut = drop[graph.edges].any(axis=1)
        lengths = graph.edge_lengths()
        for end in np.flatnonzero(drop & (graph.degrees() == 1)):
            part = _run_from(graph, int(end), drop)
            trimmed.append(TrimmedEnd(
                end=(float(graph.nodes[end, 0]), float(graph.nodes[end, 1]),
                     float(graph.nodes[end, 2])),
                length=float(lengths[cut & np.isin(graph.edges, part).any(axis=1)].sum()),
                radius=float(graph.radii[part].max()),
            ))
        index = index[~drop]
        graph = without_nodes(graph, drop)


def _run_from(graph: CenterlineGraph, end: int, drop: BoolArray) -> list[int]:
    """The dropped nodes reached from vessel end ``end`` without leaving ``drop``."""
    neighbours = graph.neighbours()
    run, seen = [end], {end}
    while True:
        ahead = [n for n in neighbours[run[-1]] if drop[n] and n not in seen]
        if not ahead:
            return run
        run.append(ahead[0])
        seen.add(ahead[0])


def _inverse(index: NDArray[np.int64], size: int) -> NDArray[np.int64]:
    out = np.full(size, -1, dtype=np.int64)
    out[index] = np.arange(len(index))
    return out


#: A given point this many node radii from the centerline, or nearer, is taken to lie in the
#: vessel around it.
GRAFT_REACH_RADII = 5.0

#: An opening whose centre lies within this many radii of a centerline node is in the wall of
#: that node's vessel (a hole in the side wall lies about one radius from the axis); a vessel
#: end the skeleton left out lies past it (2.1-2.8 radii on the trees measured).
OPENING_BESIDE_RADII = 1.5

#: Nodes tried as the start of a graft, nearest (in their radii) first: the nearest one's
#: straight run may cut a junction's corner where a farther one runs along the branch.
GRAFT_CANDIDATES = 16


def graft_to(graph: CenterlineGraph, point: FloatArray, max_gap: float,
             lumen: trimesh.Trimesh, wall: trimesh.Trimesh | None = None,
             beside: float = 0.0) -> tuple[CenterlineGraph, float]:
    """Extends ``graph`` to ``point`` (m) when its nearest vessel end lies farther than
    ``max_gap`` radii from it but a node lies within :data:`GRAFT_REACH_RADII` of its radii
    and the straight run to it stays in the closed ``lumen`` (m).

    An extracted skeleton leaves out a vessel end shorter than about three radii past a
    junction: its voxels lie in the junction's covering ball, and a short spur is pruned. A
    left coronary tree cut from the aorta 2.7 mm before its bifurcation had no centerline end
    at its inlet, and the given inlet was refused as lying 26 mm outside the lumen. The graft
    is a straight run of nodes half a radius apart. Their radius is their distance from
    ``wall``, the lumen's surface with its vessel ends open, as the skeleton's radius is the
    distance to the wall; without it (a given point may sit on the cap of a closed mesh), the
    node's own. A point within ``beside`` radii of a node lies beside the centerline, not
    past its end (an opening there is a hole in that vessel's wall), and is not grafted to.

    Returns:
        The graph (``graph`` itself when nothing is grafted) and the grafted length (m).
    """
    ends = graph.terminal_nodes()
    radii = graph.radii
    if len(ends):
        end = int(ends[np.argmin(np.linalg.norm(graph.nodes[ends] - point, axis=1))])
        if np.linalg.norm(graph.nodes[end] - point) - radii[end] <= max_gap * radii[end]:
            return graph, 0.0
    gaps = np.linalg.norm(graph.nodes - point, axis=1)
    order = np.argsort(gaps / radii)[:GRAFT_CANDIDATES]
    if gaps[order[0]] < beside * radii[order[0]]:
        return graph, 0.0
    point_radius = None if wall is None else float(wall.nearest.on_surface([point])[1][0])
    for node in order[gaps[order] <= GRAFT_REACH_RADII * radii[order]]:
        spacing = 0.5 * min(float(radii[node]), np.inf if point_radius is None else point_radius)
        count = max(1, int(np.ceil(gaps[node] / spacing)))
        steps = graph.nodes[node] + (point - graph.nodes[node]) * (np.arange(1, count + 1)
                                                                    / count)[:, None]
        # The point itself may sit on a cap; the run up to a fifth of the spacing before it
        # must be in.
        inner = steps - 0.2 * spacing * (point - graph.nodes[node]) / gaps[node]
        if not lumen.contains(inner).all():
            continue
        step_radii = (np.full(count, radii[node]) if wall is None
                      else wall.nearest.on_surface(steps)[1])
        first = graph.num_nodes
        chain = np.concatenate([[node], np.arange(first, first + count)])
        branch = None if graph.branch is None else np.concatenate(
            [graph.branch, np.full(count, graph.branch[node])])
        grafted = CenterlineGraph(
            np.vstack([graph.nodes, steps]),
            np.concatenate([radii, step_radii]),
            np.vstack([graph.edges, np.column_stack([chain[:-1], chain[1:]])]),
            dict(graph.labels), branch, graph.branch_names,
        )
        return grafted, float(gaps[node])
    return graph, 0.0
