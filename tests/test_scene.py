"""Scene composition: vessel + sheath + driver + wire, placement, names, cache, errors."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from guidewire_helpers import write_tube_vessel

from sim4endor.errors import Sim4EndoRError
from sim4endor.models import constants as names
from sim4endor.models import scene, wires
from sim4endor.models.driver import DriverConfig, add_driver
from sim4endor.models.guidewire import GuidewireConfig, segment_lengths
from sim4endor.physics import GuidewirePhysics
from sim4endor.vessels import Vessel
from sim4endor.vessels.centerline import CenterlineGraph


@pytest.fixture(scope="module")
def tube(tmp_path_factory: pytest.TempPathFactory) -> Vessel:
    return write_tube_vessel(tmp_path_factory.mktemp("vessels") / "tube")


def _id(model: mujoco.MjModel, kind: mujoco.mjtObj, name: str) -> int:
    index = mujoco.mj_name2id(model, kind, name)
    assert index >= 0, f"missing {name}"
    return index


def test_scene_compiles_with_named_elements_and_no_warnings(tube: Vessel) -> None:
    model = scene.build_model(tube)
    data = mujoco.MjData(model)
    mujoco.mj_step(model, data, 20)
    assert not any(w.number for w in data.warning)
    for kind, name in (
        (mujoco.mjtObj.mjOBJ_BODY, names.CARRIAGE_BODY),
        (mujoco.mjtObj.mjOBJ_BODY, names.SHEATH_BODY),
        (mujoco.mjtObj.mjOBJ_JOINT, names.INSERTION_JOINT),
        (mujoco.mjtObj.mjOBJ_JOINT, names.ROTATION_JOINT),
        (mujoco.mjtObj.mjOBJ_ACTUATOR, names.INSERTION_ACTUATOR),
        (mujoco.mjtObj.mjOBJ_ACTUATOR, names.ROTATION_ACTUATOR),
        (mujoco.mjtObj.mjOBJ_SITE, names.WIRE_TIP_SITE),
        (mujoco.mjtObj.mjOBJ_GEOM, names.VESSEL_PREFIX + "wall_000"),  # the STL hull
        (mujoco.mjtObj.mjOBJ_SITE, names.VESSEL_PREFIX + "target_A"),
    ):
        _id(model, kind, name)
    assert model.opt.solver == mujoco.mjtSolver.mjSOL_NEWTON
    assert model.opt.timestep == pytest.approx(0.005)
    assert np.allclose(model.opt.gravity, 0.0)


def test_wire_starts_in_the_sheath_with_the_tip_just_inside_the_inlet(tube: Vessel) -> None:
    config = scene.SceneConfig()
    model = scene.build_model(tube, config)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    carriage = data.xpos[_id(model, mujoco.mjtObj.mjOBJ_BODY, names.CARRIAGE_BODY)]
    back = config.driver.sheath_length(config.wire.length)
    np.testing.assert_allclose(carriage, [-back, 0.0, 0.0], atol=1e-9)
    tip = data.site_xpos[_id(model, mujoco.mjtObj.mjOBJ_SITE, names.WIRE_TIP_SITE)]
    assert 0.0 < tip[0] <= config.driver.initial_protrusion
    assert tip[1] == pytest.approx(config.wire.tip_lateral_offset, rel=1e-6)  # bent 'up' (+y)


def test_insertion_frame_points_along_the_inlet_with_y_up() -> None:
    for direction in ([1.0, 0.0, 0.0], [0.3, -0.2, 0.9], [0.0, 1.0, 0.0]):
        quat = scene.insertion_frame(np.array(direction))
        mat = np.zeros(9)
        mujoco.mju_quat2Mat(mat, quat)
        frame = mat.reshape(3, 3)
        np.testing.assert_allclose(frame[:, 0], np.array(direction) / np.linalg.norm(direction))
        np.testing.assert_allclose(frame.T @ frame, np.eye(3), atol=1e-12)
        assert frame[1, 1] >= 0 or abs(direction[1]) > 0.99


def test_compiled_model_is_cached_and_copied(tube: Vessel) -> None:
    config = scene.SceneConfig(timestep=0.004)
    first = scene.build_model(tube, config)
    hits = scene._compiled.cache_info().hits
    second = scene.build_model(tube, config)
    assert scene._compiled.cache_info().hits == hits + 1
    assert first is not second and first.opt.timestep == second.opt.timestep == 0.004
    first.geom_friction[:] = 0.0
    assert scene.build_model(tube, config).geom_friction.max() > 0.0


def test_rebuilt_vessel_folder_is_recompiled(tmp_path: Path) -> None:
    first = scene.build_model(write_tube_vessel(tmp_path / "t", length=0.05))
    second = scene.build_model(write_tube_vessel(tmp_path / "t", length=0.07))
    assert not np.array_equal(first.geom_pos, second.geom_pos)  # the walls moved


def test_config_for_vessel_sizes_wire_to_the_deepest_target(tube: Vessel) -> None:
    config = scene.config_for_vessel(tube)
    assert config.driver.max_insertion == pytest.approx(0.06 + 0.01)
    assert config.wire.length == pytest.approx(0.07 + config.driver.initial_protrusion + 0.003)
    scene.build_spec(tube, config)  # consistent: no error


def test_the_carriage_mass_sits_on_the_roll_axis_wherever_the_anatomy_is() -> None:
    # A patient's inlet lies anywhere in scanner coordinates; the roll servo must still see
    # only the carriage's own inertia (it once saw m |pos|^2: 0.04 kg m^2 in stEVE's anatomy).
    spec = scene.base_spec()
    driver = DriverConfig()
    add_driver(spec, np.array([0.3, -0.6, 0.1]),
               scene.insertion_frame(np.array([-0.7, 0.7, -0.2])), driver)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    inertia = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, inertia)
    roll = model.jnt_dofadr[_id(model, mujoco.mjtObj.mjOBJ_JOINT, names.ROTATION_JOINT)]
    assert inertia[roll, roll] == pytest.approx(driver.carriage_inertia)


def test_a_tip_wider_than_the_inlet_starts_straightened_in_it(tube: Vessel) -> None:
    # 6 mm at 80 degrees: far wider than the tube's bore. A real tip straightens in a
    # catheter; the wire starts straight and its elasticity keeps the shaped rest state.
    wide = GuidewireConfig(tip_length=0.006, tip_angle=math.radians(80))
    physics = GuidewirePhysics.from_vessel(tube, scene.SceneConfig(wire=wide))
    assert physics.named.model.numeric_data[names.TIP_STRAIGHT_AT_START][0] == 1.0
    physics.place_driver(0.0, 0.0)
    points = physics.wire_points()
    axis = (points[-1] - points[0]) / np.linalg.norm(points[-1] - points[0])
    off_axis = (points - points[0]) - np.outer((points - points[0]) @ axis, axis)
    assert np.abs(off_axis).max() < 1e-9
    fits = GuidewirePhysics.from_vessel(tube, scene.SceneConfig())
    assert fits.named.model.numeric_data[names.TIP_STRAIGHT_AT_START][0] == 0.0


def test_too_short_wire_is_refused_with_the_fix() -> None:
    config = scene.SceneConfig(wire=GuidewireConfig(length=0.05), driver=DriverConfig())
    with pytest.raises(Sim4EndoRError, match="max_insertion"):
        scene.build_spec(None, config)


def test_vessel_meshes_resolve_from_any_working_directory(
    tube: Vessel, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.chdir(tmp_path)
    config = dataclasses.replace(scene.SceneConfig(), timestep=0.003)
    assert scene.build_model(tube, config).nmesh == 1


def test_config_for_vessel_narrows_the_tip_for_thin_lumens(tmp_path: Path) -> None:
    thin = write_tube_vessel(tmp_path / "thin", radius=0.0009, wall=0.0005)
    config = scene.config_for_vessel(thin)
    assert config.wire.tip_angle < math.radians(20)
    assert config.wire.tip_lateral_offset <= 0.85 * (0.0009 - config.wire.radius) + 1e-9
    assert config.wire.tip_lateral_offset > 0.8 * (0.0009 - config.wire.radius)
    scene.build_spec(thin, config)  # the tip now fits the inlet
    wide = scene.config_for_vessel(write_tube_vessel(tmp_path / "wide"))
    assert wide.wire.tip_angle == GuidewireConfig().tip_angle


def _arc_graph(bend: float, radius: float, turn: float = math.pi,
               spacing: float = 2e-4) -> CenterlineGraph:
    """A centerline of a straight lead-in, an arc of axis radius ``bend`` (m) turning by
    ``turn`` and a straight lead-out, all of lumen radius ``radius``."""
    lead = np.arange(0.0, 0.01, spacing)
    angles = np.arange(0.0, turn, spacing / bend)
    arc = np.column_stack([0.01 + bend * np.sin(angles), bend * (1 - np.cos(angles)),
                           np.zeros_like(angles)])
    end, heading = arc[-1], np.array([np.cos(turn), np.sin(turn), 0.0])
    points = np.vstack([np.column_stack([lead, 0 * lead, 0 * lead]), arc,
                        end + np.outer(lead[1:] + spacing, heading)])
    edges = np.column_stack([np.arange(len(points) - 1), np.arange(1, len(points))])
    return CenterlineGraph(points, np.full(len(points), radius), edges)


def test_shaft_segments_are_cut_to_lie_in_the_tightest_bend_of_a_centerline() -> None:
    workhorse = wires.preset("workhorse")
    bend, lumen = 0.002, 0.00075  # a narrow branch's tight bend, as in a coronary tree
    room = 0.75 * (lumen - workhorse.radius)
    fitted = scene.fit_segments_to_vessel(workhorse, _arc_graph(bend, lumen))
    # A chord of length l in an arc of radius R strays R - sqrt(R^2 - l^2 / 4) from it.
    exact = 2 * math.sqrt(bend**2 - (bend - room) ** 2)
    assert fitted.max_segment_length == pytest.approx(exact, rel=0.03)
    assert fitted.max_segment_length < workhorse.max_segment_length
    # Gentle or wide: the wire's own segments already fit, and the wire is returned as is.
    for graph in (_arc_graph(0.05, lumen), _arc_graph(0.006, 0.002)):
        assert scene.fit_segments_to_vessel(workhorse, graph) is workhorse
    # A lumen narrower than the wire (a stenosis it does not pass) is not measured.
    assert scene.fit_segments_to_vessel(
        workhorse, _arc_graph(bend, 0.5 * workhorse.radius)) is workhorse


def test_only_the_wire_that_can_reach_a_tight_bend_is_cut_for_it() -> None:
    workhorse = wires.preset("workhorse")
    bend, lumen = 0.002, 0.00075
    graph = _arc_graph(bend, lumen)  # the bend runs from 10 mm to 16.3 mm along the axis
    graph = CenterlineGraph(graph.nodes, graph.radii, graph.edges, labels={"inlet": 0})
    whole = scene.fit_segments_to_vessel(workhorse, graph)
    reach = 0.05
    graded = scene.fit_segments_to_vessel(workhorse, graph, reach=reach)
    assert graded.max_segment_length == workhorse.max_segment_length
    assert graded.segment_limits[0] == (0.0, pytest.approx(whole.max_segment_length, rel=1e-3))
    lengths = segment_lengths(graded)[::-1]  # tip first
    from_tip = np.cumsum(lengths) - lengths  # each segment's distal end
    # Whatever can get into the bend (up to 50 - 10 mm from the tip) is as short as the whole
    # wire fitted to it; what never leaves the sheath is split evenly into segments of at
    # most the preset's 5 mm.
    deep = from_tip <= reach - 0.01
    assert lengths[deep].max() <= whole.max_segment_length + 1e-9
    proximal = lengths[from_tip > reach]
    assert proximal.max() <= workhorse.max_segment_length + 1e-9
    assert proximal.min() > 1.5 * whole.max_segment_length
    assert graded.num_segments < whole.num_segments
    assert lengths.sum() == pytest.approx(workhorse.length)


def _junction_graph(parent: float, branch: float, flare: float = 1.5,
                    angle: float = math.radians(85), spacing: float = 2e-4) -> CenterlineGraph:
    """A straight parent of lumen radius ``parent`` (m) with a straight branch of radius
    ``branch`` leaving its middle at ``angle``; the junction's node ``flare`` times wider
    than the parent, as a centerline's inscribed sphere is there."""
    run = np.arange(spacing, 0.01, spacing)
    heading = np.array([math.cos(angle), math.sin(angle), 0.0])
    points = np.vstack([np.column_stack([run - 0.01, 0 * run, 0 * run])[::-1], np.zeros((1, 3)),
                        np.column_stack([run, 0 * run, 0 * run]), np.outer(run, heading)])
    n = len(run)
    radii = np.concatenate([np.full(n, parent), [flare * parent], np.full(n, parent),
                            np.full(n, branch)])
    chain = np.arange(2 * n)  # proximal parent, junction node n, distal parent
    branch_nodes = np.arange(2 * n + 1, 3 * n)
    edges = np.vstack([np.column_stack([chain, chain + 1]), [[n, 2 * n + 1]],
                       np.column_stack([branch_nodes, branch_nodes + 1])])
    return CenterlineGraph(points, radii, edges)


def test_shaft_segments_are_cut_to_turn_into_a_narrow_branch() -> None:
    workhorse = wires.preset("workhorse")
    narrow = _junction_graph(0.00085, 0.00085)  # issue 15's sub-branch calibre
    # Straight branches: nothing to fit within them, but the turn into one.
    fitted = scene.fit_segments_to_vessel(workhorse, narrow)
    bend = scene.JUNCTION_BEND_RADII * 0.00085
    expected = math.sqrt(8 * bend * 0.75 * (0.00085 - workhorse.radius))
    # The branch's radius, read past the junction's flare (1.5 x the parent's at the node).
    assert fitted.max_segment_length == pytest.approx(expected)
    assert 0.0025 < fitted.max_segment_length < 0.003
    # The narrower of the two vessels meeting decides.
    assert scene.fit_segments_to_vessel(
        workhorse, _junction_graph(0.002, 0.00085)).max_segment_length == pytest.approx(expected)
    # Wide vessels (the phantoms' 2 mm) keep the wire's 5 mm; a branch no wider than the wire
    # (a stenosis it does not pass) is not measured.
    assert scene.fit_segments_to_vessel(workhorse, _junction_graph(0.002, 0.0016)) is workhorse
    assert scene.fit_segments_to_vessel(
        workhorse, _junction_graph(0.002, 0.5 * workhorse.radius)) is workhorse


def test_config_for_vessel_keeps_the_phantoms_segments() -> None:
    from sim4endor import vessels

    for name in ("simplified_phantom", "vascular_phantom"):
        vessel = vessels.load(name)
        for wire in (GuidewireConfig(), wires.preset("workhorse")):
            fitted = scene.config_for_vessel(vessel, scene.SceneConfig(wire=wire)).wire
            assert fitted.max_segment_length == wire.max_segment_length, name
            assert fitted.segment_limits is None, name


def _bent_inlet(straight: float, radius: float = 1.1e-3) -> object:
    """A vessel's inlet: ``straight`` m along +x, then a 90° turn of 6 mm axis radius."""
    from types import SimpleNamespace

    arc = np.linspace(0.0, math.pi / 2, 40)
    bend = np.stack([straight + 6e-3 * np.sin(arc), 6e-3 * (1 - np.cos(arc)), 0 * arc], 1)
    nodes = np.vstack([np.array([[0.0, 0.0, 0.0]]), bend])
    graph = CenterlineGraph(nodes=nodes, radii=np.full(len(nodes), radius),
                            edges=np.stack([np.arange(len(nodes) - 1),
                                            np.arange(1, len(nodes))], 1),
                            labels={"inlet": 0})
    return SimpleNamespace(centerline=graph, inlet_position=np.zeros(3),
                           inlet_direction=np.array([1.0, 0.0, 0.0]))


def test_the_start_protrusion_is_cut_where_the_vessel_bends_away_within_it() -> None:
    base = scene.SceneConfig(wire=wires.resolve({"preset": "workhorse", "tip": "3,75"}))
    default = base.driver.initial_protrusion
    # Straight for 20 mm: the default 8 mm.
    assert scene.fit_protrusion(_bent_inlet(0.02), base) == base
    # Bending after 2 mm: the straight wire would reach the wall about 3 mm later.
    cut = scene.fit_protrusion(_bent_inlet(0.002), base).driver.initial_protrusion
    assert base.wire.tip_length < cut < default
    for s in np.linspace(0.0, cut, 20):  # the whole protrusion keeps its clearance
        point = np.array([base.driver.sheath_overlap + s, 0.0, 0.0])
        excess = _bent_inlet(0.002).centerline.tube_excess(point)
        assert excess + base.wire.radius <= -scene.START_CLEARANCE + 1e-9
    # Bending at once: never shorter than the shaped tip needs to start free of the sheath.
    tight = scene.fit_protrusion(_bent_inlet(0.0, radius=0.4e-3), base).driver
    assert tight.initial_protrusion == pytest.approx(base.wire.tip_length + 5e-4)
    tight.check_wire(base.wire.length, base.wire.radius, base.wire.tip_length)
    # The shipped phantoms' straight inlets keep it.
    for name in ("simplified_phantom", "vascular_phantom"):
        from sim4endor import vessels

        fitted = scene.config_for_vessel(vessels.load(name), base)
        assert fitted.driver.initial_protrusion == default
