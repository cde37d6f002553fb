"""Measurements that validate the guidewire model (used by tests and the benchmark).

* :func:`cantilever` — static tip deflection of a clamped straight wire under a small tip
  load, against Euler–Bernoulli ``δ = F L³ / (3 E I)``.
* :func:`tapered_cantilever` — the same for a wire whose E·I varies along it (a tapered
  core), against the integrated Euler–Bernoulli deflection ``δ = F ∫ (L − x)² / EI(x) dx``.
* :func:`tapered_torsion` — the twist of the same clamped wire under an axial tip torque,
  against ``θ = T ∫ ds / GJ(s)`` (:func:`torsional_compliance`).
* :func:`tip_bend_direction` — the direction the pre-bent tip points to, about the shaft axis
  (for torque transmission: rotate the base, compare the tip's rotation).
* :func:`escape_depth` — how far any wire point is outside the lumen (distance from the
  centerline graph minus the local radius, positive part).
* :func:`inertia_factors` — the armature added to each joint against the real segment's
  inertia (the mass scaling multiplies it by ``mass_scale`` besides).
* :func:`steer` — the scripted rotate-then-insert policy towards a target; success is a
  manifold distance (tip projected on the centerline graph, distance along the graph, as the
  paper's reward) of at most ``tolerance``.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import mujoco
import numpy as np
from dm_control.rl import control
from numpy.typing import NDArray

from sim4endor.models import constants as names
from sim4endor.models.driver import DriverConfig
from sim4endor.models.guidewire import GuidewireConfig, segment_lengths
from sim4endor.models.scene import SceneConfig
from sim4endor.physics import GuidewirePhysics
from sim4endor.vessels import Vessel
from sim4endor.vessels.centerline import arc_lengths, points_along

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CantileverResult:
    """Outcome of :func:`cantilever` (SI units)."""

    deflection: float
    predicted: float
    free_length: float
    force: float

    @property
    def relative_error(self) -> float:
        """``|measured − predicted| / predicted``."""
        return abs(self.deflection - self.predicted) / self.predicted


def cantilever(
    wire: GuidewireConfig, timestep: float = 0.005, settle_time: float = 3.0,
    deflection_fraction: float = 0.01, soft_tip: bool = False,
) -> CantileverResult:
    """Clamps a straight wire (no pre-bend) and loads its tip sideways.

    With ``soft_tip`` the tip keeps its ``tip_stiffness_factor`` f and the prediction is
    ``F/(3EI)·(L³ − t³ + t³/f)`` for a tip of length t; otherwise the wire is uniform.

    Contacts are disabled (the sheath would hold the wire). The carriage's joints (slide and
    twist about the wire axis) cannot move under a lateral tip force, so the wire is clamped
    at the end of its first (welded) segment; the free
    length is measured from there. The load is chosen for a deflection of
    ``deflection_fraction`` of the free length (small-deflection theory holds).
    """
    factor = wire.tip_stiffness_factor if soft_tip else 1.0
    straight = dataclasses.replace(wire.straightened(), tip_stiffness_factor=factor)
    free_length = straight.length - float(segment_lengths(straight)[0])
    ei = straight.bending_stiffness
    force = 3 * ei * deflection_fraction / free_length**2
    deflection = _loaded_tip_deflection(straight, force, timestep, settle_time)
    tip = straight.tip_length
    compliance = (free_length**3 - tip**3 + tip**3 / factor) / (3 * ei)
    return CantileverResult(deflection, force * compliance, free_length, force)


def euler_bernoulli_deflection(wire: GuidewireConfig, free_length: float, force: float) -> float:
    """Small-deflection tip deflection (m) of the wire's distal ``free_length``, clamped, under
    a lateral tip ``force`` (N): ``F ∫₀ᴸ (L − x)² / EI(x) dx`` (unit-load method; x from the
    clamp), integrated with scipy's adaptive quadrature at the profile's kinks."""
    from scipy.integrate import quad

    kinks = [free_length - s for s, _ in wire.core_profile or () if 0 < s < free_length]
    kinks.append(free_length - wire.tip_length)
    value, _ = quad(
        lambda x: (free_length - x) ** 2 / float(wire.flexural_rigidity(free_length - x)),
        0.0, free_length, points=sorted(k for k in kinks if 0 < k < free_length), limit=200,
    )
    return force * value


def tapered_cantilever(
    wire: GuidewireConfig, timestep: float = 0.005, settle_time: float = 3.0,
    deflection_fraction: float = 0.01,
) -> CantileverResult:
    """Clamps the straightened wire with its E·I(s) (core profile, tip factor) and loads its
    tip sideways; the prediction is :func:`euler_bernoulli_deflection`.

    As :func:`cantilever`: contacts off, the free length runs from the end of the first
    (clamped) segment, and the load gives a deflection of ``deflection_fraction`` of it.
    """
    straight = wire.straightened()
    free_length = straight.length - float(segment_lengths(straight)[0])
    unit = euler_bernoulli_deflection(straight, free_length, 1.0)
    force = deflection_fraction * free_length / unit
    deflection = _loaded_tip_deflection(straight, force, timestep, settle_time)
    return CantileverResult(deflection, force * unit, free_length, force)


def torsional_compliance(wire: GuidewireConfig, near: float, far: float) -> float:
    """``∫ ds / GJ(s)`` (rad per N·m) over the wire from ``near`` to ``far`` metres from its
    distal end: the twist a torque passed along that stretch winds into it (scipy's
    adaptive quadrature, split at the profile's kinks)."""
    from scipy.integrate import quad

    kinks = [s for s, _ in wire.core_profile or () if near < s < far]
    if near < wire.tip_length < far:
        kinks.append(wire.tip_length)
    value, _ = quad(lambda s: 1.0 / float(wire.torsional_rigidity(s)), near, far,
                    points=sorted(kinks) or None, limit=200)
    return float(value)


@dataclass(frozen=True)
class TorsionResult:
    """Outcome of :func:`tapered_torsion` (SI units: rad, m, N·m)."""

    twist: float
    predicted: float
    free_length: float
    torque: float

    @property
    def relative_error(self) -> float:
        """``|measured − predicted| / predicted``."""
        return abs(self.twist - self.predicted) / self.predicted


def tapered_torsion(
    wire: GuidewireConfig, timestep: float = 0.005, settle_time: float = 3.0,
    twist: float = 0.05,
) -> TorsionResult:
    """Clamps the straightened wire with its G·J(s) and twists its distal segment by an axial
    torque; the prediction is ``T`` times :func:`torsional_compliance` over the free length.

    As :func:`tapered_cantilever`: contacts off, the free length runs from the end of the first
    (clamped) segment, and the torque gives about ``twist`` rad. The twist is read between the
    clamped and the distal segment's frames, so the carriage's own rotation servo is not in it.
    """
    straight = wire.straightened()
    free_length = straight.length - float(segment_lengths(straight)[0])
    unit = torsional_compliance(straight, 0.0, free_length)
    torque = twist / unit
    physics = _clamped_free_wire(straight, timestep)
    model, data = physics.model.ptr, physics.data.ptr
    bodies = physics.wire_body_ids()
    clamp, tip = int(bodies[0]), int(bodies[-1])
    for _ in range(round(settle_time / model.opt.timestep)):
        data.xfrc_applied[tip, 3:] = torque * data.xmat[tip].reshape(3, 3)[:, 0]
        physics.step()
    relative = np.zeros(4)
    mujoco.mju_mulQuat(relative, _conjugate(data.xquat[clamp]), data.xquat[tip])
    # The segments' x axes run along the wire, so the relative rotation is a roll about x.
    measured = 2.0 * math.atan2(relative[1], relative[0])
    return TorsionResult(measured, torque * unit, free_length, torque)


def _conjugate(quat: FloatArray) -> FloatArray:
    out = np.zeros(4)
    mujoco.mju_negQuat(out, quat)
    return out


def _clamped_free_wire(straight: GuidewireConfig, timestep: float) -> GuidewirePhysics:
    """The straight wire on its driver, far enough out of the sheath, with contacts off."""
    protrusion = max(DriverConfig().initial_protrusion, straight.tip_length + 0.003)
    driver = DriverConfig(
        initial_protrusion=protrusion, max_insertion=straight.length - protrusion - 0.003
    )
    physics = GuidewirePhysics.from_vessel(
        None, SceneConfig(wire=straight, driver=driver, timestep=timestep)
    )
    physics.model.ptr.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT  # free of the sheath
    return physics


def _loaded_tip_deflection(
    straight: GuidewireConfig, force: float, timestep: float, settle_time: float
) -> float:
    physics = _clamped_free_wire(straight, timestep)
    model, data = physics.model.ptr, physics.data.ptr
    start = physics.tip_position()
    tip_site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, names.WIRE_TIP_SITE)
    tip_body = int(model.site_bodyid[tip_site])
    for _ in range(round(settle_time / model.opt.timestep)):
        data.qfrc_applied[:] = 0.0
        mujoco.mj_applyFT(
            model, data, np.array([0.0, 0.0, force]), np.zeros(3), physics.tip_position(),
            tip_body, data.qfrc_applied,
        )
        physics.step()
    return float(physics.tip_position()[2] - start[2])


def drive_to(
    physics: GuidewirePhysics, insertion: float, rotation: float, settle: float = 0.0,
    control_period: float = 0.05,
) -> None:
    """Moves the driver to (insertion m, rotation rad) at its speed limits, then waits.

    Targets move by increments no faster than the driver's speed limits, as a policy's
    would; ``settle`` seconds of holding follow.
    """
    substeps = max(1, round(control_period / physics.model.opt.timestep))
    while True:
        ins, rot = physics.driver_targets()
        if abs(ins - insertion) < 1e-9 and abs(rot - rotation) < 1e-9:
            break
        physics.apply_increments(insertion - ins, rotation - rot, control_period)
        physics.step(substeps)
    physics.step(round(settle / physics.model.opt.timestep))


def tip_bend_direction(physics: GuidewirePhysics, back: float = 0.008) -> float:
    """Returns the angle (rad) of the tip's bend about the local shaft axis.

    The shaft axis is the chord of the wire between ``2·back`` and ``back`` metres from the
    tip; the bend is the tip's offset from that axis, its angle measured in a frame built
    from world +z projected orthogonal to the axis (any fixed rule works for differences).
    """
    points = physics.wire_points()
    s_tip = arc_lengths(points)[-1]
    base, mid = points_along(points, np.array([s_tip - 2 * back, s_tip - back]))
    axis = (mid - base) / np.linalg.norm(mid - base)
    offset = points[-1] - mid
    offset -= axis * np.dot(offset, axis)
    ref = np.array([0.0, 0.0, 1.0]) - axis * axis[2]
    ref /= np.linalg.norm(ref)
    other = np.cross(axis, ref)
    return float(math.atan2(np.dot(offset, other), np.dot(offset, ref)))


def escape_depth(physics: GuidewirePhysics, vessel: Vessel, offset: float = 0.0) -> float:
    """Largest distance (m) of a wire point outside the lumen; 0 when all are inside.

    Points behind the inlet plane (in the sheath) are not part of the vessel and are skipped.
    ``offset`` is added to every point's distance from the centerline: the wire radius gives
    how far the wire's surface (not its axis) reaches past the lumen surface.
    """
    points = physics.wire_points()
    ahead = (points - vessel.inlet_position) @ vessel.inlet_direction > 0
    worst = 0.0
    graph = vessel.centerline
    for point in points[ahead]:
        projection = graph.project(point)
        radius = graph.radius_at_projection(projection)
        worst = max(worst, projection.distance + offset - radius)
    return worst


@dataclass(frozen=True)
class SteerResult:
    """Outcome of one :func:`steer` episode."""

    success: bool
    final_distance: float
    sim_time: float
    wall_time: float
    cpu_time: float
    max_escape: float
    healthy: bool


def steer(
    physics: GuidewirePhysics, vessel: Vessel, target: str, rotation: float, speed: float,
    tolerance: float = 0.001, time_limit: float = 12.0, control_period: float = 0.05,
) -> SteerResult:
    """Runs the scripted policy: rotate to ``rotation`` (rad), then insert at ``speed`` (m/s).

    Stops at success (manifold distance of the tip to ``target`` <= ``tolerance``), when the
    driver reaches its insertion limit and has stalled, or at ``time_limit`` s. ``wall_time``
    and ``cpu_time`` (this thread's CPU time: the wall time a dedicated core would need, on a
    shared machine) count only stepping and the policy, not the distance bookkeeping.
    """
    graph = vessel.centerline
    to_target = graph.geodesic_from(graph.labels[target])
    with physics.reset_context():
        pass
    substeps = max(1, round(control_period / physics.model.opt.timestep))
    wall, cpu, worst, distance = 0.0, 0.0, 0.0, math.inf
    while physics.data.time < time_limit:
        start, start_cpu = time.perf_counter(), time.thread_time()
        angle = physics.driver_targets()[1]
        if abs(angle - rotation) > 1e-9:
            physics.apply_increments(0.0, rotation - angle, control_period)
        else:
            physics.apply_increments(speed * control_period, 0.0, control_period)
        try:
            physics.step(substeps)
        except control.PhysicsError:  # dm_control raises on MuJoCo's instability warnings
            break
        wall += time.perf_counter() - start
        cpu += time.thread_time() - start_cpu
        if not physics.is_finite():
            break
        worst = max(worst, escape_depth(physics, vessel))
        distance = graph.distance_along(physics.tip_position(), to_target)
        if distance <= tolerance:
            break
    healthy = physics.is_finite() and not physics.warnings()
    return SteerResult(
        success=healthy and distance <= tolerance, final_distance=distance,
        sim_time=float(physics.data.time), wall_time=wall, cpu_time=cpu,
        max_escape=worst, healthy=healthy,
    )


@dataclass(frozen=True)
class InertiaFactors:
    """How much inertia the quasi-static settings add to a wire (ratios to the real wire).

    Attributes:
        mass_scale: The factor on every segment's mass and inertia (``GuidewireConfig``).
        bending: (smallest, largest) over the ball joints of armature / the physical moment of
            inertia of the joint's segment about the joint, for bending (about an axis across
            the segment through the joint).
        twist: The same for twisting (about the segment's own axis, ``m r² / 2``).
    """

    mass_scale: float
    bending: tuple[float, float]
    twist: tuple[float, float]


def inertia_factors(wire: GuidewireConfig) -> InertiaFactors:
    """Reads the compiled wire: each joint's armature (``stiffness × armature_time²``) against
    its segment's real (unscaled) inertia about the joint, for bending and for twist."""
    physics = GuidewirePhysics.from_vessel(None, SceneConfig(wire=wire))
    model = physics.model.ptr
    bending, twist = [], []
    for body in physics._indices().wire_bodies[1:]:
        dof = int(model.jnt_dofadr[model.body_jntadr[body]])
        armature = float(model.dof_armature[dof])
        mass = float(model.body_mass[body]) / wire.mass_scale
        # Principal moments about the COM: the thin capsule's smallest is about its axis.
        inertia = model.body_inertia[body] / wire.mass_scale
        offset = float(np.linalg.norm(model.body_ipos[body]))  # joint at the body origin
        bending.append(armature / (float(np.max(inertia)) + mass * offset**2))
        twist.append(armature / float(np.min(inertia)))
    return InertiaFactors(
        wire.mass_scale, (min(bending), max(bending)), (min(twist), max(twist))
    )
