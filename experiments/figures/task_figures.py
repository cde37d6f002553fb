"""Pictures of the navigation tasks for docs/tasks/: the scene and the fluoroscopy observation.

For each domain: a top-down render (MuJoCo, offscreen) after a scripted insertion, with
each target marked, beside the task's ``pixels`` observation (fluoroscopy-like projection)
at the same moment. Writes ``docs/figures/tasks/<domain>.png``.

Usage:
    MUJOCO_GL=osmesa python experiments/figures/task_figures.py [--domains simplified_phantom]
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np

# Before anything imports MuJoCo's renderer: it reads MUJOCO_GL once.
os.environ.setdefault("MUJOCO_GL", "osmesa")

import imageio.v2 as imageio
from dm_control.mujoco import MovableCamera

from sim4endor import suite
from sim4endor.cli.render import add_sphere, add_wire, top_down_pose
from sim4endor.tasks import PixelsConfig

TARGET_COLOURS = (np.array([0.1, 0.9, 0.2, 0.9], np.float32),
                  np.array([0.2, 0.5, 1.0, 0.9], np.float32))
DEFAULT_TASKS = {
    "simplified_phantom": ("task_a", {}),
    "vascular_phantom": ("task_a", {}),
    "random_coronary": ("navigate", {"pool_size": 1}),
}


def figure(domain: str, task: str, kwargs: dict, steps: int, size: int) -> np.ndarray:
    """Returns the composed RGB figure of one domain."""
    env = suite.load(domain, task, {**kwargs, "observations": ("pixels",),
                                    "pixels": PixelsConfig(height=size, width=size)})
    timestep = env.reset()
    for _ in range(steps):
        if timestep.last():
            break
        timestep = env.step([1.0, 0.0])
    vessel = env.task.anatomy.vessel
    targets = [vessel.centerline.nodes[vessel.centerline.labels[name]]
               for name in sorted(vessel.targets)]

    def mark(_physics: object, scene: object) -> None:
        add_wire(scene, env.physics.wire_points())
        for k, point in enumerate(targets):
            add_sphere(scene, point, 2.5e-3, TARGET_COLOURS[k % len(TARGET_COLOURS)])

    camera = MovableCamera(env.physics, height=size, width=size, scene_callback=mark)
    camera.set_pose(**top_down_pose(vessel.centerline.nodes))
    scene = np.array(camera.render())
    pixels = np.repeat(timestep.observation["pixels"], 3, axis=2)
    gap = np.full((size, 8, 3), 255, np.uint8)
    env.physics.free()
    return np.concatenate([scene, gap, pixels], axis=1)


def main() -> None:
    """Writes one PNG per requested domain."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--domains", nargs="+", default=list(DEFAULT_TASKS))
    parser.add_argument("--steps", type=int, default=40, help="insertion steps before the shot")
    parser.add_argument("--size", type=int, default=360, help="pixels per panel")
    parser.add_argument("--out", type=Path, default=Path("docs/figures/tasks"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for domain in args.domains:
        task, kwargs = DEFAULT_TASKS[domain]
        path = args.out / f"{domain}.png"
        imageio.imwrite(path, figure(domain, task, kwargs, args.steps, args.size))
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
