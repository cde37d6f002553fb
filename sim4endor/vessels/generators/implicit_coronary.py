"""Coronary trees written apart from the training generators, for judging a policy outside them.

The policies are trained on :mod:`.coronary` and :mod:`.coronary_arteries` trees: named or
random branches traced in rotation-minimising frames with curvature noise, swept into exact
tubes, built on their exact axes. This family shares none of that (issue 79):

* **parametrisation**: the tree lies on the heart, an ellipsoid of 40-50 mm semi-axes; every
  branch is a walk on its surface whose heading drifts as an Ornstein-Uhlenbeck process (S-bends
  at a wavelength drawn per tree), plus a wiggle of 4-10 mm wavelength along the surface
  normal; no branch comes within 1 mm of another or of itself away from its junction; side
  branches leave the trunk at 30-100 degrees in the surface's tangent plane, sometimes as a
  trifurcation at its end; calibres follow Murray's law with an exponent drawn from 2.3-3.0
  (Kassab's morphometry gives about 2.3-3 over the coronary tree: G. S. Kassab, "Scaling laws
  of vascular trees", Am J Physiol Heart Circ Physiol 290:H894-H903, 2006) and an asymmetry
  ratio drawn per branch, the smallest kept at 0.6 mm radius; a focal stenosis of 50-70 %
  diameter on some trunks;
* **code path**: the lumen is the zero level set of a sampled distance field, meshed by
  marching cubes on a 0.15 mm grid like a CTA segmentation (scikit-image), not a tube union,
  and the folder is built from that surface as a user's mesh is, its centerline extracted from
  the mesh (:func:`build_folder`).

Use it only to evaluate: training or tuning on it would make it one more training family.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import trimesh
from numpy.typing import NDArray

from sim4endor.vessels.generators.paths import GeneratorConfigError

if TYPE_CHECKING:
    from sim4endor.vessels import Vessel

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ImplicitCoronaryConfig:
    """Ranges a tree is drawn from (lengths in mm, angles in degrees).

    Attributes:
        heart_axes: Semi-axes of the heart ellipsoid (mm), each scaled by a draw in ``scale``.
        scale: Overall anatomy scale.
        inlet_radius: Lumen radius at the ostium (mm).
        trunk_length: Trunk length (mm).
        side_branches: Side branches off the trunk (inclusive range).
        side_length: Side-branch length (mm).
        take_off: Angle between the trunk and a side branch (deg).
        murray_exponent: Murray's-law exponent of the tree.
        asymmetry: Daughter-to-continuation radius ratio at a side branch.
        min_radius: Branches that would end narrower are not drawn (mm); only a stenosis
            narrows a lumen below it.
        taper: Radius at a branch's end over its start.
        heading_noise: Standard deviation of the heading's drift (deg per sqrt(mm)).
        wavelength: Correlation length of the heading's drift (mm): the S-bends' scale.
        wiggle: Amplitude (mm) and wavelength range (mm) of the short radial wiggle.
        gap: Least gap between two vessels' walls away from their junction (mm); a branch
            that would come nearer, to another or to itself, is drawn again (ten tries).
        trifurcation: Chance that the trunk ends in three branches.
        stenosis: Chance of one focal stenosis on the trunk, and its diameter loss range.
        voxel: Marching-cubes grid spacing (mm).
    """

    heart_axes: tuple[float, float, float] = (45.0, 40.0, 50.0)
    scale: tuple[float, float] = (0.85, 1.15)
    inlet_radius: tuple[float, float] = (1.4, 1.9)
    trunk_length: tuple[float, float] = (55.0, 80.0)
    side_branches: tuple[int, int] = (3, 6)
    side_length: tuple[float, float] = (20.0, 40.0)
    take_off: tuple[float, float] = (30.0, 100.0)
    murray_exponent: tuple[float, float] = (2.3, 3.0)
    asymmetry: tuple[float, float] = (0.5, 0.85)
    min_radius: float = 0.6
    taper: float = 0.8
    heading_noise: tuple[float, float] = (1.0, 3.0)
    wavelength: tuple[float, float] = (4.0, 10.0)
    wiggle: tuple[float, tuple[float, float]] = (0.4, (4.0, 10.0))
    gap: float = 1.0
    trifurcation: float = 0.3
    stenosis: tuple[float, tuple[float, float]] = (0.5, (0.5, 0.7))
    voxel: float = 0.15


@dataclass(frozen=True)
class ImplicitTree:
    """A drawn tree: its lumen surface and where a wire enters and should go (m).

    Attributes:
        lumen: Closed lumen surface in metres, flat at the inlet.
        inlet: Centre of the inlet disc.
        targets: A point at each distal end, named ``E1``, ``E2``, ... by distance from the inlet.
        axes: Each branch's axis samples (N, 3) and lumen radii (N,), trunk first: what the
            surface was meshed from, for checks; the build does not see them.
        description: One line of provenance.
    """

    lumen: trimesh.Trimesh
    inlet: FloatArray
    targets: dict[str, FloatArray]
    axes: tuple[tuple[FloatArray, FloatArray], ...]
    description: str


@dataclass(frozen=True)
class _Branch:
    points: FloatArray  # (N, 3) mm, 0.1 mm apart
    radii: FloatArray  # (N,) mm


def _surface_normal(points: FloatArray, axes: FloatArray) -> FloatArray:
    """Unit outward normals of the ellipsoid of semi-axes ``axes`` at ``points`` on it."""
    normal = points / axes**2
    if normal.ndim == 1:  # np.linalg.norm rounds a lone vector otherwise than a row of many
        return np.asarray(normal / np.linalg.norm(normal))
    return np.asarray(normal / np.linalg.norm(normal, axis=1, keepdims=True))


def _take_off(point: FloatArray, tangent: FloatArray, axes: FloatArray, angle: float
              ) -> FloatArray:
    """The direction ``angle`` (rad) off ``tangent`` in the heart's tangent plane at ``point``."""
    length = np.linalg.norm(tangent)
    side = np.cross(_surface_normal(point, axes), tangent / length)
    return np.asarray(np.cos(angle) * tangent / length + np.sin(angle) * side)


def _surface_walk(rng: np.random.Generator, axes: FloatArray, start: FloatArray,
                  heading: FloatArray, length: float, noise: float, wavelength: float,
                  step: float = 0.1) -> FloatArray:
    """A walk on the ellipsoid from ``start`` whose heading turns by an Ornstein-Uhlenbeck
    rate (deg per mm) that decorrelates over ``wavelength`` mm."""
    count = max(2, int(length / step))
    points = np.empty((count, 3))
    point, rate = start.copy(), 0.0
    for k in range(count):
        normal = _surface_normal(point, axes)
        heading = heading - (heading @ normal) * normal
        heading /= np.linalg.norm(heading)
        rate += -rate * step / wavelength + noise * np.sqrt(step) * rng.standard_normal()
        turn = np.radians(rate * step)
        side = np.cross(normal, heading)
        heading = np.cos(turn) * heading + np.sin(turn) * side
        point = point + step * heading
        point = point / np.sqrt(np.sum((point / axes) ** 2))  # back onto the surface
        points[k] = point
    return points


def _wiggled(rng: np.random.Generator, points: FloatArray, axes: FloatArray,
             amplitude: float, wavelengths: tuple[float, float]) -> FloatArray:
    """Moves the walk along the surface normal by a sum of three short sinusoids."""
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    normal = _surface_normal(points, axes)
    offset = sum(amplitude / 3 * np.sin(2 * np.pi * arc / rng.uniform(*wavelengths)
                                        + rng.uniform(0, 2 * np.pi)) for _ in range(3))
    ramp = np.minimum(1.0, arc / 3.0)  # the ostium stays put
    return np.asarray(points + (ramp * offset)[:, None] * normal)


def _clear(path: FloatArray, radius: float, drawn: list[_Branch], gap: float) -> bool:
    """Whether ``path`` keeps ``gap`` between walls from the ``drawn`` branches and from
    itself, away from its first point (its junction)."""
    from scipy.spatial import cKDTree

    free = np.linalg.norm(path - path[0], axis=1) > 2 * radius + 3 * gap
    if not free.any():
        return True
    far = path[free]
    for other in drawn:
        nearest, index = cKDTree(other.points).query(far)
        if np.any(nearest < radius + other.radii[index] + gap):
            return False
    arc = 0.1 * np.arange(len(path))
    pairs = cKDTree(path).query_pairs(2 * radius + gap, output_type="ndarray")
    return not np.any(np.abs(arc[pairs[:, 0]] - arc[pairs[:, 1]]) > np.pi * (2 * radius + gap))


def _draw(config: ImplicitCoronaryConfig, seed: int) -> tuple[list[_Branch], FloatArray]:
    rng = np.random.default_rng(seed)
    axes = np.asarray(config.heart_axes) * rng.uniform(*config.scale)
    exponent = rng.uniform(*config.murray_exponent)
    noise, wavelength = rng.uniform(*config.heading_noise), rng.uniform(*config.wavelength)
    amplitude, wavelengths = config.wiggle
    polar = rng.uniform(0.2, 0.5) * np.pi
    start = axes * np.array([np.sin(polar), 0.0, np.cos(polar)])
    heading = np.array([np.cos(polar), rng.uniform(-0.5, 0.5), -np.sin(polar)])

    def walk(origin: FloatArray, direction: FloatArray, length: float, radius: float,
             drawn: list[_Branch]) -> FloatArray | None:
        for _ in range(10):
            path = _surface_walk(rng, axes, origin, direction, length, noise, wavelength)
            path = _wiggled(rng, path, axes, amplitude, wavelengths)
            if _clear(path, radius, drawn, config.gap):
                return path
        return None

    radius = rng.uniform(*config.inlet_radius)
    trunk = walk(start, heading, rng.uniform(*config.trunk_length), radius, [])
    if trunk is None:
        raise GeneratorConfigError(f"implicit_coronary seed {seed}: no trunk clear of itself "
                                   "in ten draws; lower heading_noise")
    trunk_r = np.full(len(trunk), radius)
    branches: list[_Branch] = []
    count = int(rng.integers(config.side_branches[0], config.side_branches[1] + 1))
    positions = np.sort(rng.uniform(0.15, 0.85, count)) * (len(trunk) - 1)
    for position in positions.astype(int):
        alpha = rng.uniform(*config.asymmetry)
        main = trunk_r[position] / (1 + alpha**exponent) ** (1 / exponent)  # Murray
        child = alpha * main
        if child * config.taper < config.min_radius:
            continue
        tangent = trunk[min(position + 1, len(trunk) - 1)] - trunk[max(position - 1, 0)]
        angle = np.radians(rng.uniform(*config.take_off)) * rng.choice([-1.0, 1.0])
        direction = _take_off(trunk[position], tangent, axes, angle)
        path = walk(trunk[position], direction, rng.uniform(*config.side_length), child,
                    [_Branch(trunk, trunk_r), *branches])
        if path is not None:  # the trunk carries on narrower past a branch it gave off
            branches.append(_Branch(path, np.linspace(child, child * config.taper, len(path))))
            trunk_r[position:] *= main / trunk_r[position]
    trunk_r *= np.linspace(1.0, config.taper, len(trunk))
    trunk_r = np.maximum(trunk_r, config.min_radius)
    chance, loss = config.stenosis
    if rng.uniform() < chance:  # a cosine dip of 50-70 % diameter over 4-6 lumen radii
        at = int(rng.uniform(0.3, 0.7) * len(trunk))
        width = rng.uniform(4, 6) * trunk_r[at] / 0.1
        dip = np.clip(1 - np.abs(np.arange(len(trunk)) - at) / (width / 2), 0, 1)
        trunk_r *= 1 - rng.uniform(*loss) * 0.5 * (1 - np.cos(np.pi * dip))
    if rng.uniform() < config.trifurcation:
        end, tangent = trunk[-1], trunk[-1] - trunk[-2]
        for sign in (-1.0, 1.0):
            child = trunk_r[-1] * rng.uniform(*config.asymmetry)
            if child * config.taper < config.min_radius:
                continue
            direction = _take_off(end, tangent, axes, sign * np.radians(rng.uniform(30, 60)))
            path = walk(end, direction, rng.uniform(*config.side_length), child,
                        [_Branch(trunk, trunk_r), *branches])
            if path is not None:
                branches.append(_Branch(path, np.linspace(child, child * config.taper,
                                                          len(path))))
    return [_Branch(trunk, trunk_r), *branches], heading


def _lumen(branches: list[_Branch], inlet_direction: FloatArray, voxel: float
           ) -> trimesh.Trimesh:
    """Marching cubes of the distance field ``min_i(|x - p_i| - r_i)`` over the branches'
    samples, cut flat at the trunk's first point (mm in, mm out)."""
    from skimage.measure import marching_cubes

    samples = np.vstack([b.points for b in branches])
    radii = np.concatenate([b.radii for b in branches])
    pad = float(radii.max()) + 3 * voxel
    lo = samples.min(axis=0) - pad
    shape = np.ceil((samples.max(axis=0) + pad - lo) / voxel).astype(int) + 1
    field = np.full(shape, 4 * voxel, dtype=np.float32)  # beyond the band: outside
    grid = [lo[k] + voxel * np.arange(shape[k]) for k in range(3)]
    for point, radius in zip(samples[::2], radii[::2], strict=True):  # 0.2 mm apart
        reach = radius + 2 * voxel
        index = [slice(max(0, int((point[k] - reach - lo[k]) / voxel)),
                       min(shape[k], int((point[k] + reach - lo[k]) / voxel) + 2))
                 for k in range(3)]
        x, y, z = (grid[k][index[k]] for k in range(3))
        distance = np.sqrt((x[:, None, None] - point[0]) ** 2 + (y[None, :, None] - point[1]) ** 2
                           + (z[None, None, :] - point[2]) ** 2) - radius
        block = tuple(index)
        field[block] = np.minimum(field[block], distance)
    inlet = branches[0].points[0]
    gx, gy, gz = np.meshgrid(*grid, indexing="ij", sparse=True)
    behind = -((gx - inlet[0]) * inlet_direction[0] + (gy - inlet[1]) * inlet_direction[1]
               + (gz - inlet[2]) * inlet_direction[2])
    # Only around the ostium: a branch curving back behind the inlet's plane stays whole.
    near = ((gx - inlet[0]) ** 2 + (gy - inlet[1]) ** 2 + (gz - inlet[2]) ** 2
            < (2.5 * branches[0].radii[0]) ** 2)
    field = np.where(near, np.maximum(field, behind.astype(np.float32)), field)
    vertices, faces, _, _ = marching_cubes(field, level=0.0, spacing=(voxel,) * 3)
    mesh = trimesh.Trimesh(vertices + lo, faces)
    if mesh.volume < 0:  # marching cubes winds its faces by the field's sign convention
        mesh.invert()
    return mesh


def implicit_coronary(config: ImplicitCoronaryConfig, seed: int) -> ImplicitTree:
    """Draws tree ``seed`` (the same seed gives the same surface)."""
    branches, heading = _draw(config, seed)
    lumen = _lumen(branches, heading, config.voxel)
    parts = lumen.split(only_watertight=False)
    lumen = max(parts, key=lambda m: len(m.faces))  # a lost sliver of a tight wiggle
    inlet = branches[0].points[0]
    ends = sorted((b.points[-1] for b in branches),
                  key=lambda p: float(np.linalg.norm(p - inlet)))
    lumen.apply_scale(1e-3)
    return ImplicitTree(
        lumen=lumen,
        inlet=inlet * 1e-3,
        targets={f"E{k + 1}": end * 1e-3 for k, end in enumerate(ends)},
        axes=tuple((b.points * 1e-3, b.radii * 1e-3) for b in branches),
        description=f"implicit_coronary seed {seed}: {len(branches)} branches on the heart's "
                    f"surface, marching cubes at {config.voxel:g} mm",
    )


def build_folder(seed: int, out_dir: Path, config: ImplicitCoronaryConfig | None = None,
                 progress: bool = False) -> Vessel:
    """Draws tree ``seed`` and builds it as a user's mesh (:func:`build_tree`)."""
    return build_tree(implicit_coronary(config or ImplicitCoronaryConfig(), seed), seed,
                      out_dir, progress)


def build_tree(tree: ImplicitTree, seed: int, out_dir: Path, progress: bool = False) -> Vessel:
    """Builds the drawn tree ``seed`` as a user's mesh: the centerline extracted from the
    surface, the inlet and the distal ends given as points."""
    from sim4endor.vessels.build import build_vessel

    return build_vessel(tree.lumen, name=f"implicit_coronary_{seed}", out_dir=out_dir,
                        units="m", inlet=tree.inlet, targets=tree.targets,
                        source=tree.description, progress=progress)
