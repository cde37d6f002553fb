"""Vessel generators: swept tubes, phantoms and random coronary trees (no build pipeline)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim4endor.vessels.centerline import CenterlineGraph
from sim4endor.vessels.generators import (
    GENERATORS,
    CoronaryTreeConfig,
    GeneratedAnatomy,
    GeneratorConfigError,
    MeshResolution,
    SimplifiedPhantomConfig,
    VascularPhantomConfig,
    coronary_tree,
    simplified_phantom,
    vascular_phantom,
)
from sim4endor.vessels.generators.command import apply_overrides, canonical_command
from sim4endor.vessels.generators.coronary import murray_split
from sim4endor.vessels.generators.paths import Arc, Frame, Straight, trace
from sim4endor.vessels.generators.tubes import (
    LumenMeshError,
    TubeBranch,
    centerline_graph,
    clearance_violations,
    lumen_mesh,
    sweep_tube,
)

MM = 1e-3
SEGMENTS = 32
# Area of the inscribed 32-gon over the circle's: the faceted tube's volume factor.
POLYGON = SEGMENTS / (2 * math.pi) * math.sin(2 * math.pi / SEGMENTS)
X_FRAME = Frame.start((0, 0, 0), (1, 0, 0), (0, 1, 0))


@pytest.fixture(scope="module")
def simplified() -> GeneratedAnatomy:
    return simplified_phantom()


@pytest.fixture(scope="module")
def vascular() -> GeneratedAnatomy:
    return vascular_phantom()


@pytest.fixture(scope="module")
def tree() -> GeneratedAnatomy:
    return coronary_tree(CoronaryTreeConfig(), seed=11)


def _tube(points: np.ndarray, radius: float) -> TubeBranch:
    return TubeBranch("tube", points, np.full(len(points), radius))


def _path_nodes(graph: CenterlineGraph, target: int) -> list[int]:
    """Nodes on the tree path from the inlet to ``target``."""
    distance = graph.geodesic_from(graph.labels["inlet"])
    neighbours: dict[int, list[int]] = {}
    for i, j in graph.edges:
        neighbours.setdefault(int(i), []).append(int(j))
        neighbours.setdefault(int(j), []).append(int(i))
    path = [target]
    while path[-1] != graph.labels["inlet"]:
        path.append(min(neighbours[path[-1]], key=lambda n: distance[n]))
    return path


def _bifurcations_before(graph: CenterlineGraph, target: str) -> int:
    degrees = graph.degrees()
    return sum(degrees[n] >= 3 for n in _path_nodes(graph, graph.labels[target]))


# ------------------------------------------------------------------------------ tubes
def test_straight_tube_is_closed_and_has_the_analytic_volume() -> None:
    points, _ = trace(X_FRAME, [Straight(30 * MM)], 0.5 * MM)
    mesh = lumen_mesh([_tube(points, 2 * MM)], SEGMENTS)
    r, length = 2 * MM, 30 * MM
    # Flat inlet, hemispherical far end (its rings are inscribed too: within the factor).
    cylinder, half_ball = math.pi * r**2 * length, 2 / 3 * math.pi * r**3
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(POLYGON * cylinder + half_ball, rel=0.01)
    assert mesh.bounds[0, 0] == pytest.approx(0.0, abs=1e-12)  # cut flat at the inlet node
    assert mesh.bounds[1, 0] == pytest.approx(length + r, rel=1e-6)  # capped beyond the end


def test_curved_tube_volume_follows_pappus() -> None:
    arc = Arc(90.0, 10 * MM, roll_deg=30.0)
    points, end = trace(X_FRAME, [arc], 0.25 * MM)
    vertices, faces = sweep_tube(points, np.full(len(points), 2 * MM), SEGMENTS)
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces)
    balls = 4 / 3 * math.pi * (2 * MM) ** 3
    assert mesh.is_watertight
    assert mesh.volume == pytest.approx(POLYGON * math.pi * (2 * MM) ** 2 * arc.length + balls,
                                        rel=0.01)
    assert np.dot(end.tangent, X_FRAME.tangent) == pytest.approx(0.0, abs=1e-9)
    assert np.linalg.norm(np.diff(points, axis=0), axis=1).max() <= 0.25 * MM + 1e-12


def test_points_farther_than_the_radius_from_the_axis_are_outside(simplified) -> None:
    rng = np.random.default_rng(0)
    graph, mesh = simplified.centerline, simplified.lumen
    lo, hi = mesh.bounds
    samples = rng.uniform(lo - 1 * MM, hi + 1 * MM, size=(1500, 3))
    offset = np.array([np.linalg.norm(p - graph.project(p).point) for p in samples])
    radius = graph.radius_at(samples)
    inside = mesh.contains(samples)
    assert not np.any(inside[offset > radius * 1.0001])
    deep = (offset < 0.95 * radius) & (samples[:, 0] > 0.1 * MM)
    assert deep.sum() > 50 and np.all(inside[deep])


def _looping_tree(return_length: float) -> list[TubeBranch]:
    """A root along +x and a child that turns round and comes back towards the root's middle."""
    root, end = trace(X_FRAME, [Straight(20 * MM)], 0.5 * MM)
    child, _ = trace(end.turned(90.0, 0.0), [
        Straight(3 * MM), Arc(90, 4 * MM, 0.0), Straight(8 * MM), Arc(90, 4 * MM, 0.0),
        Straight(return_length)], 0.5 * MM)
    return [_tube(root, 1 * MM), TubeBranch("child", child, np.full(len(child), MM), parent=0)]


def test_branches_meeting_away_from_junctions_are_rejected() -> None:
    looping = _looping_tree(return_length=1.5 * MM)  # ends 1.5 mm from the root's axis
    graph = centerline_graph(looping, {})
    assert len(clearance_violations(graph, gap=0.2 * MM)) > 0
    with pytest.raises(LumenMeshError, match="genus 1"):
        lumen_mesh(looping, SEGMENTS)
    apart = _looping_tree(return_length=0.0)  # ends 3 mm from the root's axis: 1 mm gap
    graph = centerline_graph(apart, {})
    assert len(clearance_violations(graph, gap=0.8 * MM)) == 0
    assert len(clearance_violations(graph, gap=1.6 * MM)) > 0
    assert lumen_mesh(apart, SEGMENTS).is_watertight


# ---------------------------------------------------------------------------- phantoms
def test_simplified_phantom_matches_paper_geometry(simplified) -> None:
    graph = simplified.centerline
    a, b = math.radians(35), math.radians(35)
    fork = np.array([60 * MM, 0, 0])
    expected_a = fork + 40 * MM * np.array([math.cos(a), math.sin(a), 0])
    rho, turn = 40 * MM / math.radians(40), math.radians(40)
    centre = fork + rho * np.array([-math.sin(b), -math.cos(b), 0])
    expected_b = centre + rho * np.array([math.sin(b + turn), math.cos(b + turn), 0])
    np.testing.assert_allclose(simplified.targets["A"], expected_a, atol=1e-9)
    np.testing.assert_allclose(simplified.targets["B"], expected_b, atol=1e-9)
    np.testing.assert_allclose(simplified.inlet_position, 0.0, atol=1e-12)
    np.testing.assert_allclose(simplified.inlet_direction, [1, 0, 0], atol=1e-12)
    assert graph.total_length() == pytest.approx(140 * MM, rel=1e-4)
    assert np.all(graph.radii == 2 * MM) and np.ptp(graph.nodes[:, 2]) < 1e-12
    assert graph.branch_names == ("trunk", "A", "B")
    assert sorted(int(n) for n in graph.terminal_nodes()) == sorted(
        graph.labels[k] for k in ("inlet", "A", "B"))
    assert simplified.lumen.is_watertight


def test_vascular_phantom_meets_the_complex_phantom_requirements(vascular) -> None:
    graph = vascular.centerline
    assert int(np.sum(graph.degrees() == 3)) >= 3
    assert _bifurcations_before(graph, "A") >= 2 and _bifurcations_before(graph, "B") >= 2
    assert graph.radii.min() >= 1.75 * MM
    assert np.ptp(graph.nodes, axis=0).max() + 2 * graph.radii.max() <= 150 * MM
    assert np.ptp(graph.nodes[:, 2]) > 10 * MM  # 3D, not planar
    curvature = graph.node_curvature()
    assert curvature.max() > 1 / (10 * MM)  # strongly curved (radius <= 10 mm)
    assert np.mean(curvature < 1e-6) > 0.2  # and straight runs
    assert len(clearance_violations(graph, gap=1.6 * MM)) == 0
    assert vascular.lumen.is_watertight and vascular.lumen.volume > 0


def test_phantom_jitter_is_seeded() -> None:
    config = SimplifiedPhantomConfig(angle_jitter_deg=3.0, length_jitter=0.05)
    first, again = simplified_phantom(config, seed=1), simplified_phantom(config, seed=1)
    other = simplified_phantom(config, seed=2)
    np.testing.assert_array_equal(first.centerline.nodes, again.centerline.nodes)
    assert not np.allclose(first.targets["A"], other.targets["A"])
    # Without jitter the seed plays no part.
    np.testing.assert_array_equal(simplified_phantom(seed=5).centerline.nodes,
                                  simplified_phantom(seed=6).centerline.nodes)


def test_bad_phantom_configs_name_the_problem() -> None:
    with pytest.raises(GeneratorConfigError, match="target_radius"):
        vascular_phantom(VascularPhantomConfig(target_radius=1.5 * MM))
    with pytest.raises(GeneratorConfigError, match="arc radius"):
        simplified_phantom(SimplifiedPhantomConfig(branch_b_curve_deg=170.0,
                                                   branch_b_length=8 * MM))
    with pytest.raises(GeneratorConfigError, match="come within"):
        simplified_phantom(SimplifiedPhantomConfig(branch_a_angle_deg=3, branch_b_angle_deg=3,
                                                   branch_b_curve_deg=1))


# ---------------------------------------------------------------------------- coronary
def test_coronary_tree_is_deterministic_per_seed(tree) -> None:
    again = coronary_tree(CoronaryTreeConfig(), seed=11)
    other = coronary_tree(CoronaryTreeConfig(), seed=12)
    np.testing.assert_array_equal(tree.lumen.vertices, again.lumen.vertices)
    np.testing.assert_array_equal(tree.lumen.faces, again.lumen.faces)
    np.testing.assert_array_equal(tree.centerline.nodes, again.centerline.nodes)
    assert tree.centerline.labels == again.centerline.labels
    assert tree.centerline.total_length() != pytest.approx(other.centerline.total_length())


def test_coronary_tree_levels_radii_and_taper(tree) -> None:
    graph, config = tree.centerline, CoronaryTreeConfig()
    assert tree.lumen.is_watertight and graph.num_components() == 1
    assert graph.radii.min() == pytest.approx(config.min_radius)
    assert graph.radii.max() == pytest.approx(config.root_radius)
    for name in tree.targets:
        assert _bifurcations_before(graph, name) == config.levels
        radii = graph.radii[_path_nodes(graph, graph.labels[name])[::-1]]
        assert np.all(np.diff(radii) <= 1e-15)  # tapering from the inlet to every leaf
    assert len(tree.targets) == 2**config.levels
    behind = graph.nodes[:, 0] < graph.radii + config.clearance
    axial_gap = np.hypot(graph.nodes[behind, 1], graph.nodes[behind, 2]) - graph.radii[behind]
    on_root = graph.branch[behind] == 0  # the root starts at the inlet itself
    assert np.all(axial_gap[~on_root] >= config.inlet_keep_out + config.clearance)  # sheath
    assert len(clearance_violations(graph, gap=config.clearance)) == 0


def test_murray_split_conserves_flow_and_gives_the_classic_angle() -> None:
    r1, r2, angle1, angle2 = murray_split(1.0, 1.0, 3.0)
    assert r1**3 + r2**3 == pytest.approx(1.0)
    assert angle1 == pytest.approx(angle2) == pytest.approx(37.47, abs=0.01)
    r1, r2, angle1, angle2 = murray_split(1.0, 0.5, 3.0)
    assert r2 == pytest.approx(0.5 * r1) and angle1 < angle2  # the major branch turns less


def test_coronary_tortuosity_follows_the_curvature_setting() -> None:
    def tortuosity(anatomy: GeneratedAnatomy) -> float:
        graph = anatomy.centerline
        arcs = [
            (np.linalg.norm(np.diff(graph.nodes[graph.branch == b], axis=0), axis=1).sum(),
             np.linalg.norm(graph.nodes[graph.branch == b][-1] - graph.nodes[graph.branch == b][0]))
            for b in range(len(graph.branch_names))
        ]
        return float(np.mean([arc / chord for arc, chord in arcs]))

    straight = coronary_tree(CoronaryTreeConfig(levels=2, curvature_rms=0.0), seed=3)
    winding = coronary_tree(CoronaryTreeConfig(levels=2, curvature_rms=120.0), seed=3)
    assert tortuosity(straight) == pytest.approx(1.0, abs=1e-9)
    assert tortuosity(winding) > 1.02
    kappa = winding.centerline.node_curvature()
    assert np.all(kappa * winding.centerline.radii <= 0.4 + 0.05)


def test_coronary_root_is_straight_where_the_wire_starts(tree: GeneratedAnatomy) -> None:
    """The first ``inlet_straight`` of the root lies on the inlet axis (+x from the origin),
    so the straight wire pushed past the sheath at an episode start is inside the lumen."""
    graph, config = tree.centerline, CoronaryTreeConfig()
    ostium = graph.nodes[(graph.branch == 0) & (graph.nodes[:, 0] <= config.inlet_straight)]
    assert len(ostium) > 3 and ostium[:, 0].max() > 0.9 * config.inlet_straight
    assert np.abs(ostium[:, 1:]).max() < 1e-9
    with pytest.raises(GeneratorConfigError, match="inlet_straight"):
        CoronaryTreeConfig(inlet_straight=CoronaryTreeConfig().root_length)


def test_coronary_resolution_reaches_about_the_target_face_count() -> None:
    config = CoronaryTreeConfig(levels=2, resolution=MeshResolution(target_faces=60_000))
    anatomy = coronary_tree(config, seed=0)
    assert 0.8 * 60_000 <= len(anatomy.lumen.faces) <= 1.2 * 60_000


def test_coronary_config_is_validated() -> None:
    with pytest.raises(GeneratorConfigError, match="levels"):
        CoronaryTreeConfig(levels=0)
    with pytest.raises(GeneratorConfigError, match="min_radius"):
        CoronaryTreeConfig(min_radius=2e-3, root_radius=1e-3)
    with pytest.raises(GeneratorConfigError, match="circumferential"):
        MeshResolution(circumferential_segments=4)


# ------------------------------------------------------------------------------- registry
@pytest.mark.parametrize("fixture", ["simplified", "vascular", "tree"])
def test_generated_anatomies_honour_the_contract(fixture, request) -> None:
    anatomy: GeneratedAnatomy = request.getfixturevalue(fixture)
    graph = anatomy.centerline
    assert anatomy.lumen.is_watertight and anatomy.lumen.volume > 0
    assert set(graph.labels) == {"inlet", *anatomy.targets}
    ends = {int(n) for n in graph.terminal_nodes()}
    assert {graph.labels[k] for k in graph.labels} <= ends  # inlet and targets are vessel ends
    for name, point in anatomy.targets.items():
        np.testing.assert_array_equal(graph.nodes[graph.labels[name]], point)
    np.testing.assert_array_equal(graph.nodes[graph.labels["inlet"]], anatomy.inlet_position)
    assert np.linalg.norm(anatomy.inlet_direction) == pytest.approx(1.0)
    into = graph.nodes[1] - graph.nodes[0]  # the first edge leaves the inlet into the vessel
    assert np.dot(into, anatomy.inlet_direction) > 0.99 * np.linalg.norm(into)
    assert anatomy.description


def test_registry_names_every_generator() -> None:
    assert set(GENERATORS) == {"simplified_phantom", "vascular_phantom", "coronary_tree",
                               "coronary_arteries"}
    assert GENERATORS["coronary_tree"].generate is coronary_tree
    assert GENERATORS["vascular_phantom"].config_type is VascularPhantomConfig


def test_overrides_parse_types_and_reject_unknown_keys() -> None:
    config = apply_overrides(CoronaryTreeConfig(), [
        "levels=2", "asymmetry=0.6,0.9", "resolution.target_faces=100000", "curvature_rms=80",
    ])
    assert config.levels == 2 and config.asymmetry == (0.6, 0.9)
    assert config.resolution.target_faces == 100_000 and config.curvature_rms == 80.0
    assert apply_overrides(config, ["resolution.target_faces=none"]).resolution.target_faces is None
    with pytest.raises(GeneratorConfigError, match="no field 'depth'"):
        apply_overrides(CoronaryTreeConfig(), ["depth=3"])
    with pytest.raises(GeneratorConfigError, match="type int"):
        apply_overrides(CoronaryTreeConfig(), ["levels=three"])
    with pytest.raises(GeneratorConfigError, match="KEY=VALUE"):
        apply_overrides(CoronaryTreeConfig(), ["levels"])
    assert canonical_command("coronary_tree", 3, ["levels=2"]) == (
        "sim4endor vessel generate coronary_tree --seed 3 --set levels=2")


def test_generate_parser_reads_the_documented_options() -> None:
    import argparse

    from sim4endor.vessels.generators.command import add_generate_parser, run_generate

    parser = argparse.ArgumentParser()
    add_generate_parser(parser.add_subparsers())
    args = parser.parse_args(["generate", "coronary_tree", "--seed", "3", "--set", "levels=2",
                              "--set", "curvature_rms=80", "--out", "trees/t3", "--no-cache"])
    assert (args.generator, args.seed, args.overrides) == ("coronary_tree", 3,
                                                           ["levels=2", "curvature_rms=80"])
    assert str(args.out) == "trees/t3" and args.no_cache and args.func is run_generate
    with pytest.raises(SystemExit):
        parser.parse_args(["generate", "spaghetti"])


def test_generate_vessel_rejects_bad_input_before_building(tmp_path) -> None:
    from sim4endor.vessels.generators.command import generate_vessel

    with pytest.raises(GeneratorConfigError, match="Unknown generator"):
        generate_vessel("spaghetti", out_dir=tmp_path / "x")
    with pytest.raises(GeneratorConfigError, match="no field"):
        generate_vessel("coronary_tree", out_dir=tmp_path / "x", overrides=["depth=2"])
    assert not (tmp_path / "x").exists()


def test_generate_command_builds_a_loadable_coronary_vessel(tmp_path, monkeypatch) -> None:
    from sim4endor import vessels
    from sim4endor.cli import main

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    out = tmp_path / "tree"
    status = main(["vessel", "generate", "coronary_tree", "--seed", "4", "--set", "levels=1",
                   "--out", str(out), "--no-progress"])
    vessel = vessels.load(out)
    anatomy = coronary_tree(CoronaryTreeConfig(levels=1), seed=4)
    assert status == 0 and vessel.name == "coronary_tree_seed4"
    assert set(vessel.targets) == {"T1", "T2"}
    np.testing.assert_allclose(vessel.centerline.nodes, anatomy.centerline.nodes, atol=1e-9)
    assert vessel.manifest.source == canonical_command("coronary_tree", 4, ["levels=1"])
    assert vessel.manifest.checks["wall_closed"] >= 0.95
