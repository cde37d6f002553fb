"""The redirect variants of the paper's tasks: a wire already down the wrong branch, any roll."""

from __future__ import annotations

import math

import gymnasium
import numpy as np
import pytest
from navigation_helpers import require_vessel

import sim4endor  # noqa: F401  (registers the gymnasium ids)
from sim4endor import registry, suite
from sim4endor.tasks import WRONG_BRANCH_START, InitialStateConfig, TaskConfigError
from sim4endor.tasks.starts import off_path_distance


@pytest.fixture(autouse=True)
def phantom() -> None:
    require_vessel("simplified_phantom")


def _off_path(env: suite.NavigationEnvironment) -> float:
    task = env.task
    tip = env.physics.tip_position()
    to_target, to_inlet = task.manifold_distance(), task.manifold_distance("inlet")
    return off_path_distance(to_target(tip), to_inlet(tip),
                             float(to_target.node_distances[to_inlet.target_node]))


def test_every_paper_task_has_a_redirect_variant_beside_it() -> None:
    assert [(d, t.removesuffix("_redirect")) for d, t in registry.REDIRECT] == list(
        registry.BENCHMARKING)
    assert set(registry.REDIRECT) <= set(suite.ALL_TASKS)
    assert not set(registry.REDIRECT) & set(registry.BENCHMARKING)
    entry = registry.find("vascular_phantom", "task_b_redirect")
    assert entry.gym_id == "Sim4EndoR/VascularPhantom-TaskBRedirect-v0"
    assert (entry.target, entry.start) == ("B", registry.START_WRONG_BRANCH)


def test_redirect_start_is_down_the_other_branch_rolled_anywhere() -> None:
    env = suite.load("simplified_phantom", "task_a_redirect", {"random": 0})
    assert env.task.config.initial_state == WRONG_BRANCH_START
    assert WRONG_BRANCH_START.rotation_range == pytest.approx(math.pi)
    ts = env.reset()
    low, high = WRONG_BRANCH_START.off_path_depth or (0.0, 0.0)
    assert low <= _off_path(env) < high + 2e-3  # the drive stops at the first step past it
    assert env.physics.tip_position()[1] < 0.0  # branch B lies at -y, A at +y
    assert env.physics.time() == 0.0
    ts = env.step([1.0, 0.0])
    assert math.isfinite(ts.reward) and not env.task.step_info()["is_success"]
    # The paper's task keeps its inlet start.
    paper = suite.load("simplified_phantom", "task_a", {"random": 0})
    assert paper.task.config.initial_state == InitialStateConfig()


def test_redirect_starts_are_seeded_and_deterministic() -> None:
    def start(seed: int) -> tuple[np.ndarray, tuple[float, float]]:
        env = suite.load("simplified_phantom", "task_b_redirect", {"random": seed})
        env.reset()
        return env.physics.wire_points(), env.physics.driver_targets()

    (wire0, driver0), (again, driver_again), (wire1, driver1) = start(3), start(3), start(4)
    np.testing.assert_array_equal(wire0, again)
    assert driver0 == driver_again
    assert driver0[1] != driver1[1] and not np.array_equal(wire0, wire1)


def test_redirect_task_through_gymnasium_make() -> None:
    env = gymnasium.make("Sim4EndoR/SimplifiedPhantom-TaskARedirect-v0")
    first, _ = env.reset(seed=5)
    second, _ = env.reset(seed=5)
    assert env.observation_space.shape == (6,)
    np.testing.assert_array_equal(first, second)
    env.close()


def test_initial_state_overrides_apply_on_top_of_the_redirect_start() -> None:
    env = suite.load("simplified_phantom", "task_a_redirect",
                     {"initial_state": {"off_path_depth": [0.004, 0.006]}})
    assert env.task.config.initial_state.off_path_depth == (0.004, 0.006)
    assert env.task.config.initial_state.rotation_range == pytest.approx(math.pi)
    with pytest.raises(TaskConfigError, match="lowest <= highest"):
        InitialStateConfig(off_path_depth=(0.02, 0.01))
    with pytest.raises(TaskConfigError, match="off_path_depth must be > 0"):
        InitialStateConfig(off_path_depth=(0.0, 0.01))

