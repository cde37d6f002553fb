"""Bad input meshes give clear errors or documented repairs, and nothing half-written."""

from __future__ import annotations

import functools
import logging
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh

from sim4endor import vessels
from sim4endor.cli import main
from sim4endor.vessels import build as build_module
from sim4endor.vessels.checks import CheckParams
from sim4endor.vessels.meshio import MeshInputError, prepare_lumen, read_mesh
from sim4endor.vessels.remesh import RemeshParams
from sim4endor.vessels.walls import WallParams, WallParamsError


def tube(radius: float = 1.5e-3, height: float = 20e-3) -> trimesh.Trimesh:
    return trimesh.creation.cylinder(radius=radius, height=height, sections=24).subdivide_to_size(
        height / 10
    )


def test_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "empty.stl"
    path.write_bytes(b"")
    with pytest.raises(MeshInputError, match="empty"):
        read_mesh(path)


def test_not_a_mesh(tmp_path: Path) -> None:
    path = tmp_path / "notes.obj"
    path.write_text("this is not a mesh\n")
    with pytest.raises(MeshInputError, match=str(path)):
        read_mesh(path)


def test_unsupported_suffix(tmp_path: Path) -> None:
    path = tmp_path / "scan.nii"
    path.write_bytes(b"\x00" * 10)
    with pytest.raises(MeshInputError, match="unsupported"):
        read_mesh(path)


def test_wrong_units_suggests_the_other() -> None:
    with pytest.raises(MeshInputError, match="--units m"):
        prepare_lumen(tube(), units="mm")  # a metre mesh declared as mm: 1.5 µm radius
    big = tube()
    big.apply_scale(1e3)
    with pytest.raises(MeshInputError, match="--units mm"):
        prepare_lumen(big, units="m")  # a mm mesh declared as m: 1.5 m radius


def test_radius_estimate_and_scale() -> None:
    prepared = prepare_lumen(tube(), units="m")
    assert prepared.radius_estimate == pytest.approx(1.5e-3, rel=0.1)
    assert prepared.scale == 1.0 and prepared.report.open_ends == 0


def test_disconnected_parts_error_and_keep_largest() -> None:
    small = trimesh.creation.cylinder(radius=1e-3, height=5e-3, sections=12)
    small.apply_translation([10e-3, 0, 0])
    both = trimesh.util.concatenate([tube(), small])
    with pytest.raises(MeshInputError, match="keep-largest"):
        prepare_lumen(both, units="m")
    prepared = prepare_lumen(both, units="m", keep_largest=True)
    assert len(prepared.report.dropped_components) == 1
    assert len(prepared.mesh.faces) == len(tube().faces)


def test_degenerate_faces_are_removed() -> None:
    mesh = tube()
    faces = np.vstack([mesh.faces, [[0, 0, 1]], mesh.faces[:1]])  # repeated vertex + duplicate
    prepared = prepare_lumen(trimesh.Trimesh(mesh.vertices, faces, process=False), units="m")
    assert prepared.report.removed_faces == 2
    assert prepared.mesh.is_watertight


def test_a_closed_lumens_slivers_are_collapsed_not_cut_out() -> None:
    """Marching cubes leaves zero-area slivers where the surface passes a voxel corner.
    Deleting them opened a closed lumen (a 136,178-face tree: 64 boundary edges, then "non-
    manifold boundary"); in a closed mesh they are collapsed, and it stays closed."""
    from sim4endor.vessels.generators.implicit_coronary import (
        ImplicitCoronaryConfig,
        implicit_coronary,
    )
    from sim4endor.vessels.meshio import degenerate_faces

    lumen = implicit_coronary(ImplicitCoronaryConfig(voxel=0.3), 0).lumen
    assert lumen.is_watertight and degenerate_faces(lumen).any()
    cut = lumen.copy()
    cut.update_faces(~degenerate_faces(cut))
    assert not cut.is_watertight  # what deleting them did
    prepared = prepare_lumen(lumen, units="m")
    assert prepared.report.removed_faces >= 1 and prepared.report.filled_holes == 0
    assert prepared.mesh.is_watertight and not degenerate_faces(prepared.mesh).any()


def test_small_hole_is_filled_large_hole_is_an_error() -> None:
    mesh = tube()
    side = np.flatnonzero(np.abs(mesh.face_normals[:, 2]) < 0.1)
    one = mesh.copy()
    one.update_faces(np.setdiff1d(np.arange(len(mesh.faces)), side[:1]))
    prepared = prepare_lumen(one, units="m")
    assert prepared.report.filled_holes == 1 and prepared.mesh.is_watertight
    centres = mesh.triangles_center[side]
    facing_x = centres[:, 0] > 0.7 * np.linalg.norm(centres[:, :2], axis=1)
    window = side[(np.abs(centres[:, 2]) < 4e-3) & facing_x]
    many = mesh.copy()
    many.update_faces(np.setdiff1d(np.arange(len(mesh.faces)), window))
    with pytest.raises(MeshInputError, match="hole in the vessel wall"):
        prepare_lumen(many, units="m")


def test_inward_wound_mesh_is_turned_outward_with_fresh_normals() -> None:
    """The shared real anatomy is wound inward; a stale normal cache once grew its wall inward."""
    inward = tube()
    inward = trimesh.Trimesh(inward.vertices, inward.faces[:, ::-1], process=False)
    assert inward.volume < 0
    mesh = prepare_lumen(inward, units="m").mesh
    assert mesh.volume > 0
    triangles = mesh.triangles
    winding = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    assert np.all(np.einsum("ij,ij->i", winding, mesh.face_normals) > 0)
    radial = mesh.triangles_center[:, :2]
    side = np.abs(mesh.face_normals[:, 2]) < 0.5
    assert np.all(np.einsum("ij,ij->i", radial[side], mesh.face_normals[side, :2]) > 0)


@pytest.mark.parametrize("units", ["m", "mm"])
def test_an_inward_wound_lumen_with_open_ends_is_turned_outward(units: str) -> None:
    # No signed volume to go by: until 2026-12-06 such a lumen kept its inward normals, so
    # its wall would have grown into it (a lumen whose repair opened an edge was refused with
    # an absurd radius instead).
    mesh = tube()
    mesh.update_faces(np.abs(mesh.face_normals[:, 2]) < 0.5)  # drop both caps
    mesh.remove_unreferenced_vertices()
    mesh.apply_scale(1e3 if units == "mm" else 1.0)
    inward = trimesh.Trimesh(mesh.vertices, mesh.faces[:, ::-1], process=False)
    prepared = prepare_lumen(inward, units=units).mesh
    radial = prepared.triangles_center[:, :2]
    assert np.all(np.einsum("ij,ij->i", radial, prepared.face_normals[:, :2]) > 0)


def test_open_ends_are_kept_not_filled() -> None:
    mesh = tube()
    keep = np.abs(mesh.face_normals[:, 2]) < 0.5  # drop both caps
    mesh.update_faces(keep)
    mesh.remove_unreferenced_vertices()
    prepared = prepare_lumen(mesh, units="m")
    assert prepared.report.open_ends == 2 and prepared.report.filled_holes == 0


def test_cli_error_is_one_line_and_leaves_nothing(tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "tube.stl"
    tube().export(path)
    out = tmp_path / "out"
    status = main(["vessel", "build", str(path), "--name", "x", "--out", str(out),
                   "--units", "mm", "--no-progress", "--no-cache"])
    err = capsys.readouterr().err.strip()
    assert status == 2 and "--units m" in err and len(err.splitlines()) == 1
    assert not out.exists() and not any(p.name.startswith(".out") for p in tmp_path.iterdir())


def test_the_units_error_comes_before_any_heavy_work(monkeypatch: pytest.MonkeyPatch) -> None:
    # A metre mesh declared as mm is refused on its extent, before the repairs, the component
    # split and the ray casts that cost a real CTA surface seconds and gigabytes.
    def never(*args: object, **kwargs: object) -> None:
        raise AssertionError("heavy work started before the units check")

    metres = tube()
    monkeypatch.setattr(trimesh.Trimesh, "merge_vertices", never)
    with pytest.raises(MeshInputError, match=r"mm across.*--units m"):
        prepare_lumen(metres, units="mm")


def _build(tmp_path: Path, mesh: trimesh.Trimesh, *extra: str) -> tuple[int, Path]:
    path = tmp_path / "lumen.stl"
    mesh.export(path)
    out = tmp_path / "out"
    status = main(["vessel", "build", str(path), "--name", "v", "--out", str(out), "--units",
                   "mm", "--no-progress", "--no-cache", *extra])
    return status, out


def _tube_mm() -> trimesh.Trimesh:
    mesh = tube()
    mesh.apply_scale(1e3)  # 1.5 mm radius, 20 mm long, in mm
    return mesh


@pytest.mark.parametrize("extra, message", [
    (("--target", "A=500,0,0"), "target A lies 49"),
    (("--inlet", "1000,0,0"), "inlet .* lies 99"),
])
def test_points_far_outside_the_lumen_are_refused_with_their_distance(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: tuple[str, ...],
        message: str) -> None:
    status, out = _build(tmp_path, _tube_mm(), *extra)
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert status == 2 and not out.exists()
    assert re.search(message + r"\d mm outside the lumen", err) and "LPS or RAS" in err


def test_a_negative_wall_thickness_is_refused(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stop:
        _build(tmp_path, _tube_mm(), "--wall-thickness", "-1")
    assert stop.value.code == 2 and "--wall-thickness" in capsys.readouterr().err
    with pytest.raises(WallParamsError, match="thickness"):
        WallParams(thickness=-1e-3)


def test_a_build_below_acceptance_fails_unless_allowed_and_then_warns(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], caplog: pytest.LogCaptureFixture,
        monkeypatch: pytest.MonkeyPatch) -> None:
    # Checks that cannot pass (an open fraction above 1) stand for a build that closed its
    # lumen; `sim4endor vessel build` makes its BuildParams when it runs.
    strict = CheckParams(min_lumen_open=1.5)
    monkeypatch.setattr(build_module, "BuildParams",
                        functools.partial(build_module.BuildParams, checks=strict))
    status, out = _build(tmp_path, _tube_mm())
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and not out.exists()
    assert "checks below acceptance: lumen open" in err[-1]
    assert "--allow-below-acceptance" in err[-1]
    status, out = _build(tmp_path, _tube_mm(), "--allow-below-acceptance")
    assert status == 0 and out.is_dir()
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        vessels.load(out)
    assert any("checks below acceptance" in r.getMessage() for r in caplog.records)


def _marching_cubes_y(voxel: float = 0.2) -> trimesh.Trimesh:
    """A closed Y lumen (mm) as a segmentation's marching cubes make it: a 1.6 mm trunk
    forking into 1.1 and 0.85 mm branches, sampled at ``voxel`` mm (the branches' sideways
    offsets are those of the generated tree whose lumen the old repair broke)."""
    from skimage import measure

    def capsule(points: np.ndarray, a: np.ndarray, b: np.ndarray, r: float) -> np.ndarray:
        ab = b - a
        t = np.clip(((points - a) @ ab) / (ab @ ab), 0.0, 1.0)
        return np.linalg.norm(points - (a + t[..., None] * ab), axis=-1) - r

    fork = np.array([0.0, 0.0, 20.0])
    low, high = np.array([-10.0, -6.0, -2.5]), np.array([10.0, 6.0, 36.0])
    grid = np.stack(np.meshgrid(*(np.arange(low[i], high[i], voxel) for i in range(3)),
                                indexing="ij"), -1)
    sdf = np.minimum.reduce([
        capsule(grid, np.zeros(3), fork, 1.6),
        capsule(grid, fork, fork + np.array([8.0, -2.486104997138254, 12.0]), 1.1),
        capsule(grid, fork, fork + np.array([-7.0, -1.5791369604234018, 13.0]), 0.85),
    ])
    vertices, faces, _, _ = measure.marching_cubes(sdf, 0.0, spacing=(voxel,) * 3)
    return trimesh.Trimesh(vertices + low, faces[:, ::-1], process=False)


def test_the_same_lumen_is_repaired_the_same_in_mm_m_and_um() -> None:
    # A closed marching-cubes lumen over the face budget: in millimetres and micrometres the
    # repair merged on trimesh's fixed 1e-8 of the unit, left marching cubes' nanometre-near
    # vertices apart, and the decimation then broke the lumen ("non-manifold boundary"); in
    # metres it built. Every tolerance is now relative to the lumen.
    lumen = _marching_cubes_y()
    resolution = RemeshParams(max_faces=20_000)  # the decimation of a 184,738-face lumen
    prepared = {}
    for units, scale in (("mm", 1.0), ("m", 1e-3), ("um", 1e3)):
        mesh = lumen.copy()
        mesh.apply_scale(scale)
        prepared[units] = prepare_lumen(mesh, units=units, resolution=resolution)
    reference = prepared["m"]
    assert reference.report.decimated_from > 20_000
    for units in ("mm", "um"):
        assert np.array_equal(prepared[units].mesh.faces, reference.mesh.faces), units
        np.testing.assert_allclose(prepared[units].mesh.vertices, reference.mesh.vertices,
                                   rtol=0, atol=1e-12)
        assert prepared[units].report == reference.report
    assert np.allclose(lumen.vertices, _marching_cubes_y().vertices)  # the input untouched


@pytest.mark.slow
def test_the_same_lumen_builds_the_same_in_mm_m_and_um(tmp_path: Path) -> None:
    lumen = _marching_cubes_y()
    manifests = {}
    for units, scale in (("mm", 1.0), ("m", 1e-3), ("um", 1e3)):
        mesh = lumen.copy()
        mesh.apply_scale(scale)
        vessel = build_module.build_vessel(
            mesh, name="y", out_dir=tmp_path / units, units=units, cache=False,
            progress=False, params=build_module.BuildParams(
                wall=WallParams(workers=1), resolution=RemeshParams(max_faces=20_000)))
        manifests[units] = vessel.manifest
    for units in ("mm", "um"):
        assert manifests[units].hull_count == manifests["m"].hull_count
        for key in ("lumen_open", "wall_closed", "hull_count"):
            assert manifests[units].checks[key] == manifests["m"].checks[key], (units, key)
        assert manifests[units].targets.keys() == manifests["m"].targets.keys()
