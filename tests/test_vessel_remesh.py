"""Lumens of any resolution import: coarse faces are subdivided, large meshes decimated for
the wall and kept whole for display (issue 67, item 3)."""

from __future__ import annotations

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh

from sim4endor import suite, vessels
from sim4endor.cli import main
from sim4endor.tasks.expert import CenterlineExpert, run_expert
from sim4endor.vessels.build import BuildParams, build_vessel
from sim4endor.vessels.generators.command import generate_vessel
from sim4endor.vessels.meshio import prepare_lumen
from sim4endor.vessels.mjcf_writer import DISPLAY_DIR, LUMEN_FILE
from sim4endor.vessels.remesh import MUJOCO_MAX_FACES, RemeshParams, display_parts


def _edges_ok(mesh: trimesh.Trimesh) -> bool:
    return bool(mesh.is_watertight and mesh.is_winding_consistent)


def test_a_coarsely_triangulated_cylinder_builds_with_an_open_lumen(tmp_path: Path) -> None:
    # Issue 67's try: trimesh's capped cylinder, 2 mm radius, 60 mm long, of 128 long thin
    # triangles. Built as it was, its wall closed the lumen (lumen open 0.0000).
    path = tmp_path / "cylinder.stl"
    trimesh.creation.cylinder(radius=2.0, height=60.0).export(path)
    out = tmp_path / "cylinder"
    assert main(["vessel", "build", str(path), "--name", "cylinder", "--out", str(out),
                 "--units", "mm", "--no-progress", "--no-cache"]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["checks"]["lumen_open"] >= 0.99
    assert manifest["build"]["repairs"]["subdivided_from"] == 128
    lumen = trimesh.load(out / LUMEN_FILE, force="mesh")
    assert lumen.edges_unique_length.max() <= 3.0 * manifest["inlet"]["radius"] * 1.5
    assert "faces with long edges were subdivided" in (out / "README.md").read_text()


def test_a_lumen_over_the_face_budget_is_decimated_and_kept_whole_for_display() -> None:
    # The shipped phantom's lumen, Loop-subdivided once (74,776 well-shaped triangles, as a
    # CTA surface has), against a budget of 20,000 faces.
    dense = trimesh.load(vessels.load("simplified_phantom").root / LUMEN_FILE, force="mesh")
    dense.merge_vertices()
    dense = dense.subdivide_loop(iterations=1)
    prepared = prepare_lumen(dense, units="m", resolution=RemeshParams(max_faces=20_000))
    assert len(dense.faces) > 20_000 >= len(prepared.mesh.faces)
    assert prepared.report.decimated_from == len(dense.faces)
    assert prepared.display is not None and len(prepared.display.faces) == len(dense.faces)
    assert _edges_ok(prepared.mesh)
    # The decimated lumen keeps the shape: its volume within 3 %, its radius within 3 %.
    assert prepared.mesh.volume == pytest.approx(dense.volume, rel=0.03)
    assert prepared.radius_estimate == pytest.approx(2e-3, rel=0.03)
    unchanged = prepare_lumen(dense, units="m")  # under the default budget: kept as it is
    assert unchanged.display is None and len(unchanged.mesh.faces) == len(dense.faces)


def test_the_display_mesh_is_cut_under_mujocos_limit_into_slabs_of_every_face() -> None:
    mesh = trimesh.creation.cylinder(radius=1.0, height=30.0, sections=48).subdivide_to_size(0.5)
    parts = display_parts(mesh, max_faces=1000)
    assert len(parts) == int(np.ceil(len(mesh.faces) / 1000))
    assert all(len(p.faces) <= 1000 for p in parts)
    assert sum(len(p.faces) for p in parts) == len(mesh.faces)
    assert sum(p.area for p in parts) == pytest.approx(mesh.area)
    assert display_parts(mesh)[0] is mesh  # under the limit: one part, the mesh itself


def test_remesh_params_refuse_what_cannot_work() -> None:
    with pytest.raises(ValueError, match="max_faces"):
        RemeshParams(max_faces=MUJOCO_MAX_FACES)
    with pytest.raises(ValueError, match="edge_fraction"):
        RemeshParams(edge_fraction=2.0, max_edge_fraction=1.0)


@pytest.mark.slow
def test_a_million_face_lumen_builds_and_navigates(tmp_path: Path) -> None:
    """Issue 67's done-when: a 1 M-face lumen (a generated coronary-calibre tree, Loop-
    subdivided three times: smooth, as a CTA surface is) builds and the expert navigates it."""
    tree = generate_vessel("coronary_tree", out_dir=tmp_path / "tree", seed=5, progress=False,
                           overrides=("levels=2", "root_radius=0.0016", "min_radius=0.00085"))
    lumen = trimesh.load(tree.root / LUMEN_FILE, force="mesh")
    lumen.merge_vertices()
    lumen = lumen.subdivide_loop(iterations=3)
    assert len(lumen.faces) > 1_000_000
    vessel = build_vessel(lumen, name="dense", out_dir=tmp_path / "dense", units="m",
                          inlet=tree.inlet_position, targets=tree.targets,
                          params=BuildParams(), progress=False, cache=False)
    assert vessel.manifest.below_acceptance == ""
    parts = sorted((vessel.root / DISPLAY_DIR).glob("part_*.stl"))
    assert len(parts) == int(np.ceil(len(lumen.faces) / (MUJOCO_MAX_FACES - 1)))
    model = mujoco.MjModel.from_xml_path(str(vessel.scene_path))
    assert model.mesh(f"lumen_{len(parts) - 1:03d}").id >= 0
    assert sum(len(trimesh.load(p).faces) for p in parts) == len(lumen.faces)
    for target in vessel.targets:
        env = suite.load("vessel", "navigate", {"vessel": str(vessel.root), "target": target,
                                                "wire": "workhorse"})
        assert run_expert(env, CenterlineExpert())["is_success"], target
