"""What every generator returns, and the shared step from a branch plan to a lumen + centerline."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import trimesh

from sim4endor.vessels.centerline import INLET_LABEL, CenterlineGraph, arc_lengths
from sim4endor.vessels.generators.paths import (
    Arc,
    FloatArray,
    Frame,
    GeneratorConfigError,
    Segment,
    path_length,
    trace,
)
from sim4endor.vessels.generators.tubes import (
    TubeBranch,
    centerline_graph,
    clearance_violations,
    lumen_mesh,
)


@dataclass(frozen=True)
class MeshResolution:
    """How finely the lumen surface and the centerline are sampled.

    Attributes:
        circumferential_segments: Vertices around each ring of the tube.
        axial_spacing: Largest distance between rings, which are also the centerline nodes (m).
        target_faces: If set, ``axial_spacing`` is replaced by the spacing that gives about this
            many triangles for the whole tree (before the union trims the overlaps).
    """

    circumferential_segments: int = 32
    axial_spacing: float = 0.5e-3
    target_faces: int | None = None

    def __post_init__(self) -> None:
        if self.circumferential_segments < 8:
            raise GeneratorConfigError(
                f"circumferential_segments must be >= 8, got {self.circumferential_segments}."
            )
        if self.axial_spacing <= 0:
            raise GeneratorConfigError(f"axial_spacing must be > 0 m, got {self.axial_spacing}.")
        if self.target_faces is not None and self.target_faces < 1000:
            raise GeneratorConfigError(f"target_faces must be >= 1000, got {self.target_faces}.")

    def spacing_for(self, total_length: float) -> float:
        """Returns the axial spacing (m) to use for a tree whose axes sum to ``total_length``."""
        if self.target_faces is None:
            return self.axial_spacing
        # Each ring-to-ring band holds 2 * segments triangles.
        return total_length * 2 * self.circumferential_segments / self.target_faces


@dataclass(frozen=True)
class GeneratedAnatomy:
    """A generated vessel: the input to ``sim4endor.vessels.build.build_vessel``.

    Attributes:
        lumen: Watertight lumen (blood pool) surface in model metres; flat at the inlet,
            hemispherical caps at every other end.
        centerline: The exact axis the lumen was swept along (m), labelled ``"inlet"`` and with
            each target name.
        inlet_position: Centre of the inlet disc (m).
        inlet_direction: Unit vector pointing into the vessel at the inlet.
        targets: Named target points (m), each a terminal centerline node.
        description: One-line provenance for the README and manifest ``source``.
    """

    lumen: trimesh.Trimesh
    centerline: CenterlineGraph
    inlet_position: FloatArray
    inlet_direction: FloatArray
    targets: Mapping[str, FloatArray]
    description: str


@dataclass(frozen=True)
class Stenosis:
    """A focal narrowing of a branch: a cosine-shaped dip of the lumen diameter.

    Attributes:
        center: Where along the branch, as a fraction of its length.
        length: Axial length of the narrowing (m).
        severity: Diameter reduction at its centre (0.5 = 50 % diameter stenosis).
    """

    center: float
    length: float
    severity: float

    def __post_init__(self) -> None:
        if not (0 < self.center < 1 and self.length > 0 and 0 < self.severity < 1):
            raise GeneratorConfigError(
                f"Stenosis needs 0 < center < 1, length > 0 and 0 < severity < 1, got {self}."
            )

    def factor(self, arc: FloatArray, branch_length: float) -> FloatArray:
        """Diameter factor (1 outside the narrowing) at arc lengths ``arc`` (m)."""
        offset = np.abs(arc - self.center * branch_length) / (0.5 * self.length)
        dip = 0.5 * (1.0 + np.cos(np.pi * np.minimum(offset, 1.0)))
        return 1.0 - self.severity * dip


@dataclass(frozen=True, eq=False)
class BranchPlan:
    """A branch before sampling: where it starts, its path and its radius taper.

    Attributes:
        name: Branch name.
        start: Frame at the first point (the parent's end point for a child).
        segments: The axis path.
        radius_start: Lumen radius at the first point (m).
        radius_end: Lumen radius at the last point (m); linear in arc length between.
        parent: Index of the parent plan, ``None`` for the root.
        stenosis: An optional focal narrowing on top of the taper.
        inlet_radii: Optional (arc length (m), radius (m)) knots replacing the linear taper
            up to the last knot's arc length, where it joins ``radius_end``'s taper at the
            knot's radius: e.g. a guide catheter's bore widening into the ostium. Part of
            the same branch because coaxial tubes joined end to end leave sliver faces.
    """

    name: str
    start: Frame
    segments: tuple[Segment, ...]
    radius_start: float
    radius_end: float
    parent: int | None = None
    stenosis: Stenosis | None = None
    inlet_radii: tuple[tuple[float, float], ...] = ()

    @property
    def length(self) -> float:
        """Axis length (m)."""
        return path_length(self.segments)

    def end(self) -> Frame:
        """Returns the frame at the branch's last point."""
        return trace(self.start, self.segments, spacing=math.inf)[1]

    def sample(self, spacing: float) -> TubeBranch:
        """Returns the branch sampled about every ``spacing`` metres."""
        points, _ = trace(self.start, self.segments, spacing)
        arc = arc_lengths(points)
        knots = [(0.0, self.radius_start), *self.inlet_radii, (float(arc[-1]), self.radius_end)]
        radii = np.interp(arc, [a for a, _ in knots], [r for _, r in knots])
        if self.stenosis is not None:
            radii = radii * self.stenosis.factor(arc, float(arc[-1]))
        return TubeBranch(self.name, points, radii, self.parent)


def check_bends(plan: BranchPlan, max_curvature_ratio: float = 0.5) -> None:
    """Raises if an arc of ``plan`` bends tighter than ``1 / max_curvature_ratio`` radii."""
    radius = max(plan.radius_start, plan.radius_end)
    for segment in plan.segments:
        if isinstance(segment, Arc) and segment.radius * max_curvature_ratio < radius:
            raise GeneratorConfigError(
                f"Branch {plan.name!r}: arc radius {segment.radius * 1e3:.2f} mm is tighter than "
                f"{1 / max_curvature_ratio:g} lumen radii ({radius * 1e3:.2f} mm); the swept tube "
                "would fold. Use a larger arc radius or a smaller lumen radius."
            )


def assemble(plans: Sequence[BranchPlan], targets: Mapping[str, int], description: str,
             resolution: MeshResolution, *, clearance: float) -> GeneratedAnatomy:
    """Samples the plans and builds the lumen and centerline.

    Args:
        plans: The tree, parents before children; exactly one root (plan 0).
        targets: Target name -> index of the branch whose end point is the target.
        description: Provenance line.
        resolution: Mesh and centerline sampling.
        clearance: Smallest wall-to-wall gap between lumens away from junctions (m).

    Raises:
        GeneratorConfigError: If two parts of the tree come closer than ``clearance``.
    """
    spacing = resolution.spacing_for(sum(plan.length for plan in plans))
    branches = [plan.sample(spacing) for plan in plans]
    labels = {INLET_LABEL: (0, 0), **{name: (b, -1) for name, b in targets.items()}}
    graph = centerline_graph(branches, labels)
    clashes = clearance_violations(graph, clearance)
    if len(clashes):
        i, j = clashes[0]
        names, branch = graph.branch_names, np.asarray(graph.branch)
        raise GeneratorConfigError(
            f"Branches {names[branch[i]]!r} and {names[branch[j]]!r} come within "
            f"{clearance * 1e3:g} mm of each other near {np.round(graph.nodes[i] * 1e3, 1)} mm; "
            "change their angles or lengths."
        )
    lumen = lumen_mesh(branches, resolution.circumferential_segments)
    return GeneratedAnatomy(
        lumen=lumen,
        centerline=graph,
        inlet_position=graph.nodes[graph.labels[INLET_LABEL]].copy(),
        inlet_direction=plans[0].start.tangent.copy(),
        targets={name: graph.nodes[graph.labels[name]].copy() for name in targets},
        description=description,
    )
