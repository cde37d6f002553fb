"""Shared fixtures: the shared test data folder and a fresh-output helper."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# Importing sim4endor before any test imports MuJoCo picks a headless GL backend (OSMesa when
# installed) where there is no display, as it does for users (sim4endor._gl).
import sim4endor  # noqa: F401

REPO_ROOT = Path(__file__).resolve().parents[1]
# ../shared sits beside the checkout (see DEVELOPERS.md); SIM4ENDOR_SHARED overrides it.
SHARED_DIR = Path(os.environ.get("SIM4ENDOR_SHARED", REPO_ROOT.parent / "shared"))
STEVE_DIR = SHARED_DIR / "data" / "steve_bench_dualdevicenav"


@pytest.fixture(scope="session")
def steve_bench_dir() -> Path:
    """The shared real anatomy (MIT); tests using it skip with a message when it is absent."""
    if not (STEVE_DIR / "vessel_architecture_collision.obj").is_file():
        pytest.skip(
            f"shared test data not found at {STEVE_DIR}; set SIM4ENDOR_SHARED to the shared/ "
            "folder to run the real-anatomy tests"
        )
    return STEVE_DIR
