"""Takeover demonstrations: the policy drives, the probing expert takes over where it is stuck.

A trained generalist reaches most targets and loses the rest the same way: at a side
branch's ostium it keeps trying one aim until the episode times out. Demonstrations from the
expert's own episodes (``demonstrations.episodes``) show states the policy never visits;
these are taken where the policy fails, as in HG-DAgger (Kelly et al., ICRA 2019):

``collect``
    The run's deterministic policy drives on the run's training trees (or another domain's
    or pool's: ``--domain``, ``--pool-seed``, ``--pool-size``, the task arguments of
    ``sim4endor evaluate``). When the tip has come
    no ``MIN_GAIN`` closer to the target for ``--stall-steps`` control steps, the
    :class:`~sim4endor.tasks.expert.ProbingExpert` plans from that state (its lookahead on a
    copy of the simulation) and its plan's actions drive until the plan ends; then the policy
    again. Every step's observation and action is saved with a flag saying who acted, and
    the file names the environment it came from (``env``: the run's settings as overridden).
``finetune``
    Behaviour cloning of the takeover steps' actions, anchored on the policy's own
    deterministic actions at every other saved state (half of each batch), so it learns
    where it failed and keeps what it did well. A new run folder gets the new weights (the
    critics and the optimiser as they were), to evaluate or collect the next round with.

Usage:
    python experiments/generalist/takeover.py collect RUN DATA.npz --episodes 150 --seed 1000
    python experiments/generalist/takeover.py collect RUN WIDE.npz --domain random_coronary \
        --pool-seed 200 --pool-size 40 --seed 5000    # wide (3.5-4.4 mm) generated trees
    python experiments/generalist/takeover.py finetune RUN NEW_RUN DATA.npz [DATA.npz ...]
    sim4endor evaluate NEW_RUN --suite generalisation --trees 20 --first-seed 1100

Policies with ``stall_time`` in their observation (``generalist_stall``) can tell the state
at which they first try an ostium from the same state seconds later, where the expert took
over; without it the two labels conflict.
"""

from __future__ import annotations

import argparse
import dataclasses
import io
import json
import math
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torchrl.envs import EnvBase, ExplorationType, set_exploration_type

from sim4endor._atomic import atomic_directory, atomic_write_bytes
from sim4endor.cli.args import add_task_arguments, task_arguments
from sim4endor.rl import checkpoint
from sim4endor.rl.algorithms import observation_dim
from sim4endor.rl.envs import sim4endor_env
from sim4endor.rl.evaluation import rollouts
from sim4endor.rl.runs import evaluation_env, load_agent_for, run_config
from sim4endor.rl.trainer import CONFIG_FILE
from sim4endor.tasks.expert import ProbingExpert

#: Progress (m) towards the target that resets the stall count: the probing expert's.
MIN_GAIN = ProbingExpert().probe.min_gain
#: Takeover labels are clipped this far inside [-1, 1]: the actor's tanh reaches ±1 only at
#: infinite pre-activations, which a saturated label would drive it towards.
LABEL_LIMIT = 0.98
#: What finetune writes into the new run folder beside its config and checkpoint.
RECORD_FILE = "takeover.json"


class Takeover(TensorDictModuleBase):
    """Acts with ``actor`` and hands over to the probing expert's plan where it is stuck.

    Writes ``action`` and ``takeover`` (True on the expert's steps) into the tensordict.
    """

    def __init__(self, actor: TensorDictModuleBase, env: EnvBase, stall_steps: int) -> None:
        super().__init__()
        self.in_keys = [*actor.in_keys, "step_count"]
        self.out_keys = ["action", "takeover"]
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
        takeover = bool(self._plan)
        if takeover:
            tensordict["action"] = torch.as_tensor(self._plan.pop(0), dtype=torch.float32)
        else:
            self._actor(tensordict)
        tensordict["takeover"] = torch.tensor(takeover)
        return tensordict


def collect(run: Path, out: Path, *, episodes: int, seed: int, stall_steps: int,
            max_steps: int, task_arguments: Mapping[str, Any] | None = None
            ) -> dict[str, int]:
    """Runs ``episodes`` takeover episodes of ``run`` on its training trees, or where
    ``task_arguments`` (``EnvConfig`` fields over the run's, e.g. ``{"domain":
    "random_coronary"}``) say; writes ``out`` (observation, action, takeover, episode, env)
    and returns the counts."""
    config = run_config(run)
    env_config = evaluation_env(config.env, task_arguments or {})
    env = sim4endor_env(env_config, seed)
    try:
        agent = load_agent_for(run, config, env)
        policy = Takeover(agent.env_actor, env, stall_steps)
        columns: dict[str, list[np.ndarray]] = {k: [] for k in
                                                 ("observation", "action", "takeover")}
        episode: list[np.ndarray] = []
        successes = 0
        env.set_seed(seed)
        with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
            for i, rollout in enumerate(rollouts(env, policy, trials=episodes,
                                                 max_steps=max_steps, progress=True,
                                                 desc="takeover episodes")):
                for key, values in columns.items():
                    values.append(rollout[key].numpy())
                episode.append(np.full(rollout.shape[0], i))
                successes += bool(rollout["next", "is_success"].any())
    finally:
        env.close()
    data = {k: np.concatenate(v) for k, v in columns.items()}
    data["episode"] = np.concatenate(episode)
    data["env"] = np.array(json.dumps(dataclasses.asdict(env_config)))
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **data)
    atomic_write_bytes(out, buffer.getvalue())
    takeover = data["takeover"]
    return {"episodes": episodes, "successes": successes, "steps": len(takeover),
            "takeover_steps": int(takeover.sum()),
            "episodes_with_takeover": len(np.unique(data["episode"][takeover]))}


def finetune(run: Path, new_run: Path, data_files: list[Path], *, steps: int, batch: int,
             lr: float, seed: int) -> dict[str, float]:
    """Behaviour-clones the takeovers of ``data_files`` into ``run``'s actor, anchored on its
    own actions elsewhere; writes ``new_run`` and returns the final losses."""
    config = run_config(run)
    env = sim4endor_env(config.env, seed)
    try:
        agent = load_agent_for(run, config, env)
        width = observation_dim(env.observation_spec)
    finally:
        env.close()
    data = [np.load(path) for path in data_files]
    obs = torch.as_tensor(np.concatenate([d["observation"] for d in data]), dtype=torch.float32)
    action = torch.as_tensor(np.concatenate([d["action"] for d in data]), dtype=torch.float32)
    takeover = torch.as_tensor(np.concatenate([d["takeover"] for d in data]))
    if obs.shape[-1] != width:
        raise SystemExit(f"{data_files}: observations of {obs.shape[-1]} numbers, but {run}'s "
                         f"networks read {width}: collect the data with this run's "
                         "observation set.")
    expert_steps = takeover.nonzero().squeeze(1)
    own_steps = (~takeover).nonzero().squeeze(1)
    if not len(expert_steps) or not len(own_steps):
        raise SystemExit(f"{data_files}: {len(expert_steps)} takeover and {len(own_steps)} own "
                         "steps; finetuning needs both (collect more episodes, or lower "
                         "--stall-steps).")
    actor = agent.actor

    def mode(observations: torch.Tensor) -> torch.Tensor:
        with set_exploration_type(ExplorationType.DETERMINISTIC):
            return actor(TensorDict({"observation": observations},
                                    batch_size=[len(observations)]))["action"]

    with torch.no_grad():
        own = mode(obs)
    target = torch.where(takeover[:, None], action.clamp(-LABEL_LIMIT, LABEL_LIMIT), own)
    # The loss module's actor parameters are the actor's own tensors: training the actor
    # trains the checkpoint's policy.
    optimizer = torch.optim.Adam(actor.parameters(), lr=lr)
    generator = torch.Generator().manual_seed(seed)
    losses = {"takeover": math.nan, "own": math.nan}
    for _ in range(steps):
        idx = torch.cat([
            pool[torch.randint(len(pool), (batch,), generator=generator)]
            for pool in (expert_steps, own_steps)
        ])
        error = ((mode(obs[idx]) - target[idx]) ** 2).sum(-1)
        loss = error[:batch].mean() + error[batch:].mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        error = error.detach()
        losses = {"takeover": float(error[:batch].mean()), "own": float(error[batch:].mean())}
    record = {"source": str(run), "data": [str(p) for p in data_files], "steps": steps,
              "batch": batch, "lr": lr, "seed": seed,
              "takeover_steps": len(expert_steps), "own_steps": len(own_steps),
              "final_squared_error": losses}
    with atomic_directory(new_run, overwrite=False) as staging:
        shutil.copy(run / CONFIG_FILE, staging / CONFIG_FILE)
        checkpoint.save_checkpoint(staging, agent, checkpoint.load_progress(run), None)
        (staging / RECORD_FILE).write_text(json.dumps(record, indent=2) + "\n")
    return losses


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    c = sub.add_parser("collect", help="takeover episodes on the run's training trees")
    c.add_argument("run", type=Path, help="run folder (or its best/, evaluated/FRAMES)")
    c.add_argument("out", type=Path, help=".npz file written")
    c.add_argument("--episodes", type=int, default=150)
    c.add_argument("--seed", type=int, default=1000,
                   help="environment seed (trees, targets, starts); apart from training's")
    c.add_argument("--stall-steps", type=int, default=40,
                   help="control steps without progress before the expert takes over")
    c.add_argument("--max-steps", type=int, default=800)
    c.add_argument("--domain", help="collect on this domain (default: the run's)")
    c.add_argument("--task", help="task of --domain (default: the run's)")
    add_task_arguments(c)
    f = sub.add_parser("finetune", help="behaviour cloning of the takeovers into a new run")
    f.add_argument("run", type=Path, help="the run that collected the data")
    f.add_argument("new_run", type=Path, help="new run folder (must not exist)")
    f.add_argument("data", type=Path, nargs="+", help=".npz files of collect")
    f.add_argument("--steps", type=int, default=3000, help="gradient steps")
    f.add_argument("--batch", type=int, default=128,
                   help="takeover steps per batch (as many own steps beside them)")
    f.add_argument("--lr", type=float, default=1e-4)
    f.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    if args.command == "collect":
        overrides = task_arguments(args)
        overrides.update({k: v for k, v in (("domain", args.domain), ("task", args.task)) if v})
        counts = collect(args.run, args.out, episodes=args.episodes, seed=args.seed,
                         stall_steps=args.stall_steps, max_steps=args.max_steps,
                         task_arguments=overrides)
        print(json.dumps({"out": str(args.out), **counts}))
    else:
        if args.new_run.exists():
            raise SystemExit(f"{args.new_run} exists; choose a new folder.")
        losses = finetune(args.run, args.new_run, args.data, steps=args.steps,
                          batch=args.batch, lr=args.lr, seed=args.seed)
        print(json.dumps({"new_run": str(args.new_run), "final_squared_error": losses}))


if __name__ == "__main__":
    main()
