"""The robot driver: a carriage that inserts and rotates the wire, and the introducer sheath.

The carriage is a body with a slide joint (insertion, along the insertion axis) and a hinge
about the same axis (rotation), each driven by a position servo. Commands are increments
[Δd, Δθ] per control step, limited by the speed limits and the ranges of this config; see
:meth:`sim4endor.physics.GuidewirePhysics.apply_increments`.

Only the wire that can be inside the sheath or the vessel is modelled, so the carriage starts
behind the inlet by the wire's length minus ``initial_protrusion`` and moves forward as it
inserts. The sheath, a tube of procedural convex pieces (boxes) around the insertion axis,
runs from behind the carriage's start to just inside the vessel inlet, so the wire outside
the vessel cannot buckle. The carriage itself has no colliding geoms and slides inside it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from sim4endor.errors import Sim4EndoRError
from sim4endor.models import constants as names


class DriverConfigError(Sim4EndoRError, ValueError):
    """Raised for inconsistent driver or sheath parameters; the message names the field."""


@dataclass(frozen=True)
class DriverConfig:
    """Robot carriage, servo and sheath parameters (SI units).

    Attributes:
        max_insertion: Largest insertion depth (m) beyond the start position.
        max_insertion_speed: Insertion speed limit (m/s).
        max_rotation: Rotation range is ±max_rotation (rad). Robotic PCI drivers roll the
            wire continuously; ten turns bound the commanded twist without letting a policy
            that drifts in one direction fail within an episode (measured: with two turns,
            DDPG and SAC runs that had solved Task A later failed on the limit).
        max_rotation_speed: Rotation speed limit (rad/s).
        initial_protrusion: Wire length beyond the sheath end at insertion 0 (m); must exceed
            the pre-bent tip so the tip starts free in the lumen.
        insertion_stiffness: Position-servo gain of the insertion axis (N/m).
        insertion_force_limit: Largest insertion force (N). Measured: with 2 N a wire pushed
            into a dead end buckled violently and left a 2 mm tube at dt 5 ms; 0.5 N (about
            the push force of manual PCI) stayed inside.
        rotation_stiffness: Position-servo gain of the rotation axis (N·m/rad).
        rotation_torque_limit: Largest torque (N·m).
        carriage_mass: Carriage mass (kg).
        carriage_inertia: Carriage moment of inertia about each axis (kg·m²).
        sheath_inner_radius: Inner radius of the sheath (m).
        sheath_wall_thickness: Wall thickness of the sheath (m).
        sheath_sectors: Number of convex pieces around the sheath axis.
        sheath_overlap: How far the sheath reaches past the inlet into the vessel (m).
    """

    max_insertion: float = 0.13
    max_insertion_speed: float = 0.03
    max_rotation: float = 20 * math.pi
    max_rotation_speed: float = math.pi
    initial_protrusion: float = 0.008
    insertion_stiffness: float = 500.0
    insertion_force_limit: float = 0.5
    rotation_stiffness: float = 0.05
    rotation_torque_limit: float = 0.01
    carriage_mass: float = 0.1
    carriage_inertia: float = 1e-5
    sheath_inner_radius: float = 0.0005
    sheath_wall_thickness: float = 0.0004
    sheath_sectors: int = 8
    sheath_overlap: float = 0.001

    def __post_init__(self) -> None:
        for field_name, value in vars(self).items():
            if not math.isfinite(value) or value <= 0:
                raise DriverConfigError(f"DriverConfig.{field_name} must be > 0, got {value}.")
        if self.sheath_sectors < 3:
            raise DriverConfigError(
                f"DriverConfig.sheath_sectors must be >= 3, got {self.sheath_sectors}."
            )

    def sheath_length(self, wire_length: float) -> float:
        """Length of the wire behind the inlet at insertion 0 (m)."""
        return wire_length - self.initial_protrusion

    def check_wire(self, wire_length: float, wire_radius: float, tip_length: float) -> None:
        """Raises :class:`DriverConfigError` if a wire cannot be driven by this config."""
        if self.sheath_length(wire_length) < self.max_insertion + 0.002:
            needed = self.max_insertion + 0.002 + self.initial_protrusion
            raise DriverConfigError(
                f"The wire ({wire_length * 1e3:.1f} mm) is too short for max_insertion "
                f"{self.max_insertion * 1e3:.1f} mm: the carriage would leave the sheath. Use "
                f"GuidewireConfig(length >= {needed * 1e3:.1f} mm) "
                "or a smaller DriverConfig.max_insertion."
            )
        if self.initial_protrusion <= tip_length:
            raise DriverConfigError(
                f"DriverConfig.initial_protrusion ({self.initial_protrusion * 1e3:.1f} mm) must "
                f"exceed the pre-bent tip length ({tip_length * 1e3:.1f} mm)."
            )
        if self.sheath_inner_radius <= wire_radius:
            raise DriverConfigError(
                f"DriverConfig.sheath_inner_radius ({self.sheath_inner_radius * 1e3:.2f} mm) must "
                f"exceed the wire radius ({wire_radius * 1e3:.2f} mm)."
            )


def add_driver(
    spec: mujoco.MjSpec, pos: np.ndarray, quat: np.ndarray, config: DriverConfig
) -> mujoco.MjsBody:
    """Adds the carriage (frame: insertion axis = local +x) and its servos; returns the body.

    Args:
        spec: The model spec to extend.
        pos: Carriage start position in the world (m).
        quat: Orientation of the carriage frame (w, x, y, z); local +x is the insertion axis.
        config: Driver parameters.
    """
    carriage = spec.worldbody.add_body(name=names.CARRIAGE_BODY, pos=list(pos), quat=list(quat))
    inertia = config.carriage_inertia
    carriage.mass = config.carriage_mass
    carriage.inertia = [inertia, inertia, inertia]
    # The centre of mass on the roll axis, at the body's origin. Left unset, MuJoCo 3.17's
    # compiler puts an explicit inertial frame at the body's *world* position (measured:
    # body_ipos == pos), which hangs the carriage's mass m·|pos⊥|² off the roll axis: 0.04
    # kg·m² in the stEVE anatomy (inlet 0.67 m from the origin), 4000x the carriage's own
    # inertia, so the 0.01 N·m roll servo turned the wire 0.06 rad of a commanded 1.9 in 1 s.
    carriage.ipos = [0.0, 0.0, 0.0]
    carriage.iquat = [1.0, 0.0, 0.0, 0.0]
    carriage.explicitinertial = True
    # Small insertion overshoot below 0 is allowed so the servo never fights a joint limit.
    carriage.add_joint(
        name=names.INSERTION_JOINT,
        type=mujoco.mjtJoint.mjJNT_SLIDE,
        axis=[1.0, 0.0, 0.0],
        range=[-0.002, config.max_insertion + 0.002],
    )
    carriage.add_joint(
        name=names.ROTATION_JOINT, type=mujoco.mjtJoint.mjJNT_HINGE, axis=[1.0, 0.0, 0.0]
    )
    # Critically damped servos: kv = 2 sqrt(kp m).
    for name, kp, mass, limit, ctrl_max in (
        (names.INSERTION_ACTUATOR, config.insertion_stiffness, config.carriage_mass,
         config.insertion_force_limit, config.max_insertion),
        (names.ROTATION_ACTUATOR, config.rotation_stiffness, config.carriage_inertia,
         config.rotation_torque_limit, config.max_rotation),
    ):
        actuator = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        ctrl_min = 0.0 if name == names.INSERTION_ACTUATOR else -ctrl_max
        actuator.set_to_position(kp=kp, kv=2.0 * math.sqrt(kp * mass))
        actuator.ctrlrange = [ctrl_min, ctrl_max]
        actuator.ctrllimited = True
        actuator.forcerange = [-limit, limit]
        actuator.forcelimited = True
    spec.add_numeric(name=names.MAX_INSERTION_SPEED, data=[config.max_insertion_speed])
    spec.add_numeric(name=names.MAX_ROTATION_SPEED, data=[config.max_rotation_speed])
    return carriage


def add_sheath(
    spec: mujoco.MjSpec, pos: np.ndarray, quat: np.ndarray, length: float, config: DriverConfig
) -> None:
    """Adds the static introducer sheath along local +x from ``pos`` for ``length`` metres.

    The sheath is ``sheath_sectors`` boxes whose inner faces are tangent to the inner radius
    (box–capsule collisions are analytic and cheaper than mesh hulls).
    """
    sheath = spec.worldbody.add_body(name=names.SHEATH_BODY, pos=list(pos), quat=list(quat))
    default = spec.find_default(names.SHEATH_CLASS)
    half_thickness = 0.5 * config.sheath_wall_thickness
    centre = config.sheath_inner_radius + half_thickness
    outer = config.sheath_inner_radius + config.sheath_wall_thickness
    half_width = outer * math.tan(math.pi / config.sheath_sectors)
    for k in range(config.sheath_sectors):
        angle = 2 * math.pi * k / config.sheath_sectors
        sheath.add_geom(
            default,
            name=f"{names.SHEATH_BODY}/wall_{k}",
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[0.5 * length, half_thickness, half_width],
            pos=[0.5 * length, centre * math.cos(angle), centre * math.sin(angle)],
            quat=[math.cos(angle / 2), math.sin(angle / 2), 0.0, 0.0],
        )
