"""The shared real anatomy (stEVE_bench dual-device navigation, MIT, mm, Slicer centerlines)."""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest

from sim4endor import vessels
from sim4endor.vessels.build import build_vessel
from sim4endor.vessels.meshio import read_mesh
from sim4endor.vessels.register import RegistrationParams
from sim4endor.vessels.slicer import read_slicer_centerline

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def steve(steve_bench_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> vessels.Vessel:
    mesh = read_mesh(steve_bench_dir / "vessel_architecture_collision.obj")
    graph = read_slicer_centerline([steve_bench_dir / "centerlines"])
    return build_vessel(
        mesh, name="steve_dualdevicenav", out_dir=tmp_path_factory.mktemp("real") / "steve",
        units="mm", centerline=graph, registration=RegistrationParams(),
        source="stEVE_bench dualdevicenav (lkarstensen/stEVE_bench)",
        license_text=(steve_bench_dir / "LICENSE").read_text(), progress=False, cache=False,
    )


def test_imports_compiles_and_wall_is_closed(steve: vessels.Vessel) -> None:
    assert (steve.root / "LICENSE").is_file()
    assert steve.manifest.mesh_to_model_matrix[0, 0] == pytest.approx(1e-3)
    assert steve.centerline.num_components() == 1 and len(steve.targets) >= 10
    model = mujoco.MjModel.from_xml_path(str(steve.scene_path))
    assert model.ngeom == steve.manifest.hull_count + 1
    assert steve.manifest.checks["wall_closed"] >= 0.95


def test_lumen_open_on_the_registered_centerline(steve: vessels.Vessel) -> None:
    """The Slicer curves were drawn on a finer surface than this decimated OBJ."""
    checks = steve.manifest.checks
    assert checks["lumen_open"] >= 0.99
    assert checks["lumen_open_given_centerline"] < checks["lumen_open"]  # reported, not hidden
    report = steve.manifest.build["centerline_registration"]["report"]
    assert report["given_outside"] > 0 and report["moved"] > 0.5 * report["points"]
    assert report["trimmed_length_mm"] < 0.05 * steve.centerline.total_length() * 1e3
