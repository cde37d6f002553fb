"""The ``generalist`` observation set: tip-frame entries that do not depend on where the
anatomy lies in space, and the route ahead that bends into the target's branch."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from sim4endor import suite
from sim4endor.observations import PATH_POINTS, PATH_SPACING
from sim4endor.tasks import OBSERVATION_SETS, TaskConfigError
from sim4endor.tasks.tip_frame import PathToTarget, tip_view

GENERALIST = OBSERVATION_SETS["generalist"]


@pytest.fixture(scope="module")
def stepped_env():
    """The simplified phantom's task A with the generalist set, 15 steps into an episode."""
    env = suite.load("simplified_phantom", "task_a", {"random": 3, "observations": "generalist"})
    env.reset()
    for _ in range(15):
        timestep = env.step([1.0, 0.4])
    return env, timestep


def test_generalist_set_replaces_the_paper_state(stepped_env):
    env, timestep = stepped_env
    assert tuple(timestep.observation) == GENERALIST
    spec = env.observation_spec()
    for name, value in timestep.observation.items():
        assert value.shape == spec[name].shape, name
        assert np.all(np.isfinite(value)), name
    assert timestep.observation["path_ahead"].shape == (3 * PATH_POINTS,)


def test_set_without_radius_is_the_generalist_set_less_the_calibre():
    env = suite.load("simplified_phantom", "task_a",
                     {"random": 3, "observations": "generalist_no_radius"})
    observation = env.reset().observation
    assert tuple(observation) == tuple(name for name in GENERALIST if name != "lumen_radius")
    assert set(env.observation_spec()) == set(observation)


def test_generalist_observation_is_unchanged_by_moving_the_anatomy_with_the_wire(stepped_env):
    """Same wire state, anatomy and wire rotated and translated together: same observation."""
    env, timestep = stepped_env
    physics, task = env.physics, env.task
    graph = task.anatomy.vessel.centerline
    target = graph.labels[task.target]
    tip, frame, velocity = physics.tip_position(), physics.tip_frame(), physics.tip_velocity()
    observed = timestep.observation
    for seed in range(3):
        rng = np.random.default_rng(seed)
        rotation = Rotation.random(random_state=seed).as_matrix()
        shift = rng.uniform(-0.2, 0.2, 3)
        matrix = np.eye(4)
        matrix[:3, :3], matrix[:3, 3] = rotation, shift
        moved = PathToTarget.to_node(graph.transformed(matrix), target)
        view = tip_view(moved, rotation @ tip + shift, rotation @ frame, rotation @ velocity)
        np.testing.assert_allclose(view.path_ahead.reshape(-1), observed["path_ahead"],
                                   atol=1e-9)
        np.testing.assert_allclose(view.axis_offset, observed["axis_offset"], atol=1e-7)
        np.testing.assert_allclose(view.lumen_radius, observed["lumen_radius"][0], rtol=1e-9)
        np.testing.assert_allclose(view.tip_velocity, observed["tip_velocity_local"],
                                   atol=1e-9)
    # The absolute entries of the paper's state do change: the test would see a leak.
    assert not np.allclose(rotation @ tip + shift, tip)


def test_route_ahead_bends_into_the_target_branch():
    """From the same point in the trunk, the routes to A and B part where the branches do."""
    env = suite.load("simplified_phantom", "task_a", {"random": 0})
    graph = env.task.anatomy.vessel.centerline
    to_a = PathToTarget.to_node(graph, graph.labels["A"])
    to_b = PathToTarget.to_node(graph, graph.labels["B"])
    # Start a few route lengths before the bifurcation on A's route.
    inlet = graph.nodes[graph.labels["inlet"]]
    start = graph.project(inlet)
    count = 60
    points_a = to_a.points_ahead(start, count=count)
    points_b = to_b.points_ahead(start, count=count)
    gaps = np.linalg.norm(points_a - points_b, axis=1)
    assert gaps[0] < 1e-9  # one trunk
    assert gaps[-1] > 0.01  # two branches
    steps = np.linalg.norm(np.diff(points_a, axis=0), axis=1)
    np.testing.assert_allclose(steps[steps > 1e-9], PATH_SPACING, rtol=0.02)


def test_route_ahead_stops_at_the_target():
    env = suite.load("simplified_phantom", "task_a", {"random": 0})
    graph = env.task.anatomy.vessel.centerline
    target = graph.labels["A"]
    path = PathToTarget.to_node(graph, target)
    near_target = graph.project(graph.nodes[target] + 1e-4)
    points = path.points_ahead(near_target)
    np.testing.assert_allclose(points[-1], graph.nodes[target], atol=1e-12)
    # The route's nodes from the inlet: one edge per step, each closer to the target.
    route = path.route(graph.labels["inlet"])
    assert route[0] == graph.labels["inlet"] and route[-1] == target
    edges = {frozenset(map(int, edge)) for edge in graph.edges}
    assert all(frozenset(step) in edges for step in itertools.pairwise(route))
    assert np.all(np.diff(path.node_distances[route]) < 0)


def test_unknown_observation_set_is_named():
    with pytest.raises(TaskConfigError, match=r"'expert'.*generalist"):
        suite.load("simplified_phantom", "task_a", {"observations": "expert"})
