"""Hand-written parts vs the libraries that could replace them (docs/design_choices.md).

Each section measures sim4endor's own code and its candidate library on the project's data:
correctness first, then time. The candidates are not dependencies of sim4endor; install the
ones to compare into the environment first::

    pip install kimimaro==5.8.5 pymeshfix==0.18.1 shapely==2.2.0 tabulate==0.10.0

(libigl is a dependency since signed distance moved to it.) A missing candidate skips its
rows. Run ``python experiments/benchmarks/hand_written_vs_library.py`` (all sections) or name
some: ``skeleton``, ``signed_distance``, ``holes``, ``sweep``, ``scene``, ``table``. The shared
real anatomy is read from ``../shared/data/steve_bench_dualdevicenav`` (``--data``) when present.
``signed_distance`` times whatever ``sim4endor.vessels.register.signed_distance`` is, so running
it at commit 13d51e1 gives the hand-written version's figures. Timings depend on machine load.
"""

from __future__ import annotations

import argparse
import importlib.util
import itertools
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import mujoco
import numpy as np
import trimesh
from scipy.spatial import cKDTree

from sim4endor.vessels import skeleton as sk
from sim4endor.vessels.centerline import CenterlineGraph
from sim4endor.vessels.generators import (
    CoronaryTreeConfig,
    SimplifiedPhantomConfig,
    VascularPhantomConfig,
    coronary_tree,
    simplified_phantom,
    tubes,
    vascular_phantom,
)
from sim4endor.vessels.meshio import boundary_loops, capped, prepare_lumen, read_mesh
from sim4endor.vessels.mjcf_writer import write_scene
from sim4endor.vessels.register import signed_distance

STEVE_MESH = "vessel_architecture_collision.obj"


def _has(module: str) -> bool:
    found = importlib.util.find_spec(module) is not None
    if not found:
        print(f"  ({module} not installed: its rows are skipped)")
    return found


def _timed(fn: Callable[[], object]) -> tuple[float, object]:
    start = time.perf_counter()
    out = fn()
    return time.perf_counter() - start, out


def _trees() -> dict[str, Callable[[], object]]:
    return {
        "simplified_phantom": lambda: simplified_phantom(SimplifiedPhantomConfig(), 0),
        "vascular_phantom": lambda: vascular_phantom(VascularPhantomConfig(), 0),
        "coronary seed 11": lambda: coronary_tree(CoronaryTreeConfig(), seed=11),
        "coronary seed 3": lambda: coronary_tree(CoronaryTreeConfig(), seed=3),
    }


def _axis_error(found: CenterlineGraph, truth: CenterlineGraph) -> str:
    """Length ratio and 95th-percentile offset (true radii), inside and within 3 R of an end."""
    truth_points = truth.resampled_points(5e-5)
    points = found.resampled_points(5e-5)
    dist, idx = cKDTree(truth_points).query(points)
    rel = dist / truth.radius_at(truth_points[idx])
    near_end = cKDTree(truth.nodes[truth.terminal_nodes()]).query(points)[0] < 3 * (
        truth.radius_at(truth_points[idx])
    )
    return (
        f"length {found.total_length() / truth.total_length():.3f}, ends "
        f"{len(found.terminal_nodes())}/{len(truth.terminal_nodes())}, p95 offset "
        f"{np.percentile(rel[~near_end], 95):.2f} R inside, {np.percentile(rel[near_end], 95):.2f} "
        f"R near ends (max {rel[near_end].max():.2f} R)"
    )


def _kimimaro_centerline(mesh: trimesh.Trimesh, radius: float) -> tuple[float, CenterlineGraph]:
    """kimimaro's TEASAR on sim4endor's voxel grid, then sim4endor's pruning and resampling."""
    import kimimaro

    params = sk.SkeletonParams()
    extent = mesh.bounds[1] - mesh.bounds[0]
    pitch = radius / params.voxels_per_radius
    pitch = max(pitch, float(np.cbrt(np.prod(extent + 2 * pitch) / params.max_voxels)))
    grid, origin = sk.voxelize(mesh, pitch)
    teasar = {"scale": 3.0, "const": 2.0, "pdrf_scale": 100000, "pdrf_exponent": 4,
              "soma_detection_threshold": 1e9, "soma_acceptance_threshold": 1e9,
              "soma_invalidation_scale": 1, "soma_invalidation_const": 1}
    seconds, skeletons = _timed(lambda: kimimaro.skeletonize(
        grid.astype(np.uint8), teasar_params=teasar, dust_threshold=0, fix_branching=True,
        fix_borders=False, progress=False))
    skel = skeletons[1]
    points, radii = origin + skel.vertices * pitch, skel.radius * pitch
    edges = sk._prune(points, radii, skel.edges.astype(np.int64), params.spur_length)
    used = np.unique(edges)
    remap = np.full(len(points), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    return seconds, sk._assemble(points[used], radii[used], remap[edges], params, pitch)


def skeleton(_: argparse.Namespace) -> None:
    print("skeleton: centerline of generated trees vs their exact centerline")
    kimi = _has("kimimaro")
    for name, make in _trees().items():
        anatomy = make()
        prepared = prepare_lumen(anatomy.lumen, units="m")
        mesh, radius = capped(prepared), prepared.radius_estimate
        truth = anatomy.centerline
        seconds, graph = _timed(lambda m=mesh, r=radius: sk.extract_centerline(
            m, sk.SkeletonParams(), radius_hint=r))
        print(f"  {name}: sim4endor {seconds:.2f} s (voxels to graph); {_axis_error(graph, truth)}")
        if kimi:
            total, (core, graph) = _timed(lambda m=mesh, r=radius: _kimimaro_centerline(m, r))
            print(f"  {name}: kimimaro  {total:.2f} s (skeletonize {core:.2f} s); "
                  f"{_axis_error(graph, truth)}")


def _signed_distance_case(name: str, mesh: trimesh.Trimesh, near: int, far: int) -> None:
    import igl

    rng = np.random.default_rng(0)
    face = rng.integers(len(mesh.faces), size=near)
    on_wall = np.einsum("ij,ijk->ik", rng.dirichlet([1, 1, 1], size=near), mesh.triangles[face])
    edge = float(np.median(mesh.edges_unique_length))
    points = np.vstack([on_wall + rng.normal(size=(near, 3)) * 0.1 * edge,
                        rng.uniform(*mesh.bounds, size=(far, 3))])
    vertices, faces = np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)
    inside = igl.winding_number(vertices, faces, points) > 0.5  # exact on a closed surface
    exact = np.sqrt(igl.point_mesh_squared_distance(points, vertices, faces)[0])
    print(f"  {name}: {len(mesh.faces)} faces, {len(points)} points ({near} near the wall)")
    candidates = {"sim4endor": lambda: signed_distance(mesh, points)}
    if len(mesh.faces) < 10_000:  # ray parity without embree runs out of memory on more
        candidates["trimesh"] = lambda: trimesh.proximity.signed_distance(mesh.copy(), points)
    for label, fn in candidates.items():
        seconds, value = _timed(fn)
        value = np.asarray(value)
        wrong = (value > 0) != inside
        print(f"    {label:9s} {seconds:6.2f} s, wrong sign {int(wrong.sum())}, "
              f"|distance| error max {np.abs(np.abs(value) - exact).max() * 1e3:.3f} mm")


def signed_distance_section(args: argparse.Namespace) -> None:
    print("signed distance (positive inside) vs libigl's winding number and exact distance")
    steve = args.data / STEVE_MESH
    if steve.is_file():
        _signed_distance_case("stEVE collision mesh", capped(prepare_lumen(
            read_mesh(steve), units="mm")), 20_000, 20_000)
    lumen = coronary_tree(CoronaryTreeConfig(), seed=11).lumen
    _signed_distance_case("coronary seed 11", capped(prepare_lumen(lumen, units="m")),
                          20_000, 20_000)


def _open_tube() -> trimesh.Trimesh:
    tube = trimesh.creation.cylinder(radius=1.5e-3, height=20e-3, sections=32)
    tube = tube.subdivide_to_size(1.5e-3)
    tube.update_faces(np.abs(tube.face_normals[:, 2]) < 0.5)
    tube.remove_unreferenced_vertices()
    tube.merge_vertices()
    return tube


def holes(_: argparse.Namespace) -> None:
    print("hole filling: open tube (2 vessel ends) with side holes")
    tube = _open_tube()
    z = tube.triangles_center[:, 2]
    side = np.flatnonzero(np.abs(tube.face_normals[:, 2]) < 0.1)
    two = [side[np.argmin(np.abs(z[side] + 5e-3))], side[np.argmin(np.abs(z[side] - 5e-3))]]
    around = tube.face_adjacency[(tube.face_adjacency == two[0]).any(axis=1)].ravel()
    three = [two[0], *[int(f) for f in around if f != two[0]][:2]]
    for label, gone in (("two 1-triangle holes", two), ("one 3-triangle hole", three)):
        holed = tube.copy()
        holed.update_faces(np.setdiff1d(np.arange(len(tube.faces)), gone))
        holed.remove_unreferenced_vertices()
        sizes = sorted(len(loop) for loop in boundary_loops(holed))
        print(f"  {label} (boundary loop sizes {sizes})")
        seconds, prepared = _timed(lambda h=holed: prepare_lumen(h, units="m",
                                                                 max_hole_perimeter=4.0))
        report = prepared.report
        print(f"    sim4endor prepare_lumen {seconds * 1e3:.0f} ms (all checks): filled "
              f"{report.filled_holes}, vessel ends kept {report.open_ends}")
        for fan in (False, True):
            mesh = holed.copy()
            seconds, _ = _timed(lambda m=mesh, f=fan: trimesh.repair.fill_holes(m, use_fan=f))
            left = sorted(len(loop) for loop in boundary_loops(mesh))
            print(f"    trimesh fill_holes(use_fan={fan}) {seconds * 1e3:.1f} ms: loops left "
                  f"{left}")
        if _has("pymeshfix"):
            import pymeshfix

            seconds, (v, f) = _timed(lambda h=holed: pymeshfix.clean_from_arrays(
                np.array(h.vertices, dtype=np.float64), np.array(h.faces, dtype=np.int32)))
            left = sorted(len(loop) for loop in boundary_loops(trimesh.Trimesh(v, f)))
            print(f"    pymeshfix {seconds * 1e3:.0f} ms: loops left {left}, faces "
                  f"{len(holed.faces)} -> {len(f)}")


def sweep(_: argparse.Namespace) -> None:
    print("tube sweep: the vascular phantom's branches (tapering radii)")
    captured: list[tuple[np.ndarray, np.ndarray, int, dict[str, bool]]] = []
    original = tubes.sweep_tube

    def spy(points: np.ndarray, radii: np.ndarray, segments: int, **kw: bool) -> object:
        captured.append((points, radii, segments, kw))
        return original(points, radii, segments, **kw)

    tubes.sweep_tube = spy
    try:
        vascular_phantom(VascularPhantomConfig(), 0)
    finally:
        tubes.sweep_tube = original
    shapely = _has("shapely")
    ours = library = 0.0
    reach = {"sim4endor": [], "sweep_polygon": []}  # type: dict[str, list[float]]
    for points, radii, segments, kw in captured:
        dense = np.vstack([np.linspace(a, b, 20) for a, b in itertools.pairwise(points)])
        dense_r = np.concatenate([np.linspace(a, b, 20) for a, b in itertools.pairwise(radii)])
        tree = cKDTree(dense)
        seconds, (vertices, _) = _timed(lambda p=points, r=radii, s=segments, k=kw:
                                        original(p, r, s, **k))
        ours += seconds
        dist, j = tree.query(vertices)
        reach["sim4endor"].append(float((dist / dense_r[j]).max()))
        if shapely:
            from shapely.geometry import Point

            circle = Point(0, 0).buffer(float(radii.mean()), quad_segs=segments // 4)
            seconds, mesh = _timed(lambda c=circle, p=points:
                                   trimesh.creation.sweep_polygon(c, p))
            library += seconds
            dist, j = tree.query(mesh.vertices)
            reach["sweep_polygon"].append(float((dist / dense_r[j]).max()))
    for label, seconds in (("sim4endor", ours), ("sweep_polygon", library)):
        if reach[label]:
            print(f"  {label}: {seconds * 1e3:.1f} ms for {len(captured)} branches; farthest "
                  f"vertex from the axis {max(reach[label]):.3f} local radii")


def scene(_: argparse.Namespace) -> None:
    print("scene.xml: ElementTree with <include> vs MjSpec.to_xml")
    folder = Path(__file__).resolve().parents[2] / "vessels" / "simplified_phantom"
    centre, extent = np.array([0.05, 0.0, 0.0]), 0.11
    with tempfile.TemporaryDirectory() as tmp:
        seconds, path = _timed(lambda: write_scene(Path(tmp), name="x", extent=extent,
                                                   vessel_file="simplified_phantom.xml",
                                                   centre=centre))
        lines = len(path.read_text().splitlines())
    print(f"  ElementTree: {seconds * 1e3:.2f} ms, {lines} lines, includes the vessel file")
    start = time.perf_counter()
    spec = mujoco.MjSpec.from_file(str(folder / "simplified_phantom.xml"))
    spec.stat.center, spec.stat.extent = centre, extent
    top = centre + np.array([0.0, 0.0, 2 * extent])
    spec.worldbody.add_light(name="top", pos=top, dir=[0, 0, -1])
    spec.worldbody.add_camera(name="overview", pos=top)
    xml = spec.to_xml()
    print(f"  MjSpec: {(time.perf_counter() - start) * 1e3:.0f} ms, {len(xml.splitlines())} "
          f"lines, <include> kept: {'<include' in xml}, meshes copied in: {xml.count('<mesh ')}")


def table(_: argparse.Namespace) -> None:
    from sim4endor.rl.table import RunResult, markdown_table

    print("markdown table: Table I of 36 runs")
    results = [RunResult(a, r, "simplified_phantom", t, s, 10, 7 + s, 5.2)
               for a in ("ddpg", "sac", "ppo") for r in ("manifold", "euclidean")
               for t in ("task_a", "task_b") for s in range(3)]
    text = markdown_table(results)
    seconds, _ = _timed(lambda: [markdown_table(results) for _ in range(1000)])
    print(f"  sim4endor: {seconds:.3f} ms per table (pooling included)")
    if _has("tabulate"):
        import tabulate

        lines = text.splitlines()
        header = [c.strip() for c in lines[0].strip("|").split("|")]
        rows = [[c.strip() for c in line.strip("|").split("|")] for line in lines[2:]]
        seconds, out = _timed(lambda: [tabulate.tabulate(rows, header, tablefmt="github",
                                                         disable_numparse=True)
                                       for _ in range(1000)])
        same = out[0] + "\n" == text
        print(f"  tabulate: {seconds:.3f} ms per table (formatting only); same text: {same}; "
              f"first row: {out[0].splitlines()[2][:60]}...")


SECTIONS: dict[str, Callable[[argparse.Namespace], None]] = {
    "skeleton": skeleton, "signed_distance": signed_distance_section, "holes": holes,
    "sweep": sweep, "scene": scene, "table": table,
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sections", nargs="*", help=f"any of {', '.join(SECTIONS)} (default: all)")
    parser.add_argument("--data", type=Path, default=Path(__file__).resolve().parents[3]
                        / "shared" / "data" / "steve_bench_dualdevicenav")
    args = parser.parse_args()
    unknown = set(args.sections) - set(SECTIONS)
    if unknown:
        parser.error(f"unknown section(s) {sorted(unknown)}; choose from {list(SECTIONS)}")
    for name in args.sections or SECTIONS:
        SECTIONS[name](args)


if __name__ == "__main__":
    main()
