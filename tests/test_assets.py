"""The asset resolver finds mjcf/ and vessels/ in editable and wheel installs."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from sim4endor import assets

REPO_ROOT = Path(__file__).resolve().parents[1]


def test_editable_layout_resolves_to_checkout() -> None:
    assert assets.assets_root() == REPO_ROOT
    assert assets.mjcf_dir() == REPO_ROOT / "mjcf"
    assert assets.vessels_dir() == REPO_ROOT / "vessels"


def test_missing_mjcf_file_names_available_files() -> None:
    with pytest.raises(assets.AssetNotFoundError, match="available"):
        assets.mjcf_path("no_such_file.xml")


def test_vessel_search_path_includes_env_folders(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv(assets.VESSEL_PATH_ENV, str(tmp_path))
    assert assets.vessel_search_path() == (assets.vessels_dir(), tmp_path)


def test_wheel_layout_carries_assets(tmp_path) -> None:
    """A non-editable install (a built wheel) resolves assets inside the installed package."""
    target = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps",
         "--no-build-isolation", "--target", str(target), str(REPO_ROOT)],
        check=True,
    )
    probe = (
        "import sim4endor.assets as a, sim4endor.vessels as v;"
        "print(a.assets_root()); print(','.join(v.names()))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], check=True, capture_output=True, text=True,
        cwd=tmp_path, env={"PYTHONPATH": str(target), "PATH": ""},
    ).stdout.splitlines()
    root = Path(out[0])
    assert root == target / "sim4endor" / "_assets"
    assert (root / "mjcf").is_dir() and (root / "vessels").is_dir()
    shipped = sorted(
        p.name for p in (REPO_ROOT / "vessels").iterdir() if (p / "manifest.json").is_file()
    )
    assert shipped and out[1].split(",") == shipped
