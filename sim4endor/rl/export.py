"""Exporting a trained actor for a physical robot driver (TorchScript, optionally ONNX).

Contract of the exported policy:

* input: ``observation``, float32, shape ``(6,)`` or ``(batch, 6)``:
  ``[p_x, p_y, p_z, v_x, v_y, v_z]`` = the guidewire tip position in m and its velocity in m/s,
  both in the vessel model's frame (the task's default state, paper: s_t = [p_t, v_t]);
* output: float32, shape ``(2,)`` or ``(batch, 2)``: ``[Δd, Δθ]`` normalised to [-1, 1]. The
  driver multiplies them by the task's ``ActionConfig.max_insertion_step`` (m, positive
  inserts) and ``max_rotation_step`` (rad) and applies them once per control period
  (``control_timestep``, 0.05 s by default).

The exported action is the policy's deterministic action (DDPG: the actor's output; SAC and
PPO: the tanh-normal's deterministic sample), exactly what ``sim4endor evaluate`` runs.
"""

from __future__ import annotations

import json
from pathlib import Path

import torch
from torch import nn

from sim4endor._atomic import atomic_write_text
from sim4endor.errors import Sim4EndoRError
from sim4endor.rl.algorithms import Agent
from sim4endor.rl.config import TrainConfig
from sim4endor.rl.envs import EnvFactory
from sim4endor.rl.runs import load_agent


class _SquashedPolicy(nn.Module):
    """``center + half_range · tanh(u)`` with u the actor MLP's output (DDPG, TanhModule) or
    the location of its tanh-normal (SAC, PPO: the distribution's deterministic sample)."""

    center: torch.Tensor
    half_range: torch.Tensor

    def __init__(
        self, body: nn.Module, low: torch.Tensor, high: torch.Tensor, *, gaussian: bool
    ) -> None:
        super().__init__()
        self.body = body
        self.gaussian = gaussian
        self.register_buffer("center", (high + low) / 2)
        self.register_buffer("half_range", (high - low) / 2)

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        output = self.body(observation)
        pre = output[0] if self.gaussian else output
        return self.center + self.half_range * pre.tanh()


def deterministic_policy(config: TrainConfig, agent: Agent) -> nn.Module:
    """Returns a plain ``observation -> action`` module equal to the agent's evaluation policy."""
    actor = agent.actor
    if config.algorithm == "ddpg":
        mlp_module, tanh = actor[0], actor[1]
        return _SquashedPolicy(
            mlp_module.module, tanh.action_low, tanh.action_high, gaussian=False
        ).eval()
    params_module = actor.module[0]
    space = actor.spec["action"].space
    return _SquashedPolicy(params_module.module, space.low, space.high, gaussian=True).eval()


def export_policy(
    run_dir: Path,
    out_dir: Path,
    *,
    onnx: bool = False,
    make_env: EnvFactory | None = None,
) -> list[Path]:
    """Exports the latest policy of a training run (see :func:`export_agent`).

    Args:
        run_dir: a training run folder.
        out_dir: folder for the exported files.
        onnx: also export ONNX (needs the ``onnx`` extra).
        make_env: ``seed -> env`` factory; defaults to the run's task (read for the specs).
    """
    config, agent = load_agent(run_dir, make_env)
    return export_agent(config, agent, out_dir, onnx=onnx)


def export_agent(
    config: TrainConfig, agent: Agent, out_dir: Path, *, onnx: bool = False
) -> list[Path]:
    """Writes ``policy.pt`` (TorchScript), ``policy.json`` (contract) and optionally ONNX.

    Returns:
        The written paths: ``policy.pt``, ``policy.json`` and, if asked, ``policy.onnx``.
    """
    policy = deterministic_policy(config, agent)
    obs_dim = next(policy.body.parameters()).shape[-1]  # type: ignore[union-attr]
    example = torch.zeros(1, obs_dim)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with torch.no_grad():
        scripted = torch.jit.trace(policy, (example,))
    script_path = out_dir / "policy.pt"
    tmp = script_path.with_name(".policy.pt.tmp")
    scripted.save(str(tmp))
    tmp.replace(script_path)
    contract = {
        "algorithm": config.algorithm,
        "domain": config.env.domain,
        "task": config.env.task,
        "input": f"observation float32 (..., {obs_dim}); the tasks' default state is "
        "[tip position [m] (3), tip velocity [m/s] (3)]",
        "output": "action float32 (..., 2): [delta_insertion, delta_rotation] in [-1, 1]",
        "scaling": "multiply by ActionConfig.max_insertion_step [m] and max_rotation_step [rad]",
    }
    paths = [script_path, out_dir / "policy.json"]
    atomic_write_text(paths[1], json.dumps(contract, indent=2) + "\n")
    if onnx:
        paths.append(_export_onnx(policy, example, out_dir / "policy.onnx"))
    return paths


def _export_onnx(policy: nn.Module, example: torch.Tensor, path: Path) -> Path:
    try:
        import onnx  # noqa: F401
    except ImportError as exc:
        raise Sim4EndoRError(
            "ONNX export needs the onnx extra: pip install 'sim4endor[onnx]'; "
            "the TorchScript policy.pt was written."
        ) from exc
    torch.onnx.export(
        policy, (example,), str(path), input_names=["observation"], output_names=["action"],
        dynamic_axes={"observation": {0: "batch"}, "action": {0: "batch"}},
    )
    return path
