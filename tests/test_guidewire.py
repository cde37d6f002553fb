"""The rod model: discretisation, stiffness encoding, config checks, cantilever statics."""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np
import pytest

from sim4endor.benches import validation
from sim4endor.errors import Sim4EndoRError
from sim4endor.models import constants as names
from sim4endor.models.guidewire import (
    STAINLESS_STEEL,
    GuidewireConfig,
    add_guidewire,
    segment_lengths,
    wire_vertices,
)
from sim4endor.models.scene import base_spec


def test_segments_are_fine_at_the_tip_and_coarse_along_the_shaft() -> None:
    config = GuidewireConfig()
    lengths = segment_lengths(config)
    assert lengths.sum() == pytest.approx(config.length)
    tip = lengths[-config.tip_segments :]
    np.testing.assert_allclose(tip, config.tip_length / config.tip_segments)
    assert lengths.max() <= config.max_segment_length + 1e-12
    assert np.all(np.diff(lengths) <= 1e-12)  # never longer towards the tip
    assert config.num_segments == len(lengths) < 45


def test_pre_bent_tip_offset_matches_the_arc_and_fits_a_2mm_lumen() -> None:
    config = GuidewireConfig()
    arc_radius = config.tip_length / config.tip_angle
    exact = arc_radius * (1 - math.cos(config.tip_angle))
    assert config.tip_lateral_offset == pytest.approx(exact, rel=0.02)
    assert config.tip_lateral_offset < 0.002 - config.radius
    straight = dataclasses.replace(config, tip_angle=0.0)
    assert np.allclose(wire_vertices(straight)[:, 1:], 0.0)


def test_a_secondary_curve_turns_the_shaft_behind_the_tip_in_the_tip_plane() -> None:
    tip = GuidewireConfig(tip_length=0.002, tip_angle=math.radians(60.0))
    both = dataclasses.replace(tip, secondary_distance=0.007,
                               secondary_angle=math.radians(40.0))
    lengths = segment_lengths(both)
    points = wire_vertices(both)
    headings = np.degrees(np.arctan2(*np.diff(points, axis=0)[:, 1::-1].T))
    middles = np.cumsum(lengths[::-1])[::-1] - lengths / 2  # each segment's distance from the end
    # Straight behind the curve (7 +- 1 mm), turned by all of it in front; the tip adds its own.
    assert np.allclose(headings[middles >= 0.008], 0.0)
    in_front = (middles <= 0.006) & (middles > both.tip_length)
    assert in_front.any() and np.allclose(headings[in_front], 40.0)
    assert headings[-1] == pytest.approx(40.0 + 60.0 * (1 - 0.5 / both.tip_segments))
    assert np.all(points[:, 2] == 0.0)  # in the tip's plane, to the same side
    assert both.tip_lateral_offset > tip.tip_lateral_offset + 0.003
    with pytest.raises(Sim4EndoRError, match="secondary_distance"):
        dataclasses.replace(tip, secondary_distance=0.002, secondary_angle=0.5)  # on the tip


def _compiled_wire(config: GuidewireConfig) -> mujoco.MjModel:
    spec = base_spec()
    add_guidewire(spec, spec.worldbody.add_body(name="mount"), config)
    return spec.compile()


def test_core_capsules_encode_voronoi_and_tip_stiffness() -> None:
    config = GuidewireConfig(tip_stiffness_factor=0.25)
    model = _compiled_wire(config)
    lengths = segment_lengths(config)
    core = 0.5 * config.outer_diameter
    radii = []
    for b in range(len(lengths)):
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, names.wire_body(b))
        first_geom = model.body_geomadr[body]
        assert model.geom_contype[first_geom] == 0 and model.geom_conaffinity[first_geom] == 0
        radii.append(model.geom_size[first_geom, 0])
        assert model.body_plugin[body] == 0
    stiffness = (np.array(radii) / core) ** 4
    assert stiffness[1] == pytest.approx(lengths[0] / (0.5 * lengths[1]))  # clamp half-length
    mid = len(lengths) // 2
    assert stiffness[mid] == pytest.approx(1.0)
    assert stiffness[-1] == pytest.approx(0.25)  # softened tip


def test_contact_capsules_use_outer_radius_scaled_density_and_friction() -> None:
    config = GuidewireConfig(friction=0.07, mass_scale=100.0)
    model = _compiled_wire(config)
    geom = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, names.wire_geom(3))
    assert model.geom_size[geom, 0] == pytest.approx(config.radius)
    assert model.geom_friction[geom, 0] == pytest.approx(0.07)
    assert (model.geom_contype[geom], model.geom_conaffinity[geom]) == (1, 2)
    body = model.geom_bodyid[geom]
    length = segment_lengths(config)[3]
    volume = math.pi * config.radius**2 * length + 4 / 3 * math.pi * config.radius**3
    assert model.body_mass[body] == pytest.approx(config.density * 100.0 * volume, rel=1e-6)


def test_wire_needs_the_default_classes() -> None:
    spec = mujoco.MjSpec()
    with pytest.raises(Sim4EndoRError, match="guidewire_defaults"):
        add_guidewire(spec, spec.worldbody, GuidewireConfig())


@pytest.mark.parametrize(
    "changes",
    [{"length": -1.0}, {"tip_length": 0.2}, {"tip_angle": 4.0}, {"core_diameter": 1.0},
     {"tip_segments": 0}, {"friction": -0.1}],
)
def test_bad_config_names_the_field(changes: dict) -> None:
    with pytest.raises(Sim4EndoRError, match="GuidewireConfig"):
        GuidewireConfig(**changes)


def test_stainless_preset_is_stiffer() -> None:
    assert STAINLESS_STEEL.bending_stiffness > 3 * GuidewireConfig().bending_stiffness


def test_cantilever_matches_euler_bernoulli_within_5_percent() -> None:
    # Real mass settles in ~1 s of simulated time; the mass-scaled wire reaches the same
    # static shape (slowly), which the benchmark measures.
    result = validation.cantilever(GuidewireConfig(mass_scale=1.0), settle_time=2.0)
    assert result.relative_error < 0.05
    coarse = validation.cantilever(
        GuidewireConfig(mass_scale=1.0, max_segment_length=0.01), settle_time=2.0
    )
    assert coarse.relative_error < 0.05


def test_softened_tip_bends_as_predicted() -> None:
    # A short wire with a long, 4x softer tip: the plugin must read the per-body core radius.
    wire = GuidewireConfig(
        length=0.04, tip_length=0.015, tip_segments=6, tip_stiffness_factor=0.25, mass_scale=1.0
    )
    soft = validation.cantilever(wire, soft_tip=True, settle_time=2.0)
    uniform = validation.cantilever(wire, settle_time=2.0)
    assert soft.relative_error < 0.05
    assert soft.deflection > 1.1 * uniform.deflection  # theory: 1.22x
