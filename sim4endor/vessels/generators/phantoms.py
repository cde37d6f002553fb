"""The two shipped phantoms of the paper: the simplified Y and the complex vascular tree.

Both start at the inlet (the origin) heading +x; the frame's normal is +y, so ``roll_deg`` 0
bends towards +y, 90 towards +z, 180 towards -y. Their geometry is fixed by the config; the
seed only matters when a ``*_jitter`` field is non-zero (seeded variations for training on
many similar anatomies).

Lumen radii are chosen for the 0.014 in guidewire with its 5 mm / 35° J-tip, whose tip stands
1.48 mm off the shaft axis: the tip must fit within R - r_wire = R - 0.18 mm, so R >= 1.75 mm
everywhere. The simplified phantom uses R = 2.0 mm (4 mm diameter, the top of the coronary
3-4 mm range), the geometry the guidewire spike steered 15/15 into each branch.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from sim4endor.vessels.generators.anatomy import (
    BranchPlan,
    GeneratedAnatomy,
    MeshResolution,
    assemble,
    check_bends,
)
from sim4endor.vessels.generators.paths import Arc, Frame, GeneratorConfigError, Segment, Straight

MM = 1e-3


@dataclass(frozen=True)
class SimplifiedPhantomConfig:
    """The simplified phantom (paper Fig. 2), in the x-y plane.

    Attributes:
        radius: Lumen radius everywhere (m).
        trunk_length: Straight inlet trunk from the inlet to the bifurcation (m).
        branch_a_angle_deg: Angle of straight branch A from the trunk axis (towards +y).
        branch_a_length: Length of branch A (m).
        branch_b_angle_deg: Angle of branch B at the bifurcation (towards -y).
        branch_b_curve_deg: How much further branch B curves away from A along its length.
        branch_b_length: Arc length of branch B (m).
        angle_jitter_deg: Standard deviation of seeded random changes to the three angles.
        length_jitter: Relative standard deviation of seeded random changes to the lengths.
        clearance: Smallest wall-to-wall gap between lumens away from the junction (m).
        resolution: Mesh and centerline sampling.
    """

    radius: float = 2.0 * MM
    trunk_length: float = 60.0 * MM
    branch_a_angle_deg: float = 35.0
    branch_a_length: float = 40.0 * MM
    branch_b_angle_deg: float = 35.0
    branch_b_curve_deg: float = 40.0
    branch_b_length: float = 40.0 * MM
    angle_jitter_deg: float = 0.0
    length_jitter: float = 0.0
    clearance: float = 1.6 * MM
    resolution: MeshResolution = field(default_factory=MeshResolution)


class _Branch(NamedTuple):
    name: str
    parent: str | None
    turn_deg: float
    roll_deg: float
    segments: tuple[Segment, ...]
    radius_start: float
    radius_end: float


def _jittered(branch: _Branch, rng: np.random.Generator, angle_sd: float,
              length_sd: float) -> _Branch:
    def segment(s: Segment) -> Segment:
        if isinstance(s, Straight):
            return Straight(s.length * (1.0 + length_sd * rng.standard_normal()))
        return Arc(s.angle_deg + angle_sd * rng.standard_normal(),
                   s.radius * (1.0 + length_sd * rng.standard_normal()), s.roll_deg)

    turn = branch.turn_deg + angle_sd * rng.standard_normal() if branch.parent else 0.0
    return branch._replace(turn_deg=turn, segments=tuple(segment(s) for s in branch.segments))


def _plan(layout: Sequence[_Branch]) -> list[BranchPlan]:
    """Turns a layout (parents first) into plans starting at the inlet, heading +x."""
    index = {branch.name: k for k, branch in enumerate(layout)}
    plans: list[BranchPlan] = []
    for branch in layout:
        if branch.parent is None:
            start = Frame.start((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
            parent = None
        else:
            parent = index[branch.parent]
            start = plans[parent].end().turned(branch.turn_deg, branch.roll_deg)
        plan = BranchPlan(branch.name, start, branch.segments, branch.radius_start,
                          branch.radius_end, parent)
        check_bends(plan)
        plans.append(plan)
    return plans


def _generate(layout: Sequence[_Branch], targets: dict[str, str], description: str,
              seed: int, angle_sd: float, length_sd: float, clearance: float,
              resolution: MeshResolution) -> GeneratedAnatomy:
    if angle_sd < 0 or length_sd < 0:
        raise GeneratorConfigError("angle_jitter_deg and length_jitter must be >= 0.")
    if angle_sd or length_sd:
        rng = np.random.default_rng(seed)
        layout = [_jittered(branch, rng, angle_sd, length_sd) for branch in layout]
        description += f", jittered with seed {seed}"
    plans = _plan(layout)
    names = [plan.name for plan in plans]
    return assemble(plans, {t: names.index(b) for t, b in targets.items()}, description,
                    resolution, clearance=clearance)


def simplified_phantom(config: SimplifiedPhantomConfig = SimplifiedPhantomConfig(),
                       seed: int = 0) -> GeneratedAnatomy:
    """Generates the simplified phantom: straight trunk, straight branch A, curved branch B.

    Args:
        config: Geometry; the defaults are the shipped ``simplified_phantom``.
        seed: Only used when a jitter field of ``config`` is non-zero.

    Returns:
        The anatomy with targets ``"A"`` and ``"B"`` at the branch ends (End Points A and B).
    """
    c = config
    r = c.radius
    layout = (
        _Branch("trunk", None, 0.0, 0.0, (Straight(c.trunk_length),), r, r),
        _Branch("A", "trunk", c.branch_a_angle_deg, 0.0, (Straight(c.branch_a_length),), r, r),
        _Branch("B", "trunk", c.branch_b_angle_deg, 180.0,
                (Arc(c.branch_b_curve_deg, c.branch_b_length / np.radians(c.branch_b_curve_deg),
                     180.0),), r, r),
    )
    description = (
        f"simplified phantom: {c.trunk_length / MM:g} mm straight trunk, branch A "
        f"+{c.branch_a_angle_deg:g} deg x {c.branch_a_length / MM:g} mm, branch B "
        f"-{c.branch_b_angle_deg:g} deg curving {c.branch_b_curve_deg:g} deg over "
        f"{c.branch_b_length / MM:g} mm, lumen radius {r / MM:g} mm"
    )
    return _generate(layout, {"A": "A", "B": "B"}, description, seed, c.angle_jitter_deg,
                     c.length_jitter, c.clearance, c.resolution)


@dataclass(frozen=True)
class VascularPhantomConfig:
    """The complex phantom: three bifurcations in 3D, straight and tortuous segments.

    Attributes:
        inlet_radius: Lumen radius at the inlet (m).
        target_radius: Lumen radius at the two targets (m); the radius tapers in between and
            must stay >= 1.75 mm for the J-tip (see the module docstring).
        angle_jitter_deg: Standard deviation of seeded random changes to every angle.
        length_jitter: Relative standard deviation of seeded random changes to every length.
        clearance: Smallest wall-to-wall gap between lumens away from junctions (m).
        resolution: Mesh and centerline sampling.
    """

    inlet_radius: float = 2.4 * MM
    target_radius: float = 1.8 * MM
    angle_jitter_deg: float = 0.0
    length_jitter: float = 0.0
    clearance: float = 1.6 * MM
    resolution: MeshResolution = field(default_factory=MeshResolution)


def vascular_phantom(config: VascularPhantomConfig = VascularPhantomConfig(),
                     seed: int = 0) -> GeneratedAnatomy:
    """Generates the complex vascular phantom.

    Layout (mm, degrees): a trunk with a 20 mm straight run and an S-bend (two 70° arcs of
    radius 9) ends at bifurcation 1. Its upper child climbs out of plane to bifurcation 2, where
    branch A takes a 100° bend (radius 10) and a 12 mm straight run; the lower child leaves
    straight below the S-bend's plane and curves down to bifurcation 3, where branch B winds
    through two opposite 80° bends (radius 10) before its end. Targets A and B are two
    bifurcations deep; the two other children are short straight side branches (distractors).

    Both targets are reachable by a scripted J-tip expert (``tests/test_expert.py``). The wire
    leaves the S-bend still heading about 20° towards the outer wall of its last arc (it lags
    the bend), so a child on that side wins whatever the tip does: with ``lower`` rolled to
    240° (in the plane of ``upper``, partly opposite the lag) no roll of the tip got the wire
    into it; at 270° (perpendicular to the lag) it does. The radius-7 bends of an earlier
    branch B stopped the wire at the 1 N tip-force limit; radius 10 lets it through.

    Args:
        config: Radii, jitter and resolution.
        seed: Only used when a jitter field of ``config`` is non-zero.
    """
    r_in, r_t = config.inlet_radius, config.target_radius
    if not 1.75 * MM <= r_t <= r_in:
        raise GeneratorConfigError(
            f"VascularPhantomConfig needs 1.75 mm <= target_radius <= inlet_radius, got "
            f"{r_t / MM:g} mm and {r_in / MM:g} mm (the J-tip needs 1.75 mm)."
        )

    def radius(fraction: float) -> float:
        return r_in + fraction * (r_t - r_in)

    layout = (
        _Branch("trunk", None, 0.0, 0.0,
                (Straight(20 * MM), Arc(70, 9 * MM, 0.0), Arc(70, 9 * MM, 180.0),
                 Straight(8 * MM)), radius(0.0), radius(0.25)),
        _Branch("upper", "trunk", 35.0, 60.0,
                (Straight(14 * MM), Arc(30, 25 * MM, 180.0)), radius(0.3), radius(0.5)),
        _Branch("lower", "trunk", 40.0, 270.0,
                (Arc(45, 20 * MM, 0.0), Straight(8 * MM)), radius(0.3), radius(0.5)),
        _Branch("A", "upper", 40.0, 0.0,
                (Straight(6 * MM), Arc(100, 10 * MM, 180.0), Straight(12 * MM)),
                radius(0.6), radius(1.0)),
        _Branch("upper_side", "upper", 35.0, 180.0, (Straight(25 * MM),),
                radius(0.6), radius(1.0)),
        _Branch("B", "lower", 45.0, 90.0,
                (Straight(5 * MM), Arc(80, 10 * MM, 0.0), Arc(80, 10 * MM, 180.0),
                 Straight(8 * MM)),
                radius(0.6), radius(1.0)),
        _Branch("lower_side", "lower", 30.0, 270.0, (Straight(20 * MM),),
                radius(0.6), radius(1.0)),
    )
    description = (
        f"complex vascular phantom: 3 bifurcations, S-bend trunk, tortuous branches A and B, "
        f"lumen radius {r_in / MM:g} mm at the inlet tapering to {r_t / MM:g} mm"
    )
    return _generate(layout, {"A": "A", "B": "B"}, description, seed, config.angle_jitter_deg,
                     config.length_jitter, config.clearance, config.resolution)
