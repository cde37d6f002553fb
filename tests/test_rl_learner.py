"""The learner: its shortcuts keep TorchRL's maths (a gradient step of each algorithm gives
the same weights, bit for bit, as the plain TorchRL pieces they replace: ``TensorDictModule``,
``ValueOperator``, ``SoftUpdate``, batches holding every entry the environment reports), and
the choice of its device."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch
from rl_testing import pendulum_env, tiny_config
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModule
from torchrl.envs import ExplorationType, set_exploration_type
from torchrl.modules import ValueOperator
from torchrl.objectives import SoftUpdate

from sim4endor.cli import main
from sim4endor.rl import algorithms, networks
from sim4endor.rl.algorithms import Agent, build_agent
from sim4endor.rl.config import ALGORITHMS, ConfigError
from sim4endor.rl.trainer import train


def _agent(algorithm: str, seed: int = 0) -> Agent:
    env = pendulum_env(seed)
    torch.manual_seed(seed)
    return build_agent(tiny_config(algorithm), env.observation_spec, env.action_spec)


def _rollout(agent: Agent, steps: int = 120) -> TensorDictBase:
    env = pendulum_env(1)
    with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):
        data = env.rollout(steps, agent.exploration_policy, break_when_any_done=False)
        if agent.advantage is not None:
            data = agent.advantage(data)
    return data


def _weights(agent: Agent) -> dict[str, torch.Tensor]:
    return {name: value.detach().clone() for name, value in agent.loss.state_dict().items()}


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_gradient_steps_equal_plain_torchrl(
    algorithm: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    fast = _agent(algorithm)
    with monkeypatch.context() as patch:
        patch.setattr(networks, "_Module", TensorDictModule)
        patch.setattr(networks, "_ValueOperator", ValueOperator)
        patch.setattr(algorithms, "PolyakUpdate", SoftUpdate)
        plain = _agent(algorithm)
    assert type(plain.target_updater) is (SoftUpdate if algorithm != "ppo" else type(None))
    assert _weights(fast).keys() == _weights(plain).keys()
    data = _rollout(fast)
    assert len(fast.transitions(data).keys(True, True)) < len(data.keys(True, True))
    for step in range(3):
        batch = data[torch.arange(step * 30, step * 30 + 40)]
        torch.manual_seed(step)
        fast_losses = fast.update(fast.transitions(batch), max_grad_norm=1.0)
        torch.manual_seed(step)
        plain_losses = plain.update(batch, max_grad_norm=1.0)
        assert fast_losses == plain_losses
    fast_weights, plain_weights = _weights(fast), _weights(plain)
    for name, value in fast_weights.items():
        assert torch.equal(value, plain_weights[name]), name


@pytest.mark.parametrize("algorithm", ["ddpg", "sac"])
def test_polyak_update_moves_targets_tau_of_the_way(algorithm: str) -> None:
    agent = _agent(algorithm)
    assert isinstance(agent.target_updater, algorithms.PolyakUpdate)
    with torch.no_grad():  # targets start as copies: now each source is 1 ahead
        for parameter in agent.loss.parameters():
            parameter.add_(1.0)
    before = _weights(agent)
    agent.target_updater.step()
    after = _weights(agent)
    moved = [name for name in before if not torch.equal(before[name], after[name])]
    assert moved and all(name.startswith("target_") for name in moved)
    for name in moved:
        torch.testing.assert_close(after[name] - before[name], torch.full_like(after[name], 0.005))


def test_auto_device_is_cuda_only_when_torch_sees_a_gpu(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert algorithms.learner_device("auto") == torch.device("cpu")
    assert algorithms.learner_device("cpu") == torch.device("cpu")
    with pytest.raises(ConfigError, match="device=cuda but torch sees no CUDA GPU"):
        algorithms.learner_device("cuda")
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    assert algorithms.learner_device("auto") == torch.device("cuda")
    assert algorithms.learner_device("cpu") == torch.device("cpu")


@pytest.mark.skipif(torch.cuda.is_available(), reason="needs a machine without a CUDA GPU")
def test_train_device_cuda_without_a_gpu_is_refused_before_writing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    status = main(["train", "sac", "--device", "cuda", "--frames", "10", "--out", str(out)])
    assert status == 2 and "use device=auto or device=cpu" in capsys.readouterr().err
    assert not out.exists()


def test_a_cpu_learner_acts_with_its_own_modules(tmp_path: Path) -> None:
    agent = _agent("ddpg")
    assert agent.device == torch.device("cpu")
    assert agent.env_actor is agent.actor
    assert agent.exploration_policy[0] is agent.actor  # the noise wraps the learner's actor
    config = tiny_config("sac", "device=cpu")
    train(config, tmp_path, make_env=pendulum_env, progress=False)
    # The device is where a run happens to be: resuming elsewhere (auto) is the same run.
    more = tiny_config("sac", "device=auto", "collector.total_frames=300")
    assert train(more, tmp_path, make_env=pendulum_env, progress=False)["frames"] == 300
