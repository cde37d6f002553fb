"""The wire catalogue: presets, tip shaping, tip-load and tapered-cantilever validation, and
``task_kwargs={"wire": ...}`` in every domain."""

from __future__ import annotations

import dataclasses
import math

import mujoco
import numpy as np
import pytest

from sim4endor import suite, vessels
from sim4endor.benches import validation
from sim4endor.models import constants as names
from sim4endor.models import fidelity, tip_load, wires
from sim4endor.models.guidewire import (
    GuidewireConfig,
    GuidewireConfigError,
    add_guidewire,
    segment_lengths,
    wire_vertices,
)
from sim4endor.models.scene import SceneConfig, base_spec, build_model, config_for_vessel
from sim4endor.tasks import TaskConfigError, random_coronary
from sim4endor.tasks.anatomy import compile_anatomy

RATED = [n for n in wires.names() if wires.entry(n).rated_tip_load_gf is not None]


def test_catalogue_has_the_issue_presets_and_paper_is_the_default_wire() -> None:
    assert wires.names() == ("paper", "workhorse", "intermediate", "stiff")
    # At the fast fidelity the paper preset is the published model bit for bit; converged,
    # the same wire with other numerical settings.
    published = wires.preset("paper", fidelity="fast")
    assert published == GuidewireConfig() == SceneConfig().wire
    assert wires.resolve(None) == wires.preset("paper")
    assert fidelity.numerics("converged", "paper").apply(published) == wires.preset("paper")
    assert wires.resolve(None, "fast") == published
    ratings = {n: wires.entry(n).rated_tip_load_gf for n in RATED}
    assert 0.5 <= ratings["workhorse"] <= 1.0
    assert 3.0 <= ratings["intermediate"] <= 6.0
    assert 11.0 <= ratings["stiff"] <= 13.0
    for name in RATED:
        entry = wires.entry(name)
        assert entry.rating_source.startswith("https://")
        assert entry.config.core_profile is not None
        assert entry.config.outer_diameter == pytest.approx(0.014 * 0.0254)


@pytest.mark.parametrize("name", RATED)
def test_stored_core_profile_is_the_one_derived_from_the_rating(name: str) -> None:
    entry = wires.entry(name)
    wire = entry.config
    rated = entry.rated_tip_load_gf * 1e-3 * tip_load.GRAVITY
    # The data file's diameters reproduce the rating by beam theory (0.1 um rounding).
    assert tip_load.buckling_load(wire) == pytest.approx(rated, rel=0.005)
    (_, tip), (ribbon, _), (taper_end, shaft) = wire.core_profile
    derived = tip_load.derive_tip_core_diameter(wire, rated, ribbon, taper_end, shaft)
    assert derived == pytest.approx(tip, abs=1e-7)


def test_buckling_solver_matches_euler_for_a_uniform_column() -> None:
    wire = GuidewireConfig(tip_stiffness_factor=1.0)
    exact = math.pi**2 * wire.bending_stiffness / (4 * 0.01**2)
    assert tip_load.buckling_load(wire) == pytest.approx(exact, rel=1e-4)
    assert tip_load.gram_force(exact) == pytest.approx(118.5, abs=0.1)  # issue 15's figure


@pytest.mark.parametrize("name", RATED)
def test_simulated_tip_load_is_within_10_percent_of_the_rating(name: str) -> None:
    entry = wires.entry(name)
    result = tip_load.simulate_tip_load(entry.config)
    assert result.free_length == pytest.approx(tip_load.TEST_FREE_LENGTH, abs=1e-6)
    assert result.lateral > 0.1 * result.free_length  # it buckled, not just pressed
    assert abs(result.force_gf - entry.rated_tip_load_gf) <= 0.1 * entry.rated_tip_load_gf
    # Tighter: the chain reproduces the continuous rod's buckling load (elastica + 1 %).
    assert result.force / result.predicted == pytest.approx(1.0, abs=0.06)


@pytest.mark.parametrize("name", RATED)
def test_the_tip_load_curve_has_no_first_contact_spike(name: str) -> None:
    entry = wires.entry(name)
    result = tip_load.simulate_tip_load(entry.config)
    curve = result.curve
    touching = curve.force > 0
    assert not touching[0]  # the tip starts off the plate
    # From the first contact to the read-out no settled point exceeds the rating by 20 %.
    assert tip_load.gram_force(result.peak_before_read) <= 1.2 * entry.rated_tip_load_gf
    first = tip_load.gram_force(float(curve.force[np.argmax(touching)]))
    assert 0.8 * entry.rated_tip_load_gf <= first <= 1.2 * entry.rated_tip_load_gf


@pytest.mark.parametrize("name", RATED)
def test_the_tip_load_curve_does_not_depend_on_the_mass_scaling(name: str) -> None:
    wire = wires.preset(name)
    scaled = tip_load.simulate_tip_load(wire)
    lighter = tip_load.simulate_tip_load(dataclasses.replace(wire, mass_scale=1e3))
    assert lighter.force == pytest.approx(scaled.force, rel=0.01)
    # Measured: every settled point within 2.2 % but the workhorse's first contact, 3.6 %
    # apart: its 3 mm tip is cut in 0.6 mm segments, the least settled point on the coarsest
    # tip (within 2 % everywhere with the 2 mm tip's 0.4 mm ones).
    np.testing.assert_allclose(lighter.curve.force, scaled.curve.force, rtol=0.04,
                               atol=0.01 * wires.entry(name).rated_tip_load_gf * 1e-3 * 9.81)


def test_the_bench_tests_hold_a_shaped_wire_straight_secondary_curve_and_all() -> None:
    # A secondary curve 5 mm back, left in, would bend the tip-load test's 10 mm column and
    # the cantilevers, which a manufacturer tests straight.
    shaped = wires.preset("workhorse", tip="3,75,5,50")
    assert shaped.secondary_angle > 0
    np.testing.assert_allclose(wire_vertices(shaped.straightened())[:, 1:], 0.0, atol=1e-12)
    tested, _ = tip_load.tested_wire(shaped)
    assert tested.secondary_angle == 0.0
    assert tested.tip_angle == pytest.approx(math.radians(1.0))  # the imperfection alone
    assert tested.tip_length == shaped.tip_length


def test_stiffer_core_gives_a_higher_simulated_tip_load() -> None:
    loads = [tip_load.simulate_tip_load(wires.preset(n)).force for n in RATED]
    assert loads == sorted(loads)


@pytest.mark.parametrize("name", RATED)
def test_tapered_cantilever_matches_integrated_euler_bernoulli(name: str) -> None:
    # 30 mm: mostly taper, where E·I varies up to 40-fold.
    wire = dataclasses.replace(wires.preset(name), length=0.03, mass_scale=1.0)
    result = validation.tapered_cantilever(wire, settle_time=2.0)
    assert result.relative_error < 0.05
    # The taper is in the model: the shaft's E·I alone would predict 1.75-5.8x less.
    uniform = result.force * result.free_length**3 / (3 * wire.bending_stiffness)
    assert result.deflection > 1.5 * uniform


@pytest.mark.parametrize("name", RATED)
def test_tapered_torsion_matches_the_integrated_twist(name: str) -> None:
    # Measured 2.2 / 2.5 / 1.8 % (30 mm, default mass scaling): the joints twist with the
    # core's G·J(s), taper and ribbon included.
    wire = dataclasses.replace(wires.preset(name), length=0.03)
    result = validation.tapered_torsion(wire)
    assert result.relative_error < 0.05
    # The shaft's G·J alone would predict several times less twist.
    uniform = result.torque * result.free_length / float(wire.torsional_rigidity(1.0))
    assert result.twist > 2.0 * uniform


def test_core_capsules_follow_the_profile() -> None:
    wire = wires.preset("workhorse")
    spec = base_spec()
    add_guidewire(spec, spec.worldbody.add_body(name="mount"), wire)
    model = spec.compile()
    radii = []
    for b in range(wire.num_segments):
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, names.wire_body(b))
        radii.append(model.geom_size[model.body_geomadr[body], 0])
    lengths = segment_lengths(wire)
    # Deep in the shaft the factor is the Voronoi one of a uniform rod.
    assert radii[3] == pytest.approx(0.5 * wire.core_diameter, rel=1e-6)
    # The last joint sits in the ribbon: factor (d_tip / d_shaft)^4 x l_prev / l_cell.
    (_, tip), *_ = wire.core_profile
    expected = (tip / wire.core_diameter) ** 4 * lengths[-2] / (0.5 * (lengths[-2] + lengths[-1]))
    assert (2 * radii[-1] / wire.core_diameter) ** 4 == pytest.approx(expected, rel=1e-6)


def test_tip_shapes_and_their_errors() -> None:
    shaped = wires.preset("workhorse", tip=wires.TipShape.degrees(1.5, 60.0))
    assert (shaped.tip_length, shaped.tip_angle) == pytest.approx((0.0015, math.radians(60)))
    j_tip = wires.preset("intermediate", tip="J")
    assert j_tip.tip_angle == pytest.approx(wires.J_ANGLE)
    with pytest.raises(wires.WireCatalogueError, match=r"TipShape\.length"):
        wires.TipShape(0.006, math.radians(45))
    with pytest.raises(wires.WireCatalogueError, match=r"TipShape\.angle"):
        wires.TipShape.degrees(2.0, 120.0)
    with pytest.raises(wires.WireCatalogueError, match="'S'"):
        wires.preset("workhorse", tip="S")
    curved = wires.preset("workhorse", tip=wires.TipShape.degrees(2.0, 60.0, 7.0, 40.0))
    assert (curved.secondary_distance, curved.secondary_angle) == pytest.approx(
        (0.007, math.radians(40)))
    assert wires.shaped(curved, "J").secondary_angle == 0.0  # a J has no secondary curve
    with pytest.raises(wires.WireCatalogueError, match=r"secondary_distance must be 5–10 mm"):
        wires.TipShape.degrees(4.0, 60.0, 4.5, 40.0)  # on the 4 mm tip
    with pytest.raises(wires.WireCatalogueError, match=r"TipShape\.secondary_angle"):
        wires.TipShape.degrees(2.0, 60.0, 7.0, 5.0)
    # config_for_vessel narrows the paper wire's stiff tip to the narrowest lumen; a soft
    # (tapered-core) tip only to three times the inlet's room, which a J (2.16 mm) fits in the
    # 2 mm phantom, as it does on the coronary domain.
    vessel = vessels.load("simplified_phantom")
    stiff_j = config_for_vessel(vessel, SceneConfig(wire=wires.preset("paper", tip="J"))).wire
    assert stiff_j.tip_angle < wires.J_ANGLE
    assert config_for_vessel(vessel, SceneConfig(wire=j_tip)).wire.tip_angle == wires.J_ANGLE


def test_tip_shapes_as_written_on_a_command_line() -> None:
    assert wires.parse_tip("3,75") == wires.TipShape.degrees(3.0, 75.0)
    assert wires.parse_tip(" j ") == "J"
    # The same text shapes a wire in task_kwargs, as --tip does on the command line.
    written = wires.resolve({"preset": "workhorse", "tip": "5,60"})
    assert written == wires.preset("workhorse", tip=wires.TipShape.degrees(5.0, 60.0))
    # A secondary curve: its distance from the end and its angle follow the tip's.
    assert wires.parse_tip("2,60,7,40") == wires.TipShape.degrees(2.0, 60.0, 7.0, 40.0)
    for text, message in (("3x75", r"LENGTH_MM,ANGLE_DEG \(e\.g\. 3,75\).*got '3x75'"),
                          ("3,75,1", "got '3,75,1'"),
                          ("0.5,60", r"'0\.5,60': the shaped length must be 1-5 mm"),
                          ("2,nan", "and the angle 30-90 deg"),
                          ("3,60,3.5,40", r"secondary curve 4-10 mm from the end, behind the tip"),
                          ("2,60,7,75", "and 15-60 deg")):
        with pytest.raises(wires.WireCatalogueError, match=message):
            wires.parse_tip(text)


def test_unknown_presets_and_bad_profiles_name_the_input() -> None:
    with pytest.raises(wires.WireCatalogueError, match=r"'floppy'.*'workhorse'"):
        wires.preset("floppy")
    with pytest.raises(wires.WireCatalogueError, match=r"Unknown wire fields \['colour'\]"):
        wires.resolve({"preset": "stiff", "colour": "blue"})
    with pytest.raises(wires.WireCatalogueError, match=r"'length' \(m\) and 'angle'"):
        wires.resolve({"preset": "stiff", "tip": {"length": 0.002}})
    bent = wires.resolve({"preset": "stiff", "tip": {"length": 0.002, "angle": 1.0}})
    assert (bent.tip_length, bent.tip_angle) == (0.002, 1.0)
    with pytest.raises(GuidewireConfigError, match="core_profile distances"):
        GuidewireConfig(core_profile=((0.001, 1e-4), (0.01, 2e-4)))
    with pytest.raises(GuidewireConfigError, match="core_profile diameters"):
        GuidewireConfig(core_profile=((0.0, 1e-4), (0.01, 1e-3)))
    with pytest.raises(GuidewireConfigError, match="core_profile must be"):
        GuidewireConfig(core_profile=((0.0,),))  # type: ignore[arg-type]


def _tip_core_radius(env: suite.NavigationEnvironment) -> float:
    model = env.physics.model.ptr
    site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, names.WIRE_TIP_SITE)
    return float(model.geom_size[model.body_geomadr[model.site_bodyid[site]], 0])


@pytest.mark.parametrize(
    ("domain", "task", "extra"),
    [("simplified_phantom", "task_a", {}), ("vascular_phantom", "task_b", {}),
     ("vessel", "navigate", {"vessel": "simplified_phantom", "target": "B"})],
)
def test_every_fixed_domain_takes_a_wire(domain: str, task: str, extra: dict) -> None:
    paper = _tip_core_radius(suite.load(domain, task, {**extra}))
    for wire in ("workhorse", wires.preset("stiff"), {"preset": "intermediate", "tip": "J"}):
        env = suite.load(domain, task, {**extra, "wire": wire, "random": 0})
        env.reset()
        assert np.isfinite(env.step([1.0, 0.0]).reward)
        assert _tip_core_radius(env) < 0.5 * paper  # the tapered tip, not the paper's rod
    with pytest.raises(TaskConfigError, match=r"wire.*'noodle'.*\['paper', 'workhorse'"):
        suite.load(domain, task, {**extra, "wire": "noodle"})


def test_random_coronary_takes_a_wire_and_its_tree_cache_ignores_it(
    tmp_path, monkeypatch
) -> None:
    calls = []

    def fake_member(seed, cache_dir, scene=None, same_wire=False):  # for a 10 s tree build
        calls.append((seed, cache_dir, scene))
        return compile_anatomy("simplified_phantom", scene, fit="none")

    monkeypatch.setattr(random_coronary, "build_member", fake_member)
    for wire in ({}, {"wire": "paper"}, {"wire": "workhorse"}):
        env = suite.load("random_coronary", "navigate",
                         {**wire, "pool_size": 1, "cache_dir": tmp_path, "random": 0})
        env.reset()
    (seed_a, dir_a, scene_a), (seed_b, dir_b, scene_b), (_, _, scene_c) = calls
    assert (seed_a, dir_a) == (seed_b, dir_b)  # same tree folder for every wire
    # The domain's default: the workhorse, its tip shaped 3 mm at 75°.
    assert scene_a.wire == wires.shaped(wires.preset("workhorse"), wires.TipShape.degrees(3, 75))
    assert scene_b.wire == wires.preset("paper") and scene_c.wire == wires.preset("workhorse")
    with pytest.raises(TaskConfigError, match="valid"):
        suite.load("random_coronary", "navigate", {"wire": "noodle", "cache_dir": tmp_path})


def test_catalogue_wires_run_at_their_own_step_unless_the_scene_sets_one() -> None:
    tube = vessels.load("simplified_phantom")
    workhorse = wires.preset("workhorse")
    assert workhorse.max_timestep == pytest.approx(0.0025)
    assert wires.preset("paper", fidelity="fast").max_timestep is None  # published: 5 ms
    step = {
        (name, level): build_model(tube, SceneConfig(
            wire=wires.preset(name, fidelity=level))).opt.timestep
        for name in ("paper", "workhorse", "stiff") for level in fidelity.names()
    }
    assert step == {
        ("paper", "converged"): pytest.approx(0.00125), ("paper", "fast"): pytest.approx(0.005),
        ("workhorse", "converged"): pytest.approx(0.0025),
        ("workhorse", "fast"): pytest.approx(0.0025),
        ("stiff", "converged"): pytest.approx(0.00125), ("stiff", "fast"): pytest.approx(0.0025),
    }
    chosen = build_model(tube, SceneConfig(wire=workhorse, timestep=0.004)).opt.timestep
    assert chosen == pytest.approx(0.004)  # an explicit scene step wins
    with pytest.raises(GuidewireConfigError, match="max_timestep"):
        dataclasses.replace(workhorse, max_timestep=0.0)


def test_a_fidelity_sets_the_numerics_and_never_the_wires_physics() -> None:
    numerical = {f.name for f in dataclasses.fields(fidelity.Numerics)}
    for name in wires.names():
        converged, fast = (wires.preset(name, fidelity=level) for level in fidelity.names())
        differing = {f.name for f in dataclasses.fields(GuidewireConfig)
                     if getattr(converged, f.name) != getattr(fast, f.name)}
        assert differing and differing <= numerical, name
        assert converged.integrator == "discrete" and converged.mass_scale == 100.0
        assert fast.mass_scale == 1e4
    tube = vessels.load("simplified_phantom")
    model = build_model(tube, SceneConfig(wire=wires.preset("workhorse")))
    wire_geoms = model.geom_priority == 1
    assert np.allclose(model.geom_solimp[wire_geoms], (0.9, 0.999, 0.0001, 0.5, 2.0))
    with pytest.raises(fidelity.FidelityError, match=r"'exact'.*'converged', 'fast'"):
        wires.preset("workhorse", fidelity="exact")
    with pytest.raises(wires.WireCatalogueError, match="carries its own numerical settings"):
        wires.resolve(wires.preset("workhorse"), "fast")
    with pytest.raises(GuidewireConfigError, match="contact_solimp"):
        dataclasses.replace(wires.preset("workhorse"), contact_solimp=(0.9, 0.8, 1e-4, 0.5, 2))


def test_catalogue_wires_name_their_coat_and_its_friction() -> None:
    assert wires.coatings() == {"hydrophobic": 0.1, "hydrophilic": 0.03}
    assert wires.entry("workhorse").coating == "hydrophilic"
    assert wires.preset("workhorse").friction == wires.coating_friction("hydrophilic")
    assert wires.preset("stiff").friction == wires.coating_friction("hydrophobic")
    assert wires.preset("paper").friction == GuidewireConfig().friction  # the published 0.1
    recoated = wires.resolve({"preset": "workhorse", "coating": "hydrophobic"})
    assert recoated == dataclasses.replace(wires.preset("workhorse"), friction=0.1)
    with pytest.raises(wires.WireCatalogueError, match=r"'teflon'.*hydrophilic"):
        wires.resolve({"preset": "workhorse", "coating": "teflon"})
    with pytest.raises(wires.WireCatalogueError, match="not both"):
        wires.resolve({"preset": "workhorse", "coating": "hydrophilic", "friction": 0.2})


def test_catalogue_wires_choose_elliptic_friction_cones_and_paper_keeps_the_scene_s() -> None:
    tube = vessels.load("simplified_phantom")
    cone = {
        name: build_model(tube, SceneConfig(wire=wires.preset(name, fidelity="fast"))).opt.cone
        for name in ("paper", "workhorse")
    }
    assert cone == {"paper": mujoco.mjtCone.mjCONE_PYRAMIDAL,
                    "workhorse": mujoco.mjtCone.mjCONE_ELLIPTIC}
    converged = build_model(tube, SceneConfig(wire=wires.preset("paper"))).opt.cone
    assert converged == mujoco.mjtCone.mjCONE_ELLIPTIC
    with pytest.raises(GuidewireConfigError, match=r"friction_cone.*'conical'"):
        dataclasses.replace(wires.preset("workhorse"), friction_cone="conical")
