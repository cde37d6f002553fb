"""Runs a policy deterministically for a number of episodes and records :class:`Episode` s.

The sim4endor TorchRL environments (:func:`sim4endor.envs.make_torchrl_env`) report, beside
each step's ``observation``, the tip position (``tip_position``, m, at reset too, whatever the
observation set), whether the target was reached (``is_success``), the wire–wall contact
force (``wall_force``, N), the geodesic distance from the tip to the target
(``manifold_distance``, m) and why an episode failed (``failure_code``, an index into
:data:`sim4endor.tasks.FAILURES`); one step lasts the task's control period
(``ActionConfig.control_timestep``, 0.05 s by default).
:class:`EpisodeKeys` names those entries. An environment that lacks one (e.g. a generic
control task used in tests) gives neutral values: no success, zero force, zero path lengths.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Mapping
from typing import Protocol, runtime_checkable

import numpy as np
import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torchrl.envs import EnvBase, ExplorationType, set_exploration_type
from tqdm.auto import tqdm

from sim4endor.rl.metrics import Episode
from sim4endor.tasks import FAILURES

#: Control period of the sim4endor tasks with their default action settings (20 Hz).
DEFAULT_CONTROL_TIMESTEP_S = 0.05


@runtime_checkable
class ReportsProgress(Protocol):
    """A policy with something to say on the step bar of :func:`rollouts`: the probing expert's
    look-ahead can hold one step for seconds, so it names the probes it made."""

    def progress_postfix(self) -> Mapping[str, object]:
        """What the step bar shows beside its count, e.g. ``{"probes": "2/12"}``."""
        ...


@dataclasses.dataclass(frozen=True)
class EpisodeKeys:
    """Where the metrics find what they need in a rollout.

    Attributes:
        tip_position: entry whose ``tip_slice`` holds the tip position (3,) in m.
        tip_slice: (start, stop) of the tip position within that entry.
        success: bool entry, True on the step that reached the target.
        wall_force: wire–wall contact force in N.
        tip_force: wall force on the shaped tip in N.
        distance: distance from the tip to the target along the centerline in m.
        control_timestep_s: simulated seconds per step (completion time = steps × this).
        failure_code: int entry, 0 or the 1-based index of the failure reason in ``failures``.
        failures: the failure reasons ``failure_code`` counts.
    """

    tip_position: str = "tip_position"
    tip_slice: tuple[int, int] = (0, 3)
    success: str = "is_success"
    wall_force: str = "wall_force"
    tip_force: str = "tip_force"
    distance: str = "manifold_distance"
    control_timestep_s: float = DEFAULT_CONTROL_TIMESTEP_S
    failure_code: str = "failure_code"
    failures: tuple[str, ...] = FAILURES


def rollout_episodes(
    env: EnvBase,
    policy: TensorDictModuleBase,
    *,
    trials: int,
    max_steps: int,
    seed: int,
    keys: EpisodeKeys = EpisodeKeys(),
    progress: bool = False,
    desc: str = "evaluate",
    leave: bool = True,
) -> list[Episode]:
    """Runs ``trials`` deterministic episodes of ``policy`` (its mode, no exploration noise).

    The env is reseeded with ``seed`` first, so two calls see the same start states.
    ``progress`` shows the bars of :func:`rollouts`.
    """
    env.set_seed(seed)
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        return [
            episode_from_rollout(rollout, keys)
            for rollout in rollouts(env, policy, trials=trials, max_steps=max_steps, keys=keys,
                                    progress=progress, desc=desc, leave=leave)
        ]


def rollouts(
    env: EnvBase,
    policy: TensorDictModuleBase,
    *,
    trials: int,
    max_steps: int,
    keys: EpisodeKeys = EpisodeKeys(),
    progress: bool = False,
    desc: str = "evaluate",
    leave: bool = True,
) -> Iterator[TensorDictBase]:
    """Yields ``trials`` episodes of ``policy`` in ``env``, each a rollout with time along dim
    0, as it goes (``max_steps`` at most each). ``progress`` shows a bar counting episodes and
    successes (``leave``: kept when done) and under it one counting the episode's steps, with
    the distance to the target and what a :class:`ReportsProgress` policy says: an episode
    can take minutes. The caller sets the exploration type and gradient mode."""
    successes = 0
    with (tqdm(total=trials, unit="episodes", desc=desc, disable=not progress,
               leave=leave) as bar,
          tqdm(total=max_steps, unit="steps", desc="steps", disable=not progress,
               leave=False) as steps):
        says = policy.progress_postfix if isinstance(policy, ReportsProgress) else dict

        def count_step(_env: EnvBase, tensordict: TensorDictBase) -> None:
            postfix = dict(says())
            if keys.distance in tensordict.keys():
                postfix["to_target"] = f"{1e3 * float(tensordict[keys.distance]):.1f} mm"
            steps.update()
            steps.set_postfix(postfix, refresh=False)

        for _ in range(trials):
            steps.reset()
            rollout = env.rollout(max_steps, policy, callback=count_step if progress else None,
                                  break_when_any_done=True)
            successes += reached(rollout, keys)
            bar.update()
            bar.set_postfix(success=f"{successes}/{bar.n}")
            yield rollout


def reached(rollout: TensorDictBase, keys: EpisodeKeys = EpisodeKeys()) -> bool:
    """Whether one episode's rollout reached the target (False when the env does not say)."""
    nxt = rollout["next"]
    return bool(nxt[keys.success].any()) if keys.success in nxt.keys() else False


def episode_from_rollout(rollout: TensorDictBase, keys: EpisodeKeys = EpisodeKeys()) -> Episode:
    """Turns one episode's rollout tensordict (time along dim 0) into an :class:`Episode`.

    The shortest path is the distance to the target after the first step plus the tip's
    first displacement (the reset state carries no distance; the first step is short).
    """
    nxt = rollout["next"]
    steps = rollout.shape[0]
    present = set(nxt.keys())
    if keys.tip_position in present:
        lo, hi = keys.tip_slice
        tips = torch.cat([rollout[keys.tip_position][:1], nxt[keys.tip_position]])[:, lo:hi]
        tips_np = tips.double().numpy()
    else:
        tips_np = np.zeros((steps + 1, 3))
    forces = nxt[keys.wall_force].reshape(-1).numpy() if keys.wall_force in present else np.zeros(0)
    tip_forces = (nxt[keys.tip_force].reshape(-1).numpy() if keys.tip_force in present
                  else np.zeros(0))
    code = int(nxt[keys.failure_code][-1]) if keys.failure_code in present else 0
    shortest = 0.0
    if keys.distance in present:
        first_move = float(np.linalg.norm(tips_np[1] - tips_np[0]))
        shortest = float(nxt[keys.distance][0]) + first_move
    return Episode(
        tip_positions=tips_np,
        success=reached(rollout, keys),
        duration_s=steps * keys.control_timestep_s,
        wall_forces=forces,
        shortest_path_m=shortest,
        episode_return=float(nxt["reward"].sum()),
        failure=keys.failures[code - 1] if code else "",
        tip_forces=tip_forces,
    )


def success_fraction(done_steps: TensorDictBase, keys: EpisodeKeys = EpisodeKeys()) -> float | None:
    """Fraction of finished episodes in ``done_steps`` (the ``next`` entries of done steps)
    that succeeded; None when the env does not report success."""
    # len(), not numel(): a TensorDict with batch size (0,) reports numel() == 1.
    if keys.success not in done_steps.keys() or len(done_steps) == 0:
        return None
    return float(done_steps[keys.success].float().mean())
