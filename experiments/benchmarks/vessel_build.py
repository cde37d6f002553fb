"""Vessel build benchmark: build time, hull count, lumen-open and wall-closed fractions.

Per shipped phantom (regenerated from code with its exact centerline), for the shared real
anatomy (../shared/data/steve_bench_dualdevicenav, Slicer centerlines) when present, and for
never-seen random coronary trees (~100k faces) built with the centerline EXTRACTED from the
mesh, compared with the generator's true centerline (length ratio, 95th-percentile offset in
true radii). Builds bypass the cache. Run: ``python experiments/benchmarks/vessel_build.py``
(``--coronary-seeds 1 2 3``, ``--skip-real``). Timings depend on machine load.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from sim4endor.vessels.build import build_vessel
from sim4endor.vessels.generators import (
    GENERATORS,
    CoronaryTreeConfig,
    MeshResolution,
    coronary_tree,
)
from sim4endor.vessels.meshio import read_mesh
from sim4endor.vessels.slicer import read_slicer_centerline

REPO = Path(__file__).resolve().parents[2]
STEVE = REPO.parent / "shared" / "data" / "steve_bench_dualdevicenav"


def row(name: str, vessel, seconds: float, extra: str = "") -> None:
    checks = vessel.manifest.checks
    print(
        f"{name:28s} faces {extra:>7s}  time {seconds:6.1f} s  "
        f"hulls {vessel.manifest.hull_count:5d}"
        f"  lumen_open {checks['lumen_open']:.4f}  wall_closed {checks['wall_closed']:.4f}"
    )


def centerline_error(found, truth) -> tuple[float, float]:
    truth_points = truth.resampled_points(5e-5)
    dist, idx = cKDTree(truth_points).query(found.resampled_points(5e-5))
    radius = truth.radius_at(truth_points[idx[::10]])
    return found.total_length() / truth.total_length(), float(
        np.percentile(dist[::10] / radius, 95)
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--coronary-seeds", type=int, nargs="*", default=[1, 2])
    parser.add_argument("--skip-real", action="store_true")
    args = parser.parse_args()
    out = Path(tempfile.mkdtemp(prefix="vessel_bench_"))
    for name in ("simplified_phantom", "vascular_phantom"):
        spec = GENERATORS[name]
        anatomy = spec.generate(spec.config_type(), 0)
        start = time.perf_counter()
        vessel = build_vessel(
            anatomy.lumen,
            name=name,
            out_dir=out / name,
            centerline=anatomy.centerline,
            inlet=anatomy.inlet_position,
            targets=anatomy.targets,
            progress=False,
            cache=False,
        )
        row(name, vessel, time.perf_counter() - start, str(len(anatomy.lumen.faces)))
    if not args.skip_real and STEVE.is_dir():
        start = time.perf_counter()
        mesh = read_mesh(STEVE / "vessel_architecture_collision.obj")
        graph = read_slicer_centerline([STEVE / "centerlines"])
        vessel = build_vessel(
            mesh,
            name="steve_dualdevicenav",
            out_dir=out / "steve",
            units="mm",
            centerline=graph,
            progress=False,
            cache=False,
        )
        row("steve_dualdevicenav (real)", vessel, time.perf_counter() - start, str(len(mesh.faces)))
    for seed in args.coronary_seeds:
        config = CoronaryTreeConfig(resolution=MeshResolution(target_faces=100_000))
        anatomy = coronary_tree(config, seed=seed)
        start = time.perf_counter()
        vessel = build_vessel(
            anatomy.lumen,
            name=f"coronary_{seed}",
            out_dir=out / f"cor{seed}",
            inlet=anatomy.inlet_position,
            progress=False,
            cache=False,
        )
        seconds = time.perf_counter() - start
        ratio, p95 = centerline_error(vessel.centerline, anatomy.centerline)
        row(f"coronary seed {seed} (extracted)", vessel, seconds, str(len(anatomy.lumen.faces)))
        print(f"{'':28s} centerline length ratio {ratio:.3f}, p95 offset {p95:.3f} R")
    print(f"folders under {out}")


if __name__ == "__main__":
    main()
