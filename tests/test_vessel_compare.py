"""Semantic comparison of vessel folders: rounding passes, real changes are named."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh

from sim4endor import vessels
from sim4endor.vessels.compare import folder_differences


@pytest.fixture()
def copy(tmp_path: Path) -> Path:
    folder = tmp_path / "simplified_phantom"
    shutil.copytree(vessels.load("simplified_phantom").root, folder)
    return folder


def _edit_stl(path: Path, shift: float) -> None:
    """Moves the first vertex of an STL by ``shift`` metres along x (float32, as stored)."""
    mesh = trimesh.load(path, force="mesh", process=False)
    vertices = np.array(mesh.vertices)
    vertices[mesh.faces[0, 0], 0] += shift
    trimesh.Trimesh(vertices, mesh.faces, process=False).export(path, file_type="stl")


def test_a_folder_equals_its_copy(copy: Path) -> None:
    assert folder_differences("simplified_phantom", copy) == []


def test_float32_rounding_of_the_lumen_is_not_a_difference(copy: Path) -> None:
    lumen = copy / "lumen.stl"
    x = float(trimesh.load(lumen, force="mesh", process=False).vertices[0, 0])
    _edit_stl(lumen, float(np.spacing(np.float32(x))))  # one float32 ulp
    assert folder_differences("simplified_phantom", copy) == []


def test_a_moved_hull_is_named(copy: Path) -> None:
    _edit_stl(copy / "hulls" / "hull_007.stl", 1e-5)
    differences = folder_differences("simplified_phantom", copy)
    assert any("hull_007.stl" in d for d in differences), differences


def test_a_moved_target_and_a_missing_entry_are_named(copy: Path) -> None:
    manifest = json.loads((copy / "manifest.json").read_text())
    manifest["targets"]["A"][0] += 1e-6
    del manifest["build"]["keep_largest"]
    manifest["checks"]["build_time_s"] = 99.0  # differs between identical builds: ignored
    (copy / "manifest.json").write_text(json.dumps(manifest))
    differences = folder_differences("simplified_phantom", copy)
    assert len(differences) == 2, differences
    assert any("targets.A.0" in d for d in differences)
    assert any("'keep_largest' only in the expected" in d for d in differences)


def test_a_renamed_geom_and_a_changed_camera_are_named(copy: Path) -> None:
    mjcf = copy / "simplified_phantom.xml"
    mjcf.write_text(mjcf.read_text().replace('name="wall_003"', 'name="wall_x"'))
    scene = copy / "scene.xml"
    scene.write_text(scene.read_text().replace('fovy="60"', 'fovy="45"'))
    differences = folder_differences("simplified_phantom", copy)
    assert any("geom names differ" in d for d in differences), differences
    assert any("fovy" in d for d in differences), differences
