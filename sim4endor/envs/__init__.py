"""Environment adapters: gymnasium (ids registered on ``import sim4endor``) and TorchRL.

Example:
    >>> import gymnasium, sim4endor
    >>> env = gymnasium.make("Sim4EndoR/SimplifiedPhantom-TaskA-v0")      # doctest: +SKIP
    >>> from sim4endor.envs import make_torchrl_env
    >>> td_env = make_torchrl_env("simplified_phantom", "task_a")         # doctest: +SKIP
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from torchrl.envs import EnvBase


def make_torchrl_env(domain: str, task: str, *args: Any, **kwargs: Any) -> EnvBase:
    """Returns a TorchRL env; see :func:`sim4endor.envs.torchrl_env.make_torchrl_env`."""
    # torch/torchrl import lazily: gymnasium users should not pay for them.
    from sim4endor.envs.torchrl_env import make_torchrl_env as make

    return make(domain, task, *args, **kwargs)


__all__ = ["make_torchrl_env"]
