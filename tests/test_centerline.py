"""CenterlineGraph: validation, geodesic distances, projection and JSON round trip."""

from __future__ import annotations

import numpy as np
import pytest

from sim4endor.vessels.centerline import CenterlineError, CenterlineGraph, arc_lengths


def y_graph(spacing: float = 1e-3) -> CenterlineGraph:
    """Trunk along +x to (30 mm, 0), branch A up-right and branch B down-right, 20 mm each."""
    trunk = [np.array([x, 0.0, 0.0]) for x in np.arange(0, 0.030 + 1e-9, spacing)]
    nodes = list(trunk)
    edges = [(i, i + 1) for i in range(len(trunk) - 1)]
    junction = len(trunk) - 1
    ends = {}
    for name, sign in (("A", 1.0), ("B", -1.0)):
        direction = np.array([np.cos(np.pi / 4), sign * np.sin(np.pi / 4), 0.0])
        prev = junction
        for k in range(1, 21):
            nodes.append(trunk[-1] + k * spacing * direction)
            edges.append((prev, len(nodes) - 1))
            prev = len(nodes) - 1
        ends[name] = prev
    return CenterlineGraph(
        nodes=np.array(nodes), radii=np.full(len(nodes), 1.5e-3), edges=np.array(edges),
        labels={"inlet": 0, **ends},
    )


def test_lengths_and_topology() -> None:
    g = y_graph()
    assert g.total_length() == pytest.approx(0.070, rel=1e-9)
    assert set(g.terminal_nodes()) == {0, g.labels["A"], g.labels["B"]}
    assert g.num_components() == 1


def test_geodesic_is_longer_than_euclidean_in_the_wrong_branch() -> None:
    g = y_graph()
    to_a = g.geodesic_from(g.labels["A"])
    wrong = g.nodes[g.labels["B"]] - np.array([0.0, 0.0, 0.0])  # end of branch B
    geodesic = g.distance_along(wrong, to_a)
    euclid = float(np.linalg.norm(wrong - g.nodes[g.labels["A"]]))
    assert geodesic == pytest.approx(0.040, rel=1e-9)  # down B to the junction, up A
    assert euclid == pytest.approx(0.020 * np.sqrt(2), rel=1e-9)
    assert geodesic > 1.4 * euclid


def test_distance_along_interpolates_within_an_edge() -> None:
    g = y_graph()
    to_inlet = g.geodesic_from(0)
    assert g.distance_along([0.0105, 0.0003, 0.0], to_inlet) == pytest.approx(0.0105)


def test_projection_reports_offset() -> None:
    proj = y_graph().project([0.010, 0.001, 0.0])
    assert proj.distance == pytest.approx(0.001)
    np.testing.assert_allclose(proj.point, [0.010, 0.0, 0.0], atol=1e-12)


def test_projection_matches_brute_force_over_edges() -> None:
    g = y_graph()
    for point in np.random.default_rng(0).uniform(-0.01, 0.06, size=(50, 3)):
        candidates = []
        for i, j in g.edges:
            ab = g.nodes[j] - g.nodes[i]
            t = float(np.clip(np.dot(point - g.nodes[i], ab) / np.dot(ab, ab), 0.0, 1.0))
            candidates.append(g.nodes[i] + t * ab)
        closest = min(candidates, key=lambda c: float(np.linalg.norm(point - c)))
        proj = g.project(point)
        np.testing.assert_allclose(proj.point, closest, atol=1e-9)
        assert proj.distance == pytest.approx(float(np.linalg.norm(point - closest)), abs=1e-9)
        i, j = g.edges[proj.edge]
        np.testing.assert_allclose(
            g.nodes[i] + proj.fraction * (g.nodes[j] - g.nodes[i]), proj.point, atol=1e-12
        )
        assert g.radius_at_projection(proj) == pytest.approx(1.5e-3)


def test_tube_excess_is_the_union_of_tubes_near_a_small_side_branch() -> None:
    """A point inside a wide trunk but nearer to a thin side branch's axis is inside."""
    trunk = [[x, 0.0, 0.0] for x in np.arange(0.0, 0.0201, 1e-3)]
    step = 1e-3 / np.sqrt(2.0)  # the side branch leaves at 45 degrees from x = 10 mm
    side = [[0.010 + k * step, k * step, 0.0] for k in range(1, 11)]
    nodes = np.array(trunk + side)
    edges = [(i, i + 1) for i in range(len(trunk) - 1)] + [(10, len(trunk))]
    edges += [(len(trunk) + k, len(trunk) + k + 1) for k in range(9)]
    radii = np.r_[np.full(len(trunk), 2.5e-3), np.full(10, 0.6e-3)]
    g = CenterlineGraph(nodes=nodes, radii=radii, edges=np.array(edges))
    point = np.array([0.0135, 0.0022, 0.0])  # 2.2 mm off the trunk's axis, 0.92 off the side's
    proj = g.project(point)
    assert proj.distance - g.radius_at_projection(proj) > 0  # the nearest tube alone: outside
    assert g.tube_excess(point) == pytest.approx(2.2e-3 - 2.5e-3)
    for x in np.random.default_rng(1).uniform(-0.005, 0.025, size=(40, 3)):
        brute = min(float(np.linalg.norm(x - (nodes[i] + t * (nodes[j] - nodes[i]))))
                    - ((1 - t) * radii[i] + t * radii[j])
                    for i, j in edges
                    for t in [float(np.clip(np.dot(x - nodes[i], nodes[j] - nodes[i])
                                            / np.dot(nodes[j] - nodes[i], nodes[j] - nodes[i]),
                                            0.0, 1.0))])
        assert g.tube_excess(x) == pytest.approx(brute, abs=1e-12)


def test_curvature_weighting_penalises_bends() -> None:
    g = y_graph()
    plain = g.geodesic_from(0)[g.labels["A"]]
    weighted = g.geodesic_from(0, curvature_weight=5.0)[g.labels["A"]]
    assert weighted > plain
    with pytest.raises(ValueError, match="curvature_weight"):
        g.edge_weights(-1.0)


def test_json_round_trip(tmp_path) -> None:
    g = y_graph()
    g.save(tmp_path / "centerline.json")
    back = CenterlineGraph.load(tmp_path / "centerline.json")
    np.testing.assert_allclose(back.nodes, g.nodes, atol=1e-9)
    assert back.labels == g.labels
    np.testing.assert_array_equal(back.edges, g.edges)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"radii": np.zeros(3)}, "positive"),
        ({"edges": np.array([[0, 5]])}, "existing nodes"),
        ({"labels": {"A": 9}}, "missing node"),
        ({"radii": np.ones(2)}, "one entry per node"),
    ],
)
def test_malformed_graphs_are_rejected(kwargs, message) -> None:
    base = {"nodes": np.eye(3), "radii": np.ones(3), "edges": np.array([[0, 1], [1, 2]])}
    with pytest.raises(CenterlineError, match=message):
        CenterlineGraph(**{**base, **kwargs})


def test_missing_file_names_the_path(tmp_path) -> None:
    with pytest.raises(CenterlineError, match="No centerline file"):
        CenterlineGraph.load(tmp_path / "nope.json")


def test_arc_lengths_run_along_the_polyline() -> None:
    points = np.array([[0.0, 0.0, 0.0], [0.003, 0.0, 0.0], [0.003, 0.004, 0.0]])
    np.testing.assert_allclose(arc_lengths(points), [0.0, 0.003, 0.007])
