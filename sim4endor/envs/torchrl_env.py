"""TorchRL environments of the navigation suite (through the gymnasium adapter)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import torch
from torchrl.data import Composite, Unbounded
from torchrl.envs import Compose, RewardSum, StepCounter, TransformedEnv
from torchrl.envs.gym_like import default_info_dict_reader
from torchrl.envs.libs.gym import GymWrapper

from sim4endor.envs.gym import NUMERIC_INFO_KEYS, NavigationEnv


def make_torchrl_env(
    domain: str,
    task: str,
    task_kwargs: Mapping[str, Any] | None = None,
    environment_kwargs: Mapping[str, Any] | None = None,
    *,
    device: str | torch.device = "cpu",
    transforms: bool = True,
) -> TransformedEnv | GymWrapper:
    """Returns a TorchRL environment of a suite task.

    The tensordict holds ``"observation"`` (float32; the gymnasium adapter's state vector,
    default ``[tip_position (m), tip_velocity (m/s)]``), ``"action"`` (2,) in [-1, 1],
    ``"reward"``, ``"done"``/``"terminated"``/``"truncated"``, ``"tip_position"`` (3,) m
    (also at reset) and, after each step, the reward terms and diagnostics as float entries
    (``"reward_distance"``,
    ``"reward_goal"``, ``"reward_failure"``, ``"manifold_distance"``, ``"wall_force"``, ...),
    ``"is_success"`` (bool) and ``"failure_code"`` (int64, see
    :func:`sim4endor.tasks.navigation.failure_code`). It is picklable through its arguments, so
    ``ParallelEnv(n, functools.partial(make_torchrl_env, domain, task, task_kwargs))`` works.

    Args:
        domain: Suite domain, e.g. ``"simplified_phantom"``.
        task: Suite task, e.g. ``"task_a"``.
        task_kwargs: See :func:`sim4endor.suite.load` (``random`` seeds the task).
        environment_kwargs: See :func:`sim4endor.suite.load`.
        device: Torch device of the output tensors.
        transforms: Add ``StepCounter`` (``"step_count"``) and ``RewardSum``
            (``"episode_reward"``), which training loops and logging read.
    """
    env = GymWrapper(NavigationEnv(domain, task, task_kwargs, environment_kwargs), device=device)
    dtypes = {"is_success": torch.bool, "failure_code": torch.int64}
    shapes = {"tip_position": (3,)}
    info_spec = Composite(
        {
            key: Unbounded(shape=shapes.get(key, ()), dtype=dtypes.get(key, torch.float64),
                           device=device)
            for key in NUMERIC_INFO_KEYS
        }
    )
    env.set_info_dict_reader(default_info_dict_reader(list(NUMERIC_INFO_KEYS), spec=info_spec))
    if not transforms:
        return env
    return TransformedEnv(env, Compose(StepCounter(), RewardSum()))
