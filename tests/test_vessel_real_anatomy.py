"""The shared real anatomy (stEVE_bench dual-device navigation, MIT, mm, Slicer centerlines)."""

from __future__ import annotations

from pathlib import Path

import mujoco
import pytest

from sim4endor import vessels
from sim4endor.vessels.build import build_vessel
from sim4endor.vessels.meshio import read_mesh
from sim4endor.vessels.slicer import read_slicer_centerline

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def steve(steve_bench_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> vessels.Vessel:
    mesh = read_mesh(steve_bench_dir / "vessel_architecture_collision.obj")
    graph = read_slicer_centerline([steve_bench_dir / "centerlines"])
    return build_vessel(
        mesh, name="steve_dualdevicenav", out_dir=tmp_path_factory.mktemp("real") / "steve",
        units="mm", centerline=graph, source="stEVE_bench dualdevicenav (lkarstensen/stEVE_bench)",
        license_text=(steve_bench_dir / "LICENSE").read_text(), progress=False, cache=False,
    )


def test_imports_compiles_and_wall_is_closed(steve: vessels.Vessel) -> None:
    assert (steve.root / "LICENSE").is_file()
    assert steve.manifest.mesh_to_model_matrix[0, 0] == pytest.approx(1e-3)
    assert steve.centerline.num_components() == 1 and len(steve.targets) >= 10
    model = mujoco.MjModel.from_xml_path(str(steve.scene_path))
    assert model.ngeom == steve.manifest.hull_count + 1
    assert steve.manifest.checks["wall_closed"] >= 0.95


@pytest.mark.xfail(
    strict=True,
    reason="measured 0.73: the Slicer curves were made on another surface; on this coarse "
    "(~6 mm edges), apparently self-overlapping OBJ many curve points lie within 0.4 R of "
    "the surface or outside it (see docs/bring_your_own_cta.md)",
)
def test_lumen_open(steve: vessels.Vessel) -> None:
    assert steve.manifest.checks["lumen_open"] >= 0.99
