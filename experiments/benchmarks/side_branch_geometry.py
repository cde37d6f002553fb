"""Side-branch geometry against reachability: which branches the expert misses, and why.

Reads the rows that ``expert_reachability.py --domain coronary --json`` printed (one JSON line
per episode: ``seed``, ``target``, ``outcome``), finds for each target the junction where its
path leaves the vessel it came along (the last bifurcation before the target), and measures
there, on the tree's centerline:

- ``parent_diameter_mm``: the lumen 2 mm upstream of the junction;
- ``branch_diameter_mm``: the lumen 3 mm into the branch;
- ``angle_deg``: between the direction the path comes in (over the 3 mm upstream) and the
  branch's first 3 mm;
- ``ratio``: branch over parent diameter.

It prints the success of the rows grouped by that ratio, by parent diameter and by angle, so a
reader sees which side branches defeat the wire (docs/tasks/coronary.md, Measured). Only side
branches count: a target whose path takes the wider daughter at its last bifurcation (a trunk's
end, such as LAD_distal or PDA) is skipped.

Usage:
    python experiments/benchmarks/side_branch_geometry.py ROWS.jsonl [ROWS.jsonl ...] [--json]
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from sim4endor import suite
from sim4endor.tasks.tip_frame import PathToTarget
from sim4endor.vessels.centerline import INLET_LABEL, CenterlineGraph

#: Where the diameters and directions are read (m): upstream of the junction, into the branch.
UPSTREAM, INTO = 0.002, 0.003
#: Bins of the printed tables (lower edges).
RATIO_BINS = (0.0, 0.5, 0.55, 0.6)
PARENT_BINS_MM = (0.0, 2.8, 3.2, 3.5)
ANGLE_BINS_DEG = (0.0, 45.0, 60.0, 75.0)


@dataclass(frozen=True)
class Junction:
    """The bifurcation where the path to a target leaves its parent vessel."""

    parent_diameter_mm: float
    branch_diameter_mm: float
    angle_deg: float

    @property
    def ratio(self) -> float:
        """Branch over parent diameter."""
        return self.branch_diameter_mm / self.parent_diameter_mm


def path_to(graph: CenterlineGraph, target: str) -> list[int]:
    """The centerline nodes from the inlet to ``target`` (the route the ``path_ahead``
    observation follows)."""
    return PathToTarget.to_node(graph, graph.labels[target]).route(graph.labels[INLET_LABEL])


def walk(graph: CenterlineGraph, neighbours: list[list[int]], start: int, first: int,
         length: float) -> int:
    """The node ``length`` (m) along the vessel from ``start`` through its neighbour ``first``
    (the vessel's last node if it ends or forks before); ``neighbours`` is
    ``graph.neighbours()``."""
    previous, node, travelled = start, first, 0.0
    while True:
        travelled += float(np.linalg.norm(graph.nodes[node] - graph.nodes[previous]))
        ahead = [n for n in neighbours[node] if n != previous]
        if travelled >= length or len(ahead) != 1:
            return node
        previous, node = node, ahead[0]


def junction(graph: CenterlineGraph, target: str) -> Junction | None:
    """The last bifurcation on the path to ``target`` if the path takes its narrower daughter
    there (a side branch), else None."""
    path = path_to(graph, target)
    degrees = graph.degrees()
    forks = [i for i, node in enumerate(path[1:-1], start=1) if degrees[node] > 2]
    if not forks:
        return None
    at = forks[-1]
    fork, into = path[at], path[at + 1]
    neighbours = graph.neighbours()
    daughters = [n for n in neighbours[fork] if n != path[at - 1]]
    widths = {n: float(graph.radii[walk(graph, neighbours, fork, n, INTO)]) for n in daughters}
    if widths[into] >= max(widths.values()):
        return None
    along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(
        np.diff(graph.nodes[path], axis=0), axis=1))])
    s = along[at]

    def node_at(length: float) -> int:
        return path[int(np.clip(np.searchsorted(along, length), 0, len(path) - 1))]

    centre = graph.nodes[fork]
    incoming = centre - graph.nodes[node_at(s - 3e-3)]
    branch = graph.nodes[node_at(s + INTO)] - centre
    cosine = incoming @ branch / (np.linalg.norm(incoming) * np.linalg.norm(branch))
    return Junction(parent_diameter_mm=round(2e3 * float(graph.radii[node_at(s - UPSTREAM)]), 2),
                    branch_diameter_mm=round(2e3 * float(graph.radii[node_at(s + INTO)]), 2),
                    angle_deg=round(math.degrees(math.acos(float(np.clip(cosine, -1, 1)))), 1))


def tree_centerline(seed: int) -> CenterlineGraph:
    """The centerline of coronary tree ``seed`` (built and cached on first use)."""
    env = suite.load("coronary", "navigate", {"pool_seed": seed, "pool_size": 1})
    graph = env.task.anatomy.vessel.centerline
    env.close()
    return graph


def read_rows(paths: Iterable[Path]) -> list[dict[str, object]]:
    """The episode rows of reachability output files (their summary lines skipped)."""
    rows = []
    for path in paths:
        for line in path.read_text().splitlines():
            row = json.loads(line)
            if "target" in row:
                rows.append(row)
    return rows


def table(title: str, rows: list[tuple[Junction, bool]], value: str,
          bins: tuple[float, ...]) -> str:
    """Successes per bin of ``value`` (a Junction attribute), as a Markdown table."""
    lines = [f"| {title} | reached |", "|---|---|"]
    edges = (*bins, math.inf)
    for low, high in itertools.pairwise(edges):
        hits = [ok for j, ok in rows if low <= getattr(j, value) < high]
        span = f">= {low:g}" if high == math.inf else f"{low:g}-{high:g}"
        lines.append(f"| {span} | {sum(hits)}/{len(hits)} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rows", nargs="+", type=Path, help="expert_reachability --json output")
    parser.add_argument("--json", action="store_true", help="one JSON line per row")
    args = parser.parse_args()
    graphs: dict[int, CenterlineGraph] = {}
    measured: list[tuple[Junction, bool]] = []
    for row in read_rows(args.rows):
        seed, target = int(str(row["seed"])), str(row["target"])
        if seed not in graphs:
            graphs[seed] = tree_centerline(seed)
        found = junction(graphs[seed], target)
        if found is None:
            continue
        ok = row["outcome"] == "success"
        measured.append((found, ok))
        if args.json:
            print(json.dumps({"seed": seed, "target": target, "outcome": row["outcome"],
                              **asdict(found), "ratio": round(found.ratio, 3)}), flush=True)
    print(f"{sum(ok for _, ok in measured)}/{len(measured)} side-branch targets reached")
    print(table("branch/parent diameter", measured, "ratio", RATIO_BINS))
    print(table("parent diameter (mm)", measured, "parent_diameter_mm", PARENT_BINS_MM))
    print(table("angle (deg)", measured, "angle_deg", ANGLE_BINS_DEG))


if __name__ == "__main__":
    main()
