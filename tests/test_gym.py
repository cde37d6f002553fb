"""Gymnasium adapter: registered ids, check_env, seeding, terminated vs truncated, rendering."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from navigation_helpers import require_vessel

import sim4endor  # noqa: F401  (registers the ids)
from sim4endor import registry

TASK_A = "Sim4EndoR/SimplifiedPhantom-TaskA-v0"


@pytest.fixture(autouse=True)
def phantom() -> None:
    require_vessel("simplified_phantom")


def test_every_registry_entry_has_a_gym_id() -> None:
    for entry in registry.ENTRIES:
        spec = gymnasium.spec(entry.gym_id)
        assert spec.kwargs == {"domain": entry.domain, "task": entry.task}


def test_check_env_passes() -> None:
    env = gymnasium.make(TASK_A)
    # Rendering needs an offscreen GL context chosen before MuJoCo loads: tested below.
    check_env(env.unwrapped, skip_render_check=True)
    assert env.observation_space.shape == (6,)
    assert env.action_space.shape == (2,)


def test_reset_seed_reproduces_the_episode() -> None:
    def rollout(seed: int) -> np.ndarray:
        env = gymnasium.make("Sim4EndoR/SimplifiedPhantom-TaskB-v0")
        env.action_space.seed(seed)
        obs = [env.reset(seed=seed)[0]]
        for _ in range(10):
            obs.append(env.step(env.action_space.sample())[0])
        return np.array(obs)

    np.testing.assert_array_equal(rollout(4), rollout(4))


def test_success_terminates_and_time_limit_truncates() -> None:
    env = gymnasium.make(TASK_A)
    env.reset(seed=0)
    for _ in range(120):
        _, reward, terminated, truncated, info = env.step(np.array([1.0, 0.0], np.float32))
        if terminated or truncated:
            break
    assert terminated and not truncated and info["is_success"] and reward > 100
    assert set(("reward_distance", "reward_goal", "reward_failure")) <= set(info)

    short = gymnasium.make(TASK_A, environment_kwargs={"time_limit": 0.2})
    short.reset(seed=0)
    flags = [short.step(np.zeros(2, np.float32))[2:4] for _ in range(4)]
    assert flags == [(False, False)] * 3 + [(False, True)]


def test_pixels_make_a_dict_space() -> None:
    env = gymnasium.make(TASK_A, task_kwargs={"observations": ("pixels",)})
    assert isinstance(env.observation_space, gymnasium.spaces.Dict)
    assert env.observation_space["pixels"].shape == (64, 64, 1)
    assert env.observation_space["state"].shape == (6,)


@pytest.mark.render
def test_rgb_rendering_offscreen() -> None:
    # A fresh process: MUJOCO_GL must be chosen before MuJoCo's renderer is first imported.
    script = textwrap.dedent(f"""
        import gymnasium, sim4endor
        env = gymnasium.make({TASK_A!r}, render_mode="rgb_array", width=64, height=48)
        env.reset(seed=0)
        frame = env.render()
        assert frame.shape == (48, 64, 3) and frame.std() > 0, frame.shape
    """)
    env = {**os.environ, "MUJOCO_GL": "osmesa", "PYOPENGL_PLATFORM": "osmesa"}
    result = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
