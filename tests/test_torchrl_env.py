"""TorchRL environment: spec check, reward-term keys, ParallelEnv."""

from __future__ import annotations

import functools

import pytest
import torch
from navigation_helpers import require_vessel
from torchrl.envs import ParallelEnv
from torchrl.envs.utils import check_env_specs

from sim4endor.envs import make_torchrl_env


@pytest.fixture(autouse=True)
def phantom() -> None:
    require_vessel("simplified_phantom")


def test_check_env_specs_passes_and_terms_are_reported() -> None:
    env = make_torchrl_env("simplified_phantom", "task_a", {"random": 0})
    check_env_specs(env, seed=0)
    td = env.rollout(4, break_when_any_done=True)
    assert td["next", "observation"].shape == (4, 6)
    assert td["next", "observation"].dtype == torch.float32
    terms = td["next", "reward_distance"] + td["next", "reward_goal"] + td["next", "reward_failure"]
    torch.testing.assert_close(terms.float(), td["next", "reward"].squeeze(-1))
    assert td["next", "step_count"][-1].item() == 4


def test_works_inside_parallel_env() -> None:
    make = functools.partial(make_torchrl_env, "simplified_phantom", "task_b", {"random": 0})
    # fork: spawn works too but re-imports torch per worker (~30 s on a busy 2-core box).
    env = ParallelEnv(2, make, mp_start_method="fork")
    try:
        td = env.rollout(3)
        assert td.batch_size == torch.Size([2, 3])
        assert torch.isfinite(td["next", "reward"]).all()
    finally:
        env.close()
