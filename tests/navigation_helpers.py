"""Helpers shared by the navigation-environment tests (suite, tasks, gym, TorchRL)."""

from __future__ import annotations

import pytest

from sim4endor import vessels


def require_vessel(name: str) -> vessels.Vessel:
    """Returns the shipped vessel ``name`` or skips the test, naming what is missing."""
    try:
        return vessels.load(name)
    except vessels.VesselNotFoundError:
        pytest.skip(f"vessel folder {name!r} is not built (vessels/{name}/ missing)")
