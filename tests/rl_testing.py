"""Helpers of the tests/test_rl_*.py modules: a tiny standard env and tiny budgets.

The training library is tested on gymnasium's Pendulum-v1 (3-dim observation, 1-dim action
in [-2, 2]) so the loop, losses, checkpoints and export are exercised in seconds, without the
guidewire simulation; scripts and notebooks are tested on the sim4endor tasks themselves.
"""

from __future__ import annotations

from torchrl.envs import EnvBase, GymEnv

from sim4endor.rl.config import TrainConfig, apply_overrides, default_config
from sim4endor.rl.envs import with_episode_return

#: A budget that runs every part of the loop (random warm-up, updates, evaluation, checkpoint).
TINY = (
    "collector.total_frames=200",
    "collector.frames_per_batch=100",
    "collector.init_random_frames=100",
    "optim.updates_per_batch=20",
    "network.hidden_sizes=[32, 32]",
    "network.observation_scale=[]",  # the default scales fit the 6-entry guidewire state
    "replay.size=1000",
    "eval.interval_frames=100",
    "eval.trials=2",
    "eval.max_steps=20",
    "checkpoint_interval_frames=100",
    "ppo.epochs=2",
    "ppo.minibatch_size=50",
    "logger.backend=csv",
)


def pendulum_env(seed: int) -> EnvBase:
    """Pendulum-v1 with an episode return, seeded."""
    env = with_episode_return(GymEnv("Pendulum-v1"))
    env.set_seed(seed)
    return env


def tiny_config(algorithm: str, *overrides: str) -> TrainConfig:
    """The algorithm's defaults at the :data:`TINY` budget, plus ``overrides``."""
    return apply_overrides(default_config(algorithm), [*TINY, *overrides])
