"""Torque transmission through a tortuous path: the lag and the whip of the tip's roll.

A wire lying in bends does not turn its tip as its proximal end is turned: friction and the
shaft's twist store the roll and release it in a jump (whip). :func:`bent_tube_physics` builds
a small test lumen, a 2 mm-radius tube along an S of two 90° bends (centerline bend radius
8 mm) in the x–y plane, from rings of boxes (box–capsule contacts are analytic and fast);
:func:`roll_test` inserts a wire through both bends and turns the driver through 360°.

Definitions (the benchmark's ``torque_lag_deg`` and ``whip``):

* lag: the commanded roll minus the roll of the tip's bend direction
  (:func:`sim4endor.benches.validation.tip_bend_direction`, unwrapped, relative to its value
  before the turn) at the moment the command reaches 360°; ``residual_deg`` is the same
  after ``hold`` seconds of holding;
* whip: the largest tip roll speed over any ``window`` (50 ms, one control step) during the
  turn and the hold, divided by the commanded roll speed; ``max_jump_deg`` is the largest tip
  roll within one window.

With a ``grip`` the wire's roll is resisted just behind its shaped tip by a friction torque, as
where a lesion or a tight ostium holds it. That torque no longer comes from the wire's own
bending stiffness, as the bends' friction does, so the wind-up it adds (the lag with the grip
minus the lag without) is ``grip · ∫ ds / GJ(s)`` from the gripped segment to the clamp
(``predicted_windup_deg``; measured by :func:`grip_windup_deg`): a stiffer core transmits
it with less lag. Without a grip the
bends' friction torque scales with the core's E·I and the wind-up with E·I / G·J = 1 + ν, so
the lag does not depend on the core (docs/guidewire.md).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np
from dm_control.mujoco import wrapper
from numpy.typing import NDArray

from sim4endor.benches.validation import drive_to, tip_bend_direction, torsional_compliance
from sim4endor.models import constants as names
from sim4endor.models.driver import DriverConfig
from sim4endor.models.guidewire import GuidewireConfig, segment_lengths
from sim4endor.models.scene import SceneConfig, build_spec, starts_straight
from sim4endor.physics import GuidewirePhysics

FloatArray = NDArray[np.float64]

#: Test lumen: inner radius, centerline bend radius, straight lengths around the bends (m).
TUBE_RADIUS = 0.002
BEND_RADIUS = 0.008
STRAIGHTS = (0.006, 0.006, 0.024)
#: Insertion that puts the tip 20 mm into the last straight (m).
INSERTION = STRAIGHTS[0] + STRAIGHTS[1] + math.pi * BEND_RADIUS + 0.020 - 0.008
DRIVER = DriverConfig(max_insertion=INSERTION + 0.002)
#: Grip of the gripped roll (N·m): the friction torque of a 0.56 N squeeze, just under the
#: tasks' 0.6 N tip-force failure, on a 0.014" jacket (radius 0.178 mm) at the hydrophobic
#: coat's friction of 0.1. No published torque with which a lesion holds a wire was found;
#: this is a load of that order, the same for every wire.
GRIP = 1e-5


def s_path(step: float = 0.002) -> FloatArray:
    """Centerline points (m) of the test lumen: +x, a 90° bend to +y, a 90° bend back to +x."""
    points = [np.array([-0.001, 0.0, 0.0])]
    heading, position = 0.0, np.zeros(3)
    for straight, turn in zip(STRAIGHTS, (1.0, -1.0, 0.0), strict=True):
        direction = np.array([math.cos(heading), math.sin(heading), 0.0])
        count = max(1, math.ceil(straight / step))
        for k in range(1, count + 1):
            points.append(position + direction * straight * k / count)
        position = points[-1]
        if turn:
            count = math.ceil(0.5 * math.pi * BEND_RADIUS / step)
            centre = position + BEND_RADIUS * turn * np.array([-direction[1], direction[0], 0])
            for k in range(1, count + 1):
                angle = heading + turn * 0.5 * math.pi * k / count
                radial = np.array([math.sin(angle), -math.cos(angle), 0.0]) * turn
                points.append(centre + BEND_RADIUS * radial)
            heading += turn * 0.5 * math.pi
            position = points[-1]
    return np.array(points)


def add_tube(
    spec: mujoco.MjSpec, path: FloatArray, radius: float = TUBE_RADIUS, sectors: int = 12,
    thickness: float = 0.0008,
) -> None:
    """Adds a tube of box rings along ``path`` to the world body (static wall geoms).

    The boxes collide like vessel hulls (contype 2, conaffinity 1; world-body geoms, so the
    wall contact sensors see them); each is lengthened by its chord's outer arc plus 0.3 mm
    so the rings overlap on the outside of a bend.
    """
    half_width = (radius + thickness) * math.tan(math.pi / sectors)
    for index, (start, end) in enumerate(itertools.pairwise(path)):
        axis = (end - start) / np.linalg.norm(end - start)
        normal = np.cross([0.0, 0.0, 1.0], axis)
        normal /= np.linalg.norm(normal)
        half_length = 0.5 * np.linalg.norm(end - start) * (1 + (radius + thickness)
                                                           / BEND_RADIUS) + 0.0003
        for k in range(sectors):
            phi = 2 * math.pi * k / sectors
            radial = math.cos(phi) * normal + math.sin(phi) * np.array([0.0, 0.0, 1.0])
            quat = np.zeros(4)
            frame = np.column_stack([axis, radial, np.cross(axis, radial)])
            mujoco.mju_mat2Quat(quat, frame.ravel())
            spec.worldbody.add_geom(
                name=f"tube/{index:03d}_{k:02d}", type=mujoco.mjtGeom.mjGEOM_BOX,
                size=[half_length, 0.5 * thickness, half_width],
                pos=list(0.5 * (start + end) + radial * (radius + 0.5 * thickness)),
                quat=list(quat), contype=2, conaffinity=1, condim=3, friction=[0.1, 0.005, 1e-4],
                solref=[0.004, 1.0], solimp=[0.99, 0.999, 0.0001, 0.5, 2.0], group=3,
                rgba=[0.8, 0.3, 0.3, 0.25],
            )


def bench_wire(wire: GuidewireConfig) -> GuidewireConfig:
    """``wire`` shortened to what the insertion needs (fewer segments, faster steps)."""
    return dataclasses.replace(
        wire, length=DRIVER.max_insertion + DRIVER.initial_protrusion + 0.003
    )


def bent_tube_physics(wire: GuidewireConfig, timestep: float | None = None) -> GuidewirePhysics:
    """The :func:`bench_wire` of ``wire`` on its driver at the inlet (origin, +x) of the
    S-shaped test lumen.

    It starts as in an episode (:meth:`GuidewirePhysics.from_model`): a tip wider than the
    tube straightened in it.
    """
    wire = bench_wire(wire)
    spec = build_spec(None, SceneConfig(wire=wire, driver=DRIVER, timestep=timestep))
    add_tube(spec, s_path())
    spec.numeric(names.TIP_STRAIGHT_AT_START).data = [float(starts_straight(wire, TUBE_RADIUS))]
    return GuidewirePhysics.from_model(wrapper.MjModel(spec.compile()))


def held_tips(wire: GuidewireConfig, holds: Sequence[float],
              timestep: float | None = None) -> list[FloatArray]:
    """Inserts ``wire`` through both bends, then holds the driver still: the tip's position
    (m) after each successive hold of ``holds`` seconds.

    A position is non-finite once the simulation is unhealthy (non-finite state or a MuJoCo
    warning), so a difference with it never passes for a small shift.
    """
    physics = bent_tube_physics(wire, timestep)
    drive_to(physics, INSERTION, 0.0)
    tips = []
    for hold in holds:
        drive_to(physics, INSERTION, 0.0, settle=hold)
        healthy = physics.is_finite() and not physics.warnings()
        tips.append(physics.tip_position() if healthy else np.full(3, np.inf))
    return tips


@dataclass(frozen=True)
class RollResult:
    """Outcome of :func:`roll_test` (degrees; ``whip`` is a ratio of speeds).

    ``command_deg`` and ``tip_deg`` are the commanded roll and the tip's, once per ``window``
    from the start of the turn (empty if the simulation diverged).
    """

    lag_deg: float
    residual_deg: float
    whip: float
    max_jump_deg: float
    tip_in_last_straight: bool
    healthy: bool
    predicted_windup_deg: float = 0.0
    command_deg: tuple[float, ...] = ()
    tip_deg: tuple[float, ...] = ()


def roll_test(
    wire: GuidewireConfig, speed: float = math.pi / 2, hold: float = 2.0,
    window: float = 0.05, timestep: float | None = None, grip: float = 0.0,
) -> RollResult:
    """Inserts ``wire`` through both bends, then turns the driver 360° at ``speed`` rad/s.

    See the module docstring for the definitions. The bend direction's reference chord runs
    between b and 2b from the wire's end, b = tip length + 2 mm, so it measures the pre-bent
    tip against the shaft just behind it, not the shaft's curve further back.

    ``grip`` (N·m) resists the roll of the wire's last segment before its shaped part: the
    whole torque once that segment rolls at ``speed``, in proportion below it. (A steeper,
    Coulomb-like brake, applied explicitly each step, rings on the light tip segments.)
    """
    physics = bent_tube_physics(wire, timestep)
    shape_start = physics.shape_start_index()
    gripped = int(physics.wire_body_ids()[shape_start - 1])
    bench = bench_wire(wire)
    lengths = segment_lengths(bench)
    # From the gripped segment's middle (the grip acts on it as a whole) to the clamp at the
    # end of the first, welded segment, both counted from the tip.
    near = float(lengths[shape_start:].sum() + 0.5 * lengths[shape_start - 1])
    windup = grip * torsional_compliance(bench, near, float(lengths[1:].sum()))
    back = wire.tip_length + 0.002
    drive_to(physics, INSERTION, 0.0, settle=0.5)
    tip_x = float(physics.tip_position()[0])
    # The bend direction's reference chord lies in the last straight.
    last_straight = tip_x > STRAIGHTS[0] + 2 * BEND_RADIUS + 2 * back
    substeps = max(1, round(window / physics.model.opt.timestep))
    start = tip_bend_direction(physics, back)
    angles, commands = [0.0], [0.0]
    turn_steps = round(2 * math.pi / speed / window)
    for k in range(1, turn_steps + round(hold / window) + 1):
        command = 2 * math.pi * min(k, turn_steps) / turn_steps
        physics.set_driver_targets(INSERTION, command)
        for _ in range(substeps):
            if grip:
                _resist_roll(physics, gripped, grip, speed)
            physics.step()
        if not physics.is_finite():
            return RollResult(math.inf, math.inf, math.inf, math.inf, last_straight, False,
                              math.degrees(windup))
        roll = tip_bend_direction(physics, back) - start
        # Unwrap against the previous reading.
        roll += 2 * math.pi * round((angles[-1] - roll) / (2 * math.pi))
        angles.append(roll)
        commands.append(command)
    tip, command_arr = np.degrees(angles), np.degrees(commands)
    jumps = np.abs(np.diff(tip))
    return RollResult(
        lag_deg=float(command_arr[turn_steps] - tip[turn_steps]),
        residual_deg=float(command_arr[-1] - tip[-1]),
        whip=float(jumps.max() / math.degrees(speed * window)),
        max_jump_deg=float(jumps.max()),
        tip_in_last_straight=last_straight,
        healthy=not physics.warnings(),
        predicted_windup_deg=math.degrees(windup),
        command_deg=tuple(command_arr.tolist()),
        tip_deg=tuple(tip.tolist()),
    )


def grip_windup_deg(free: RollResult, gripped: RollResult, window: float = 0.05,
                    after: float = 1.0) -> float:
    """The lag a grip adds to a roll (degrees): the gripped run's lag minus the free run's,
    averaged over the turn from ``after`` seconds to its end (both runs of :func:`roll_test`
    with the same wire and ``window``). The lag swings by tens of degrees as the tip's bend
    turns through the bends' planes, so one reading, such as the lag at the turn's end,
    carries that swing's differences too; the average over the turn does not."""
    command = np.asarray(free.command_deg)
    if not command.size or not gripped.tip_deg:
        return math.inf  # a run that diverged
    end = int(np.argmax(command >= command.max() - 1e-9))
    added = np.asarray(free.tip_deg) - np.asarray(gripped.tip_deg)  # same commands in both
    return float(added[round(after / window):end + 1].mean())


def _resist_roll(physics: GuidewirePhysics, body: int, torque: float, speed: float) -> None:
    """Sets ``body``'s applied torque against its roll about its own (x) axis: ``torque``
    N·m at ``speed`` rad/s or more, in proportion below."""
    model, data = physics.model.ptr, physics.data.ptr
    velocity = np.zeros(6)
    # World-oriented: a body's local frame here would be its inertial one, whose axes
    # need not be the segment's.
    mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body, velocity, 0)
    axis = data.xmat[body].reshape(3, 3)[:, 0]
    roll_rate = float(velocity[:3] @ axis)
    data.xfrc_applied[body, 3:] = -torque * float(np.clip(roll_rate / speed, -1.0, 1.0)) * axis
