"""build_vessel on small synthetic tubes: output contract, checks, MuJoCo loading, cache, CLI."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh

from sim4endor import vessels
from sim4endor.cli import main
from sim4endor.vessels import build as build_module
from sim4endor.vessels.build import BuildError, BuildParams, build_vessel
from sim4endor.vessels.centerline import CenterlineGraph
from sim4endor.vessels.checks import check_folder
from sim4endor.vessels.mjcf_writer import HULL_DIR, hull_mesh_name
from sim4endor.vessels.walls import WallParams

R = 1.5e-3
L = 20e-3
SERIAL = BuildParams(wall=WallParams(workers=1))


def straight_tube() -> tuple[trimesh.Trimesh, CenterlineGraph]:
    """A capped straight tube along z (m) and its exact centerline."""
    tube = trimesh.creation.cylinder(radius=R, height=L, sections=24).subdivide_to_size(1.2e-3)
    n = 41
    z = np.linspace(-L / 2, L / 2, n)
    graph = CenterlineGraph(
        np.column_stack([np.zeros(n), np.zeros(n), z]),
        np.full(n, R),
        np.column_stack([np.arange(n - 1), np.arange(1, n)]),
    )
    return tube, graph


@pytest.fixture(autouse=True)
def _private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> vessels.Vessel:
    os.environ.setdefault("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("cache")))
    tube, graph = straight_tube()
    out = tmp_path_factory.mktemp("v") / "tube"
    return build_vessel(
        tube, name="tube", out_dir=out, centerline=graph, params=SERIAL, progress=False,
        cache=False, inlet=np.array([0.0, 0.0, -L / 2]), license_text="MIT test",
    )


def test_output_contract(built: vessels.Vessel) -> None:
    root = built.root
    for name in ("manifest.json", "tube.xml", "scene.xml", "centerline.json", "lumen.stl",
                 "README.md", "LICENSE"):
        assert (root / name).is_file(), name
    hulls = sorted((root / "hulls").glob("hull_*.stl"))
    assert len(hulls) == built.manifest.hull_count > 8
    assert (root / "hulls" / "hull_000.stl").read_bytes()[:5] != b"solid"  # binary STL
    manifest = json.loads((root / "manifest.json").read_text())
    assert manifest["mjcf"] == "tube.xml" and manifest["units"] == "m"
    assert np.allclose(np.asarray(manifest["mesh_to_model"]), np.eye(4))
    np.testing.assert_allclose(built.inlet_direction, [0, 0, 1], atol=1e-6)
    np.testing.assert_allclose(built.inlet_position, [0, 0, -L / 2], atol=1e-9)
    assert built.manifest.inlet.radius == pytest.approx(R)
    assert set(built.targets) == {"T1"}
    np.testing.assert_allclose(built.targets["T1"], [0, 0, L / 2], atol=1e-9)
    labels = built.centerline.labels
    assert labels["inlet"] == 0 and labels["T1"] == built.centerline.num_nodes - 1


def test_checks_pass_and_are_recorded(built: vessels.Vessel) -> None:
    checks = built.manifest.checks
    assert checks["lumen_open"] == 1.0
    assert checks["wall_closed"] >= 0.99
    assert checks["build_time_s"] > 0
    report = check_folder(built)
    assert report["passed"] and report["compiles"]
    assert report["hull_count"] == built.manifest.hull_count


def test_mjcf_names_classes_and_loads_without_warnings(built: vessels.Vessel) -> None:
    for path in (built.mjcf_path, built.scene_path):
        model = mujoco.MjModel.from_xml_path(str(path))
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        assert sum(w.number for w in data.warning) == 0
    model = mujoco.MjModel.from_xml_path(str(built.mjcf_path))
    wall = model.geom("wall_000")
    assert int(wall.contype[0]) == 2 and int(wall.conaffinity[0]) == 1
    np.testing.assert_allclose(wall.solimp, [0.99, 0.999, 0.0001, 0.5, 2])
    np.testing.assert_allclose(wall.solref, [0.004, 1])
    assert wall.friction[0] == pytest.approx(0.1)
    lumen = model.geom("lumen")
    assert int(lumen.contype[0]) == 0 and int(lumen.conaffinity[0]) == 0
    np.testing.assert_allclose(model.site("inlet").pos, built.inlet_position)
    np.testing.assert_allclose(model.site("target_T1").pos, built.targets["T1"])
    assert "../" not in built.mjcf_path.read_text()  # self-contained folder


def test_inlet_cap_has_no_wall(built: vessels.Vessel) -> None:
    """A wire enters along +z at the inlet: no hull may cover the inlet disc."""
    model = mujoco.MjModel.from_xml_path(str(built.mjcf_path))
    disc = np.array([[x, y, -L / 2 - 1e-4] for x in (-5e-4, 0, 5e-4) for y in (-5e-4, 0, 5e-4)])
    hulls = [trimesh.load(p, force="mesh") for p in sorted((built.root / "hulls").glob("*.stl"))]
    for hull in hulls:
        assert np.all(trimesh.proximity.signed_distance(hull, disc) < 0)
    assert model.ngeom == built.manifest.hull_count + 1


def test_hulls_keep_lumen_open_and_wall_closed_exactly(built: vessels.Vessel) -> None:
    """Independent of the build's own checks: exact signed distances with trimesh."""
    hulls = [trimesh.load(p, force="mesh") for p in sorted((built.root / "hulls").glob("*.stl"))]
    axis = np.column_stack([np.zeros(30), np.zeros(30), np.linspace(-L / 2 + R, L / 2 - R, 30)])
    for hull in hulls:
        assert np.all(trimesh.proximity.signed_distance(hull, axis) < -0.4 * R)
    ring = np.array([[(R + 4e-4) * np.cos(a), (R + 4e-4) * np.sin(a), z]
                     for a in np.linspace(0, 2 * np.pi, 17)[:-1] for z in (-5e-3, 0, 5e-3)])
    depth = np.full(len(ring), -np.inf)  # trimesh: positive inside; points on a face count
    for hull in hulls:
        depth = np.maximum(depth, trimesh.proximity.signed_distance(hull, ring))
    assert np.all(depth > -1e-7)


def test_cache_makes_rebuild_instant_and_identical(tmp_path: Path) -> None:
    tube, graph = straight_tube()
    first = build_vessel(tube, name="t", out_dir=tmp_path / "a", centerline=graph, params=SERIAL,
                         progress=False)
    start = time.perf_counter()
    second = build_vessel(tube, name="t", out_dir=tmp_path / "b", centerline=graph,
                          params=SERIAL, progress=False)
    assert time.perf_counter() - start < first.manifest.checks["build_time_s"]
    assert first.manifest.content_hash == second.manifest.content_hash
    assert (first.root / "t.xml").read_text() == (second.root / "t.xml").read_text()
    thicker = BuildParams(wall=WallParams(workers=1, thickness=1e-3))
    third = build_vessel(tube, name="t", out_dir=tmp_path / "c", centerline=graph,
                         params=thicker, progress=False)
    assert third.manifest.content_hash != first.manifest.content_hash


def test_mm_units_scale_to_metres(tmp_path: Path) -> None:
    tube, graph = straight_tube()
    tube_mm = tube.copy()
    tube_mm.apply_scale(1e3)
    vessel = build_vessel(tube_mm, name="mm", out_dir=tmp_path / "mm", units="mm",
                          centerline=graph, params=SERIAL, progress=False, cache=False,
                          targets={"A": np.array([0.0, 0.0, 10.0])})
    assert vessel.manifest.mesh_to_model_matrix[0, 0] == pytest.approx(1e-3)
    np.testing.assert_allclose(vessel.targets["A"], [0, 0, 0.01])
    assert trimesh.load(vessel.root / "lumen.stl").bounds[1][2] == pytest.approx(L / 2)


def test_cli_build_check_list(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                              capsys: pytest.CaptureFixture[str]) -> None:
    tube, graph = straight_tube()
    mesh_path = tmp_path / "tube.stl"
    tube.export(mesh_path)
    graph.save(tmp_path / "centerline.json")
    out = tmp_path / "vessels" / "clitube"
    status = main(["vessel", "build", str(mesh_path), "--name", "clitube", "--out", str(out),
                   "--units", "m", "--centerline", str(tmp_path / "centerline.json"),
                   "--workers", "1", "--no-progress", "--decomposition", "hull"])
    assert status == 0 and "lumen open 1.0000" in capsys.readouterr().out
    assert vessels.load(out).manifest.build["wall"]["use_coacd"] is False
    assert main(["vessel", "check", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["passed"] is True
    monkeypatch.setenv("SIM4ENDOR_VESSEL_PATH", str(tmp_path / "vessels"))
    assert main(["vessel", "list"]) == 0
    assert "clitube" in capsys.readouterr().out.split()


def test_open_ended_tube_with_extracted_centerline(tmp_path: Path) -> None:
    tube, _ = straight_tube()
    tube.update_faces(np.abs(tube.face_normals[:, 2]) < 0.5)  # no caps: open vessel ends
    tube.remove_unreferenced_vertices()
    vessel = build_vessel(tube, name="open", out_dir=tmp_path / "open", params=SERIAL,
                          progress=False, cache=False)
    assert vessel.manifest.build["repairs"]["open_ends"] == 2
    assert vessel.centerline.total_length() == pytest.approx(L, rel=0.1)
    assert abs(float(vessel.inlet_direction[2])) == pytest.approx(1.0, abs=0.05)
    assert vessel.manifest.checks["lumen_open"] >= 0.99
    assert vessel.manifest.checks["wall_closed"] >= 0.95


def test_a_model_mujoco_refuses_is_a_named_build_error_and_writes_nothing(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """If MuJoCo cannot compile what the build wrote, the build raises a BuildError naming
    the vessel, the hull and MuJoCo's reason, not MuJoCo's traceback, and leaves no folder."""
    write_meshes = build_module.write_meshes

    def with_a_three_vertex_hull(folder: Path, hulls: list, lumen: trimesh.Trimesh,
                                 display: trimesh.Trimesh | None) -> int:
        parts = write_meshes(folder, hulls, lumen, display)
        three = trimesh.Trimesh([[0, 0, 0], [1e-3, 0, 0], [0, 1e-3, 0], [0, 1e-3, 0]],
                                [[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]], process=False)
        three.export(folder / HULL_DIR / f"{hull_mesh_name(0)}.stl", file_type="stl")
        return parts

    monkeypatch.setattr(build_module, "write_meshes", with_a_three_vertex_hull)
    tube, graph = straight_tube()
    out = tmp_path / "tube"
    with pytest.raises(BuildError, match=rf"tube: MuJoCo cannot compile .*{hull_mesh_name(0)}"):
        build_vessel(tube, name="tube", out_dir=out, centerline=graph, params=SERIAL,
                     progress=False, cache=False, inlet=np.array([0.0, 0.0, -L / 2]))
    assert not out.exists()


def test_a_target_apart_from_the_inlet_along_the_centerline_is_refused(tmp_path: Path) -> None:
    """A centerline in two pieces, the target in the other one from the inlet, is refused
    with the target named: no path leads there (the manifold distance is infinite)."""
    tube, graph = straight_tube()
    cut = np.array([edge for edge in graph.edges if set(edge) != {20, 21}])
    two_pieces = CenterlineGraph(graph.nodes, graph.radii, cut)
    with pytest.raises(BuildError, match="given is in 2 pieces, and end is not joined to the "
                                         "inlet"):
        build_vessel(tube, name="tube", out_dir=tmp_path / "tube", centerline=two_pieces,
                     params=SERIAL, progress=False, cache=False,
                     inlet=np.array([0.0, 0.0, -L / 2]), targets={"end": np.array([0, 0, L / 2])})
    assert not (tmp_path / "tube").exists()
