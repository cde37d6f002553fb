"""Resumable checkpoints of a training run.

A run folder holds ``config.yaml`` and ``checkpoint/`` with ``state.pt`` (networks, target
networks, optimiser, exploration schedule, counters and torch's RNG state) and ``replay.pt``
(the filled part of an off-policy replay buffer, as plain tensors: dumping the storage
itself would write its whole 1e6-transition capacity). ``checkpoint/`` is replaced
atomically, so an interrupted save leaves the previous checkpoint intact. Everything loads
with ``torch.load(weights_only=True)``: no pickled code.

A buffer that had wrapped around is restored in storage order, so after a resume the oldest
transitions overwritten next may differ slightly from an uninterrupted run.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import torch
from tensordict import TensorDict
from torchrl.data import ReplayBuffer

from sim4endor._atomic import atomic_directory
from sim4endor.errors import Sim4EndoRError
from sim4endor.rl.algorithms import Agent

CHECKPOINT_DIR = "checkpoint"
STATE_FILE = "state.pt"
REPLAY_FILE = "replay.pt"


class CheckpointError(Sim4EndoRError):
    """A run folder has no usable checkpoint."""


@dataclasses.dataclass(frozen=True)
class Progress:
    """Counters of a run, saved with each checkpoint.

    Attributes:
        frames: environment steps collected.
        episodes: episodes finished during training.
        updates: gradient steps taken.
        wall_clock_s: wall-clock seconds spent training, summed over resumptions.
    """

    frames: int = 0
    episodes: int = 0
    updates: int = 0
    wall_clock_s: float = 0.0


def has_checkpoint(run_dir: Path) -> bool:
    """True if ``run_dir`` holds a checkpoint."""
    return (Path(run_dir) / CHECKPOINT_DIR / STATE_FILE).is_file()


def save_checkpoint(
    run_dir: Path, agent: Agent, progress: Progress, replay_buffer: ReplayBuffer | None
) -> None:
    """Writes the checkpoint of ``run_dir`` (replacing the previous one atomically)."""
    with atomic_directory(Path(run_dir) / CHECKPOINT_DIR) as staging:
        state = {
            "agent": agent.state_dict(),
            "progress": dataclasses.asdict(progress),
            "torch_rng": torch.get_rng_state(),
        }
        torch.save(state, staging / STATE_FILE)
        if replay_buffer is not None and len(replay_buffer):
            # clone(): a slice is a view and would save the whole preallocated storage.
            filled = replay_buffer.storage[: len(replay_buffer)].clone()
            torch.save(filled.to_dict(), staging / REPLAY_FILE)


def load_progress(run_dir: Path) -> Progress:
    """Returns the counters of ``run_dir``'s checkpoint (zeros when it has none)."""
    path = Path(run_dir) / CHECKPOINT_DIR / STATE_FILE
    if not path.is_file():
        return Progress()
    return Progress(**torch.load(path, weights_only=True)["progress"])


def load_checkpoint(
    run_dir: Path, agent: Agent, replay_buffer: ReplayBuffer | None = None
) -> Progress:
    """Restores ``agent`` (and ``replay_buffer`` if given) from ``run_dir``; returns its counters.

    Raises:
        CheckpointError: when ``run_dir`` has no checkpoint.
    """
    path = Path(run_dir) / CHECKPOINT_DIR / STATE_FILE
    if not path.is_file():
        raise CheckpointError(
            f"No checkpoint in {run_dir} (expected {path}); train with `sim4endor train ... "
            f"--out {run_dir}` first."
        )
    state = torch.load(path, weights_only=True)
    agent.load_state_dict(state["agent"])
    torch.set_rng_state(state["torch_rng"])
    replay = path.parent / REPLAY_FILE
    if replay_buffer is not None and replay.is_file():
        data = torch.load(replay, weights_only=True)
        replay_buffer.extend(TensorDict.from_dict(data, auto_batch_size=True, batch_dims=1))
    return Progress(**state["progress"])
