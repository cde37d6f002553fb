"""Navigation task: stepping, determinism, success and each failure state, observations."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from navigation_helpers import require_vessel

from sim4endor import suite
from sim4endor.observations import DISTANCE_HORIZON, FORCE_HORIZON, STALL_HORIZON
from sim4endor.rewards import RewardConfig
from sim4endor.tasks import (
    InitialStateConfig,
    InvalidActionError,
    PixelsConfig,
    TerminationConfig,
    fluoroscopy,
)
from sim4endor.tasks.anatomy import compile_anatomy
from sim4endor.tasks.navigation import lumen_excess

INSERT = np.array([1.0, 0.0])


@pytest.fixture(autouse=True)
def phantom() -> None:
    require_vessel("simplified_phantom")


def _run(env: suite.NavigationEnvironment, actions: np.ndarray) -> list:
    steps = [env.reset()]
    for action in actions:
        steps.append(env.step(action))
        if steps[-1].last():
            break
    return steps


def test_reset_and_steps_are_finite() -> None:
    env = suite.load("simplified_phantom", "task_a", {"random": 0})
    for ts in _run(env, np.tile(INSERT, (5, 1))):
        assert all(np.all(np.isfinite(v)) for v in ts.observation.values())
        assert ts.reward is None or math.isfinite(ts.reward)
    assert list(ts.observation) == ["tip_position", "tip_velocity"]


def test_same_seed_and_actions_give_identical_trajectories() -> None:
    actions = np.random.default_rng(3).uniform(-1, 1, size=(25, 2))
    runs = [_run(suite.load("simplified_phantom", "task_b", {"random": 7}), actions)
            for _ in range(2)]
    for a, b in zip(*runs, strict=True):
        assert a.reward == b.reward
        for key in a.observation:
            np.testing.assert_array_equal(a.observation[key], b.observation[key])


def test_episode_starts_are_seeded_and_differ() -> None:
    """The roll and depth of the start come from the task's generator: trials differ."""
    env = suite.load("simplified_phantom", "task_a", {"random": 11})
    starts = [env.reset().observation["tip_position"] for _ in range(3)]
    assert not np.allclose(starts[0], starts[1]) and not np.allclose(starts[1], starts[2])
    again = suite.load("simplified_phantom", "task_a", {"random": 11}).reset()
    np.testing.assert_array_equal(again.observation["tip_position"], starts[0])
    rotation = env.physics.rotation_angle()
    assert abs(rotation) <= env.task.config.initial_state.rotation_range + 1e-9
    fixed = suite.load("simplified_phantom", "task_a",
                       {"initial_state": InitialStateConfig(0.0, 0.0)})
    assert fixed.reset() and fixed.physics.rotation_angle() == 0.0


def test_inserting_into_branch_a_succeeds_and_terminates() -> None:
    env = suite.load("simplified_phantom", "task_a")
    last = _run(env, np.tile(INSERT, (120, 1)))[-1]
    info = env.task.step_info()
    assert last.last() and last.discount == 0.0
    assert info["is_success"] and info["failure"] == ""
    assert info["distance"] <= 1e-3
    assert last.reward == pytest.approx(100.0 + info["reward_distance"])


def test_rotating_half_a_turn_then_inserting_reaches_b() -> None:
    env = suite.load("simplified_phantom", "task_b")
    turn = np.tile([0.0, 1.0], (20, 1))  # 20 x 9 deg: the J-tip now points into branch B
    last = _run(env, np.vstack([turn, np.tile(INSERT, (120, 1))]))[-1]
    info = env.task.step_info()
    assert last.last() and info["is_success"], info
    assert info["tip_force"] < env.task.config.termination.max_tip_force
    assert info["tip_force"] <= info["wall_force"]


@pytest.mark.parametrize(
    ("termination", "action", "reason"),
    [
        (TerminationConfig(max_insertion=0.004), INSERT, "insertion_limit"),
        (TerminationConfig(max_rotation=0.2), np.array([0.0, 1.0]), "rotation_limit"),
        (TerminationConfig(max_tip_force=1e-4), INSERT, "tip_force"),
    ],
)
def test_failure_states_terminate_with_the_penalty(
    termination: TerminationConfig, action: np.ndarray, reason: str
) -> None:
    env = suite.load("simplified_phantom", "task_b", {"termination": termination})
    last = _run(env, np.tile(action, (120, 1)))[-1]
    info = env.task.step_info()
    assert last.last() and last.discount == 0.0
    assert info["failure"] == reason and not info["is_success"]
    assert last.reward == pytest.approx(-100.0 + info["reward_distance"])


@pytest.mark.parametrize("mean", [False, True])
def test_the_tip_force_is_the_step_mean_where_the_termination_says(
        mean: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """With ``tip_force_mean`` (the coronary limits) an impact spike at the step's end does
    not end the episode; the mean over the step is the failure's, the info's and the
    observation's tip force. The paper's tasks keep the force at the step's end."""
    termination = TerminationConfig(tip_force_mean=mean)
    env = suite.load("simplified_phantom", "task_a",
                     {"termination": termination, "observations": ("tip_force",), "random": 0})
    env.reset()
    physics = type(env.physics)
    monkeypatch.setattr(physics, "tip_contact_force", lambda self: 2.0)  # > 1 N: a spike
    monkeypatch.setattr(physics, "mean_tip_contact_force", lambda self: 0.1)
    last = env.step(INSERT)
    info = env.task.step_info()
    assert info["tip_force"] == last.observation["tip_force"][0] == (0.1 if mean else 2.0)
    assert info["failure"] == ("" if mean else "tip_force")


def test_the_coronary_limits_compare_the_mean_tip_force() -> None:
    assert suite.load("coronary", "navigate", {"pool_size": 1}).task.config.termination \
        .tip_force_mean


def test_a_failure_on_the_step_that_reaches_the_target_is_not_a_success() -> None:
    # Every tip is "at the target" (success within 1 m) and the first roll breaks the rotation
    # limit: the failure wins, as a tip pressing the wall past the limit at the target is harm.
    env = suite.load(
        "simplified_phantom",
        "task_a",
        {
            "reward": RewardConfig(success_distance=1.0),
            "termination": TerminationConfig(max_rotation=0.01),
            # No initial roll: one drawn near -9° would let the first roll stay in the limit
            # (seen once: about 1 run in 50 with an unseeded task).
            "initial_state": {"rotation_range": 0.0},
        },
    )
    last = _run(env, [np.array([0.0, 1.0])])[-1]
    info = env.task.step_info()
    assert last.last() and info["failure"] == "rotation_limit" and not info["is_success"]
    assert info["reward_goal"] == 0.0 and info["reward_failure"] == -100.0


def test_instability_is_a_failure_not_a_crash() -> None:
    env = suite.load("simplified_phantom", "task_a")
    first = env.reset()
    env.physics.data.qvel[:] = np.nan
    last = env.step(INSERT)
    assert last.last() and last.discount == 0.0 and last.reward == -100.0
    assert env.task.step_info()["failure"] == "instability"
    np.testing.assert_array_equal(last.observation["tip_position"],
                                  first.observation["tip_position"])
    assert env.step(INSERT).first()  # the next step starts a new episode


@pytest.mark.parametrize("bad", [[np.nan, 0.0], [0.0, np.inf], [1.0, 0.0, 0.0]])
def test_invalid_actions_are_rejected_before_mujoco(bad: list[float]) -> None:
    env = suite.load("simplified_phantom", "task_a")
    env.reset()
    ctrl = env.physics.data.ctrl.copy()
    with pytest.raises(InvalidActionError):
        env.step(np.array(bad))
    np.testing.assert_array_equal(env.physics.data.ctrl, ctrl)


def test_optional_observations_have_documented_shapes() -> None:
    extras = ("target_position", "wire_shape", "last_action", "insertion", "rotation",
              "manifold_distance")
    env = suite.load("simplified_phantom", "task_a", {"observations": extras})
    env.reset()
    obs = env.step(INSERT).observation
    n_points = len(env.physics.wire_points())
    shapes = {k: v.shape for k, v in obs.items()}
    spec = {k: v.shape for k, v in env.observation_spec().items()}
    assert shapes == spec == {"tip_position": (3,), "tip_velocity": (3,), "target_position": (3,),
                      "wire_shape": (3 * n_points,), "last_action": (2,), "insertion": (1,),
                      "rotation": (1,), "manifold_distance": (1,)}
    np.testing.assert_allclose(obs["target_position"], env.task.target_position)
    np.testing.assert_allclose(obs["last_action"], INSERT)
    assert obs["insertion"][0] > 0
    assert obs["manifold_distance"][0] == pytest.approx(env.task.step_info()["manifold_distance"])


def test_the_distance_entry_saturates_at_the_horizon() -> None:
    # The vascular phantom's targets start about 104-107 mm away along the route.
    env = suite.load("vascular_phantom", "task_a", {"observations": ("manifold_distance",)})
    observed = env.reset().observation["manifold_distance"][0]
    assert env.task.manifold_distance()(env.physics.tip_position()) > DISTANCE_HORIZON
    assert observed == DISTANCE_HORIZON


@pytest.mark.parametrize("force", [0.3, 1234.0])
def test_the_force_entries_saturate_but_the_info_does_not(
        force: float, monkeypatch: pytest.MonkeyPatch) -> None:
    """A pinched shaft segment reads kilonewtons (docs/tasks/coronary.md); the observation
    caps them, the step's info and the tip-force failure keep the force itself."""
    env = suite.load("simplified_phantom", "task_a",
                     {"observations": ("tip_force", "wall_force"), "random": 0})
    env.reset()
    physics = type(env.physics)
    monkeypatch.setattr(physics, "wall_contact_force", lambda self: force)
    monkeypatch.setattr(physics, "tip_contact_force", lambda self: force / 10)
    obs = env.step(INSERT).observation
    assert obs["wall_force"][0] == min(force, FORCE_HORIZON)
    assert obs["tip_force"][0] == min(force / 10, FORCE_HORIZON)
    assert env.task.step_info()["wall_force"] == force


def test_the_stall_entry_counts_the_time_since_the_last_progress() -> None:
    """Pushing up the trunk is progress at every step; holding still is none, and the entry
    grows by a control step each step until it saturates; pushing on again resets it."""
    env = suite.load("simplified_phantom", "task_a",
                     {"observations": ("stall_time",), "random": 0})
    control_step = env.control_timestep()
    assert env.reset().observation["stall_time"][0] == 0.0
    for _ in range(5):
        pushed = env.step(INSERT).observation["stall_time"][0]
        assert pushed <= 2 * control_step  # 1 mm of progress takes one or two steps
    held = [env.step([0.0, 0.0]).observation["stall_time"][0] for _ in range(4)]
    np.testing.assert_allclose(np.diff(held), control_step)
    for _ in range(round(STALL_HORIZON / control_step)):
        saturated = env.step([0.0, 0.0]).observation["stall_time"][0]
    assert saturated == STALL_HORIZON
    for _ in range(3):
        pushed = env.step(INSERT).observation["stall_time"][0]
    assert pushed <= 2 * control_step


def test_pixels_show_the_lumen_and_the_wire_without_opengl() -> None:
    env = suite.load("simplified_phantom", "task_a",
                     {"observations": ("pixels",), "pixels": PixelsConfig(height=48, width=40)})
    env.reset()
    for _ in range(30):
        pixels = env.step(INSERT).observation["pixels"]
    assert pixels.shape == (48, 40, 1) and pixels.dtype == np.uint8
    values = set(np.unique(pixels))
    assert values == {fluoroscopy.WIRE, fluoroscopy.LUMEN, fluoroscopy.BACKGROUND}
    # ~45 mm of wire inside the framed vessel at ~3 mm per pixel: a line of >= 10 pixels.
    assert np.count_nonzero(pixels == fluoroscopy.WIRE) >= 10


def test_euclidean_reward_reports_both_distances() -> None:
    env = suite.load("simplified_phantom", "task_b", {"reward": "euclidean"})
    _run(env, np.tile(INSERT, (50, 1)))  # rotation 0 goes into branch A, the wrong one
    info = env.task.step_info()
    assert info["distance"] < info["manifold_distance"]


def test_lumen_excess_is_negative_inside_and_positive_outside() -> None:
    anatomy = compile_anatomy("simplified_phantom")
    graph, vessel = anatomy.vessel.centerline, anatomy.vessel
    mid = graph.nodes[len(graph.nodes) // 4]
    radius = graph.radius_at(mid[None])[0]
    assert lumen_excess(anatomy, mid) == pytest.approx(-radius)
    normal = np.cross(vessel.inlet_direction, [0.0, 0.0, 1.0])
    assert lumen_excess(anatomy, mid + 3 * radius * normal / np.linalg.norm(normal)) > 0
    behind = vessel.inlet_position - 0.01 * vessel.inlet_direction
    assert lumen_excess(anatomy, behind) == -math.inf


def test_a_tip_outside_the_centerlines_tubes_but_in_the_lumen_is_inside() -> None:
    """A tube's radius is the distance to the nearest wall, so a lumen that is not round
    reaches past its tubes. Before, the tubes alone decided: on a real patient's tree an
    episode ended 'outside_lumen' (0.53 mm) with the tip 0.34 mm inside the mesh. Here the
    vascular phantom's centerline with its radii halved stands for such a lumen."""
    anatomy = compile_anatomy("vascular_phantom")
    graph = anatomy.vessel.centerline
    thin = dataclasses.replace(anatomy, vessel=dataclasses.replace(
        anatomy.vessel, centerline=dataclasses.replace(graph, radii=graph.radii / 2)))
    k = len(graph.nodes) // 3
    tangent = graph.nodes[k + 1] - graph.nodes[k - 1]
    normal = np.cross(tangent, [0.0, 0.0, 1.0])
    normal /= np.linalg.norm(normal)
    radius = float(graph.radii[k])
    tubes = thin.vessel.centerline
    inside = graph.nodes[k] + 0.75 * radius * normal
    assert tubes.tube_excess(inside) > 0.2 * radius  # outside every tube
    assert -0.4 * radius < lumen_excess(thin, inside) < -0.1 * radius  # in the lumen
    outside = graph.nodes[k] + 1.5 * radius * normal
    assert 0.3 * radius < lumen_excess(thin, outside) < 0.7 * radius


def test_reset_distance_is_measured_at_the_placed_start() -> None:
    env = suite.load("simplified_phantom", "task_a", {"random": 3})
    env.reset()
    task = env.task
    # The first step's distance reward compares with this, so it must be the start pose's.
    assert task._d_last == task.manifold_distance()(env.physics.tip_position())


def test_straight_insertion_passes_the_vascular_phantom_to_a() -> None:
    # The shaft presses on the S-bends with well over 1 N in total; only the tip force counts.
    # Whether a blind push gets through depends on the initial roll: of seeds 0-5, two pass
    # and the others stop at the 1 N tip-force limit, mostly in branch A's 100° bend. Which
    # two changes with small changes of the contact model (seeds 1 and 5 without the wire's
    # 0.1 mm contact margin, 0 and 5 with it); seed 5 passed both times.
    env = suite.load("vascular_phantom", "task_a", {"random": 5})
    env.reset()
    forces = []
    for _ in range(400):
        last = env.step([0.5, 0.0])
        forces.append(env.task.step_info()["wall_force"])
        if last.last():
            break
    info = env.task.step_info()
    assert info["is_success"], info
    assert max(forces) > env.task.config.termination.max_tip_force


@pytest.mark.parametrize("domain", ["random_coronary", "coronary"])
def test_pool_trees_get_wires_for_their_own_depth_unless_the_wire_is_observed(
    domain, tmp_path, monkeypatch
) -> None:
    """Each pool tree's wire is fitted to its deepest target (fewer segments, faster); with
    ``wire_shape`` observed every tree keeps the pool's wire, so the entry has one size."""
    from sim4endor.tasks import coronary, random_coronary

    module = coronary if domain == "coronary" else random_coronary
    modes = []

    def fake_member(*args, **kwargs):  # stands in for a tree build: (..., scene, same_wire)
        scene, same_wire = args[-2:]
        modes.append(same_wire)
        return compile_anatomy("simplified_phantom", scene,
                               fit="none" if same_wire else "travel")

    monkeypatch.setattr(module, "build_member", fake_member)
    for observations in ((), ("wire_shape",)):
        env = suite.load(domain, "navigate", {"pool_size": 1, "cache_dir": tmp_path,
                                              "random": 0, "observations": observations})
        env.reset()
    assert modes[0] is False and modes[-1] is True


def test_travel_fit_keeps_the_tip_and_sizes_the_wire_to_the_deepest_target() -> None:
    from sim4endor.models import wires
    from sim4endor.models.scene import SceneConfig, config_for_vessel, fit_travel

    vessel = compile_anatomy("simplified_phantom").vessel
    wide = SceneConfig(wire=dataclasses.replace(wires.preset("paper"), tip_angle=1.2))
    travel = fit_travel(vessel, wide)
    full = config_for_vessel(vessel, wide)
    assert travel.driver.max_insertion == full.driver.max_insertion
    assert travel.wire.length == full.wire.length
    assert travel.wire.tip_angle == 1.2 > full.wire.tip_angle  # only config_for_vessel narrows
