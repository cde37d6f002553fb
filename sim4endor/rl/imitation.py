"""Learning from the privileged expert: its episodes, its takeovers, and cloning them.

The scripted experts of :mod:`sim4endor.tasks.expert` read the wire's shape and the
centerline, which no policy sees; what they do is still a good teacher for a policy that reads
only its observation set. Two ways of asking them, both saved as :class:`Episodes`:

* **demonstrations**: the reactive :class:`~sim4endor.tasks.expert.CenterlineExpert` drives
  whole episodes (behaviour cloning's data);
* **takeovers** (HG-DAgger, Kelly et al., ICRA 2019): a policy drives, and where the tip has
  come no ``MIN_GAIN`` closer to the target for ``stall_steps`` control steps, the
  :class:`~sim4endor.tasks.expert.ProbingExpert` plans from that state (its lookahead on a copy
  of the simulation) and its plan drives until it ends. Only the expert's steps are labels:
  the states where the policy fails, which demonstrations never visit.

:func:`clone` fits a policy's deterministic action to the labels (mean squared error).
DAgger with the plain expert labelling every state the policy visits was measured and made
the policy worse (the plain expert's retreats and retries follow its own history, so its
labels on another driver's states contradict each other;
docs/results/generalisation/expert_dagger_rounds.csv): hence the
takeovers, where the expert drives what it labels.

A learnt **teacher** has no such history: a privileged policy is a function of its
observation, so it labels any state consistently. :class:`Teaching` distils it into a
student that reads another observation set (the ``deployable`` one of what a cath lab
measures): the teacher drives the demonstrations, and in later rounds the student drives
while the teacher labels every state it visits, from that state's privileged observation
(DAgger, Ross, Gordon and Bagnell, AISTATS 2011; teacher-student as in Chen et al.,
"Learning by cheating", CoRL 2019).
"""

from __future__ import annotations

import dataclasses
import io
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torchrl.envs import EnvBase, ExplorationType, set_exploration_type
from tqdm.auto import trange

from sim4endor._atomic import atomic_write_bytes
from sim4endor.rl import baselines
from sim4endor.rl.evaluation import reached, rollouts
from sim4endor.tasks.expert import ProbingExpert

#: Progress (m) towards the target that resets the stall count: the probing expert's.
MIN_GAIN = ProbingExpert().probe.min_gain
#: Labels are clipped this far inside [-1, 1]: the actor's tanh reaches ±1 only at infinite
#: pre-activations, which a saturated label would drive it towards.
LABEL_LIMIT = 0.98


@dataclasses.dataclass(frozen=True)
class Episodes:
    """Steps of some episodes, flattened along the first axis.

    Attributes:
        observation: the policy's observation at every step, ``(steps, width)``.
        action: the action taken, ``(steps, 2)``.
        expert: whether the step is a label: the expert took it, or a teacher labelled it
            (``label``), ``(steps,)``.
        episode: the episode index of every step, ``(steps,)``.
        success: whether each episode reached its target, ``(episodes,)``.
        label: the action to learn at every step, ``(steps, 2)``: the teacher's where a
            teacher labels the steps another policy drove; ``None`` (and in chunks saved
            before teachers): the action taken.
    """

    observation: np.ndarray
    action: np.ndarray
    expert: np.ndarray
    episode: np.ndarray
    success: np.ndarray
    label: np.ndarray = None  # type: ignore[assignment]  # filled in: the action taken

    def __post_init__(self) -> None:
        if self.label is None:
            object.__setattr__(self, "label", self.action)

    def save(self, path: Path) -> None:
        """Writes a compressed ``.npz``, atomically (a file that exists is complete)."""
        buffer = io.BytesIO()
        np.savez_compressed(buffer, **dataclasses.asdict(self))
        atomic_write_bytes(path, buffer.getvalue())

    @classmethod
    def load(cls, path: Path) -> Episodes:
        """Reads what :meth:`save` wrote."""
        with np.load(path) as data:
            return cls(**{field.name: data[field.name] for field in dataclasses.fields(cls)
                          if field.name in data.files})

    @property
    def labels(self) -> tuple[np.ndarray, np.ndarray]:
        """The labelled steps: their observations and labels."""
        return self.observation[self.expert], self.label[self.expert]

    def successful(self) -> Episodes:
        """Only the episodes that reached their target (indices renumbered from 0)."""
        reached = np.unique(self.episode)[self.success]  # sorted: the order of ``success``
        keep = np.isin(self.episode, reached)
        return Episodes(self.observation[keep], self.action[keep], self.expert[keep],
                        np.searchsorted(reached, self.episode[keep]), self.success[self.success],
                        self.label[keep])


class Takeover(TensorDictModuleBase):
    """Acts with ``actor`` and hands over to the probing expert's plan where it is stuck.

    Writes ``action`` and ``expert`` (True on the expert's steps) into the tensordict.
    """

    def __init__(self, actor: TensorDictModuleBase, env: EnvBase, stall_steps: int) -> None:
        super().__init__()
        self.in_keys = [*actor.in_keys, "step_count"]
        self.out_keys = ["action", "expert"]
        self._actor = actor
        # The expert reads the physics, which the TorchRL wrappers hand through by attribute.
        self._dm_env = env.base_env.dm_env
        self._expert = ProbingExpert()
        self._stall_steps = stall_steps
        self._plan: list[np.ndarray] = []
        self._closest, self._since = math.inf, 0

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        physics, task = self._dm_env.physics, self._dm_env.task
        if int(tensordict["step_count"]) == 0:
            self._plan, self._closest, self._since = [], math.inf, 0
        distance = task.manifold_distance()
        d = distance.at(distance.project(physics.tip_position()))
        if d < self._closest - MIN_GAIN:
            self._closest, self._since = d, 0
        else:
            self._since += 1
        if not self._plan and self._since >= self._stall_steps:
            self._plan = self._expert.plan(physics, task, self._closest)
            self._since = 0  # an empty plan: the policy tries again for as long
        expert = bool(self._plan)
        if expert:
            tensordict["action"] = torch.as_tensor(self._plan.pop(0), dtype=torch.float32)
        else:
            self._actor(tensordict)
        tensordict["expert"] = torch.tensor(expert)
        return tensordict


class _Demonstration(TensorDictModuleBase):
    """The plain expert driving, every step marked as the expert's."""

    def __init__(self, env: EnvBase) -> None:
        super().__init__()
        self.in_keys = ["step_count"]
        self.out_keys = ["action", "expert"]
        self._expert = baselines.policy(baselines.ScriptedExpert(), env)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        self._expert(tensordict)
        tensordict["expert"] = torch.tensor(True)
        return tensordict


@dataclasses.dataclass(frozen=True)
class Teacher:
    """A privileged policy that labels a student's states.

    Attributes:
        actor: its deterministic actor, reading ``observation``.
        entries: its observation entries, in the order its observation vector holds them.
    """

    actor: TensorDictModuleBase
    entries: tuple[str, ...]


class Teaching(TensorDictModuleBase):
    """Labels every step with the teacher's action on that state's privileged observation;
    acts with ``student`` (None: the teacher drives). Writes ``action``, ``label`` and
    ``expert`` (every step is a label)."""

    def __init__(self, teacher: Teacher, student: TensorDictModuleBase | None,
                 env: EnvBase) -> None:
        super().__init__()
        self.in_keys = list(student.in_keys) if student is not None else ["observation"]
        self.out_keys = ["action", "label", "expert"]
        self._teacher, self._student = teacher, student
        self._dm_env = env.base_env.dm_env

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        task, physics = self._dm_env.task, self._dm_env.physics
        # Flattened as the gymnasium adapter flattens the student's: entries in order.
        privileged = np.concatenate([np.ravel(value) for value in
                                     task.observe(physics, self._teacher.entries).values()])
        view = TensorDict({"observation": torch.as_tensor(privileged, dtype=torch.float32)})
        label = self._teacher.actor(view)["action"]
        if self._student is None:
            tensordict["action"] = label
        else:
            self._student(tensordict)
        tensordict["label"] = label
        tensordict["expert"] = torch.tensor(True)
        return tensordict


def collect(env: EnvBase, actor: TensorDictModuleBase | None, *, episodes: int,
            max_steps: int, stall_steps: int = 40, teacher: Teacher | None = None,
            progress: bool = False, desc: str = "episodes") -> Episodes:
    """Runs ``episodes`` episodes in ``env``.

    Without a ``teacher``: the plain expert's demonstrations when ``actor`` is None, else
    ``actor`` (deterministic) with the probing expert's takeovers after ``stall_steps``
    control steps without progress. With one: the teacher drives when ``actor`` is None,
    else ``actor`` drives, and the teacher labels every step.
    """
    if teacher is not None:
        driver: TensorDictModuleBase = Teaching(teacher, actor, env)
    else:
        driver = _Demonstration(env) if actor is None else Takeover(actor, env, stall_steps)
    columns: dict[str, list[np.ndarray]] = {"observation": [], "action": [], "expert": [],
                                            "episode": [], "label": []}
    success = []
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        for i, rollout in enumerate(rollouts(env, driver, trials=episodes, max_steps=max_steps,
                                             progress=progress, desc=desc)):
            for key in ("observation", "action", "expert"):
                columns[key].append(rollout[key].numpy())
            columns["label"].append(rollout["label" if teacher is not None
                                            else "action"].numpy())
            columns["episode"].append(np.full(rollout.shape[0], i))
            success.append(reached(rollout))
    return Episodes(**{k: np.concatenate(v) for k, v in columns.items()},
                    success=np.array(success, dtype=bool))


def clone(actor: TensorDictModuleBase, groups: Sequence[tuple[np.ndarray, np.ndarray]], *,
          steps: int, batch: int, lr: float, seed: int, progress: bool = False,
          desc: str = "clone") -> float:
    """Fits ``actor``'s deterministic action to labels (clipped to ±``LABEL_LIMIT``) by Adam on
    random batches; returns the last batch's mean squared error.

    ``groups`` are ``(observations, labels)`` pairs, each an equal share of every batch: a few
    thousand takeover labels beside tens of thousands of demonstrated ones still teach what
    to do where the policy stalls. ``actor`` is trained in place: an agent's actor shares its
    tensors with the agent's loss module, so the agent's checkpoint holds the cloned policy.
    """
    tensors = [(torch.as_tensor(obs, dtype=torch.float32),
                torch.as_tensor(label, dtype=torch.float32).clamp(-LABEL_LIMIT, LABEL_LIMIT))
               for obs, label in groups if len(label)]
    if not tensors:
        raise ValueError("clone: no labelled steps to learn from.")
    share = max(1, batch // len(tensors))
    optimizer = torch.optim.Adam(actor.parameters(), lr=lr)
    generator = torch.Generator().manual_seed(seed)
    error = math.nan
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in trange(steps, unit="steps", desc=desc, disable=not progress):
            picks = [torch.randint(len(label), (share,), generator=generator)
                     for _, label in tensors]
            obs = torch.cat([o[idx] for (o, _), idx in zip(tensors, picks, strict=True)])
            target = torch.cat([t[idx] for (_, t), idx in zip(tensors, picks, strict=True)])
            action = actor(TensorDict({"observation": obs}, batch_size=[len(obs)]))["action"]
            loss = ((action - target) ** 2).sum(-1).mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            error = float(loss.detach())
    return error
