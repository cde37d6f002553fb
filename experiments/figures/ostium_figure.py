"""Draws the plain expert's wire at a side branch's ostium, in the branch's plane, one row per
wire and tip, for docs/tasks/coronary.md.

    sim4endor vessel generate coronary_arteries --seed 3005 --set side=right --out t3005
    python experiments/figures/ostium_figure.py --vessel t3005 --target AM \\
        --row workhorse 5,90 0 4.9,5.0,5.1,5.2 --row workhorse 2,60,7,40 1 9.55,9.7,9.85,10.0 \\
        --out docs/figures/secondary_curve_3005_am.png      # 2026-11-29, later

    # 2026-12-02 (evening). DIR: `sim4endor vessel generate coronary_tree --seed 3130 --set
    # root_radius=0.002 --set min_radius=0.0008 --set levels=2`, its lumen.stl then built
    # with `sim4endor vessel build LUMEN --units m` and the generated folder's inlet and
    # targets (coronary.md, Measured, 2026-12-02, later)
    python experiments/figures/ostium_figure.py --vessel DIR --target T2 \\
        --row workhorse 3,75,7,40 0 7.0,7.3,7.4,8.1 \\
        --row intermediate 3,75,7,40 0 21.9,21.95,22.1,23.0 \\
        --title "T2 of tree 3130 built from its lumen mesh, plain expert, tip 3 mm/75° with 40° \\
    7 mm back. Top, workhorse: the tip's end reaches the ostium (7.30 s) and flips back into \\
    the parent. Bottom, intermediate: it reaches the ostium and the wire follows it in" \\
        --out docs/figures/wire_choice_3130_t2.png

    # 2026-12-02 (night), the same folder: two tip shapes on the workhorse
    python experiments/figures/ostium_figure.py --vessel DIR --target T2 \\
        --row workhorse 3,75,7,40 0 7.0,7.3,7.4,8.1 \\
        --row workhorse 2,90,5,60 0 3.8,3.9,4.0,5.45 \\
        --title "T2 of tree 3130 built from its lumen mesh, plain expert, workhorse wire. Top, \\
    tip 3 mm/75° with 40° 7 mm back: the tip's end reaches the ostium (7.30 s) and flips back \\
    into the parent. Bottom, tip 2 mm/90° with 60° 5 mm back: the hook points into the branch \\
    as it passes the ostium (3.80 s) and the wire follows it in" \\
        --out docs/figures/tip_shape_3130_t2.png

Each row is one episode of ``run_expert``'s ``CenterlineExpert`` on the ``vessel`` domain with
the row's wire preset, tip shape and start seed, drawn at the row's instants (s, multiples of
the 50 ms control step). Drawn: the centerline and its lumen circles near the junction where
the path to the target leaves its parent, and the last 40 wire vertices.
"""

from __future__ import annotations

import argparse
import textwrap
from pathlib import Path
from typing import NamedTuple

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from sim4endor import suite
from sim4endor.tasks.expert import CenterlineExpert
from sim4endor.tasks.tip_frame import PathToTarget
from sim4endor.vessels.centerline import INLET_LABEL, CenterlineGraph


class Row(NamedTuple):
    """One episode of the figure: its wire, tip, start seed and the instants drawn."""

    preset: str
    tip: str
    seed: int
    times: tuple[float, ...]

    @classmethod
    def parse(cls, words: list[str]) -> Row:
        preset, tip, seed, times = words
        try:
            return cls(preset, tip, int(seed), tuple(float(t) for t in times.split(",")))
        except ValueError as err:
            raise argparse.ArgumentTypeError(
                f"--row {' '.join(words)}: expected PRESET TIP SEED T1,T2,... ({err})") from None


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


def shots(vessel: str, target: str, row: Row) -> tuple[CenterlineGraph, dict[float, np.ndarray]]:
    """The vessel's centerline, and the wire's vertices at each of the row's instants."""
    env = suite.load("vessel", "navigate", {"vessel": vessel, "target": target,
                                            "random": row.seed,
                                            "wire": {"preset": row.preset, "tip": row.tip}})
    expert = CenterlineExpert()
    timestep = env.reset()
    wires: dict[float, np.ndarray] = {}
    while not timestep.last() and len(wires) < len(row.times):
        timestep = env.step(expert(env.physics, env.task))
        for instant in row.times:
            if abs(env.physics.time() - instant) < 1e-6:
                wires[instant] = env.physics.wire_points()
    return env.task.anatomy.vessel.centerline, wires


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--vessel", required=True, help="a vessel folder")
    parser.add_argument("--target", required=True)
    parser.add_argument("--row", nargs=4, action="append", required=True,
                        metavar=("PRESET", "TIP", "SEED", "TIMES"),
                        help="a wire preset, tip shape (as --tip), start seed and instants "
                             "(s, comma-separated); repeat for more rows")
    parser.add_argument("--title", default="", help="the figure's title")
    parser.add_argument("--out", type=Path, required=True, help="the PNG to write")
    args = parser.parse_args()
    try:
        rows = [Row.parse(words) for words in args.row]
    except argparse.ArgumentTypeError as err:
        parser.error(str(err))
    episodes = [shots(args.vessel, args.target, row) for row in rows]
    graph = episodes[0][0]  # every row loads the same folder
    origin, plane = branch_plane(graph, args.target)

    def project(points: np.ndarray) -> np.ndarray:
        return (points - origin) @ plane.T * 1e3

    outline = []  # the centerline's edges near the junction, and their lumen radii (mm)
    for i, j in graph.edges:
        ends = project(graph.nodes[[i, j]])
        if np.abs(ends).max() < 14:
            outline.append((ends, graph.radii[i] * 1e3))
    width = max(len(row.times) for row in rows)
    fig, axes = plt.subplots(len(rows), width, figsize=(3.5 * width, 3.1 * len(rows)),
                             squeeze=False)
    for row, (_, wires), row_axes in zip(rows, episodes, axes, strict=True):
        for ax, instant in zip(row_axes, row.times, strict=False):
            for ends, radius in outline:
                ax.plot(ends[:, 0], ends[:, 1], "k-", lw=0.5)
                ax.add_patch(plt.Circle(ends[0], radius, fill=False, lw=0.2, color="gray"))
            if instant in wires:
                wire = project(wires[instant][-40:])
                ax.plot(wire[:, 0], wire[:, 1], "r.-", ms=3, lw=1.2)
                ax.plot(*wire[-1], "bo", ms=5)
            ax.set(xlim=(-10, 8), ylim=(-4, 8), aspect="equal")
            ax.set_title(f"{row.preset}, tip {row.tip}, t = {instant:.2f} s", fontsize=9)
            ax.tick_params(labelsize=7)
        for ax in row_axes[len(row.times):]:
            ax.set_visible(False)
        row_axes[0].set_ylabel("mm, in the branch's plane")
    title = args.title or f"{args.target} of {Path(args.vessel).name}, plain expert"
    fig.suptitle("\n".join(textwrap.wrap(title, 40 * width)), fontsize=9)
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=100)
    print(args.out)


if __name__ == "__main__":
    main()
