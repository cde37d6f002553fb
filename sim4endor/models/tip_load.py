"""The manufacturer's tip-load test, in beam theory and in MuJoCo.

Convention (the one this package rates and validates against): the straight wire is held
``free_length`` = 10 mm from its distal end and its tip is pushed perpendicular against a
fixed plate; the tip load is the force at which that 10 mm column buckles, in gram-force
(1 gf = 9.80665 mN). Coronary tip loads are quoted as the "weight needed to be applied to
bend / buckle the tip" (A. Hoye, *The language of CTO interventions*,
https://slideplayer.com./amp/1525275); the 10 mm holding distance is the one issue 15
names. The plate is frictionless, so the tip may slide on it and the column is
clamped-free: for a uniform core ``P = π² E I / (4 L²)``. A plate that pinned the tip would
give 8.2x more, so the convention matters as much as the core.

* :func:`buckling_load` — the buckling load of the continuous rod with the wire's E·I(s)
  (clamped-free column, solved as a Sturm–Liouville eigenproblem by finite differences).
* :func:`force_deflection` — the same test in MuJoCo as a bench records it: the wire's
  distal ``free_length`` is pushed by a kinematic clamp against a frictionless plate in
  small steps, each held until the wire has settled, and the plate force of every step
  makes the settled force–deflection curve.
* :func:`simulate_tip_load` — the tip load read on that curve where the column's ends have
  come 5 % of ``free_length`` closer (the buckled tip is visibly bent).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import NDArray
from scipy.linalg import eigh_tridiagonal

from sim4endor.models import constants as names
from sim4endor.models.guidewire import GuidewireConfig, add_guidewire, segment_lengths
from sim4endor.models.scene import base_spec, set_wire_options

#: Standard gravity: 1 gram-force in newtons is 1e-3 x this.
GRAVITY = 9.80665
_CLAMP_JOINT = "tip_load/clamp"
#: The clamp's mass (kg): far above the wire's, so the solver bends the wire rather than
#: accelerating the (prescribed) clamp, as it would for an immovable mocap body.
_CLAMP_MASS = 1e4
#: The tip-load test's free length: the wire is held 10 mm from its end (m).
TEST_FREE_LENGTH = 0.010


def gram_force(newtons: float) -> float:
    """Converts a force in N to gram-force."""
    return newtons / (1e-3 * GRAVITY)


def column_buckling_load(
    rigidity: Callable[[NDArray[np.float64]], NDArray[np.float64]], length: float,
    nodes: int = 2000,
) -> float:
    """Lowest buckling load (N) of a clamped-free column of E·I ``rigidity(x)``.

    ``x`` is the distance from the clamp (m). With θ the slope, equilibrium of the deflected
    column under an axial end load P gives ``(EI θ')' + P θ = 0`` with ``θ(0) = 0`` and
    ``θ'(L) = 0`` (no moment at the free end); P is the smallest eigenvalue of the
    finite-volume discretisation ``K θ = P M θ`` (second order in ``1 / nodes``).
    """
    h = length / nodes
    # E·I of the cells between consecutive nodes 0..nodes (node 0 is the clamp).
    ei = rigidity(h * (np.arange(nodes, dtype=np.float64) + 0.5))
    diagonal = np.empty(nodes)
    diagonal[:-1] = (ei[:-1] + ei[1:]) / h**2
    diagonal[-1] = ei[-1] / h**2
    off = -ei[1:] / h**2
    mass = np.ones(nodes)
    mass[-1] = 0.5  # the free end's half cell
    scale = 1.0 / np.sqrt(mass)
    values = eigh_tridiagonal(
        diagonal * scale**2, off * scale[:-1] * scale[1:], eigvals_only=True,
        select="i", select_range=(0, 0),
    )
    return float(values[0])


def buckling_load(wire: GuidewireConfig, free_length: float = TEST_FREE_LENGTH) -> float:
    """Tip load (N) of ``wire`` by beam theory: its distal ``free_length`` as a clamped-free
    column with the wire's E·I(s) (core profile and tip softening included)."""
    return column_buckling_load(
        lambda x: wire.flexural_rigidity(free_length - x), free_length
    )


def derive_tip_core_diameter(
    wire: GuidewireConfig, tip_load: float, ribbon: float, taper_end: float,
    shaft_diameter: float, free_length: float = TEST_FREE_LENGTH,
) -> float:
    """The distal core diameter (m) that gives ``wire`` a rated ``tip_load`` (N).

    The core profile is a uniform ribbon over the distal ``ribbon`` (m), a linear taper to
    ``shaft_diameter`` at ``taper_end`` (m from the tip), then the shaft; the distal diameter
    is found by bisection on :func:`buckling_load` (which grows monotonically with it). This
    is how the catalogue's profiles (``wires.toml``) were derived.
    """

    def load(diameter: float) -> float:
        profile = ((0.0, diameter), (ribbon, diameter), (taper_end, shaft_diameter))
        trial = dataclasses.replace(
            wire, core_diameter=shaft_diameter, core_profile=profile, tip_stiffness_factor=1.0
        )
        return buckling_load(trial, free_length)

    low, high = 1e-7, shaft_diameter
    while high - low > 1e-11:
        middle = 0.5 * (low + high)
        low, high = (low, middle) if load(middle) > tip_load else (middle, high)
    return 0.5 * (low + high)


@dataclass(frozen=True, eq=False)
class ForceDeflection:
    """A settled force–deflection curve of the tip-load test, one point per clamp position.

    Attributes:
        clamp: Clamp advance from the start (m); the tip starts just off the plate.
        shortening: End-to-end shortening of the free length, as a fraction of it.
        force: Plate force, settled (N).
        lateral: Sideways deflection of the tip from the clamp's axis (m).
        free_length: The free length at the start (m).
    """

    clamp: NDArray[np.float64]
    shortening: NDArray[np.float64]
    force: NDArray[np.float64]
    lateral: NDArray[np.float64]
    free_length: float

    def at(self, shortening: float, values: NDArray[np.float64]) -> float:
        """``values`` interpolated at a relative ``shortening`` (linear between points)."""
        return float(np.interp(shortening, self.shortening, values))


@dataclass(frozen=True)
class TipLoadResult:
    """Outcome of :func:`simulate_tip_load` (SI units).

    Attributes:
        force: Plate force at the read-out shortening (N), interpolated on the curve.
        predicted: Beam-theory buckling load of the same column (N).
        shortening: The read-out's end-to-end shortening of the free length (m).
        free_length: Free length from the clamp to the tip (m).
        lateral: Sideways deflection of the tip at the read-out (m): the column has buckled.
        curve: The settled force–deflection curve the force was read on.
    """

    force: float
    predicted: float
    shortening: float
    free_length: float
    lateral: float
    curve: ForceDeflection

    @property
    def force_gf(self) -> float:
        """``force`` in gram-force."""
        return gram_force(self.force)

    @property
    def peak_before_read(self) -> float:
        """The largest settled plate force (N) before the read-out: above :attr:`force` only
        where the curve overshoots at first contact (a spike), never otherwise."""
        before = self.curve.shortening <= self.shortening / self.free_length
        return float(np.max(self.curve.force[before], initial=0.0))


def tested_wire(
    wire: GuidewireConfig, free_length: float = TEST_FREE_LENGTH, clamp_length: float = 0.002
) -> tuple[GuidewireConfig, NDArray[np.float64]]:
    """The wire as tested, and its segment lengths (proximal first).

    The distal ``free_length`` keeps the segments the wire has in a vessel (the segment
    that straddles ``free_length`` is cut there), behind a rigid ``clamp_length`` segment,
    so the test measures the discretisation the navigation tasks use. The wire is straight
    but for a 1° imperfection over its tip: a perfectly straight simulated column would not
    buckle.
    """
    distal = segment_lengths(wire)[::-1]  # tip first
    ends = np.cumsum(distal)
    kept = distal[: int(np.searchsorted(ends, free_length - 1e-9)) + 1].copy()
    kept[-1] -= float(np.sum(kept)) - free_length
    lengths = np.concatenate([[clamp_length], kept[::-1]])
    tested = dataclasses.replace(
        wire.straightened(math.radians(1.0)), length=float(np.sum(lengths))
    )
    return tested, lengths


def _scene(
    wire: GuidewireConfig, lengths: NDArray[np.float64], timestep: float | None, gap: float
) -> mujoco.MjModel:
    spec = base_spec()
    set_wire_options(spec, wire, timestep)
    # A body on a slide joint whose position the test prescribes. Not a mocap body: with a
    # mocap parent the cable plugin's forces came out NaN at t = 0 in about 1 of 3 processes
    # (MuJoCo 3.17; measured, cause not found), with a jointed parent in none of 18.
    clamp = spec.worldbody.add_body(name="clamp")
    clamp.add_joint(name=_CLAMP_JOINT, type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[1.0, 0.0, 0.0])
    clamp.add_geom(
        type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.001, 0.0, 0.0], mass=_CLAMP_MASS, contype=0,
        conaffinity=0, group=3,
    )
    add_guidewire(spec, clamp, wire, lengths)
    # Higher priority than the wire's geoms: the plate's condim 1 (no friction) is used.
    # ``gap`` (m) from the tip's end.
    plate_x = wire.length + wire.radius + gap
    spec.worldbody.add_geom(
        name="plate", type=mujoco.mjtGeom.mjGEOM_BOX, size=[1e-4, 0.005, 0.005],
        pos=[plate_x + 1e-4, 0.0, 0.0], contype=2, conaffinity=1, condim=1, priority=2,
        solref=[0.004, 1.0], solimp=[0.99, 0.999, 0.0001, 0.5, 2.0],
    )
    return spec.compile()


def force_deflection(
    wire: GuidewireConfig, free_length: float = TEST_FREE_LENGTH, max_shortening: float = 0.1,
    increment: float = 5e-5, speed: float = 0.002, hold: float = 1.0,
    timestep: float | None = None,
) -> ForceDeflection:
    """The tip-load test's settled force–deflection curve: the plate force at each clamp
    position, as a slow bench push records it.

    The clamp advances by ``increment`` (m) at ``speed`` (m/s), then holds for ``hold`` s; a
    point is the plate force, the shortening and the tip's sideways deflection averaged over
    the hold's last 50 ms. The tip starts 0.1 mm plus the wire's contact margin off the plate,
    so the first points carry no force. Held still after each increment, the wire's
    (mass-scaled) inertia has stopped acting when a point is read, so the curve does not
    depend on the mass scaling or the push speed (``tests/test_wires.py``). A continuous push
    at a bench's speed does not give that: the clamp shortens the column faster than its
    scaled mass can move sideways to buckle, and the plate reads 10-40 times the rating over
    the first 50 ms of contact (docs/guidewire.md, "Tip-load test"). The scene takes the
    wire's numerical options (:func:`~sim4endor.models.scene.set_wire_options`); ``timestep``
    (s) replaces its step.

    Raises:
        RuntimeError: If the simulation goes unstable.
    """
    tested, lengths = tested_wire(wire, free_length)
    model = _scene(tested, lengths, timestep, gap=1e-4 + wire.contact_margin)
    timestep = model.opt.timestep
    data = mujoco.MjData(model)
    plate = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "plate")
    tip = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, names.WIRE_TIP_SITE)
    first_joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, names.wire_body(1))
    slide = int(model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT,
                                                    _CLAMP_JOINT)])
    mujoco.mj_forward(model, data)
    free = float(data.site_xpos[tip, 0] - data.xpos[first_joint, 0])
    read_steps = max(1, round(0.05 / timestep))
    ramp_steps = max(1, round(increment / speed / timestep))
    hold_steps = max(read_steps, round(hold / timestep))
    points: list[tuple[float, float, float, float]] = []
    clamp = 0.0
    while not points or points[-1][1] < max_shortening:
        readings = []
        for k in range(ramp_steps + hold_steps):
            if k < ramp_steps:
                clamp += increment / ramp_steps
            data.qpos[slide], data.qvel[slide] = clamp, 0.0  # prescribed, not simulated
            mujoco.mj_step(model, data)
            if data.warning[mujoco.mjtWarning.mjWARN_BADQACC].number or not np.all(
                    np.isfinite(data.qpos)):
                raise RuntimeError(
                    f"The tip-load simulation went unstable at t = {data.time:.2f} s.")
            if k >= ramp_steps + hold_steps - read_steps:
                offset = data.site_xpos[tip] - data.xpos[first_joint]
                readings.append((_plate_force(model, data, plate),
                                 float(np.linalg.norm(offset[1:])), float(offset[0])))
        force, lateral, span = np.mean(readings, axis=0)
        points.append((clamp, (free - span) / free, force, lateral))
    clamps, shortening, forces, laterals = (np.array(column) for column in zip(*points,
                                                                               strict=True))
    return ForceDeflection(clamps, shortening, forces, laterals, free)


def simulate_tip_load(
    wire: GuidewireConfig, free_length: float = TEST_FREE_LENGTH, shortening: float = 0.05,
    **curve_options: float,
) -> TipLoadResult:
    """The tip load in MuJoCo: the plate force on the settled force–deflection curve
    (:func:`force_deflection`) where the column's ends have come ``shortening`` x
    ``free_length`` closer. That is past the buckling point, where a clamped–free column's
    elastica carries (1 + s/4 + ...) times the buckling load at a relative shortening s:
    about 1 % more at 5 %, so the read-out does not hinge on the exact shortening.
    ``curve_options`` go to :func:`force_deflection`.
    """
    curve = force_deflection(wire, free_length, max_shortening=shortening + 0.01,
                             **curve_options)
    return TipLoadResult(
        force=curve.at(shortening, curve.force), predicted=buckling_load(
            tested_wire(wire, free_length)[0], curve.free_length),
        shortening=shortening * curve.free_length, free_length=curve.free_length,
        lateral=curve.at(shortening, curve.lateral), curve=curve,
    )


def _plate_force(model: mujoco.MjModel, data: mujoco.MjData, plate: int) -> float:
    total = 0.0
    wrench = np.zeros(6)
    for k in range(data.ncon):
        contact = data.contact[k]
        if plate in (contact.geom1, contact.geom2):
            mujoco.mj_contactForce(model, data, k, wrench)
            total += wrench[0]
    return total
