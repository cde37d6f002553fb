"""Pushing the wire into a dead end: penetration into the hulls, and what too much force does.

:func:`push_test` drives the wire at the driver's full insertion speed into a branch's closed
end and keeps pushing at the driver's force limit (``DriverConfig.insertion_force_limit``;
the servo saturates once its target leads the carriage by limit / stiffness). It reports:

* penetration: the deepest overlap of a wire capsule with a wall hull, from MuJoCo's own
  contact distance (``contact.dist`` < 0; :meth:`GuidewirePhysics.wall_contact_distances`),
  so it is measured against the collision geometry, not the nominal lumen;
* the largest total wall force (N, read every physics step; on a blow-up, up to the step
  that diverged) and the largest mean of it over a control step (the quasi-static force, as
  the task's tip-force limit reads it: the force of one physics step includes the impacts of
  the wire's scaled mass), whether any wire point (its axis) left the nominal lumen by more than
  ``escape_tolerance`` (:func:`sim4endor.benches.validation.escape_depth`; a non-finite state
  counts as having left, since MuJoCo resets it and the wire can no longer be located), and
  whether the state became non-finite or MuJoCo warned;
* the wall force helical-buckling theory gives at the control step where the mean wall force
  peaked (:func:`helical_wall_force`).

A wire pushed far past its tip load buckles into a helix along the tube, and the wall holds
the helix: Lubinski's contact force per unit length is ``c F^2 / (4 E I)`` for an axial force
``F``, a radial clearance ``c`` and a flexural rigidity ``E I`` (A. Lubinski, W. S. Althouse and
J. L. Logan, "Helical buckling of tubing sealed in packers", J. Petroleum Technology 14(6):
655-670, 1962; R. F. Mitchell, "New concepts for helical buckling", SPE Drilling Engineering
3(3):303-310, 1988). Over the ~0.1 m of a soft wire in a 4 mm lumen that is many times the
push itself: at 2 N the workhorse (shaft E I 8.1e-6 N m^2) must press the wall with ~30 N.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from dm_control.rl import control

from sim4endor.benches.validation import escape_depth
from sim4endor.models.guidewire import GuidewireConfig
from sim4endor.models.scene import SceneConfig, config_for_vessel
from sim4endor.physics import GuidewirePhysics
from sim4endor.vessels import Vessel


@dataclass(frozen=True)
class PushResult:
    """Outcome of :func:`push_test` (SI units; penetration is positive when overlapping)."""

    force_limit: float
    max_penetration: float
    wire_radius: float
    max_wall_force: float
    max_mean_wall_force: float
    max_push: float
    max_escape: float
    left_lumen: bool
    finite: bool
    warnings: tuple[str, ...]
    sim_time: float
    stopped: bool = False
    helical_wall_force: float = 0.0

    @property
    def penetration_over_radius(self) -> float:
        """Deepest hull penetration in wire radii."""
        return self.max_penetration / self.wire_radius


def helical_wall_force(push: float, clearance: float, length: float, rigidity: float) -> float:
    """The wall force (N) that holds a wire pushed with ``push`` (N) and helically buckled
    over ``length`` (m) of a tube with radial ``clearance`` (m): the push, taken by the dead end,
    plus Lubinski's ``clearance push^2 / (4 rigidity)`` per unit length (module docstring)."""
    return push + clearance * push**2 * length / (4.0 * rigidity)


def _length_in_lumen(physics: GuidewirePhysics, vessel: Vessel) -> float:
    points = physics.wire_points()
    inside = vessel.centerline.tube_excesses(points) < 0.0
    segments = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return float(segments[inside[1:] & inside[:-1]].sum())


def push_physics(
    vessel: Vessel, wire: GuidewireConfig, force_limit: float, timestep: float | None = None,
    travel: float = 0.04,
) -> GuidewirePhysics:
    """The scene of ``vessel`` fitted by ``config_for_vessel``, with the driver's insertion
    force limit set to ``force_limit`` (N) and ``travel`` (m) of insertion beyond the deepest
    target, so that a soft wire buckling in the dead end cannot take up all the driver's
    travel before the servo pushes at its limit. The wire starts as in an episode
    (:meth:`GuidewirePhysics.from_model`): a tip wider than the inlet straightened in it."""
    config = config_for_vessel(vessel, SceneConfig(wire=wire, timestep=timestep), margin=travel)
    driver = dataclasses.replace(config.driver, insertion_force_limit=force_limit)
    return GuidewirePhysics.from_vessel(vessel, dataclasses.replace(config, driver=driver))


def push_test(
    vessel: Vessel, wire: GuidewireConfig, force_limit: float = 0.5, rotation: float = 0.0,
    duration: float = 6.0, control_period: float = 0.05, escape_tolerance: float | None = None,
    timestep: float | None = None, stop_push_force: float | None = None,
) -> PushResult:
    """Rolls the driver to ``rotation`` (rad), then inserts at full speed for ``duration`` s.

    The insertion target runs to the end of the driver's travel, past the branch's closed
    end, so the wire ends up pushed at ``force_limit``. ``escape_tolerance`` (default: the
    wire radius) is how far the wire axis may lie outside the nominal lumen (whose hulls sit
    up to a few tenths of a millimetre off it) before the wire counts as having left it.
    With ``stop_push_force`` the run ends (``stopped``) after the first control step whose
    driver push exceeds it: the navigation task's ``push_force`` failure, checked the same way.
    """
    physics = push_physics(vessel, wire, force_limit, timestep)
    tolerance = wire.radius if escape_tolerance is None else escape_tolerance
    substeps = max(1, round(control_period / physics.model.opt.timestep))
    v_ins = physics.max_speeds()[0]
    penetration = force = mean_force = escape = push = helical = 0.0
    clearance = float(np.median(vessel.centerline.radii)) - wire.radius
    finite, stopped, time = True, False, 0.0
    while physics.data.time < duration and not stopped:
        angle = physics.driver_targets()[1]
        if abs(angle - rotation) > 1e-9:
            physics.apply_increments(0.0, rotation - angle, control_period)
        else:
            physics.apply_increments(v_ins * control_period, 0.0, control_period)
        total = 0.0
        for _ in range(substeps):
            try:
                physics.step()
            except control.PhysicsError:  # raised on MuJoCo's instability warnings
                finite = False
                break
            distances = physics.wall_contact_distances()
            if distances.size:
                penetration = max(penetration, -float(distances.min()))
            total += physics.wall_contact_force()
            force = max(force, physics.wall_contact_force())
            time = float(physics.data.time)  # MuJoCo resets the time of a diverged state
        if total / substeps > mean_force:
            mean_force = total / substeps
            helical = helical_wall_force(physics.insertion_force(), clearance,
                                         _length_in_lumen(physics, vessel),
                                         wire.bending_stiffness)
        if not finite or not physics.is_finite():
            finite = False
            break
        escape = max(escape, escape_depth(physics, vessel))
        push = max(push, physics.insertion_force())
        stopped = stop_push_force is not None and physics.insertion_force() > stop_push_force
    return PushResult(
        force_limit=force_limit, max_penetration=penetration, wire_radius=wire.radius,
        max_wall_force=force, max_mean_wall_force=mean_force, max_push=push, max_escape=escape,
        left_lumen=escape > tolerance or not finite, finite=finite,
        warnings=tuple(physics.warnings()), sim_time=time, stopped=stopped,
        helical_wall_force=helical,
    )
