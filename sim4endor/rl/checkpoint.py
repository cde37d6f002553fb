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
import typing
from pathlib import Path
from typing import Any

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


def _read(path: Path, keys: tuple[str, ...], fix: str) -> dict[str, Any]:
    """Loads a checkpoint file (tensors and plain data only), or says why it cannot be used.

    torch's own message is not passed on: for a file that is not a weights-only checkpoint it
    suggests ``weights_only=False``, which would run whatever code the file holds.
    """
    try:
        # map_location: a run trained on a GPU resumes or is evaluated on any machine.
        data = torch.load(path, weights_only=True, map_location="cpu")
    except Exception as exc:  # torch raises RuntimeError, EOFError, UnpicklingError, ...
        raise CheckpointError(
            f"{path} is not a readable checkpoint ({type(exc).__name__}: truncated, "
            f"overwritten or not written by sim4endor); {fix}"
        ) from None
    missing = [k for k in keys if not isinstance(data, dict) or k not in data]
    if missing:
        raise CheckpointError(f"{path} is not a sim4endor checkpoint (no {missing}); {fix}")
    return typing.cast(dict[str, Any], data)


def _restart_hint(path: Path) -> str:
    return f"delete {path.parent} to start the run again, or restore it from a backup."


def _progress(state: dict[str, Any], path: Path) -> Progress:
    try:
        return Progress(**state["progress"])
    except TypeError as exc:
        raise CheckpointError(f"{path} holds unreadable counters ({exc}); "
                              f"{_restart_hint(path)}") from None


def load_progress(run_dir: Path) -> Progress:
    """Returns the counters of ``run_dir``'s checkpoint (zeros when it has none)."""
    path = Path(run_dir) / CHECKPOINT_DIR / STATE_FILE
    if not path.is_file():
        return Progress()
    return _progress(_read(path, ("progress",), _restart_hint(path)), path)


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
    state = _read(path, ("agent", "progress", "torch_rng"), _restart_hint(path))
    progress = _progress(state, path)
    try:
        agent.load_state_dict(state["agent"])
        torch.set_rng_state(state["torch_rng"])
    except (RuntimeError, KeyError, TypeError, ValueError) as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise CheckpointError(
            f"{path} does not fit this run's networks ({reason}); was it copied from another "
            f"run? {_restart_hint(path)}"
        ) from None
    replay = path.parent / REPLAY_FILE
    if replay_buffer is not None and replay.is_file():
        data = _read(replay, (), "delete it to resume with an empty replay buffer.")
        try:
            transitions = TensorDict.from_dict(data, auto_batch_size=True, batch_dims=1)
        except Exception as exc:  # tensordict raises several types on malformed data
            raise CheckpointError(
                f"{replay} is not a readable replay buffer ({type(exc).__name__}); delete it to "
                "resume with an empty buffer."
            ) from None
        # A checkpoint written before the replay kept only the loss's entries holds them all.
        replay_buffer.extend(agent.transitions(transitions))
    return progress
