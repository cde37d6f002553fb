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

import contextlib
import json
import logging
import tempfile
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import torch
from torch import nn

from sim4endor._atomic import atomic_write_bytes, atomic_write_text, holds_output
from sim4endor.errors import Sim4EndoRError
from sim4endor.rl.algorithms import Agent
from sim4endor.rl.config import TrainConfig
from sim4endor.rl.envs import EnvFactory
from sim4endor.rl.runs import load_agent
from sim4endor.rl.trainer import CONFIG_FILE

#: The exported files.
POLICY_FILE, CONTRACT_FILE, ONNX_FILE = "policy.pt", "policy.json", "policy.onnx"


class ExportError(Sim4EndoRError, ValueError):
    """The source of an export is neither a training run nor an exported policy."""


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


@holds_output("out_dir")
def export_policy(
    source: Path,
    out_dir: Path,
    *,
    onnx: bool = False,
    make_env: EnvFactory | None = None,
) -> list[Path]:
    """Exports the latest policy of a training run, or re-exports an exported policy.

    Args:
        source: a training run folder (see :func:`export_agent`), or a folder (or its
            ``policy.pt``) this function wrote before: its ``policy.pt`` and ``policy.json``
            are copied and, with ``onnx``, converted.
        out_dir: folder for the exported files.
        onnx: also export ONNX (needs the ``onnx`` extra).
        make_env: ``seed -> env`` factory; defaults to the run's task (read for the specs).

    Raises:
        ExportError: when ``source`` is neither, or ``out_dir`` holds other files than an
            export's (an export never overwrites what it did not write).
    """
    source = Path(source)
    _check_out(Path(out_dir))
    folder = source.parent if source.name == POLICY_FILE else source
    if (folder / POLICY_FILE).is_file() and (folder / CONTRACT_FILE).is_file():
        return _reexport(folder, Path(out_dir), onnx=onnx)
    if source.is_dir() and not (source / CONFIG_FILE).is_file():
        raise ExportError(
            f"{source} is neither a training run folder (no {CONFIG_FILE}) nor an exported "
            f"policy ({POLICY_FILE} and {CONTRACT_FILE})."
        )
    config, agent = load_agent(source, make_env)
    return export_agent(config, agent, out_dir, onnx=onnx)


def _check_out(out_dir: Path) -> None:
    """Refuses an ``out_dir`` that is a file or holds files an export does not write."""
    if out_dir.exists() and not out_dir.is_dir():
        raise ExportError(f"--out {out_dir} exists and is not a folder; choose another.")
    exported = {POLICY_FILE, CONTRACT_FILE, ONNX_FILE}
    foreign = sorted(p.name for p in out_dir.iterdir() if p.name not in exported) \
        if out_dir.is_dir() else []
    if foreign:
        shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5
                                          else "")
        raise ExportError(
            f"--out {out_dir} holds files an export does not write ({shown}); choose a new or "
            f"empty folder (an export writes {POLICY_FILE}, {CONTRACT_FILE} and, with --onnx, "
            f"{ONNX_FILE})."
        )


def _reexport(folder: Path, out_dir: Path, *, onnx: bool) -> list[Path]:
    """Copies an exported policy and, if asked, converts its TorchScript program to ONNX."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = [out_dir / POLICY_FILE, out_dir / CONTRACT_FILE]
    for path in paths:
        if path.resolve() != (folder / path.name).resolve():
            atomic_write_bytes(path, (folder / path.name).read_bytes())
    if onnx:
        module = torch.jit.load(str(folder / POLICY_FILE), map_location="cpu")
        inputs = json.loads((folder / CONTRACT_FILE).read_text())["observation"]["shape"][-1]
        paths.append(_export_onnx(module, torch.zeros(1, int(inputs)), out_dir / ONNX_FILE))
    return paths


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
    # The contract first: a run it cannot describe leaves no policy.pt without its policy.json.
    contract = json.dumps(policy_contract(config, obs_dim), indent=2) + "\n"
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with torch.no_grad():
        scripted = torch.jit.trace(policy, (example,))
    script_path = out_dir / POLICY_FILE
    tmp = script_path.with_name(".policy.pt.tmp")
    scripted.save(str(tmp))
    tmp.replace(script_path)
    paths = [script_path, out_dir / CONTRACT_FILE]
    atomic_write_text(paths[1], contract)
    if onnx:
        paths.append(_export_onnx(policy, example, out_dir / ONNX_FILE))
    return paths


def policy_contract(config: TrainConfig, obs_dim: int) -> dict[str, Any]:
    """Everything a robot-side consumer needs besides the network, with units (``policy.json``).

    The observation scale factors are listed for reference only: they are inside the network,
    which takes the observation in SI units.
    """
    from sim4endor.tasks.config import ActionConfig

    # Training never changes the task's action settings (EnvConfig has none): the defaults.
    action = ActionConfig()
    entries = _observation_layout(config.env.observation_names(), obs_dim)
    return {
        "format": "sim4endor-policy/1",
        "algorithm": config.algorithm,
        "environment": {
            "domain": config.env.domain,
            "task": config.env.task,
            "task_kwargs": config.env.task_kwargs(config.seed),
            "frame": "the vessel model's frame (for a built vessel folder: its mesh's "
                     "coordinates converted to metres); 'tip frame' entries are in the body "
                     "frame of the wire's distal segment",
        },
        "observation": {
            "name": "observation", "dtype": "float32", "shape": ["batch (optional)", obs_dim],
            "entries": entries,
            "scale_inside_network": list(config.observation_scale()),
        },
        "action": {
            "name": "action", "dtype": "float32", "shape": ["batch (optional)", 2],
            "bounds": [-1.0, 1.0],
            "entries": [
                {"name": "delta_insertion", "index": 0, "scale": action.max_insertion_step,
                 "unit": "m", "meaning": "insertion step = action[0] * scale; > 0 pushes in"},
                {"name": "delta_rotation", "index": 1, "scale": action.max_rotation_step,
                 "unit": "rad", "meaning": "roll step about the wire axis = action[1] * scale"},
            ],
            "control_period_s": action.control_timestep,
        },
    }


def _observation_layout(names: tuple[str, ...], obs_dim: int) -> list[dict[str, Any]] | None:
    """Slices of the observation vector, or None when it is not a sim4endor task's (tests)."""
    from sim4endor.observations import OBSERVATION_UNITS

    sizes = {name: OBSERVATION_UNITS[name][1] for name in names}
    unknown = [name for name, size in sizes.items() if size is None]
    if len(unknown) == 1:  # the wire's vertex count: whatever the others leave
        sizes[unknown[0]] = obs_dim - sum(size or 0 for size in sizes.values())
    counts = [size or 0 for size in sizes.values()]
    if len(unknown) > 1 or sum(counts) != obs_dim or min(counts) < 1:
        return None
    layout, start = [], 0
    for name, size in zip(names, counts, strict=True):
        layout.append({"name": name, "slice": [start, start + size],
                       "unit": OBSERVATION_UNITS[name][0]})
        start += size
    return layout


@contextlib.contextmanager
def _quiet_exporter() -> Iterator[None]:
    """Keeps the ONNX exporter's chatter out of the command's output: a line per torchvision
    operator it skips (torchvision is not a dependency) and PyTorch's own deprecation
    warnings, which say nothing about the policy."""
    exporter = logging.getLogger("torch.onnx")
    level = exporter.level
    exporter.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FutureWarning)
            yield
    finally:
        exporter.setLevel(level)


def _export_onnx(policy: nn.Module, example: torch.Tensor, path: Path) -> Path:
    """Writes ``policy`` as one self-contained ONNX file at ``path`` (atomically)."""
    try:
        import onnx
    except ImportError as exc:
        raise Sim4EndoRError(
            "ONNX export needs the onnx extra: pip install 'sim4endor[onnx]'; "
            "the TorchScript policy.pt was written."
        ) from exc
    batch: dict[str, Any]
    if isinstance(policy, torch.jit.ScriptModule):
        # A loaded TorchScript program (a re-export) only converts with the TorchScript-based
        # exporter; the default one traces Python modules.
        batch = {"dynamo": False,
                 "dynamic_axes": {"observation": {0: "batch"}, "action": {0: "batch"}}}
    else:
        # verbose=False: the exporter's progress lines would mix into the CLI's output.
        batch = {"dynamic_shapes": ({0: torch.export.Dim("batch")},), "verbose": False}
    # The exporter may keep the weights in a file beside its output, named after it; staged
    # in a folder of its own, loaded back with them and written as one file, the exported
    # policy.onnx is all a robot needs (a copy of policy.onnx alone runs).
    with (tempfile.TemporaryDirectory(prefix=f".{path.name}.", dir=path.parent) as staging,
          _quiet_exporter()):
        staged = Path(staging) / path.name
        torch.onnx.export(policy, (example,), str(staged), input_names=["observation"],
                          output_names=["action"], **batch)
        model = onnx.load(str(staged), load_external_data=True)
    atomic_write_bytes(path, model.SerializeToString())
    return path
