"""Seeded random coronary-like trees: tapering radii (Murray's law), tortuous 3D branches.

The tree grows breadth first from the inlet (origin, heading +x). Every branch above the last
level splits in two. Child radii follow Murray's law ``r_p^n = r_1^n + r_2^n`` with a random
asymmetry ``r_2 / r_1``, and are then clamped to ``min_radius`` so the tree stays navigable (so
deep generations can break the law); branching angles follow Murray's minimum-work optimum
``cos θ_1 = (r_p^4 + r_1^4 - r_2^4) / (2 r_p^2 r_1^2)`` plus jitter. Tortuosity is a smooth random
curvature: the curvature vector (in the rotation-minimising frame) is Gaussian-filtered white
noise with a given RMS and correlation length, capped so the tube never folds. A child that
would come closer than ``clearance`` to another part of the tree (away from its own junction),
or pass behind the inlet close to the introducer sheath's axis, is redrawn; after
``attempts`` failures it is left out (that junction then just continues as one vessel).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from scipy.ndimage import gaussian_filter1d

from sim4endor.vessels.generators.anatomy import (
    BranchPlan,
    GeneratedAnatomy,
    MeshResolution,
    assemble,
)
from sim4endor.vessels.generators.paths import Arc, Frame, GeneratorConfigError, Segment, Straight
from sim4endor.vessels.generators.tubes import centerline_graph, clearance_violations

logger = logging.getLogger(__name__)

# Spacing used only while growing (clearance checks); the output uses the configured resolution.
_CHECK_SPACING = 0.5e-3


@dataclass(frozen=True)
class CoronaryTreeConfig:
    """Parameters of a random coronary tree (SI units; angles in degrees).

    Attributes:
        levels: Bifurcation generations along every root-to-leaf path (2-4).
        root_radius: Lumen radius at the inlet (m).
        min_radius: Smallest lumen radius anywhere (m).
        root_length: Axis length of the root branch (m).
        length_ratio: Range of child length / parent length, drawn uniformly.
        taper: Radius at a branch's end / radius at its start (before clamping).
        murray_exponent: Exponent ``n`` of Murray's law (3 for laminar flow).
        asymmetry: Range of minor / major child radius (before clamping), drawn uniformly.
        angle_jitter_deg: Standard deviation added to Murray's branching angles.
        min_angle_deg: Smallest angle between a child and its parent's direction.
        curvature_rms: RMS curvature of the axis (1/m); 0 gives straight branches.
        curvature_length: Correlation length of the curvature along the axis (m).
        max_curvature_ratio: Cap on curvature × local radius (< 1 or the tube folds).
        clearance: Smallest wall-to-wall gap between lumens away from junctions (m); two wall
            thicknesses keep the walls built around them apart.
        inlet_keep_out: Radius around the axis behind the inlet plane (where the introducer
            sheath sits) that branches keep out of (m), in addition to ``clearance``.
        inlet_straight: Straight axis length after the inlet (m), where the wire starts: the
            driver pushes 8-9 mm of straight wire, pre-bent tip included, past the sheath at
            an episode start, and a root that curved within that length put the tip inside
            the wall (pool tree 6 then blew up at the second step with no action). Like the
            ostial segment where a guide catheter seats.
        attempts: Redraws of a child before it is left out.
        resolution: Mesh and centerline sampling.
    """

    levels: int = 3
    root_radius: float = 1.6e-3
    min_radius: float = 0.85e-3
    root_length: float = 25e-3
    length_ratio: tuple[float, float] = (0.65, 0.9)
    taper: float = 0.9
    murray_exponent: float = 3.0
    asymmetry: tuple[float, float] = (0.55, 1.0)
    angle_jitter_deg: float = 8.0
    min_angle_deg: float = 15.0
    curvature_rms: float = 60.0
    curvature_length: float = 6e-3
    max_curvature_ratio: float = 0.4
    clearance: float = 1.6e-3
    inlet_keep_out: float = 3e-3
    inlet_straight: float = 12e-3
    attempts: int = 30
    resolution: MeshResolution = field(default_factory=MeshResolution)

    def __post_init__(self) -> None:
        checks = (
            (1 <= self.levels <= 5, "levels must be in 1..5"),
            (0 < self.min_radius <= self.root_radius, "need 0 < min_radius <= root_radius"),
            (self.root_length > 0, "root_length must be > 0"),
            (0 < self.length_ratio[0] <= self.length_ratio[1], "length_ratio must be (lo, hi) > 0"),
            (0 < self.taper <= 1, "taper must be in (0, 1]"),
            (0 < self.asymmetry[0] <= self.asymmetry[1] <= 1, "asymmetry must be within (0, 1]"),
            (self.curvature_rms >= 0 and self.curvature_length > 0, "curvature must be >= 0"),
            (0 < self.max_curvature_ratio < 1, "max_curvature_ratio must be in (0, 1)"),
            (min(self.clearance, self.inlet_keep_out) >= 0, "clearance and inlet_keep_out >= 0"),
            (0 <= self.inlet_straight < self.root_length,
             "inlet_straight must be in [0, root_length)"),
            (self.attempts >= 1, "attempts must be >= 1"),
        )
        for ok, message in checks:
            if not ok:
                raise GeneratorConfigError(f"CoronaryTreeConfig: {message} (got {self}).")


def murray_split(parent_radius: float, asymmetry: float, exponent: float
                 ) -> tuple[float, float, float, float]:
    """Returns child radii ``(r_1, r_2)`` and Murray's optimal angles ``(θ_1, θ_2)`` (degrees).

    Args:
        parent_radius: Radius of the parent at the junction (m).
        asymmetry: ``r_2 / r_1`` in (0, 1].
        exponent: Murray exponent ``n`` in ``r_p^n = r_1^n + r_2^n``.
    """
    r1 = parent_radius / (1.0 + asymmetry**exponent) ** (1.0 / exponent)
    r2 = asymmetry * r1
    rp2, r12, r22 = parent_radius**2, r1**2, r2**2

    def angle(own: float, other: float) -> float:
        cos = (rp2**2 + own**2 - other**2) / (2.0 * rp2 * own)
        return math.degrees(math.acos(min(1.0, max(-1.0, cos))))

    return r1, r2, angle(r12, r22), angle(r22, r12)


class Tortuosity(Protocol):
    """The curvature settings a tortuous path reads (of a tree generator's config)."""

    @property
    def curvature_rms(self) -> float: ...
    @property
    def curvature_length(self) -> float: ...
    @property
    def max_curvature_ratio(self) -> float: ...


class Clearance(Protocol):
    """The spacing settings :func:`fits` reads (of a tree generator's config)."""

    @property
    def clearance(self) -> float: ...
    @property
    def inlet_keep_out(self) -> float: ...


def tortuous_path(length: float, radius: float, config: Tortuosity,
                  rng: np.random.Generator, base: float = 0.0) -> tuple[Segment, ...]:
    """Returns a smooth random path of ``length`` metres as a run of short arcs.

    Args:
        length: Axis length (m).
        radius: Lumen radius, which caps the curvature (m).
        config: RMS and correlation length of the random curvature, and its cap.
        rng: The tree's generator.
        base: A steady curvature (1/m) added in one plane (the path's initial normal), e.g.
            an artery following the heart's surface; 0 for noise only.
    """
    piece = min(config.curvature_length / 4.0, length / 4.0)
    count = max(4, math.ceil(length / piece))
    piece = length / count
    noise = rng.standard_normal((count, 2))
    if config.curvature_rms == 0.0 and base == 0.0:
        return (Straight(length),)
    sigma = config.curvature_length / piece
    smooth = gaussian_filter1d(noise, sigma, axis=0, mode="reflect")
    # Unit RMS per component: divide by the filter's gain on white noise (its kernel's norm).
    impulse = np.zeros(8 * math.ceil(sigma) + 1)
    impulse[len(impulse) // 2] = 1.0
    gain = float(np.linalg.norm(gaussian_filter1d(impulse, sigma)))
    curvature = smooth / gain * config.curvature_rms / math.sqrt(2.0) + np.array([base, 0.0])
    magnitude = np.linalg.norm(curvature, axis=1)
    cap = config.max_curvature_ratio / radius
    segments: list[Segment] = []
    for (cx, cy), kappa in zip(curvature, np.minimum(magnitude, cap), strict=True):
        if kappa * piece < 1e-6:
            segments.append(Straight(piece))
        else:
            roll = math.degrees(math.atan2(cy, cx))
            segments.append(Arc(math.degrees(kappa * piece), 1.0 / kappa, roll))
    return tuple(segments)


def fits(plans: list[BranchPlan], candidate: BranchPlan, config: Clearance) -> bool:
    """True if ``candidate`` keeps ``config.clearance`` from the rest of the tree and out of
    the space behind the inlet where the introducer sheath is."""
    trial = [*plans, candidate]
    branches = [plan.sample(_CHECK_SPACING) for plan in trial]
    points, radii = branches[-1].points[1:], branches[-1].radii[1:]
    behind = points[:, 0] < radii + config.clearance
    if np.any(np.hypot(points[behind, 1], points[behind, 2])
              < config.inlet_keep_out + radii[behind] + config.clearance):
        return False  # around the axis behind the inlet, where the introducer sheath is
    graph = centerline_graph(branches, {})
    own = np.flatnonzero(graph.branch == len(trial) - 1)
    clashes = clearance_violations(graph, config.clearance, nodes=own, margin=_CHECK_SPACING)
    return len(clashes) == 0


def coronary_tree(config: CoronaryTreeConfig = CoronaryTreeConfig(), seed: int = 0
                  ) -> GeneratedAnatomy:
    """Generates a random coronary-like tree.

    Args:
        config: Tree parameters.
        seed: Seed of the tree's own ``numpy.random.Generator``; the same seed and config give
            the identical mesh and centerline.

    Returns:
        The anatomy; targets ``T1``, ``T2``, ... are the leaf ends in breadth-first order.
    """
    rng = np.random.default_rng(seed)
    start = Frame.start((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    root_end = max(config.taper * config.root_radius, config.min_radius)
    ostium = (Straight(config.inlet_straight),) if config.inlet_straight > 0 else ()
    root_path = ostium + tortuous_path(config.root_length - config.inlet_straight,
                                       config.root_radius, config, rng)
    plans = [BranchPlan("b0", start, root_path, config.root_radius, root_end)]
    depth = [0]
    children: dict[int, int] = {}
    index = 0
    while index < len(plans):
        if depth[index] < config.levels:
            placed = _grow_children(plans, index, config, rng)
            children[index] = placed
            depth += [depth[index] + 1] * placed
        index += 1
    leaves = [i for i in range(len(plans)) if children.get(i, 0) == 0]
    description = (
        f"random coronary tree, seed {seed}: {len(plans)} branches, {config.levels} levels, "
        f"radius {config.root_radius * 1e3:.2f}-{config.min_radius * 1e3:.2f} mm "
        f"(Murray n={config.murray_exponent:g}), curvature RMS {config.curvature_rms:g} 1/m"
    )
    return assemble(plans, {f"T{k + 1}": leaf for k, leaf in enumerate(leaves)}, description,
                    config.resolution, clearance=config.clearance)


def _grow_children(plans: list[BranchPlan], index: int, config: CoronaryTreeConfig,
                   rng: np.random.Generator) -> int:
    """Appends up to two children of ``plans[index]``; returns how many were placed.

    The first child's bifurcation plane (roll) is redrawn on every attempt; the second child
    starts on the opposite side of that plane and spreads out to any roll in its later attempts.
    """
    parent = plans[index]
    end = parent.end()
    asymmetry = rng.uniform(*config.asymmetry)
    r1, r2, angle1, angle2 = murray_split(parent.radius_end, asymmetry, config.murray_exponent)
    plane = rng.uniform(0.0, 360.0)
    placed = 0
    for k, (radius, angle) in enumerate(((r1, angle1), (r2, angle2))):
        radius = max(radius, config.min_radius)
        name = f"{parent.name}.{k}"
        for attempt in range(config.attempts):
            if k == 0:
                roll = rng.uniform(0.0, 360.0)
            else:
                spread = 20.0 if attempt < config.attempts // 2 else 90.0
                roll = plane + 180.0 + spread * rng.standard_normal()
            length = parent.length * rng.uniform(*config.length_ratio)
            jitter = config.angle_jitter_deg * rng.standard_normal()
            candidate = BranchPlan(
                name,
                end.turned(max(config.min_angle_deg, angle + jitter), roll),
                tortuous_path(length, radius, config, rng),
                radius,
                max(config.taper * radius, config.min_radius),
                parent=index,
            )
            if fits(plans, candidate, config):
                plans.append(candidate)
                plane = roll if k == 0 else plane
                placed += 1
                break
        else:
            logger.debug("left out branch %s after %d attempts", name, config.attempts)
    return placed
