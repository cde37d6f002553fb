"""Environment factories for training: a picklable ``seed -> EnvBase`` callable per config.

Collectors with several workers build their environments in subprocesses, so a factory is a
``functools.partial`` of a module-level function (picklable), never a lambda.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

from torchrl.envs import EnvBase, RewardSum, TransformedEnv

from sim4endor.rl.config import EnvConfig

#: Builds one environment seeded with the given integer.
EnvFactory = Callable[[int], EnvBase]


def sim4endor_env(config: EnvConfig, seed: int, *, evaluation: bool = False) -> EnvBase:
    """Returns the TorchRL env of the sim4endor task ``config`` names (default action scaling).

    Its ``observation`` is the config's observation set (the paper's ``[tip_position (m),
    tip_velocity (m/s)]`` by default, then any ``extra_observations``) and each step reports
    the tip position, the reward terms and diagnostics (``is_success``, ``wall_force``, ...)
    beside it.

    Args:
        config: Domain, task and task arguments.
        seed: The task's seed.
        evaluation: Use the evaluation split of generated trees (``config.eval_pool_seed``).
    """
    from sim4endor.envs import make_torchrl_env

    task_kwargs = config.task_kwargs(seed, evaluation=evaluation)
    return with_episode_return(make_torchrl_env(config.domain, config.task,
                                                task_kwargs=task_kwargs))


def env_factory(config: EnvConfig, *, evaluation: bool = False) -> EnvFactory:
    """Returns the picklable factory of the sim4endor task named by ``config``.

    Args:
        config: Domain, task and task arguments.
        evaluation: Build the evaluation split's environments (held-out generated trees).
    """
    return functools.partial(sim4endor_env, config, evaluation=evaluation)


def with_episode_return(env: EnvBase) -> EnvBase:
    """Adds ``episode_reward`` (running sum of rewards) unless the env already reports it."""
    if "episode_reward" in env.observation_spec.keys():
        return env
    return TransformedEnv(env, RewardSum())
