"""The viewer's teleoperation session (no window needed) and the headless render command."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from navigation_helpers import require_vessel

from sim4endor import suite
from sim4endor.cli import render, view
from sim4endor.errors import Sim4EndoRError


@pytest.fixture(autouse=True)
def phantom() -> None:
    require_vessel("simplified_phantom")


def test_keys_set_speeds_and_steps_are_recorded(tmp_path: Path) -> None:
    session = view.TeleopSession(suite.load("simplified_phantom", "task_a"), record=True)
    for key in (view.KEY_UP, view.KEY_UP, view.KEY_UP, view.KEY_UP, view.KEY_UP, view.KEY_LEFT):
        session.on_key(key)
    np.testing.assert_allclose(session.speed, [1.0, -view.NOTCH])  # clipped at full speed
    for _ in range(5):
        session.tick()
    session.on_key(view.KEY_S)
    session.tick()
    session.on_key(view.KEY_R)
    session.tick()  # reset: not recorded
    session.tick()
    assert "D " in session.status() and "command insert +0.00" in session.status()
    out = tmp_path / "demo.npz"
    session.recording.save(out)
    data = view.load_recording(out)
    assert data["actions"].shape == (7, 2) and data["observations"].shape == (7, 6)
    np.testing.assert_allclose(data["actions"][:5], [[1.0, -view.NOTCH]] * 5)
    np.testing.assert_allclose(data["actions"][5], [0.0, 0.0])
    np.testing.assert_array_equal(data["episode"], [0] * 6 + [1])
    np.testing.assert_allclose(data["reward_terms"].sum(axis=1), data["rewards"])
    assert data["observations"][4, 0] > data["observations"][0, 0]  # the tip moved in


def test_builtin_and_missing_policies() -> None:
    np.testing.assert_allclose(render.load_policy("insert", 0)(np.zeros(6)), [1.0, 0.0])
    a = render.load_policy("random", 3)(np.zeros(6))
    assert a.shape == (2,) and np.all(np.abs(a) <= 1)
    with pytest.raises(render.PolicyLoadError, match="neither"):
        render.load_policy("no_such_policy.pt", 0)
    for expert in ("expert", "probing-expert"):
        with pytest.raises(render.PolicyLoadError, match="expert needs the environment"):
            render.load_policy(expert, 0)


def test_the_probing_expert_is_a_built_in_policy_that_starts_each_episode_afresh() -> None:
    from sim4endor import suite
    from sim4endor.tasks.expert import ProbingExpert

    env = suite.load("simplified_phantom", "task_a", {"random": 0})
    env.reset()
    policy = render.load_policy("probing-expert", 0, env)
    reference = ProbingExpert()
    for _ in range(40):  # far enough that the next episode's start reads as a wrong branch
        action = policy(np.zeros(6))
        np.testing.assert_array_equal(action, reference(env.physics, env.task))
        env.step(action)
    # A new episode (as `view` starts one on R): the policy's expert starts afresh.
    env.reset()
    reference.reset()
    for _ in range(5):
        action = policy(np.zeros(6))
        np.testing.assert_array_equal(action, reference(env.physics, env.task))
        env.step(action)


def test_a_training_run_folder_is_a_policy(tmp_path: Path) -> None:
    from rl_testing import tiny_config

    from sim4endor.rl.export import export_policy
    from sim4endor.rl.trainer import train

    run_dir = tmp_path / "run"
    train(tiny_config("ddpg", "collector.total_frames=100"), run_dir, progress=False)
    policy = render.load_policy(str(run_dir), 0)
    exported = render.load_policy(str(export_policy(run_dir, tmp_path / "export")[0]), 0)
    observation = np.array([0.01, -0.02, 0.0, 0.001, 0.0, -0.002])
    action = policy(observation)
    assert action.shape == (2,) and np.all(np.abs(action) <= 1)
    np.testing.assert_allclose(action, exported(observation), atol=1e-6)
    with pytest.raises(Sim4EndoRError, match="not a training run folder"):
        render.load_policy(str(tmp_path), 0)


def test_expert_policy_acts_on_the_environment_not_the_observation() -> None:
    from sim4endor import suite

    env = suite.load("simplified_phantom", "task_b", {"random": 1})
    env.reset()
    policy = render.load_policy("expert", 0, env)
    action = policy(np.zeros(6))
    assert action.shape == (2,) and action[0] > 0.0  # the trunk is straight ahead: push


@pytest.mark.render
def test_render_writes_a_video(tmp_path: Path) -> None:
    out = tmp_path / "episode.mp4"
    args = ["render", "simplified_phantom", "task_a", "--out", str(out), "--max-steps", "10",
            "--width", "160", "--height", "128"]
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY")}
    result = subprocess.run([sys.executable, "-m", "sim4endor", *args], env=env,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    # Nothing from dm_control's exit hooks (e.g. "cannot schedule new futures after shutdown").
    assert "Error" not in result.stderr and "Traceback" not in result.stderr, result.stderr
    import imageio.v2 as imageio

    # Not list(reader): the ffmpeg reader reports an infinite length.
    frames = [frame for frame in imageio.get_reader(out)]
    assert len(frames) == 11 and frames[0].shape == (128, 160, 3)
    assert not np.array_equal(frames[0], frames[-1])


def test_a_policy_drives_the_viewer_until_a_key_takes_over() -> None:
    env = suite.load("simplified_phantom", "task_a")
    session = view.TeleopSession(env, policy=render.load_policy("insert", 0))
    assert "policy driving" in session.status()
    session.tick()
    assert env.task.step_info()["insertion_command"] > 0  # the policy pushed
    session.on_key(view.KEY_DOWN)
    inserted = env.task.step_info()["insertion_command"]
    session.tick()
    assert env.task.step_info()["insertion_command"] < inserted  # the key pulled back
    session.on_key(view.KEY_S)  # hands back to the policy
    assert "policy driving" in session.status()


@pytest.mark.render
def test_render_with_motion_draws_the_moving_hulls(tmp_path: Path) -> None:
    """With --motion the wall's hulls are drawn (the lumen's display mesh stands still)."""
    from sim4endor.cli.render import wall_view

    out = tmp_path / "beating.mp4"
    args = ["render", "coronary", "navigate", "--motion", "--out", str(out), "--max-steps", "6",
            "--width", "160", "--height", "128", "--no-progress", "--pool-size", "1"]
    env = {k: v for k, v in os.environ.items() if k not in ("MUJOCO_GL", "DISPLAY")}
    result = subprocess.run([sys.executable, "-m", "sim4endor", *args], env=env,
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    import imageio.v2 as imageio

    assert len([frame for frame in imageio.get_reader(out)]) == 7
    option = wall_view()
    assert option.geomgroup[3] == 1 and option.geomgroup[1] == 0
