"""Draws what the cath lab's sensors show, for docs/tasks/cathlab.md.

    python experiments/figures/cathlab_figure.py --out docs/figures/cathlab_biplane.png

The scripted expert drives a coronary tree (pool seed 0) in a biplane lab with the default
sensors; at a few instants each plane shows the true wire's projection, the tracked wire (the
tip and the points behind it, noisy and late), the roadmap with its registration error, and
the roadmap points the policy reads ahead of the tracked tip's match.
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/figures/cathlab_biplane.png"))
    parser.add_argument("--seed", type=int, default=0, help="task seed (tree and views)")
    parser.add_argument("--steps", type=int, nargs="+", default=[20, 60, 100],
                        help="control steps at which to draw")
    args = parser.parse_args()
    env = suite.load("coronary", "navigate", {"random": args.seed,
                                              "observations": "deployable_biplane",
                                              "cathlab": {"biplane": True}})
    expert = CenterlineExpert()
    timestep = env.reset()
    lab = env.task.cathlab
    assert lab is not None
    graph = env.task.anatomy.vessel.centerline
    tree = lab.image(graph.nodes)
    figure, axes = plt.subplots(2, len(args.steps), figsize=(4.2 * len(args.steps), 8.4),
                                squeeze=False)
    step = 0
    for column, wanted in enumerate(sorted(args.steps)):
        while step < wanted and not timestep.last():
            timestep = env.step(expert(env.physics, env.task))
            step += 1
        obs = timestep.observation
        wire = lab.image(env.physics.wire_points())
        for plane, suffix in enumerate(("", "_b")):
            ax = axes[plane, column]
            tracked = obs[f"tracked_wire{suffix}"].reshape(-1, 2)
            ahead = obs[f"roadmap_ahead{suffix}"].reshape(-1, 2)
            offset = obs[f"roadmap_offset{suffix}"]
            # The image entries are relative to the tracked tip, which the lab keeps for
            # drawing (the policy is not told where on the image it lies).
            tip = lab.tracked_tip[plane]
            for i, j in graph.edges:
                ax.plot(*tree[plane, [i, j]].T * 1e3, color="0.85", lw=3, zorder=0)
            ax.plot(*lab.roadmap[plane].T * 1e3, color="tab:blue", lw=1, ls="--",
                    label="roadmap (registration error)")
            ax.plot(*wire[plane].T * 1e3, color="k", lw=1.5, label="wire (true projection)")
            ax.plot(*(tip + np.vstack([[0, 0], tracked])).T * 1e3, "o", color="tab:red",
                    ms=4, label="tracked tip and wire")
            ax.plot(*(tip + offset) * 1e3, "s", color="tab:green", ms=6, mfc="none",
                    label="roadmap match")
            ax.plot(*(tip + ahead).T * 1e3, ".", color="tab:green", label="roadmap ahead")
            ax.set_aspect("equal")
            ax.set_xlim(tip[0] * 1e3 - 25, tip[0] * 1e3 + 25)
            ax.set_ylim(tip[1] * 1e3 - 25, tip[1] * 1e3 + 25)
            ax.set_title(f"plane {'AB'[plane]}, step {step} ({step * 0.05:.1f} s)", fontsize=9)
            ax.set_xlabel("image x (mm, isocentre)")
            ax.set_ylabel("image y (mm)")
    axes[0, 0].legend(fontsize=7, loc="lower left")
    figure.suptitle(f"The cath lab's view: coronary tree {env.task.anatomy.vessel.name}, "
                    f"target {env.task.target}, biplane, default sensors", fontsize=10)
    figure.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(args.out, dpi=110)
    print(args.out)


if __name__ == "__main__":
    main()
