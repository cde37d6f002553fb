"""Actor and critic networks for DDPG, SAC and PPO, as TensorDict modules.

Every network reads the flat ``observation`` entry (the task's state: tip position in m and
tip velocity in m/s by default) and, for critics, the normalised ``action`` in [-1, 1]. The
actors end in a tanh so their output always lies inside the action spec's bounds.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch
from tensordict import TensorDictBase
from tensordict.nn import NormalParamExtractor, TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.data import TensorSpec
from torchrl.modules import MLP, ProbabilisticActor, TanhModule, TanhNormal, ValueOperator

from sim4endor.rl.config import ConfigError, NetworkConfig

OBSERVATION_KEY = "observation"
ACTION_KEY = "action"

_ACTIVATIONS: dict[str, type[nn.Module]] = {"relu": nn.ReLU, "tanh": nn.Tanh}


class ScaledMLP(nn.Module):
    """Concatenates its inputs, multiplies them by fixed factors, then runs an MLP."""

    scale: torch.Tensor

    def __init__(self, scale: torch.Tensor, net: MLP) -> None:
        super().__init__()
        self.register_buffer("scale", scale)
        self.net = net

    def forward(self, *inputs: torch.Tensor) -> torch.Tensor:
        return self.net(torch.cat(inputs, dim=-1) * self.scale)


class _Module(TensorDictModule):
    """``TensorDictModule`` that stores its output tensors as they are.

    tensordict 0.14 passes every output through ``TensorDict.from_any``, which for a plain
    tensor asks importlib whether pandas is installed: a search of ``sys.path`` per output
    when it is not (~0.07 ms). That is 7 searches per SAC gradient step (~0.45 ms of ~6) and
    2 per environment step of the collector's policy.
    """

    def _write_to_tensordict(
        self,
        tensordict: TensorDictBase,
        tensors: Sequence[torch.Tensor],
        tensordict_out: TensorDictBase | None = None,
        out_keys: object = None,
    ) -> TensorDictBase:
        if tensordict_out is not None or out_keys is not None or self.inplace is not True:
            return super()._write_to_tensordict(tensordict, tensors, tensordict_out, out_keys)
        for key, tensor in zip(self.out_keys_source, tensors, strict=True):
            tensordict.set(key, tensor)
        return tensordict


class _ValueOperator(_Module, ValueOperator):
    """``ValueOperator`` that stores its output as it is (see :class:`_Module`)."""


def mlp(
    in_features: int, out_features: int, config: NetworkConfig, obs_dim: int | None = None
) -> ScaledMLP:
    """An MLP with ``config``'s hidden sizes and activation, reading ``in_features`` inputs
    whose first ``obs_dim`` (default: all) are the observation, scaled by
    ``config.observation_scale``.

    Raises:
        ConfigError: when ``observation_scale`` does not have one factor per observation entry.
    """
    obs_dim = in_features if obs_dim is None else obs_dim
    scale = torch.ones(in_features)
    if config.observation_scale:
        if len(config.observation_scale) != obs_dim:
            raise ConfigError(
                f"network.observation_scale has {len(config.observation_scale)} factors but the "
                f"observation has {obs_dim} entries; set network.observation_scale=[] or give "
                f"{obs_dim} factors."
            )
        scale[:obs_dim] = torch.tensor(config.observation_scale)
    net = MLP(
        in_features=in_features,
        out_features=out_features,
        num_cells=list(config.hidden_sizes),
        activation_class=_ACTIVATIONS[config.activation],
    )
    return ScaledMLP(scale, net)


def deterministic_actor(
    obs_dim: int, action_spec: TensorSpec, config: NetworkConfig
) -> TensorDictSequential:
    """DDPG actor: observation -> tanh-squashed action inside ``action_spec``."""
    action_dim = int(action_spec.shape[-1])
    return TensorDictSequential(
        _Module(mlp(obs_dim, action_dim, config), in_keys=[OBSERVATION_KEY], out_keys=["param"]),
        TanhModule(in_keys=["param"], out_keys=[ACTION_KEY], spec=action_spec),
    )


def stochastic_actor(
    obs_dim: int, action_spec: TensorSpec, config: NetworkConfig
) -> ProbabilisticActor:
    """SAC/PPO actor: a tanh-normal policy; its mode is the deterministic evaluation action."""
    action_dim = int(action_spec.shape[-1])
    body = nn.Sequential(mlp(obs_dim, 2 * action_dim, config), NormalParamExtractor())
    module = _Module(body, in_keys=[OBSERVATION_KEY], out_keys=["loc", "scale"])
    space = action_spec.space
    return ProbabilisticActor(
        module,
        in_keys=["loc", "scale"],
        out_keys=[ACTION_KEY],
        spec=action_spec,
        distribution_class=TanhNormal,
        distribution_kwargs={"low": space.low, "high": space.high},
        return_log_prob=True,
    )


def action_value(obs_dim: int, action_dim: int, config: NetworkConfig) -> ValueOperator:
    """Q(s, a) critic of DDPG and SAC."""
    return _ValueOperator(
        mlp(obs_dim + action_dim, 1, config, obs_dim), in_keys=[OBSERVATION_KEY, ACTION_KEY]
    )


def state_value(obs_dim: int, config: NetworkConfig) -> ValueOperator:
    """V(s) critic of PPO."""
    return _ValueOperator(mlp(obs_dim, 1, config), in_keys=[OBSERVATION_KEY])

