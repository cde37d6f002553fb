"""Wrong-branch starts: the wire already down a branch off the path to the target.

A start at the inlet with the pre-bent tip pointing roughly into the target's branch lets a
constant push solve the phantom tasks (docs/tasks/index.md, "Open-loop baselines"). A start
down another branch cannot be solved by pushing: the wire has to come back to the bifurcation,
turn and go on, and how far and how much depends on where the tip is.
"""

from __future__ import annotations

import math

from sim4endor.errors import Sim4EndoRError
from sim4endor.physics import GuidewirePhysics
from sim4endor.rewards import ManifoldDistance
from sim4endor.tasks.anatomy import Anatomy
from sim4endor.tasks.config import ActionConfig
from sim4endor.tasks.steering import FIXED_AIM, CenterlineSteering

#: Control steps the expert may take to get the tip off the path; the phantoms need 30-60.
MAX_DRIVE_STEPS = 400


class StartError(Sim4EndoRError, RuntimeError):
    """Raised when the wire could not be driven to a wrong-branch start."""


def off_path_distance(tip_to_target: float, tip_to_inlet: float, inlet_to_target: float
                      ) -> float:
    """How far (m, along the centerline) a point lies off the inlet-to-target path.

    On the path the two legs add up to the path's length; down a side branch both legs run
    back to the branching point, so the excess is twice the distance to it.
    """
    return 0.5 * (tip_to_target + tip_to_inlet - inlet_to_target)


def drive_off_path(
    physics: GuidewirePhysics,
    anatomy: Anatomy,
    distances: tuple[ManifoldDistance, ManifoldDistance, ManifoldDistance],
    depth: float,
    action: ActionConfig,
) -> tuple[float, float]:
    """Steers the wire towards a decoy node until its tip is ``depth`` off the target's path.

    Args:
        physics: The physics, with the wire at its start pose and the driver holding it.
        anatomy: The episode's anatomy.
        distances: Distance functions to the decoy, to the task's target and to the inlet.
        depth: How far (m) off the path to the target the tip must be.
        action: Scales the expert's actions into driver commands, as in an episode.

    Returns:
        The commanded (insertion m, rotation rad) at the end of the drive.

    Raises:
        StartError: If the tip is not ``depth`` off the path after :data:`MAX_DRIVE_STEPS`.
    """
    to_decoy, to_target, to_inlet = distances
    inlet_to_target = float(to_target.node_distances[to_inlet.target_node])
    steering = CenterlineSteering(FIXED_AIM)
    insertion, rotation = physics.driver_targets()
    for _ in range(MAX_DRIVE_STEPS):
        tip = physics.tip_position()
        if off_path_distance(to_target(tip), to_inlet(tip), inlet_to_target) >= depth:
            return insertion, rotation
        insert, rotate = steering.steer(physics, anatomy, to_decoy, action.max_rotation_step)
        insertion = max(0.0, insertion + float(insert) * action.max_insertion_step)
        rotation += float(rotate) * action.max_rotation_step
        step(physics, insertion, rotation, action)
    raise StartError(
        f"The expert did not get the tip {depth * 1e3:.1f} mm off the path to the target of "
        f"{anatomy.key} in {MAX_DRIVE_STEPS} control steps; lower "
        "InitialStateConfig.off_path_depth."
    )


def turn_in(physics: GuidewirePhysics, insertion: float, rotation: float, roll: float,
            action: ActionConfig) -> float:
    """Turns the carriage by ``roll`` (rad) at its top speed, insertion held; returns the
    commanded rotation at the end."""
    steps = math.ceil(abs(roll) / action.max_rotation_step)
    for k in range(1, steps + 1):
        step(physics, insertion, rotation + roll * k / steps, action)
    return rotation + roll


def step(physics: GuidewirePhysics, insertion: float, rotation: float, action: ActionConfig
         ) -> None:
    """Sets the driver's targets and advances one control step."""
    physics.set_driver_targets(insertion, rotation)
    physics.step(action.physics_steps(physics.timestep()))
