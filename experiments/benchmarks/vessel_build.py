"""Vessel build benchmark: build time, hull count, lumen-open and wall-closed fractions.

Every vessel is built twice, with the wall decomposition ``hull`` (plain hulls + bisection) and
``coacd`` (the default: CoACD also tried where bisection needs three or more hulls). Vessels:
per shipped phantom (regenerated from code with its exact centerline; the shipped folders are
pinned to ``hull``), the shared real anatomy (../shared/data/steve_bench_dualdevicenav, Slicer
centerlines registered onto the lumen; the raw curves' lumen-open figure is printed too) when
present, and never-seen random coronary trees (~100k faces) built with the centerline
EXTRACTED from the mesh, compared with the generator's true centerline (length ratio,
95th-percentile offset in true radii). Builds bypass the cache. Run:
``python experiments/benchmarks/vessel_build.py`` (``--coronary-seeds 1 2 3``, ``--skip-real``,
``--workers 1``). Timings depend on machine load.
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from sim4endor.vessels import Vessel
from sim4endor.vessels.build import BuildParams, build_vessel
from sim4endor.vessels.generators import (
    GENERATORS,
    SHIPPED_PHANTOM_WALL,
    CoronaryTreeConfig,
    MeshResolution,
    coronary_tree,
)
from sim4endor.vessels.meshio import read_mesh
from sim4endor.vessels.register import RegistrationParams
from sim4endor.vessels.slicer import read_slicer_centerline
from sim4endor.vessels.walls import WallParams

REPO = Path(__file__).resolve().parents[2]
STEVE = REPO.parent / "shared" / "data" / "steve_bench_dualdevicenav"
METHODS = ("hull", "coacd")


def row(name: str, method: str, vessel: Vessel, seconds: float, faces: int) -> None:
    checks = vessel.manifest.checks
    given = checks.get("lumen_open_given_centerline")
    print(
        f"{name:28s} {method:5s} faces {faces:7d}  time {seconds:6.1f} s  "
        f"hulls {vessel.manifest.hull_count:5d}  lumen_open {checks['lumen_open']:.4f}  "
        f"wall_closed {checks['wall_closed']:.4f}"
        + ("" if given is None else f"  (given curves: lumen_open {given:.4f})")
    )


def centerline_error(found, truth) -> tuple[float, float]:
    truth_points = truth.resampled_points(5e-5)
    dist, idx = cKDTree(truth_points).query(found.resampled_points(5e-5))
    radius = truth.radius_at(truth_points[idx[::10]])
    return found.total_length() / truth.total_length(), float(
        np.percentile(dist[::10] / radius, 95)
    )


def both(build: Callable[[WallParams], Vessel], workers: int, name: str, faces: int) -> Vessel:
    """Builds with each decomposition method, prints a row each; returns the CoACD build.

    ``hull`` is the pinned wall of the shipped phantoms; ``coacd`` the default wall.
    """
    vessel = None
    for method in METHODS:
        wall = SHIPPED_PHANTOM_WALL if method == "hull" else WallParams()
        start = time.perf_counter()
        vessel = build(dataclasses.replace(wall, workers=workers))
        row(name, method, vessel, time.perf_counter() - start, faces)
    assert vessel is not None
    return vessel


def build_generated(anatomy, name: str, out: Path, extracted: bool, wall: WallParams) -> Vessel:
    """Builds a generated anatomy; ``extracted`` ignores its true centerline and targets."""
    return build_vessel(
        anatomy.lumen, name=name, out_dir=out / name,
        centerline=None if extracted else anatomy.centerline, inlet=anatomy.inlet_position,
        targets=None if extracted else anatomy.targets, params=BuildParams(wall=wall),
        progress=False, cache=False,
    )


def build_real(out: Path, wall: WallParams) -> Vessel:
    """Builds the shared real anatomy with its Slicer curves registered onto the lumen."""
    return build_vessel(
        read_mesh(STEVE / "vessel_architecture_collision.obj"), name="steve_dualdevicenav",
        out_dir=out / "steve", units="mm",
        centerline=read_slicer_centerline([STEVE / "centerlines"]),
        registration=RegistrationParams(), params=BuildParams(wall=wall), progress=False,
        cache=False,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--coronary-seeds", type=int, nargs="*", default=[1, 2])
    parser.add_argument("--skip-real", action="store_true")
    parser.add_argument("--workers", type=int, default=2, help="processes for the wall")
    args = parser.parse_args()
    out = Path(tempfile.mkdtemp(prefix="vessel_bench_"))
    for name in ("simplified_phantom", "vascular_phantom"):
        spec = GENERATORS[name]
        anatomy = spec.generate(spec.config_type(), 0)
        both(partial(build_generated, anatomy, name, out, False), args.workers, name,
             len(anatomy.lumen.faces))
    if not args.skip_real and STEVE.is_dir():
        faces = len(read_mesh(STEVE / "vessel_architecture_collision.obj").faces)
        both(partial(build_real, out), args.workers, "steve_dualdevicenav (real)", faces)
    for seed in args.coronary_seeds:
        config = CoronaryTreeConfig(resolution=MeshResolution(target_faces=100_000))
        anatomy = coronary_tree(config, seed=seed)
        vessel = both(partial(build_generated, anatomy, f"coronary_{seed}", out, True),
                      args.workers, f"coronary seed {seed} (extracted)", len(anatomy.lumen.faces))
        ratio, p95 = centerline_error(vessel.centerline, anatomy.centerline)
        print(f"{'':28s} centerline length ratio {ratio:.3f}, p95 offset {p95:.3f} R")
    print(f"folders under {out}")


if __name__ == "__main__":
    main()
