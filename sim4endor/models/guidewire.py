"""The guidewire: a discrete Cosserat rod (MuJoCo 3.17 ``mujoco.elasticity.cable`` plugin).

This is the only module that knows about the cable plugin. Its narrow interface is
:class:`GuidewireConfig` (physical parameters in SI units) and :func:`add_guidewire`, which
adds the wire to a body of an :class:`mujoco.MjSpec`; the rest of the package addresses the
wire through the names in :mod:`sim4endor.models.constants`. A later MuJoCo-4 1D-flexcomp rod
replaces this module only.

How the rod is built (and why):

* A chain of rigid capsule bodies joined by ball joints; the plugin adds bending and twisting
  torques ``E·I/l`` and ``G·J/l`` at every joint. The wire lies along the parent body's +x axis;
  its pre-bent distal tip curves towards the parent's +y axis (rotation 0 of the driver).
* Segments are non-uniform: ``tip_segments`` short segments along the pre-bent tip, then
  lengths grow geometrically (``segment_growth``) up to ``max_segment_length`` along the shaft.
  Per-step cost grows about with the cube of the segment count (dense chain mass matrix), so
  a coarse shaft is what makes the wire fast.
* The plugin derives each joint's stiffness from the radius of the FIRST geom of the joint's
  body and from the distance to the previous body. Each body therefore carries a hidden,
  massless, non-colliding *core* capsule whose radius encodes the stiffness we want at that
  joint: ``E·I`` of the core, times the tip softening factor, times ``l_prev / l_voronoi``
  so that the joint represents the rod length around its vertex (the usual discrete-rod
  Voronoi length). This makes non-uniform segments and a softer tip exact, and brings the
  cantilever error from O(1/N) to O(1/N²). A tapered core (``core_profile``, the catalogue's
  real wires) enters the same factor as ``(d(s)/d_ref)^4``, averaged over the joint's cell.
  The second geom is the contact capsule with the wire's outer radius.
* The first body is welded to the parent (the driver's clamp); ``flat="false"`` makes the
  built (pre-bent) shape the rest shape.
* Optionally (``chain_bodies``, set by the catalogue's wires) the wire is several chains
  instead of one. A serial chain's mass matrix is dense, and the Newton solver's cost grows
  with the square of its degrees of freedom, most of a step on the complex anatomies. Each
  chain after the first starts at a free body that copies the previous chain's last segment
  and is welded to it (as stiff as MuJoCo allows), and has its own plugin instance; the
  joint after the copy is the rod's joint there, so no joint is lost and the chains are the
  same rod. ``GuidewirePhysics.place_driver`` moves the roots with the clamp.
* Quasi-static mass scaling: the wire's inertia is negligible next to its elastic and contact
  forces, and MuJoCo's soft contacts work in acceleration space, so a real 0.1 g wire tunnels
  through the wall at usable time steps. ``mass_scale`` multiplies the density (and gravity
  stays off in ``mjcf/options.xml``). Static results (cantilever deflection, torque transfer)
  do not depend on mass; the validation benchmark measures them with and without scaling.
  Ball-joint damping and armature are needed because the plugin's forces are explicit; both
  are set per joint in proportion to the joint's stiffness (``damping_time``,
  ``armature_time``).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import types
from dataclasses import dataclass

import mujoco
import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim4endor.errors import Sim4EndoRError
from sim4endor.models import constants as names

_CABLE_PLUGIN = "mujoco.elasticity.cable"
INCH = 0.0254
#: Arc length (m) over which a secondary curve (GuidewireConfig.secondary_angle) bends: a
#: cardiologist's finger bend, short next to the curve's 4-10 mm distance from the tip.
SECONDARY_CURVE_LENGTH = 0.002
#: MuJoCo's friction cones by the name GuidewireConfig.friction_cone takes.
FRICTION_CONES = types.MappingProxyType({"pyramidal": mujoco.mjtCone.mjCONE_PYRAMIDAL,
                                         "elliptic": mujoco.mjtCone.mjCONE_ELLIPTIC})
#: MuJoCo's integrators by the name GuidewireConfig.integrator takes.
INTEGRATORS = types.MappingProxyType({"implicitfast": mujoco.mjtIntegrator.mjINT_IMPLICITFAST,
                                      "discrete": mujoco.mjtIntegrator.mjINT_DISCRETE})


class GuidewireConfigError(Sim4EndoRError, ValueError):
    """Raised for physically impossible wire parameters; the message names the field."""


@dataclass(frozen=True)
class GuidewireConfig:
    """Physical parameters of the guidewire (SI units).

    Attributes:
        length: Modelled wire length (m): only the part that can be inside the sheath and
            vessel is simulated (the driver's carriage clamps its proximal end).
        outer_diameter: Outer diameter (m); default 0.014 in = 0.356 mm.
        core_diameter: Diameter of the load-bearing core (m) used for the bending/twisting
            stiffness; ``None`` uses ``outer_diameter`` (the modulus is then an effective one).
        youngs_modulus: Young's modulus of the core (Pa); nitinol ~60 GPa.
        shear_modulus: Shear modulus of the core (Pa); nitinol ~23 GPa (ν = 0.3).
        tip_length: Arc length of the pre-bent distal tip (m).
        tip_angle: Total pre-bend angle of the tip (rad); 35° over 5 mm gives a 1.48 mm
            lateral offset, which fits a 2 mm-radius lumen.
        secondary_angle: Pre-bend (rad) of an optional secondary curve on the shaft behind the
            tip, in the tip's plane and to the same side; 0 (default): none. A cardiologist
            shapes one to reach across a wide vessel: the primary curve matches the angle to
            negotiate, the secondary the vessel's size (docs/guidewire.md, "Shaping the tip").
        secondary_distance: Distance (m) from the distal end to the middle of the secondary
            curve, which spreads its angle over :data:`SECONDARY_CURVE_LENGTH`. It must lie
            proximal of the tip: at least ``tip_length`` + that length / 2.
        tip_stiffness_factor: Bending/twisting stiffness of the tip relative to the shaft.
        friction: Sliding friction coefficient of wire contacts (the wire's geoms have
            priority, so this value is used against walls and sheath). The catalogue's
            presets take it from their coat (:func:`sim4endor.models.wires.coatings`).
        density: Physical density of the wire (kg/m³); nitinol ~6450.
        mass_scale: Quasi-static mass-scaling factor applied to ``density`` (see module doc).
        tip_segments: Number of (equal) segments along the pre-bent tip.
        max_segment_length: Longest shaft segment (m).
        segment_limits: Optional shorter limits along the shaft: ``((s, l), ...)`` pairs of
            distance from the distal tip ``s`` (m, strictly increasing, starting at 0) and
            longest segment ``l`` (m) from there to the next pair (``max_segment_length``
            caps them all). ``None`` (default): ``max_segment_length`` everywhere. A scene
            sets them so that only the wire that can reach a tight bend is cut short
            (:func:`sim4endor.models.scene.fit_segments_to_vessel`).
        segment_growth: Ratio between consecutive segment lengths from tip to shaft (>= 1).
        damping_time: Ball-joint damping as a time constant (s): each joint's damping is
            ``damping_time`` times its bending stiffness ``E·I/l`` (N·m/rad), so short tip
            segments and long shaft segments relax alike.
        armature_time: Ball-joint armature as a time (s): armature = stiffness ×
            ``armature_time²``. The plugin's spring is explicit, so the time step must stay
            well below ``armature_time``. Measured at dt 5 ms: 7.5 ms blew up in 6 of 48
            insertion episodes in the vascular phantom, 15 ms in none (nor in 48 more).
        chain_bodies: Longest run of wire bodies in one kinematic chain, or ``None`` for one
            chain from the clamp to the tip. A serial chain's mass matrix is dense, so
            MuJoCo's cost per step grows with the square of its degrees of freedom; split
            into chains, the wire costs about linearly in its segments (see
            :func:`add_guidewire`). Counted from the tip, so the pre-bent tip lies in one
            chain; at least ``tip_segments``. The welds between chains go unstable under
            joint damping of a second or more (``damping_time`` ≥ 1 s; 0.2 s is fine).
        max_timestep: Longest physics time step (s) this wire is simulated at: a scene whose
            step is longer (``mjcf/options.xml``: 5 ms) and that does not set its own
            (``SceneConfig.timestep``) runs at this one instead. ``None`` (default): the
            scene's step. The catalogue's presets set it (:mod:`sim4endor.models.wires`).
        friction_cone: MuJoCo friction cone of the scene this wire is simulated in:
            ``"pyramidal"``, ``"elliptic"``, or ``None`` (default) for the scene's own
            (``mjcf/options.xml``: pyramidal). With pyramidal cones a wire held in a bent
            lumen never comes to rest (joint speeds of 1-30 rad/s with the driver still,
            the tip wandering over millimetres at friction 0.03); with elliptic cones it
            does (docs/guidewire.md, "Friction cones"). The catalogue's presets set
            ``"elliptic"``; a scene holds one wire, so the wire's choice is the scene's.
        integrator: MuJoCo integrator of the scene this wire is simulated in:
            ``"implicitfast"``, ``"discrete"`` (MuJoCo 3.13 on: the constraint solve in the
            metric of mass plus implicit damping), or ``None`` (default) for the scene's own
            (``mjcf/options.xml``: implicitfast). Numerical, like ``friction_cone``;
            docs/guidewire.md, "Convergence", measures both.
        contact_margin: Distance (m) from a wall at which the wire's contacts start to act:
            MuJoCo's geom margin, so the wire collides as if ``2 × contact_margin`` wider.
            Every preset keeps the default 0.1 mm (the ``paper`` preset bit for bit the
            published model); 0 collides at the jacket's true radius, which overlapped the
            hulls by up to 0.8 wire radii at the driver's push (docs/guidewire.md, "Contact
            at the true radius").
        contact_solimp: MuJoCo impedance (``solimp``: dmin, dmax, width m, midpoint, power)
            of the wire's contacts, or ``None`` (default) for the wire class's
            (``mjcf/guidewire_defaults.xml``: 0.99, 0.999, 0.1 mm, 0.5, 2). The wire's geoms
            have priority, so it is every wire contact's. A softer start (dmin 0.9) lets a
            loaded contact settle inside the margin instead of flickering at its edge, where a
            light wire's segment, freed for one step, is thrown through the wall
            (docs/guidewire.md, "Converged by default"). Numerical, like ``integrator``.
        core_profile: Optional tapered core: ``((s, d), ...)`` pairs of distance from the
            distal tip ``s`` (m, strictly increasing, starting at 0) and core diameter ``d``
            (m), linear in between and constant beyond the last pair. ``None`` (default)
            keeps the uniform core. Each joint's stiffness then includes
            ``(d(s) / d_ref)^4`` (``d_ref`` = ``core_diameter`` or ``outer_diameter``),
            averaged over the rod length the joint represents (see
            :func:`stiffness_profile`). The catalogue's presets
            (:mod:`sim4endor.models.wires`) set it.
    """

    length: float = 0.15
    outer_diameter: float = 0.014 * INCH
    core_diameter: float | None = None
    youngs_modulus: float = 60e9
    shear_modulus: float = 60e9 / 2.6
    tip_length: float = 0.005
    tip_angle: float = math.radians(35.0)
    secondary_angle: float = 0.0
    secondary_distance: float = 0.0
    tip_stiffness_factor: float = 0.5
    friction: float = 0.1
    density: float = 6450.0
    mass_scale: float = 1e4
    tip_segments: int = 5
    max_segment_length: float = 0.005
    segment_limits: tuple[tuple[float, float], ...] | None = None
    segment_growth: float = 1.5
    damping_time: float = 0.025
    armature_time: float = 0.015
    chain_bodies: int | None = None
    max_timestep: float | None = None
    friction_cone: str | None = None
    integrator: str | None = None
    contact_margin: float = 1e-4
    contact_solimp: tuple[float, float, float, float, float] | None = None
    core_profile: tuple[tuple[float, float], ...] | None = None

    def __post_init__(self) -> None:
        positive = (
            "length", "outer_diameter", "youngs_modulus", "shear_modulus", "tip_length",
            "tip_stiffness_factor", "density", "mass_scale", "max_segment_length",
        )
        for field_name in positive:
            value = getattr(self, field_name)
            if not (math.isfinite(value) and value > 0):
                raise GuidewireConfigError(
                    f"GuidewireConfig.{field_name} must be > 0, got {value}."
                )
        if self.core_diameter is not None and not 0 < self.core_diameter <= self.outer_diameter:
            raise GuidewireConfigError(
                f"GuidewireConfig.core_diameter must be in (0, outer_diameter="
                f"{self.outer_diameter}], got {self.core_diameter}."
            )
        if self.tip_length >= self.length:
            raise GuidewireConfigError(
                f"GuidewireConfig.tip_length ({self.tip_length} m) must be shorter than "
                f"length ({self.length} m)."
            )
        if not 0 <= self.tip_angle < math.pi:
            raise GuidewireConfigError(
                f"GuidewireConfig.tip_angle must be in [0, pi) rad, got {self.tip_angle}."
            )
        if not 0 <= self.secondary_angle < math.pi:
            raise GuidewireConfigError(
                "GuidewireConfig.secondary_angle must be in [0, pi) rad, got "
                f"{self.secondary_angle}."
            )
        nearest = self.tip_length + SECONDARY_CURVE_LENGTH / 2
        if self.secondary_angle and not (
            math.isfinite(self.secondary_distance)
            and nearest - 1e-12 <= self.secondary_distance < self.length - SECONDARY_CURVE_LENGTH
        ):
            raise GuidewireConfigError(
                f"GuidewireConfig.secondary_distance must be >= tip_length + "
                f"{SECONDARY_CURVE_LENGTH / 2} m ({nearest} m: the secondary curve lies behind "
                f"the tip) and within the wire, got {self.secondary_distance}."
            )
        if self.tip_segments < 1 or self.segment_growth < 1:
            raise GuidewireConfigError(
                "GuidewireConfig.tip_segments must be >= 1 and segment_growth >= 1, got "
                f"{self.tip_segments} and {self.segment_growth}."
            )
        if self.chain_bodies is not None and self.chain_bodies < self.tip_segments:
            raise GuidewireConfigError(
                "GuidewireConfig.chain_bodies must be >= tip_segments (the tip stays in one "
                f"chain), got {self.chain_bodies} with {self.tip_segments} tip segments."
            )
        if not all(math.isfinite(value) and value >= 0 for value in (
                self.friction, self.damping_time, self.armature_time, self.contact_margin)):
            raise GuidewireConfigError(
                "GuidewireConfig.friction, damping_time, armature_time and contact_margin "
                "must be finite and >= 0."
            )
        if self.max_timestep is not None and not (
            math.isfinite(self.max_timestep) and self.max_timestep > 0
        ):
            raise GuidewireConfigError(
                f"GuidewireConfig.max_timestep must be > 0 or None, got {self.max_timestep}."
            )
        if self.friction_cone not in (None, *FRICTION_CONES):
            raise GuidewireConfigError(
                f"GuidewireConfig.friction_cone must be one of {list(FRICTION_CONES)} or None, "
                f"got {self.friction_cone!r}."
            )
        if self.integrator not in (None, *INTEGRATORS):
            raise GuidewireConfigError(
                f"GuidewireConfig.integrator must be one of {list(INTEGRATORS)} or None, "
                f"got {self.integrator!r}."
            )
        if self.contact_solimp is not None:
            _check_solimp(self.contact_solimp)
        if self.segment_limits is not None:
            _check_segment_limits(self.segment_limits)
        if self.core_profile is not None:
            _check_core_profile(self.core_profile, self.outer_diameter)

    @property
    def radius(self) -> float:
        """Outer radius (m)."""
        return 0.5 * self.outer_diameter

    @property
    def reference_core_diameter(self) -> float:
        """Core diameter of the shaft stiffness ``bending_stiffness`` (m)."""
        return self.outer_diameter if self.core_diameter is None else self.core_diameter

    @property
    def bending_stiffness(self) -> float:
        """Shaft flexural rigidity E·I (N·m²) of ``reference_core_diameter``."""
        return self.youngs_modulus * math.pi * self.reference_core_diameter**4 / 64.0

    def flexural_rigidity(self, from_tip: ArrayLike) -> NDArray[np.float64]:
        """E·I (N·m²) at distances ``from_tip`` (m) from the distal end.

        Includes the core profile and ``tip_stiffness_factor`` over the distal
        ``tip_length``: the continuous rod that the joints discretise.
        """
        return self.bending_stiffness * stiffness_profile(self, from_tip)

    def torsional_rigidity(self, from_tip: ArrayLike) -> NDArray[np.float64]:
        """G·J (N·m²) at distances ``from_tip`` (m) from the distal end.

        The plugin twists every joint with the G·J of the same core capsule it bends with,
        and a round core's J is twice its I, so G·J = E·I · 2G/E along the whole profile.
        """
        return self.flexural_rigidity(from_tip) * 2.0 * self.shear_modulus / self.youngs_modulus

    def straightened(self, tip_angle: float = 0.0) -> GuidewireConfig:
        """The same wire with its tip and any secondary curve unbent, as a bench test holds
        it; ``tip_angle`` (rad) leaves that much bend over the tip as an imperfection."""
        return dataclasses.replace(self, tip_angle=tip_angle, secondary_angle=0.0)

    @property
    def tip_lateral_offset(self) -> float:
        """Sideways offset of the tip end from the shaft axis caused by the pre-bends (m):
        the tip's and any secondary curve's."""
        return float(abs(wire_vertices(self)[-1, 1]))

    @property
    def num_segments(self) -> int:
        """Number of rigid segments (bodies) of the discretised wire."""
        return len(segment_lengths(self))


def _check_solimp(solimp: tuple[float, ...]) -> None:
    try:
        dmin, dmax, width, midpoint, power = (float(value) for value in solimp)
    except (TypeError, ValueError):
        dmin = dmax = width = midpoint = power = math.nan
    if not (0 < dmin <= dmax < 1 and width > 0 and 0 < midpoint < 1 and power >= 1):
        raise GuidewireConfigError(
            "GuidewireConfig.contact_solimp must be MuJoCo's (dmin, dmax, width m, midpoint, "
            f"power) with 0 < dmin <= dmax < 1, width > 0, 0 < midpoint < 1 and power >= 1, "
            f"got {solimp!r}."
        )


def _check_segment_limits(limits: tuple[tuple[float, float], ...]) -> None:
    try:
        points = np.array(limits, dtype=np.float64)
    except (TypeError, ValueError):
        points = np.zeros((0, 0))
    if not (points.ndim == 2 and points.shape[1] == 2 and len(points) >= 1
            and np.all(np.isfinite(points)) and points[0, 0] == 0.0
            and np.all(np.diff(points[:, 0]) > 0) and np.all(points[:, 1] > 0)):
        raise GuidewireConfigError(
            "GuidewireConfig.segment_limits must be (distance from tip m, longest segment m) "
            "pairs with distances starting at 0 and increasing strictly and lengths > 0, got "
            f"{limits!r}."
        )


def _check_core_profile(profile: tuple[tuple[float, float], ...], outer: float) -> None:
    try:
        points = np.array(profile, dtype=np.float64)
    except (TypeError, ValueError):
        points = np.zeros((0, 0))
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 1:
        raise GuidewireConfigError(
            "GuidewireConfig.core_profile must be a tuple of (distance from tip m, core "
            f"diameter m) pairs, got {profile!r}."
        )
    s, d = points[:, 0], points[:, 1]
    if not (np.all(np.isfinite(points)) and s[0] == 0.0 and np.all(np.diff(s) > 0)):
        raise GuidewireConfigError(
            "GuidewireConfig.core_profile distances must start at 0 (the tip) and increase "
            f"strictly, got {s.tolist()}."
        )
    if not np.all((d > 0) & (d <= outer)):
        raise GuidewireConfigError(
            f"GuidewireConfig.core_profile diameters must be in (0, outer_diameter={outer}], "
            f"got {d.tolist()}."
        )


def core_diameter_at(config: GuidewireConfig, from_tip: ArrayLike) -> NDArray[np.float64]:
    """Core diameter (m) at distances ``from_tip`` (m) from the distal end."""
    s = np.asarray(from_tip, dtype=np.float64)
    if config.core_profile is None:
        return np.full_like(s, config.reference_core_diameter)
    points = np.array(config.core_profile)
    return np.interp(s, points[:, 0], points[:, 1])


def stiffness_profile(config: GuidewireConfig, from_tip: ArrayLike) -> NDArray[np.float64]:
    """E·I at ``from_tip`` (m from the distal end) relative to ``bending_stiffness``."""
    s = np.asarray(from_tip, dtype=np.float64)
    relative = (core_diameter_at(config, s) / config.reference_core_diameter) ** 4
    # The historical rule: the pre-bent tip, by arc length, is softer by a constant factor.
    return np.where(s < config.tip_length - 1e-12, config.tip_stiffness_factor, 1.0) * relative


#: Nitinol core (the default).
NITINOL = GuidewireConfig()
#: Stainless-steel core: E = 200 GPa, G = 77 GPa, ρ = 7900 kg/m³.
STAINLESS_STEEL = GuidewireConfig(youngs_modulus=200e9, shear_modulus=77e9, density=7900.0)


def segment_lengths(config: GuidewireConfig) -> NDArray[np.float64]:
    """Returns the segment lengths (m), proximal first.

    The tip has ``tip_segments`` equal segments; going proximally, each shaft segment is
    ``segment_growth`` times the previous one until the longest allowed there
    (``max_segment_length``, or ``segment_limits``'); the remaining shaft is split into
    equal segments no longer than that, zone by zone of ``segment_limits``. A zone shorter
    than its limit joins the next one under the shorter of their limits, so that no segment
    is cut short at a zone's border.
    """
    tip = config.tip_length / config.tip_segments
    distal: list[float] = []  # shaft segments, tip side first
    start = config.tip_length  # distance from the tip where the next segment starts
    step = tip * config.segment_growth
    while step < _longest_segment(config, start) and step < config.length - start:
        distal.append(step)
        start += step
        step *= config.segment_growth
    borders = [s for s, _ in config.segment_limits or () if start < s < config.length]
    zone_start, cap = start, _longest_segment(config, start)
    for zone_end in [*borders, config.length]:
        if zone_end - zone_start < cap and zone_end < config.length:
            cap = min(cap, _longest_segment(config, zone_end))
            continue  # too short for a segment of its own: it joins the next zone
        count = max(1, math.ceil((zone_end - zone_start) / cap - 1e-9))
        distal += [(zone_end - zone_start) / count] * count
        zone_start = zone_end
        cap = _longest_segment(config, zone_end)
    return np.array(distal[::-1] + [tip] * config.tip_segments)


def _longest_segment(config: GuidewireConfig, from_tip: float) -> float:
    """The longest shaft segment (m) allowed from ``from_tip`` (m from the distal end) on."""
    longest = config.max_segment_length
    for start, limit in config.segment_limits or ():
        if start > from_tip + 1e-12:
            break
        longest = min(config.max_segment_length, limit)
    return longest


def wire_vertices(config: GuidewireConfig) -> NDArray[np.float64]:
    """Returns the (N+1, 3) rest-shape vertices in the mount frame (wire along +x, tip to +y)."""
    lengths = segment_lengths(config)
    return _rest_vertices(lengths, _segment_headings(config, lengths))


def _rest_vertices(
    lengths: NDArray[np.float64], headings: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The (N+1, 3) vertices of segments of ``lengths`` and in-plane ``headings`` (rad)."""
    steps = lengths[:, None] * np.stack([np.cos(headings), np.sin(headings), 0 * headings], 1)
    return np.vstack([np.zeros(3), np.cumsum(steps, axis=0)])


def _segment_headings(config: GuidewireConfig,
                      lengths: NDArray[np.float64]) -> NDArray[np.float64]:
    """In-plane heading (rad) of each segment of ``lengths`` in the rest shape."""
    # Mid-segment headings of a discretised circular arc over the tip segments.
    count = len(lengths)
    headings = np.zeros(count)
    k = np.arange(config.tip_segments)
    headings[count - config.tip_segments :] = (k + 0.5) * config.tip_angle / config.tip_segments
    if config.secondary_angle:
        # Every segment distal of the secondary curve turns by its angle, the segments whose
        # middles lie on the curve by their share of it.
        from_tip = np.cumsum(lengths[::-1])[::-1] - lengths / 2
        share = (config.secondary_distance + SECONDARY_CURVE_LENGTH / 2 - from_tip) \
            / SECONDARY_CURVE_LENGTH
        headings += config.secondary_angle * np.clip(share, 0.0, 1.0)
    return headings


def _stiffness_factors(
    config: GuidewireConfig, lengths: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Per-body factor on E·I and G·J that the core capsule radius encodes (see module doc)."""
    if config.core_profile is not None:
        return _profile_factors(config, lengths)
    count = len(lengths)
    factors = np.ones(count)
    arc = np.concatenate([[0.0], np.cumsum(lengths)])
    tip_start = config.length - config.tip_length
    for b in range(1, count):
        # Joint b sits at vertex b, between segments b-1 and b. The first joint is at the
        # clamp, so it represents only half of the following segment.
        voronoi = 0.5 * lengths[b] if b == 1 else 0.5 * (lengths[b - 1] + lengths[b])
        softening = config.tip_stiffness_factor if arc[b] > tip_start + 1e-12 else 1.0
        factors[b] = softening * lengths[b - 1] / voronoi
    return factors


def _profile_factors(
    config: GuidewireConfig, lengths: NDArray[np.float64], samples: int = 64
) -> NDArray[np.float64]:
    """Stiffness factors of a wire with a core profile.

    A joint stands for the rod around its vertex (its Voronoi cell); rod pieces in series add
    compliances, so the joint's stiffness is ``1 / ∫ ds / EI(s)`` over that cell (the
    harmonic mean of E·I). Measured on the presets' 60 mm cantilevers, this and E·I sampled
    at the vertex both stay within 0.3 % of beam theory; the cell mean is kept because it
    does not depend on where a kink of the profile falls inside a (5 mm) shaft segment.
    """
    count = len(lengths)
    factors = np.ones(count)
    arc = np.concatenate([[0.0], np.cumsum(lengths)])
    for b in range(1, count):
        start = arc[b] if b == 1 else arc[b] - 0.5 * lengths[b - 1]
        end = arc[b] + 0.5 * lengths[b]
        # Midpoint rule on a fine grid of the cell (distances from the tip).
        edges = np.linspace(start, end, samples + 1)
        middle = config.length - 0.5 * (edges[:-1] + edges[1:])
        compliance = np.sum(np.diff(edges) / stiffness_profile(config, middle))
        factors[b] = lengths[b - 1] / compliance
    return factors


def add_guidewire(
    spec: mujoco.MjSpec, parent: mujoco.MjsBody, config: GuidewireConfig,
    lengths: NDArray[np.float64] | None = None,
) -> None:
    """Adds the wire to ``parent`` of ``spec`` (its proximal end welded at the parent origin).

    ``spec`` must hold the default classes of ``mjcf/guidewire_defaults.xml``
    (:func:`sim4endor.models.scene.base_spec` provides them).

    Args:
        spec: The model spec to extend; the cable plugin is activated in it.
        parent: Body that clamps the wire (the driver's carriage).
        config: Wire parameters.
        lengths: Segment lengths (m, proximal first, summing to ``config.length``, the last
            ``tip_segments`` forming the tip) instead of :func:`segment_lengths`; the
            tip-load test uses it to clamp the wire at an exact distance from its tip.

    Raises:
        GuidewireConfigError: If the spec lacks the guidewire default classes, or
            ``lengths`` do not add up to the wire.
    """
    for cls in (names.WIRE_CLASS, names.WIRE_CORE_CLASS):
        if spec.find_default(cls) is None:
            raise GuidewireConfigError(
                f"The model spec has no default class {cls!r}; build it from "
                "sim4endor.models.scene.base_spec(), which includes mjcf/guidewire_defaults.xml."
            )
    if lengths is None:
        lengths = segment_lengths(config)
    elif abs(float(np.sum(lengths)) - config.length) > 1e-9 or len(lengths) <= config.tip_segments:
        raise GuidewireConfigError(
            f"add_guidewire lengths sum to {float(np.sum(lengths))} m in {len(lengths)} "
            f"segments; GuidewireConfig.length is {config.length} m with "
            f"{config.tip_segments} tip segments."
        )
    headings = _segment_headings(config, lengths)
    factors = _stiffness_factors(config, lengths)
    core_radius = 0.5 * (config.core_diameter or config.outer_diameter)
    # Joint b's bending stiffness as the plugin will compute it: E·I·factor / l_(b-1).
    joint_stiffness = np.zeros(len(lengths))
    joint_stiffness[1:] = config.bending_stiffness * factors[1:] / lengths[:-1]

    spec.activate_plugin(_CABLE_PLUGIN)
    segments = _Segments(config, lengths, headings, factors, core_radius, joint_stiffness)
    first_bodies = chain_starts(config, len(lengths))
    bounds = [*first_bodies, len(lengths)]
    clamp_pos, clamp_quat = _world_pose(parent)
    _add_plugin_instance(spec, config, names.WIRE_PLUGIN)
    body = segments.add_chain(spec, parent, range(bounds[0], bounds[1]), names.WIRE_PLUGIN)
    vertices = _rest_vertices(lengths, headings)
    for first, end in itertools.pairwise(bounds[1:]):
        # The chain's root is a free body that copies segment first-1, welded to it.
        pos, quat = np.zeros(3), np.zeros(4)
        mujoco.mju_rotVecQuat(pos, vertices[first - 1], clamp_quat)
        mujoco.mju_mulQuat(quat, clamp_quat, _turn(headings[first - 1]))
        root = spec.worldbody.add_body(name=names.wire_chain_root(first), pos=pos + clamp_pos,
                                       quat=quat)
        root.add_freejoint(name=names.wire_chain_root(first))
        plugin = f"{names.WIRE_PLUGIN}_{first:03d}"
        _add_plugin_instance(spec, config, plugin)
        segments.add_root_copy(spec, root, first - 1, plugin)
        body = segments.add_chain(spec, root, range(first, end), plugin)
        weld = spec.add_equality(name=names.wire_chain_root(first))
        weld.type = mujoco.mjtEq.mjEQ_WELD
        weld.objtype = mujoco.mjtObj.mjOBJ_BODY
        weld.name1, weld.name2 = names.wire_body(first - 1), root.name
        # Relative pose = the one at qpos0 (identity: the copy coincides), torque scale 1.
        weld.data = np.array([0.0] * 10 + [1.0] + [0.0] * (len(weld.data) - 11))
        # As stiff as MuJoCo allows (its time constant is clamped to 2 dt) and nearly hard:
        # measured over 400 random env steps, the welds yield at most 0.19° and 0.016 mm
        # (vascular phantom with a split paper wire; coronary tree 1017, workhorse).
        weld.solref = [1e-6, 1.0]
        weld.solimp = [0.99999, 0.99999, 0.001, 0.5, 2.0]
    # At the far end of the last segment. Hidden (site group 3) and wire-sized: the default
    # 5 mm site would hide the tip.
    body.add_site(
        name=names.WIRE_TIP_SITE, pos=[float(lengths[-1]), 0.0, 0.0],
        size=[config.radius, 0, 0], group=3,
    )


def chain_starts(config: GuidewireConfig, count: int) -> list[int]:
    """Index of the first body of each kinematic chain of a ``count``-body wire (0 first).

    Chains are counted from the tip, ``config.chain_bodies`` bodies each, so the tip lies in
    the last one; the first chain, clamped to the driver, takes what is left.
    """
    size = config.chain_bodies
    if size is None or size >= count:
        return [0]
    return [0, *range(count - size * ((count - 1) // size), count, size)]


def _turn(angle: float) -> NDArray[np.float64]:
    """Quaternion of a turn by ``angle`` about +z (the plane of the pre-bent tip)."""
    return np.array([math.cos(angle / 2), 0.0, 0.0, math.sin(angle / 2)])


def _world_pose(body: mujoco.MjsBody) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """World position and orientation of a spec body at qpos0, from its ancestors' poses."""
    pos, quat = np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])
    while body.name != "world":
        if body.frame is not None or body.alt.type != mujoco.mjtOrientation.mjORIENTATION_QUAT:
            raise GuidewireConfigError(
                f"add_guidewire cannot place a split wire under body {body.name!r}, which is "
                "attached to a frame or oriented other than by a quaternion; use "
                "chain_bodies=None there."
            )
        local = np.array(body.quat, dtype=np.float64)
        local /= np.linalg.norm(local)
        moved, turned = np.zeros(3), np.zeros(4)
        mujoco.mju_rotVecQuat(moved, pos, local)
        mujoco.mju_mulQuat(turned, local, quat)
        pos, quat = moved + np.array(body.pos), turned
        body = body.parent
    return pos, quat


@dataclass(frozen=True)
class _Segments:
    """The wire's bodies as add_guidewire lays them out, one chain at a time."""

    config: GuidewireConfig
    lengths: NDArray[np.float64]
    headings: NDArray[np.float64]
    factors: NDArray[np.float64]
    core_radius: float
    joint_stiffness: NDArray[np.float64]

    def add_root_copy(self, spec: mujoco.MjSpec, root: mujoco.MjsBody, index: int,
                      plugin: str) -> None:
        """Gives a chain's root the core of segment ``index``, which it copies, and its mass.

        Its rotational inertia is the armature of the joint behind the copy (isotropic), as
        the other bodies see through their joints; a soft weld yields in inverse proportion
        to the inertia it holds. Armature on the free joint would also add that much to its
        translation, a thousand times a real segment's mass: the real-mass cantilever was
        then 34 % short of its static deflection after 2 s (6 % with this inertia). The copy
        carries no contacts (segment ``index`` does) and adds one segment's (scaled) mass
        per chain, which the quasi-static wire ignores.
        """
        config, length = self.config, float(self.lengths[index])
        self._core(spec, root, index)
        root.explicitinertial = True
        root.mass = config.density * config.mass_scale * math.pi * config.radius**2 * (
            length + 4.0 * config.radius / 3.0)
        root.ipos = [0.5 * length, 0.0, 0.0]  # MuJoCo 3.17 puts an unset one at the world pos
        root.iquat = [1.0, 0.0, 0.0, 0.0]
        # Body 0 is clamped and has no joint: a copy of it takes the armature of joint 1.
        armature = float(self.joint_stiffness[max(index, 1)]) * config.armature_time**2
        root.inertia = [armature] * 3
        _join_plugin(root, plugin)

    def add_chain(self, spec: mujoco.MjSpec, parent: mujoco.MjsBody, indices: range,
                  plugin: str) -> mujoco.MjsBody:
        """Adds bodies ``indices`` as a serial chain under ``parent``; returns the last.

        ``parent`` is the clamp for the first chain, or the root that copies body
        ``indices[0] - 1`` for the others, so each body's pose follows from the previous one.
        """
        config, body = self.config, parent
        wire_default = spec.find_default(names.WIRE_CLASS)
        for index in indices:
            previous = index - 1
            turn = self.headings[index] - (self.headings[previous] if index else 0.0)
            body = body.add_body(
                name=names.wire_body(index),
                pos=[self.lengths[previous] if index else 0.0, 0.0, 0.0],
                quat=_turn(turn),
            )
            if index > 0:
                body.add_joint(
                    name=names.wire_joint(index),
                    type=mujoco.mjtJoint.mjJNT_BALL,
                    damping=config.damping_time * self.joint_stiffness[index],
                    armature=self.joint_stiffness[index] * config.armature_time**2,
                )
            self._core(spec, body, index)
            geom = body.add_geom(
                wire_default,
                name=names.wire_geom(index),
                type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                fromto=[0.0, 0.0, 0.0, self.lengths[index], 0.0, 0.0],
                size=[config.radius, 0.0, 0.0],
                density=config.density * config.mass_scale,
                friction=[config.friction, 0.005, 0.0001],
                margin=config.contact_margin,
            )
            if config.contact_solimp is not None:
                geom.solimp = config.contact_solimp
            _join_plugin(body, plugin)
        return body

    def _core(self, spec: mujoco.MjSpec, body: mujoco.MjsBody, index: int) -> None:
        # The plugin reads a joint's stiffness from the first geom of the joint's body.
        body.add_geom(
            spec.find_default(names.WIRE_CORE_CLASS),
            type=mujoco.mjtGeom.mjGEOM_CAPSULE,
            fromto=[0.0, 0.0, 0.0, self.lengths[index], 0.0, 0.0],
            size=[self.core_radius * self.factors[index] ** 0.25, 0.0, 0.0],
        )


def _add_plugin_instance(spec: mujoco.MjSpec, config: GuidewireConfig, name: str) -> None:
    plugin = spec.add_plugin(name=name, plugin_name=_CABLE_PLUGIN, active=True)
    plugin.config = {
        "bend": repr(config.youngs_modulus),
        "twist": repr(config.shear_modulus),
        "flat": "false",
    }


def _join_plugin(body: mujoco.MjsBody, name: str) -> None:
    """Puts ``body`` in the cable plugin instance ``name`` (one per chain)."""
    body.plugin.plugin_name = _CABLE_PLUGIN
    body.plugin.name = name
    body.plugin.active = True
