"""Draws the plain expert's wire at a side branch's ostium, in the branch's plane, with two tip
shapes, for docs/tasks/coronary.md (2026-11-29, later).

    sim4endor vessel generate coronary_arteries --seed 3005 --set side=right --out t3005
    python experiments/figures/secondary_curve_figure.py --vessel t3005 --target AM \\
        [--out docs/figures/secondary_curve_3005_am.png]

Each row is one episode of ``run_expert``'s ``CenterlineExpert`` on the ``vessel`` domain (the
start seed and the four instants given per row; the defaults are the moments at tree 3005's
acute marginal where the 5 mm/90° tip's end reaches the ostium and is dragged on down the
parent, and where the 2 mm/60° tip with a 40° secondary curve 7 mm back enters). Drawn: the
centerline and its lumen circles near the junction, and the last 40 wire vertices.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sim4endor import suite
from sim4endor.tasks.expert import CenterlineExpert
from sim4endor.tasks.navigation import INLET_LABEL
from sim4endor.tasks.tip_frame import PathToTarget
from sim4endor.vessels.centerline import CenterlineGraph

#: (tip, start seed, instants in s) of each row.
ROWS = (("5,90", 0, (4.9, 5.0, 5.1, 5.2)), ("2,60,7,40", 1, (9.55, 9.7, 9.85, 10.0)))


def branch_plane(graph: CenterlineGraph, target: str) -> tuple[np.ndarray, np.ndarray]:
    """The junction where the path to ``target`` leaves its parent, and the in-plane axes
    (rows: along the parent, towards the branch)."""
    path = PathToTarget.to_node(graph, graph.labels[target]).route(
        int(graph.labels[INLET_LABEL]))
    degrees = graph.degrees()
    at = max(i for i, node in enumerate(path) if degrees[node] >= 3)
    nodes = graph.nodes
    along = nodes[path[at]] - nodes[path[at - 4]]
    along /= np.linalg.norm(along)
    branch = nodes[path[at + 3]] - nodes[path[at]]
    branch -= (branch @ along) * along
    return nodes[path[at]], np.stack([along, branch / np.linalg.norm(branch)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--vessel", required=True, help="a vessel folder")
    parser.add_argument("--target", default="AM")
    parser.add_argument("--out", type=Path,
                        default=Path("docs/figures/secondary_curve_3005_am.png"))
    args = parser.parse_args()
    fig, axes = plt.subplots(len(ROWS), 4, figsize=(14, 3.1 * len(ROWS)))
    for (tip, seed, times), row in zip(ROWS, axes, strict=True):
        env = suite.load("vessel", "navigate", {
            "vessel": args.vessel, "target": args.target, "random": seed,
            "wire": {"preset": "workhorse", "tip": tip}})
        graph = env.task.anatomy.vessel.centerline
        origin, axes_in_plane = branch_plane(graph, args.target)

        def project(points: np.ndarray, origin: np.ndarray = origin,
                    plane: np.ndarray = axes_in_plane) -> np.ndarray:
            return (points - origin) @ plane.T * 1e3

        expert = CenterlineExpert()
        timestep = env.reset()
        shots = {}
        while not timestep.last() and len(shots) < len(times):
            timestep = env.step(expert(env.physics, env.task))
            for instant in times:
                if abs(env.physics.time() - instant) < 1e-6:
                    shots[instant] = env.physics.wire_points()
        for ax, instant in zip(row, times, strict=True):
            for i, j in graph.edges:
                ends = project(graph.nodes[[i, j]])
                if np.abs(ends).max() < 14:
                    ax.plot(ends[:, 0], ends[:, 1], "k-", lw=0.5)
                    ax.add_patch(plt.Circle(ends[0], graph.radii[i] * 1e3, fill=False, lw=0.2,
                                            color="gray"))
            if instant in shots:
                wire = project(shots[instant][-40:])
                ax.plot(wire[:, 0], wire[:, 1], "r.-", ms=3, lw=1.2)
                ax.plot(*wire[-1], "bo", ms=5)
            ax.set(xlim=(-10, 8), ylim=(-4, 8), aspect="equal")
            ax.set_title(f"tip {tip}, t = {instant:.2f} s", fontsize=9)
            ax.tick_params(labelsize=7)
        row[0].set_ylabel("mm, in the branch's plane")
    fig.suptitle(f"{args.target} of {Path(args.vessel).name}, plain expert: top, 5 mm/90°, the "
                 "tip's end reaches the ostium and is dragged on down the parent; bottom, "
                 "2 mm/60° with 40° 7 mm back, the tip crosses to the ostium and enters",
                 fontsize=9)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=100)
    print(args.out)


if __name__ == "__main__":
    main()
