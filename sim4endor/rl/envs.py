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


def sim4endor_env(
    domain: str, task: str, reward: str, seed: int, extra_observations: tuple[str, ...] = ()
) -> EnvBase:
    """Returns the TorchRL env of a sim4endor task (default action scaling).

    Its ``observation`` is ``[tip_position (m), tip_velocity (m/s), *extra_observations]``
    and each step reports the reward terms and diagnostics (``is_success``, ``wall_force``,
    ...) beside it.
    """
    from sim4endor.envs import make_torchrl_env

    task_kwargs = {"random": seed, "reward": reward, "observations": extra_observations}
    return with_episode_return(make_torchrl_env(domain, task, task_kwargs=task_kwargs))


def env_factory(config: EnvConfig) -> EnvFactory:
    """Returns the picklable factory of the sim4endor task named by ``config``."""
    return functools.partial(
        sim4endor_env,
        config.domain,
        config.task,
        config.reward,
        extra_observations=config.extra_observations,
    )


def with_episode_return(env: EnvBase) -> EnvBase:
    """Adds ``episode_reward`` (running sum of rewards) unless the env already reports it."""
    if "episode_reward" in env.observation_spec.keys():
        return env
    return TransformedEnv(env, RewardSum())
