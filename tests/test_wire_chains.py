"""A wire split into kinematic chains (GuidewireConfig.chain_bodies) is the same rod."""

from __future__ import annotations

import dataclasses

import mujoco
import numpy as np
import pytest
from navigation_helpers import require_vessel

from sim4endor import vessels
from sim4endor.benches import validation
from sim4endor.models import constants as names
from sim4endor.models import fidelity, wires
from sim4endor.models.guidewire import GuidewireConfig, GuidewireConfigError, chain_starts
from sim4endor.models.scene import config_for_vessel
from sim4endor.physics import GuidewirePhysics

SPLIT = GuidewireConfig(chain_bodies=6)


@pytest.mark.parametrize(("count", "size", "starts"), [
    (12, 6, [0, 6]), (13, 6, [0, 1, 7]), (6, 6, [0]), (5, 6, [0]), (20, None, [0]),
])
def test_chains_are_counted_from_the_tip(count: int, size: int | None, starts: list[int]) -> None:
    assert chain_starts(GuidewireConfig(chain_bodies=size), count) == starts


def test_the_tip_stays_in_one_chain() -> None:
    with pytest.raises(GuidewireConfigError, match="chain_bodies"):
        GuidewireConfig(chain_bodies=4)  # 5 tip segments


def test_the_catalogue_splits_its_wires_and_the_published_paper_wire_stays_one_chain() -> None:
    assert wires.preset("paper", fidelity="fast").chain_bodies is None
    for level in fidelity.names():
        for name in ("workhorse", "intermediate", "stiff"):
            assert wires.preset(name, fidelity=level).chain_bodies == 6
    assert wires.preset("paper").chain_bodies == 6


def _placed(wire: GuidewireConfig, vessel: vessels.Vessel) -> GuidewirePhysics:
    config = dataclasses.replace(config_for_vessel(vessel), wire=wire)
    physics = GuidewirePhysics.from_vessel(vessel, config)
    physics.place_driver(0.004, 1.3)  # a roll, so the chains' roots must follow the clamp
    mujoco.mj_forward(physics.model.ptr, physics.data.ptr)
    return physics


def test_a_split_wire_starts_where_the_one_chain_wire_does() -> None:
    # The vascular phantom's inlet is off the origin and tilted: the roots' world poses
    # compose the driver's. Both the shaped and the straightened-at-start tip.
    require_vessel("vascular_phantom")
    vessel = vessels.load("vascular_phantom")
    for wire in (GuidewireConfig(), wires.preset("workhorse")):
        one = _placed(dataclasses.replace(wire, chain_bodies=None), vessel)
        split_config = dataclasses.replace(wire, chain_bodies=6)
        split = _placed(split_config, vessel)
        model, data = split.model.ptr, split.data.ptr
        chains = chain_starts(split_config, one.num_wire_segments())
        assert model.neq == len(chains) - 1 > 0
        np.testing.assert_allclose(split.wire_points(), one.wire_points(), atol=1e-9)
        np.testing.assert_allclose(split.tip_frame(), one.tip_frame(), atol=1e-9)
        welds = data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        assert np.abs(data.efc_pos[welds]).max() < 1e-9
        assert split.num_wire_segments() == one.num_wire_segments()
        assert split.tip_start_index() == one.tip_start_index()


def test_a_split_cantilever_bends_as_beam_theory_and_the_one_chain_wire() -> None:
    # Real mass: the welds must hold without the mass scaling's inertia. The split wire
    # settles more slowly (94 % of the static deflection after 2 s), hence 6 s.
    one = validation.cantilever(GuidewireConfig(mass_scale=1.0), settle_time=2.0)
    split = validation.cantilever(dataclasses.replace(SPLIT, mass_scale=1.0), settle_time=6.0)
    assert split.relative_error < 0.05
    assert split.deflection == pytest.approx(one.deflection, rel=0.02)


def test_the_wall_force_counts_the_contacts_of_every_chain() -> None:
    require_vessel("vascular_phantom")
    vessel = vessels.load("vascular_phantom")
    physics = GuidewirePhysics.from_vessel(
        vessel, dataclasses.replace(config_for_vessel(vessel), wire=SPLIT))
    physics.place_driver(0.0, 0.0)
    insertion, checked = 0.0, 0
    while insertion < 0.09:
        insertion += 0.0005
        physics.set_driver_targets(insertion, 0.0)
        for _ in range(4):
            physics.step()
        forces, bodies = physics._wall_contacts()
        wire_bodies = physics._indices().wire_bodies
        first_chain_end = chain_starts(SPLIT, len(wire_bodies))[1]
        if np.isin(bodies, wire_bodies[first_chain_end:]).any():
            checked += 1
            assert physics.wall_contact_force() == pytest.approx(forces.sum(), rel=1e-9)
            tip = np.isin(bodies, wire_bodies[physics.tip_start_index():])
            assert physics.tip_contact_force() == pytest.approx(forces[tip].sum(), rel=1e-9)
    assert checked > 10
    # A chain with more contacts than its sensor's slots: the total comes from the list.
    physics.data.ptr.sensordata[physics._indices().wall_sensors[-1]] = (
        names.CONTACT_SENSOR_SLOTS + 1)
    assert physics.wall_contact_force() == pytest.approx(forces.sum(), rel=1e-9)
