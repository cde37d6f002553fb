"""Reward terms: manifold vs Euclidean distance on a small Y graph built here."""

from __future__ import annotations

import numpy as np
import pytest

from sim4endor import rewards
from sim4endor.vessels.centerline import CenterlineGraph

MM = 1e-3


def y_graph() -> CenterlineGraph:
    """Trunk 0..60 mm along +x, branch A straight at +35°, branch B at -35° curving away."""
    trunk = np.stack([np.linspace(0, 60, 31) * MM, np.zeros(31), np.zeros(31)], axis=1)
    fork = trunk[-1]
    s = np.linspace(0, 40, 21)[1:] * MM
    a_dir = np.array([np.cos(np.radians(35)), np.sin(np.radians(35)), 0.0])
    branch_a = fork + s[:, None] * a_dir
    # B: heading -35° turning a further -40° over 40 mm.
    heading = np.radians(-35) - np.radians(40) * np.linspace(0, 1, 21)
    steps = np.stack([np.cos(heading), np.sin(heading), np.zeros(21)], axis=1)[1:] * 2 * MM
    branch_b = fork + np.cumsum(steps, axis=0)
    nodes = np.vstack([trunk, branch_a, branch_b])
    n_t, n_a = len(trunk), len(branch_a)
    edges = [(k, k + 1) for k in range(n_t - 1)]
    edges += [(n_t - 1, n_t)] + [(n_t + k, n_t + k + 1) for k in range(n_a - 1)]
    b0 = n_t + n_a
    edges += [(n_t - 1, b0)] + [(b0 + k, b0 + k + 1) for k in range(len(branch_b) - 1)]
    labels = {"inlet": 0, "A": n_t + n_a - 1, "B": len(nodes) - 1}
    return CenterlineGraph(nodes, np.full(len(nodes), 2 * MM), np.array(edges), labels)


@pytest.fixture(scope="module")
def graph() -> CenterlineGraph:
    return y_graph()


def test_manifold_distance_is_arc_length_along_the_path(graph: CenterlineGraph) -> None:
    to_a = rewards.make_distance(rewards.RewardConfig(), graph, "A")
    assert to_a(graph.nodes[graph.labels["inlet"]]) == pytest.approx(100 * MM, rel=1e-9)
    # A point off the axis projects onto it: 1 mm above the trunk at x = 30 mm.
    assert to_a(np.array([30 * MM, 1 * MM, 0.0])) == pytest.approx(70 * MM, rel=1e-9)
    assert to_a(graph.nodes[graph.labels["A"]]) == pytest.approx(0.0, abs=1e-12)


def test_wrong_branch_is_euclidean_closer_but_manifold_farther(graph: CenterlineGraph) -> None:
    fork = graph.nodes[30]
    b_dir = np.array([np.cos(np.radians(-35)), np.sin(np.radians(-35)), 0.0])
    wrong = fork + 5 * MM * b_dir  # just past the bifurcation, in branch B
    manifold = rewards.make_distance(rewards.RewardConfig(metric="manifold"), graph, "A")
    euclid = rewards.make_distance(rewards.RewardConfig(metric="euclidean"), graph, "A")
    # Moving from the fork into the wrong branch: Euclidean says progress, manifold says not.
    assert euclid(wrong) < euclid(fork)
    assert manifold(wrong) > manifold(fork)
    assert manifold(wrong) == pytest.approx(45 * MM, rel=1e-2)  # B curves slightly
    cfg = rewards.RewardConfig()
    assert rewards.distance_reward(euclid(fork), euclid(wrong), cfg.distance_divisor_mm) > 0
    wrong_way = rewards.distance_reward(manifold(fork), manifold(wrong))
    assert wrong_way == pytest.approx(-0.05, rel=1e-2)


def test_distance_reward_uses_millimetres() -> None:
    # Paper: R_dist = (D_last - D_current) / 100 with D in mm; 1 mm of progress earns 0.01.
    assert rewards.distance_reward(0.010, 0.009) == pytest.approx(0.01)
    assert rewards.distance_reward(0.009, 0.010) == pytest.approx(-0.01)


def test_reward_terms_sum_goal_and_failure() -> None:
    cfg = rewards.RewardConfig()
    ok = rewards.reward_terms(cfg, 2 * MM, 0.5 * MM, success=True, failed=False)
    assert (ok.distance, ok.goal, ok.failure) == (pytest.approx(0.015), 100.0, 0.0)
    assert ok.total == pytest.approx(100.015)
    bad = rewards.reward_terms(cfg, 2 * MM, 2 * MM, success=False, failed=True)
    assert bad.total == -100.0


def test_curvature_weight_lengthens_curved_paths_only(graph: CenterlineGraph) -> None:
    inlet = graph.nodes[0]
    plain_b = rewards.make_distance(rewards.RewardConfig(), graph, "B")
    bent_b = rewards.make_distance(rewards.RewardConfig(curvature_weight=50.0), graph, "B")
    bent_a = rewards.make_distance(rewards.RewardConfig(curvature_weight=50.0), graph, "A")
    plain_a = rewards.make_distance(rewards.RewardConfig(), graph, "A")
    assert bent_b(inlet) > plain_b(inlet) * 1.01  # branch B is curved
    # Trunk and A are straight: their turn angles are rounding errors of the node coordinates
    # (~1e-16 rad with atan2), which weigh in at w·κ·r ~ 1e-14 of the length; 1e-12 bounds that
    # on any machine.
    assert bent_a(inlet) == pytest.approx(plain_a(inlet), rel=1e-12)


def test_bad_configuration_names_the_setting(graph: CenterlineGraph) -> None:
    with pytest.raises(rewards.RewardConfigError, match="geodesic"):
        rewards.RewardConfig(metric="geodesic")  # type: ignore[arg-type]
    with pytest.raises(rewards.RewardConfigError, match="'C'"):
        rewards.make_distance(rewards.RewardConfig(), graph, "C")


def test_disconnected_graph_is_rejected() -> None:
    nodes = np.array([[0, 0, 0], [1, 0, 0], [5, 0, 0], [6, 0, 0]], dtype=float) * MM
    graph = CenterlineGraph(nodes, np.full(4, MM), np.array([[0, 1], [2, 3]]), {"T": 3})
    with pytest.raises(rewards.RewardConfigError, match="not connected"):
        rewards.make_distance(rewards.RewardConfig(), graph, "T")
