"""The wire in the shipped simplified phantom: steering into A and B, staying inside.

Skipped until ``vessels/simplified_phantom`` exists. The seeded 10-try validation per branch
is ``experiments/benchmarks/guidewire_validation.py`` (and the slow test below).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim4endor import vessels
from sim4endor.benches import validation
from sim4endor.models.scene import config_for_vessel
from sim4endor.physics import GuidewirePhysics


@pytest.fixture(scope="module")
def phantom() -> vessels.Vessel:
    try:
        return vessels.load("simplified_phantom")
    except vessels.VesselNotFoundError:
        pytest.skip("vessels/simplified_phantom is not built yet")


@pytest.mark.parametrize(("target", "rotation"), [("A", 0.0), ("B", math.pi)])
def test_rotate_then_insert_reaches_each_branch(
    phantom: vessels.Vessel, target: str, rotation: float
) -> None:
    physics = GuidewirePhysics.from_vessel(phantom, config_for_vessel(phantom))
    result = validation.steer(physics, phantom, target, rotation, speed=0.025)
    assert result.healthy
    assert result.success, f"tip stopped {result.final_distance * 1e3:.1f} mm from {target}"
    assert result.max_escape == 0.0


def test_wrong_rotation_ends_in_the_other_branch(phantom: vessels.Vessel) -> None:
    physics = GuidewirePhysics.from_vessel(phantom, config_for_vessel(phantom))
    result = validation.steer(physics, phantom, "A", math.pi, speed=0.025, time_limit=6.0)
    assert not result.success and result.healthy
    graph = phantom.centerline
    to_b = graph.distance_along(physics.tip_position(), graph.geodesic_from(graph.labels["B"]))
    assert to_b < result.final_distance


@pytest.mark.slow
def test_seeded_steering_success_rate_is_at_least_90_percent(phantom: vessels.Vessel) -> None:
    rng = np.random.default_rng(0)
    physics = GuidewirePhysics.from_vessel(phantom, config_for_vessel(phantom))
    for target, base in (("A", 0.0), ("B", math.pi)):
        wins = sum(
            validation.steer(
                physics, phantom, target, base + math.radians(rng.uniform(-15, 15)),
                speed=0.02 * rng.uniform(0.75, 1.5),
            ).success
            for _ in range(10)
        )
        assert wins >= 9, f"{target}: {wins}/10"


def test_insertion_into_the_vascular_phantom_stays_stable() -> None:
    # Regression: with armature_time 7.5 ms this path blew up at t = 4.7 s (BADQACC).
    try:
        vessel = vessels.load("vascular_phantom")
    except vessels.VesselNotFoundError:
        pytest.skip("vessels/vascular_phantom is not built yet")
    physics = GuidewirePhysics.from_vessel(vessel, config_for_vessel(vessel))
    result = validation.steer(physics, vessel, "A", 0.0, speed=0.02, time_limit=6.0)
    assert result.healthy
    assert result.max_escape == 0.0
