"""Seeded left and right coronary trees with the calibres of normal human coronary arteries.

Unlike :func:`~sim4endor.vessels.generators.coronary.coronary_tree` (a generic random tree),
this generator follows the named arteries of ``coronary_arteries.toml``: left main → LAD
(proximal, mid, distal) with two diagonals and LCX (proximal, mid, distal) with two obtuse
marginals; or the RCA (proximal, mid, distal) with a right ventricular branch, the acute
marginal, PDA and posterolateral branch. Each
segment's start diameter is drawn from its published mean ± SD (quantitative angiography of
normal arteries); a bifurcating segment tapers to the end diameter Finet's law gives for its
children (``D_parent = 0.678 (D_1 + D_2)``). Lengths, bifurcation angles and the heart's
curve under each segment are drawn from the ranges of the file; on top, random tortuosity
(smooth curvature noise, as in ``coronary_tree``), optional tight bends of 90° and more and
optional focal stenoses.

The tree starts in a guide catheter: a rigid tube of the catheter's inner radius (7F:
0.081 in inner diameter) seated coaxially in the ostium, where the wire starts, so the free
wire enters the artery at the ostium as in PCI. Its wall is part of the vessel's wall hulls.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from typing import Any, Literal

import numpy as np

from sim4endor.vessels.generators.anatomy import (
    BranchPlan,
    GeneratedAnatomy,
    MeshResolution,
    Stenosis,
    assemble,
)
from sim4endor.vessels.generators.coronary import fits, tortuous_path
from sim4endor.vessels.generators.paths import Arc, Frame, GeneratorConfigError, Segment, Straight
from sim4endor.vessels.meshio import MeshInputError, prepare_lumen

#: Finet's law: parent diameter = FINET × (sum of the two daughter diameters).
FINET = 0.678
#: Inner diameter of a 7F guide catheter, 0.081 in (m).
GUIDE_7F_INNER_DIAMETER = 0.081 * 0.0254

Side = Literal["left", "right"]
#: Draws of one seed before a tree with its trunks whole and a mesh without sliver faces is
#: given up on.
_ATTEMPTS = 5


@dataclass(frozen=True)
class ArterySegment:
    """One named segment of ``coronary_arteries.toml`` (figures as (mean, sd)).

    Attributes:
        name: Segment name, e.g. ``"LAD_mid"``; a target's label.
        parent: Name of the segment it branches from (``""`` for the first).
        diameter: Lumen diameter at its start (mm).
        distal_diameter: Lumen diameter at its end (mm), for segments that do not bifurcate.
        length: Axis length (mm).
        angle: Angle from the parent's end direction (deg).
        roll: Plane of that angle about the parent's axis (deg).
        turn: Steady curve of the segment in its plane (deg).
    """

    name: str
    parent: str
    diameter: tuple[float, float]
    length: tuple[float, float]
    angle: tuple[float, float]
    roll: tuple[float, float]
    turn: tuple[float, float]
    distal_diameter: tuple[float, float] | None = None


def arteries(side: Side) -> tuple[ArterySegment, ...]:
    """Returns the segments of the left or right coronary tree, parents first."""
    text = resources.files(__package__).joinpath("coronary_arteries.toml").read_text("utf-8")
    rows: list[dict[str, Any]] = tomllib.loads(text)[side]

    def pair(row: dict[str, Any], key: str) -> tuple[float, float]:
        mean, sd = row[key]
        return float(mean), float(sd)

    return tuple(
        ArterySegment(
            name=row["name"], parent=row["parent"], diameter=pair(row, "diameter"),
            length=pair(row, "length"), angle=pair(row, "angle"), roll=pair(row, "roll"),
            turn=pair(row, "turn"),
            distal_diameter=pair(row, "distal_diameter") if "distal_diameter" in row else None,
        )
        for row in rows
    )


@dataclass(frozen=True)
class CoronaryArteriesConfig:
    """Parameters of a generated left or right coronary tree (SI units; angles in degrees).

    Attributes:
        side: ``"left"`` (LM, LAD, LCX) or ``"right"`` (RCA).
        size_sd: Spread of the drawn diameters and lengths in published SDs, clipped at 2 SD
            (0: the mean sizes). Angles, rolls and turns keep their SDs, unclipped.
        min_diameter: Smallest drawn lumen diameter (m): the vessels PCI treats, and the
            calibre a 0.014 in wire is steered through, are 1.5 mm and wider.
        stenoses: Number of focal stenoses, on distinct segments drawn at random.
        stenosis_severity: Range of diameter reduction of a stenosis (fraction).
        stenosis_length: Range of a stenosis' axial length (m).
        min_angle_deg: Smallest angle between a segment and its parent's end direction.
        tight_bend_probability: Chance that a segment has one tight bend (drawn only where its
            arc fits in the segment's drawn length with a fifth to spare).
        tight_bend_angle_deg: Range of a tight bend's angle.
        tight_bend_radius: Range of a tight bend's axis radius, in lumen radii (>= 2.5: the
            swept tube folds below 1 / ``max_curvature_ratio`` radii).
        curvature_rms: RMS of the random curvature (1/m) on top of each segment's steady turn.
        curvature_length: Correlation length of the random curvature (m).
        max_curvature_ratio: Cap on curvature × local lumen radius.
        catheter_radius: Inner radius of the guide catheter (m); default 7F.
        catheter_length: Length of the catheter's tip modelled before the ostium (m).
        ostium_length: Length over which the lumen widens from the catheter to the artery (m).
        clearance: Smallest wall-to-wall gap between lumens away from junctions (m).
        inlet_keep_out: Radius around the axis behind the inlet (the driver's sheath) that
            branches keep out of (m), in addition to ``clearance``.
        attempts: Redraws of a segment that does not fit before it is left out (with its
            children; a parent left with no child ends in a target). A main vessel (a
            parent's first child listed, its continuation, or a segment with children of its
            own) is never left out: the whole tree is drawn again instead.
        resolution: Mesh and centerline sampling.
    """

    side: Side = "left"
    size_sd: float = 1.0
    min_diameter: float = 1.5e-3
    stenoses: int = 0
    stenosis_severity: tuple[float, float] = (0.3, 0.7)
    stenosis_length: tuple[float, float] = (4e-3, 10e-3)
    min_angle_deg: float = 15.0
    tight_bend_probability: float = 0.3
    tight_bend_angle_deg: tuple[float, float] = (90.0, 120.0)
    tight_bend_radius: tuple[float, float] = (2.6, 4.0)
    curvature_rms: float = 30.0
    curvature_length: float = 6e-3
    max_curvature_ratio: float = 0.4
    catheter_radius: float = GUIDE_7F_INNER_DIAMETER / 2
    catheter_length: float = 15e-3
    ostium_length: float = 2e-3
    clearance: float = 1.6e-3
    inlet_keep_out: float = 3e-3
    attempts: int = 30
    resolution: MeshResolution = field(default_factory=MeshResolution)

    def __post_init__(self) -> None:
        checks = (
            (self.side in ("left", "right"), "side must be 'left' or 'right'"),
            (self.size_sd >= 0, "size_sd must be >= 0"),
            (self.min_diameter > 0, "min_diameter must be > 0"),
            (0 <= self.stenoses <= 3, "stenoses must be in 0..3"),
            (0 < self.stenosis_severity[0] <= self.stenosis_severity[1] < 1,
             "stenosis_severity must be (lo, hi) within (0, 1)"),
            (0 < self.stenosis_length[0] <= self.stenosis_length[1],
             "stenosis_length must be (lo, hi) > 0"),
            (0 < self.min_angle_deg < 90, "min_angle_deg must be in (0, 90)"),
            (0 <= self.tight_bend_probability <= 1, "tight_bend_probability must be in [0, 1]"),
            (0 < self.tight_bend_angle_deg[0] <= self.tight_bend_angle_deg[1] <= 180,
             "tight_bend_angle_deg must be (lo, hi) within (0, 180]"),
            (1 / self.max_curvature_ratio <= self.tight_bend_radius[0]
             <= self.tight_bend_radius[1], "tight_bend_radius must be >= 1/max_curvature_ratio"),
            (self.curvature_rms >= 0 and self.curvature_length > 0, "curvature must be >= 0"),
            (0 < self.max_curvature_ratio < 1, "max_curvature_ratio must be in (0, 1)"),
            (min(self.catheter_radius, self.catheter_length, self.ostium_length) > 0,
             "the catheter's radius and lengths must be > 0"),
            (min(self.clearance, self.inlet_keep_out) >= 0, "clearance and inlet_keep_out >= 0"),
            (self.attempts >= 1, "attempts must be >= 1"),
        )
        for ok, message in checks:
            if not ok:
                raise GeneratorConfigError(f"CoronaryArteriesConfig: {message} (got {self}).")


@dataclass(frozen=True)
class AnatomyVariation:
    """Ranges a ``wide`` tree's generator settings are drawn from, one draw per seed: anatomy
    beyond the normal arteries of the default settings, as elderly and diseased adults have it
    (issue 79, "train wide").

    Every range holds the default setting, so a wide pool holds normal trees too. Tortuosity:
    the default 30 1/m RMS curvature at 6 mm correlation up to 110 1/m at 2.5 mm, S-bends and
    wiggles of a few millimetres' wavelength (radius of curvature down to 9 mm RMS; the cap of
    ``max_curvature_ratio`` is kept, so no tube folds). Stenoses: up to two focal narrowings of
    50-70 % diameter, the range between a "significant" (>= 50 %) and a severe one in the
    ACC/AHA grading (Scanlon et al., J Am Coll Cardiol 1999;33:1756-1824). Calibre: diameters
    spread over 1.5 published SDs (clipped at 2), the smallest kept at 1.2 mm (0.6 mm radius),
    the distal calibres a 0.014 in wire still reaches.

    Attributes:
        curvature_rms: Range of ``CoronaryArteriesConfig.curvature_rms`` (1/m).
        curvature_length: Range of its correlation length (m).
        tight_bend_probability: Range of the chance of a tight bend per segment.
        stenoses: Inclusive range of the number of stenoses.
        stenosis_severity: Their diameter reduction (fraction).
        size_sd: Spread of diameters and lengths in published SDs.
        min_diameter: Smallest drawn lumen diameter (m).
    """

    curvature_rms: tuple[float, float] = (30.0, 110.0)
    curvature_length: tuple[float, float] = (2.5e-3, 6e-3)
    tight_bend_probability: tuple[float, float] = (0.3, 0.7)
    stenoses: tuple[int, int] = (0, 2)
    stenosis_severity: tuple[float, float] = (0.5, 0.7)
    size_sd: float = 1.5
    min_diameter: float = 1.2e-3

    def draw(self, side: Side, seed: int) -> CoronaryArteriesConfig:
        """The generator settings of the wide tree of ``seed``: the same seed, the same
        settings. Drawn from a stream of their own, apart from the tree's (which
        :func:`coronary_arteries` seeds with ``seed``)."""
        rng = np.random.default_rng([seed, _VARIATION_STREAM])
        return CoronaryArteriesConfig(
            side=side,
            size_sd=self.size_sd,
            min_diameter=self.min_diameter,
            stenoses=int(rng.integers(self.stenoses[0], self.stenoses[1] + 1)),
            stenosis_severity=self.stenosis_severity,
            tight_bend_probability=float(rng.uniform(*self.tight_bend_probability)),
            curvature_rms=float(rng.uniform(*self.curvature_rms)),
            curvature_length=float(rng.uniform(*self.curvature_length)),
        )


#: Second entry of the seed sequence of a wide tree's settings (any constant; it keeps their
#: stream apart from the tree's own).
_VARIATION_STREAM = 79


@dataclass(frozen=True)
class _Drawn:
    """A segment's drawn figures (m, deg)."""

    spec: ArterySegment
    diameter: float
    distal_diameter: float
    length: float
    stenosis: Stenosis | None


def coronary_arteries(config: CoronaryArteriesConfig = CoronaryArteriesConfig(), seed: int = 0
                      ) -> GeneratedAnatomy:
    """Generates a left or right coronary tree behind a guide catheter.

    Args:
        config: Tree parameters.
        seed: Seed of the tree's own ``numpy.random.Generator``; the same seed and config give
            the identical mesh and centerline.

    Returns:
        The anatomy; its inlet is the catheter's proximal end and its targets are the distal
        ends of the tree, labelled by artery (e.g. ``LAD_distal``, ``D1``, ``OM1``).
    """
    # The tube union now and then leaves sliver faces whose removal by the importer opens the
    # surface (1 of 80 trees measured), and now and then a main vessel's continuation finds no
    # room (right seed 3005's distal RCA: the RCA then ended in a 65° kink into its acute
    # marginal, no anatomy); such a draw is replaced by the next one of the seed's own
    # sequence, so a seed still gives one tree.
    error: Exception
    for attempt in range(_ATTEMPTS):
        rng = np.random.default_rng(seed if attempt == 0 else [seed, attempt])
        try:
            anatomy = _generate(config, seed, rng)
        except _TrunkCut as exc:
            error = exc
            continue
        try:
            prepare_lumen(anatomy.lumen, units="m", source=f"coronary_arteries seed {seed}")
        except MeshInputError as exc:
            error = exc
            continue
        return anatomy
    raise GeneratorConfigError(f"Every one of {_ATTEMPTS} draws failed: {error}")


class _TrunkCut(Exception):
    """A main vessel's continuation found no room in the tree."""


def _generate(config: CoronaryArteriesConfig, seed: int, rng: np.random.Generator
              ) -> GeneratedAnatomy:
    drawn = _draw(arteries(config.side), config, rng)
    root = drawn[0]
    start = Frame.start((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    # The root artery's branch begins inside the guide catheter, whose bore widens into it at
    # the ostium (one branch: coaxial tubes joined end to end leave sliver faces).
    ostium = config.catheter_length + config.ostium_length
    plans = [BranchPlan(
        root.spec.name, start,
        (Straight(ostium), *_path(root, config, rng)),
        config.catheter_radius, root.distal_diameter / 2,
        inlet_radii=((config.catheter_length, config.catheter_radius),
                     (ostium, root.diameter / 2)),
    )]
    index_of = {root.spec.name: 0}
    children: dict[str, int] = {}
    # The main vessels: every segment with branches of its own (the LCX off the left main) and
    # each one's first child listed, its continuation.
    continuation: dict[str, str] = {}
    for segment in drawn[1:]:
        continuation.setdefault(segment.spec.parent, segment.spec.name)
    main = set(continuation) | set(continuation.values())
    for segment in drawn[1:]:
        parent = index_of.get(segment.spec.parent)
        if parent is None:
            continue  # its parent was left out
        plan = _place(plans, parent, segment, config, rng)
        if plan is None and segment.spec.name in main:
            raise _TrunkCut(f"{segment.spec.name} found no room in {config.attempts} draws")
        if plan is not None:
            index_of[segment.spec.name] = len(plans)
            plans.append(plan)
            children[segment.spec.parent] = children.get(segment.spec.parent, 0) + 1
    targets = {name: index for name, index in index_of.items() if children.get(name, 0) == 0}
    stenosed = [s.spec.name for s in drawn if s.stenosis is not None and s.spec.name in index_of]
    description = (
        f"{config.side} coronary tree, seed {seed}: {len(plans)} arteries "
        f"({', '.join(index_of)}), lumen diameter "
        f"{root.diameter * 1e3:.2f}-{min(s.distal_diameter for s in drawn) * 1e3:.2f} mm, "
        f"behind a guide catheter of {2 * config.catheter_radius * 1e3:.2f} mm inner diameter"
        + (f"; stenoses in {', '.join(stenosed)}" if stenosed else "")
    )
    return assemble(plans, targets, description, config.resolution, clearance=config.clearance)


def _draw(specs: tuple[ArterySegment, ...], config: CoronaryArteriesConfig,
          rng: np.random.Generator) -> list[_Drawn]:
    """Draws every segment's diameters, length and stenosis; bifurcations obey Finet's law."""

    def normal(figure: tuple[float, float]) -> float:
        mean, sd = figure
        return mean + float(np.clip(rng.standard_normal(), -2.0, 2.0)) * sd * config.size_sd

    def diameter(figure: tuple[float, float]) -> float:
        return max(normal(figure) * 1e-3, config.min_diameter)

    start = {s.name: diameter(s.diameter) for s in specs}
    lengths = {s.name: max(normal(s.length), 0.3 * s.length[0]) * 1e-3 for s in specs}
    # Not in the root: its branch starts in the catheter (and a left-main lesion is its own
    # procedure).
    narrowed = set(rng.choice([s.name for s in specs[1:]], size=config.stenoses, replace=False))
    drawn = []
    for spec in specs:
        kids = [start[s.name] for s in specs if s.parent == spec.name]
        if spec.distal_diameter is not None:
            end = diameter(spec.distal_diameter)
        elif len(kids) >= 2:
            end = FINET * sum(sorted(kids)[-2:])
        else:
            end = kids[0] if kids else start[spec.name]
        # A lumen narrows downstream: clamp the law's end diameter into [largest child, start].
        end = min(max(end, max(kids, default=0.0)), start[spec.name])
        stenosis = None
        if spec.name in narrowed:
            stenosis = Stenosis(float(rng.uniform(0.3, 0.7)),
                                float(rng.uniform(*config.stenosis_length)),
                                float(rng.uniform(*config.stenosis_severity)))
        drawn.append(_Drawn(spec, start[spec.name], end, lengths[spec.name], stenosis))
    return drawn


def _place(plans: list[BranchPlan], parent: int, segment: _Drawn,
           config: CoronaryArteriesConfig, rng: np.random.Generator) -> BranchPlan | None:
    """Draws the segment's path until it keeps clear of the tree; None after ``attempts``."""
    spec = segment.spec
    end = plans[parent].end()
    for _ in range(config.attempts):
        # Not below min_angle_deg: a child coaxial with its parent's end leaves sliver faces.
        angle = max(config.min_angle_deg, rng.normal(*spec.angle))
        turned = end.turned(angle, rng.normal(*spec.roll))
        candidate = BranchPlan(
            spec.name, turned, _path(segment, config, rng), segment.diameter / 2,
            segment.distal_diameter / 2, parent=parent, stenosis=segment.stenosis,
        )
        if fits(plans, candidate, config):
            return candidate
    return None


def _path(segment: _Drawn, config: CoronaryArteriesConfig,
          rng: np.random.Generator) -> tuple[Segment, ...]:
    """The segment's axis: its steady turn with random tortuosity, maybe one tight bend."""
    length, radius = segment.length, segment.diameter / 2
    steady = math.radians(max(0.0, rng.normal(*segment.spec.turn))) / length
    if rng.uniform() >= config.tight_bend_probability:
        return tortuous_path(length, radius, config, rng, base=steady)
    bend = float(rng.uniform(*config.tight_bend_angle_deg))
    bend_radius = float(rng.uniform(*config.tight_bend_radius)) * radius
    arc_length = math.radians(bend) * bend_radius
    room = length - arc_length
    if room < 0.2 * length:
        # No room for the bend in the artery's drawn length (a 10 mm left main cannot hold the
        # 9-19 mm arc of a 90-120 deg bend on 2.6-4 of its radii): no tight bend. Drawing it
        # anyway made such a segment up to twice as long as drawn, curled behind the catheter.
        return tortuous_path(length, radius, config, rng, base=steady)
    before = float(rng.uniform(0.3, 0.7)) * room
    after = room - before
    return (
        *tortuous_path(before, radius, config, rng, base=steady),
        Arc(bend, bend_radius, float(rng.uniform(0.0, 360.0))),
        *tortuous_path(after, radius, config, rng, base=steady),
    )
