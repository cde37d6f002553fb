"""Draws one PNG per vessel: lumen surface, centerline graph, inlet and targets.

Usage:
    python experiments/figures/vessel_figures.py                    # the shipped phantoms
    python experiments/figures/vessel_figures.py my_vessel --out /tmp/figs
    python experiments/figures/vessel_figures.py --coronary-seeds 0 1 2   # generated, unbuilt
    python experiments/figures/vessel_figures.py --arteries-seeds 0 1 --stenoses 1

Reads built vessel folders through ``sim4endor.vessels.load`` (names or paths), or generates
random coronary trees without building them, and writes ``<out>/<name>.png`` (default
``docs/figures``): a top view (x-y) and a 3D view, in mm.
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import trimesh
from matplotlib.collections import LineCollection, PolyCollection
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

from sim4endor import vessels
from sim4endor.tasks.coronary import side_of
from sim4endor.vessels.centerline import CenterlineGraph
from sim4endor.vessels.generators import (
    CoronaryArteriesConfig,
    CoronaryTreeConfig,
    GeneratedAnatomy,
    coronary_arteries,
    coronary_tree,
)

REPO = Path(__file__).resolve().parents[2]
LUMEN_FILE = "lumen.stl"
TARGET_COLOURS = ("tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive")


def draw_vessel(vessel: vessels.Vessel, out: Path) -> Path:
    """Draws a built vessel folder and returns the PNG's path."""
    return draw(vessel.name, trimesh.load(vessel.root / LUMEN_FILE, force="mesh"),
                vessel.centerline, vessel.inlet_position, vessel.inlet_direction,
                vessel.targets, f"{vessel.manifest.hull_count} wall hulls", out)


def draw_generated(name: str, anatomy: GeneratedAnatomy, out: Path) -> Path:
    """Draws a generated (not built) anatomy and returns the PNG's path."""
    return draw(name, anatomy.lumen, anatomy.centerline, anatomy.inlet_position,
                anatomy.inlet_direction, anatomy.targets,
                f"{len(anatomy.lumen.faces)} lumen faces, not built", out)


def draw(name: str, lumen: trimesh.Trimesh, graph: CenterlineGraph, inlet_position: np.ndarray,
         direction: np.ndarray, targets: Mapping[str, np.ndarray], note: str, out: Path) -> Path:
    """Draws a lumen with its centerline, inlet and targets; returns the PNG's path."""
    tri = np.asarray(lumen.triangles) * 1e3
    segments = graph.nodes[graph.edges] * 1e3
    inlet = inlet_position * 1e3
    arrow = 0.1 * float(np.ptp(graph.nodes, axis=0).max()) * 1e3 * np.asarray(direction)

    fig = plt.figure(figsize=(13, 6))
    top = fig.add_subplot(1, 2, 1)
    top.add_collection(PolyCollection(tri[:, :, :2], facecolor=(0.85, 0.3, 0.3, 0.12),
                                      edgecolor="none"))
    top.add_collection(LineCollection(segments[:, :, :2], colors="k", linewidths=1.2))
    top.annotate("", xy=inlet[:2] + arrow[:2], xytext=inlet[:2],
                 arrowprops={"arrowstyle": "->", "color": "tab:green", "lw": 2})
    top.plot(*inlet[:2], "o", color="tab:green", ms=8, label="inlet (wire enters)")
    view = fig.add_subplot(1, 2, 2, projection="3d")
    light = np.abs(lumen.face_normals @ (np.array([0.3, -0.5, 0.8]) / np.sqrt(0.98)))
    shade = np.column_stack([0.5 + 0.45 * light, 0.2 + 0.25 * light, 0.2 + 0.25 * light,
                             np.full(len(light), 0.18)])
    view.add_collection3d(Poly3DCollection(tri, facecolors=shade, edgecolor="none"))
    view.add_collection3d(Line3DCollection(segments, colors="k", linewidths=1.0))
    view.quiver(*inlet, *arrow, color="tab:green", linewidth=2)
    view.scatter(*inlet, color="tab:green", s=40)
    for (target, point), colour in zip(sorted(targets.items()), TARGET_COLOURS * 10,
                                       strict=False):
        p = point * 1e3
        top.plot(*p[:2], "*", color=colour, ms=14, label=f"target {target}")
        top.annotate(target, p[:2], textcoords="offset points", xytext=(6, 6), fontsize=12)
        view.scatter(*p, color=colour, marker="*", s=120)
        view.text(*p, f" {target}", fontsize=11)
    lo, hi = lumen.bounds * 1e3
    top.set(xlim=(lo[0] - 2, hi[0] + 2), ylim=(lo[1] - 2, hi[1] + 2), aspect="equal",
            xlabel="x (mm)", ylabel="y (mm)", title="top view (x-y)")
    top.legend(loc="best", fontsize=9)
    centre, half = 0.5 * (lo + hi), 0.5 * float(np.max(hi - lo))
    view.set(xlim=(centre[0] - half, centre[0] + half), ylim=(centre[1] - half, centre[1] + half),
             zlim=(centre[2] - half, centre[2] + half), xlabel="x (mm)", ylabel="y (mm)",
             zlabel="z (mm)", title="3D view")
    view.view_init(elev=25, azim=-60)
    fig.suptitle(
        f"{name}: lumen radius {graph.radii.min() * 1e3:.2f}-{graph.radii.max() * 1e3:.2f}"
        f" mm, centerline {graph.total_length() * 1e3:.0f} mm, {note}"
    )
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("vessels", nargs="*", help="vessel names or folders (default: the "
                        "shipped phantoms, unless --coronary-seeds is given)")
    parser.add_argument("--coronary-seeds", type=int, nargs="*", default=[],
                        help="also draw generated random coronary trees of these seeds")
    parser.add_argument("--arteries-seeds", type=int, nargs="*", default=[],
                        help="also draw generated coronary_arteries trees of these seeds (even "
                             "seeds left, odd right, as in the coronary domain)")
    parser.add_argument("--stenoses", type=int, default=0, help="stenoses per arteries tree")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "figures")
    args = parser.parse_args()
    matplotlib.use("Agg")
    generated = args.coronary_seeds or args.arteries_seeds
    names = args.vessels or ([] if generated else ["simplified_phantom", "vascular_phantom"])
    for name in names:
        print(draw_vessel(vessels.load(name), args.out))
    for seed in args.coronary_seeds:
        anatomy = coronary_tree(CoronaryTreeConfig(), seed)
        print(draw_generated(f"coronary_tree_seed{seed}", anatomy, args.out))
    for seed in args.arteries_seeds:
        config = CoronaryArteriesConfig(side=side_of(seed, "both"), stenoses=args.stenoses)
        anatomy = coronary_arteries(config, seed)
        print(draw_generated(f"{config.side}_coronary_seed{seed}", anatomy, args.out))


if __name__ == "__main__":
    main()
