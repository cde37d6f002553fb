"""Renders the guidewire inside a phantom for docs/guidewire.md (MuJoCo offscreen).

    MUJOCO_GL=osmesa python experiments/figures/guidewire_figure.py \
        [--vessel simplified_phantom] [--out docs/figures/guidewire_in_phantom.png]

The wire is steered into branch B (rotate 180°, insert) and stopped past the bifurcation;
the picture shows the vessel walls (translucent), the sheath and the wire, seen from +z:
the whole phantom above, a close-up of the tip below.
"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "osmesa")

import imageio.v3 as iio
import mujoco
import numpy as np

from sim4endor import vessels
from sim4endor.models import constants as names
from sim4endor.models.scene import config_for_vessel
from sim4endor.physics import GuidewirePhysics


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--vessel", default="simplified_phantom")
    parser.add_argument("--depth", type=float, default=0.085, help="insertion (m)")
    parser.add_argument("--out", type=Path, default=Path("docs/figures/guidewire_in_phantom.png"))
    args = parser.parse_args()
    vessel = vessels.load(args.vessel)
    physics = GuidewirePhysics.from_vessel(vessel, config_for_vessel(vessel))
    while physics.rotation_angle() < math.pi - 1e-3 or physics.insertion_depth() < args.depth:
        angle = physics.driver_targets()[1]
        rotated = angle >= math.pi - 1e-9
        physics.apply_increments(0.02 * 0.05 if rotated else 0.0, math.pi - angle, 0.05)
        physics.step(10)
        if physics.data.time > 20.0:
            break
    model = physics.model.ptr
    for geom in range(model.ngeom):  # translucent vessel so the wire inside shows
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom) or ""
        if name.startswith(names.VESSEL_PREFIX):
            model.geom_rgba[geom] = [0.85, 0.35, 0.35, 0.18]
        elif name.startswith(names.WIRE_PREFIX):
            model.geom_rgba[geom] = [0.25, 0.65, 1.0, 1.0]
        elif name.startswith(names.SHEATH_BODY):
            model.geom_rgba[geom] = [0.9, 0.8, 0.3, 0.3]
    model.vis.headlight.ambient[:] = 0.4
    camera = mujoco.MjvCamera()
    camera.lookat[:] = vessel.centerline.nodes.mean(axis=0)
    camera.distance = 1.3 * float(np.ptp(vessel.centerline.nodes, axis=0).max())
    camera.elevation, camera.azimuth = -90.0, 90.0
    option = mujoco.MjvOption()
    option.geomgroup[:] = [1, 1, 1, 1, 0, 0]  # hide the wire's stiffness cores (group 5)
    views = []
    with mujoco.Renderer(model, height=480, width=960) as renderer:
        renderer.update_scene(physics.data.ptr, camera=camera, scene_option=option)
        views.append(renderer.render())
        # Close-up of the tip: the 0.36 mm wire is a few pixels wide in the overview.
        camera.lookat[:] = physics.tip_position()
        camera.distance = 0.025
        renderer.update_scene(physics.data.ptr, camera=camera, scene_option=option)
        views.append(renderer.render())
    pixels = np.concatenate(views, axis=0)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(args.out, pixels)
    print(f"wrote {args.out} (tip at {np.round(physics.tip_position() * 1e3, 1)} mm)")


if __name__ == "__main__":
    main()
