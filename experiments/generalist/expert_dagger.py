"""DAgger from the plain expert: a measurement towards a cheaper generalist recipe (issue 67).

The shipped recipe (the model card's "Training") spends 97 min on SAC and 83 min on takeover
rounds with the probing expert, whose lookahead makes an episode cost 2-12 s. The plain
:class:`~sim4endor.tasks.expert.CenterlineExpert` (``baselines.ScriptedExpert``) is
reactive (one label costs a projection on the centerline) and, with the workhorse's
catalogue tip (``3,75,5,50``), reaches 96.9 % of the targets of fresh coronary-calibre trees
by itself
(experiments/results/reachability/vessel_build_fresh_calibre_trees_3200-3223_*). This script
measures what DAgger (Ross et al., AISTATS 2011) with it as the teacher gives, and in how
much wall-clock:

round 0
    the expert drives ``--episodes`` episodes on the training trees; every step's observation
    (the run's observation set) and the expert's action are kept;
round k > 0
    the policy of round k-1 drives (deterministic actions) and the expert, fed the same
    states, labels every step; the data of all rounds so far is cloned into the actor (mean
    squared error to the labels, clipped inside the tanh's range) from round k-1's weights.

Every round writes ``OUT/round_K`` (a run folder: evaluate it with ``sim4endor evaluate
OUT/round_K --suite generalisation --trees 20 --first-seed 1100``), its data
``OUT/data_K.npz`` and a line of ``OUT/rounds.jsonl`` (episodes, successes, steps, seconds).
Rerunning the same command resumes after the last finished round.

Measured (2026-12-05, seeds 1 and 2, 60 episodes a round, both seeds and a CI run sharing the
2 cores; experiments/results/generalisation/expert_dagger_2026-12-05_seed*.jsonl; a round's
``successes`` are its driver's on the training trees, so round k's are round k-1's policy's):
the expert reached 48/60 and 54/60; cloning its 60 episodes alone (``round_0``: 11.5-11.7 min
of collecting, 34-47 s of cloning) drove 50/60 and 49/60, as well as its teacher; the DAgger
rounds after it made the policy worse (16/60 and 7/60 after round 1, 24-32/60 after round 4),
because the plain expert is stateful (its retreat from a wrong branch and its retry offsets
follow its own history), so its labels on the policy's states contradict each other. Zero-shot
(``sim4endor evaluate OUT/round_0 --suite generalisation --trees 10 --no-baselines --json``,
one episode per case; ..._seed*_round_0_held_out_10_trees.json), the cloned ``round_0``
reached 43/50 and 46/50 targets of held-out trees 1000-1009 and 4/4 phantom targets (stEVE's
aorta 0/13, as the shipped generalist): cloning the expert's own episodes, not DAgger with it,
is the cheap start a recipe can build on.

Usage:
    python experiments/generalist/expert_dagger.py OUT --rounds 4 --episodes 100 --seed 1
"""

from __future__ import annotations

import argparse
import io
import json
import math
import time
from pathlib import Path

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torchrl.envs import EnvBase, ExplorationType, set_exploration_type

from sim4endor._atomic import atomic_directory, atomic_write_bytes
from sim4endor.assets import run_or_policy
from sim4endor.rl import baselines, checkpoint
from sim4endor.rl.algorithms import Agent, build_agent
from sim4endor.rl.config import TrainConfig, apply_overrides, save_config
from sim4endor.rl.envs import sim4endor_env
from sim4endor.rl.evaluation import reached, rollouts
from sim4endor.rl.runs import load_agent_for, run_config
from sim4endor.rl.trainer import CONFIG_FILE

#: Labels are clipped this far inside [-1, 1]: the actor's tanh reaches ±1 only at infinite
#: pre-activations, which a saturated label would drive it towards.
LABEL_LIMIT = 0.98
#: The shipped generalist's settings (observation set, trees, network), with the workhorse's
#: catalogue tip, on which the plain expert is measured.
BASE = "generalist"
TIP = "3,75,5,50"


class Labelled(TensorDictModuleBase):
    """Acts with ``actor`` (or the expert, when ``actor`` is None) and writes the plain
    expert's action for the same state as ``label``."""

    def __init__(self, actor: TensorDictModuleBase | None, env: EnvBase) -> None:
        super().__init__()
        self.in_keys = [*(actor.in_keys if actor else ()), "step_count"]
        self.out_keys = ["action", "label"]
        self._actor = actor
        self._expert = baselines.policy(baselines.ScriptedExpert(), env)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        self._expert(tensordict)
        tensordict["label"] = tensordict["action"].clone()
        if self._actor is not None:
            self._actor(tensordict)
        return tensordict


def collect(env: EnvBase, actor: TensorDictModuleBase | None, *, episodes: int,
            max_steps: int, desc: str) -> tuple[dict[str, np.ndarray], int]:
    """Runs ``episodes`` episodes; returns their observations and labels, and the successes."""
    policy = Labelled(actor, env)
    observations, labels = [], []
    successes = 0
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        for rollout in rollouts(env, policy, trials=episodes, max_steps=max_steps,
                                progress=True, desc=desc):
            observations.append(rollout["observation"].numpy())
            labels.append(rollout["label"].numpy())
            successes += reached(rollout)
    return {"observation": np.concatenate(observations),
            "label": np.concatenate(labels)}, successes


def clone(agent: Agent, data: list[dict[str, np.ndarray]], *, steps: int, batch: int,
          lr: float, seed: int) -> float:
    """Fits the actor's deterministic action to the labels of ``data``; returns the last
    batch's mean squared error."""
    obs = torch.as_tensor(np.concatenate([d["observation"] for d in data]), dtype=torch.float32)
    target = torch.as_tensor(np.concatenate([d["label"] for d in data]),
                             dtype=torch.float32).clamp(-LABEL_LIMIT, LABEL_LIMIT)
    actor = agent.actor
    optimizer = torch.optim.Adam(actor.parameters(), lr=lr)
    generator = torch.Generator().manual_seed(seed)
    error = math.nan
    with set_exploration_type(ExplorationType.DETERMINISTIC):
        for _ in range(steps):
            idx = torch.randint(len(obs), (batch,), generator=generator)
            action = actor(TensorDict({"observation": obs[idx]}, batch_size=[batch]))["action"]
            loss = ((action - target[idx]) ** 2).sum(-1).mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            error = float(loss.detach())
    return error


def save_round(folder: Path, config: TrainConfig, agent: Agent) -> None:
    with atomic_directory(folder, overwrite=True) as staging:
        save_config(config, staging / CONFIG_FILE)
        checkpoint.save_checkpoint(staging, agent, checkpoint.Progress(), None)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path, help="output folder (resumed when it exists)")
    parser.add_argument("--rounds", type=int, default=4, help="rounds after the expert's")
    parser.add_argument("--episodes", type=int, default=100, help="episodes per round")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--steps", type=int, default=4000, help="gradient steps per round")
    parser.add_argument("--batch", type=int, default=256)
    parser.add_argument("--lr", type=float, default=3e-4)
    parser.add_argument("--max-steps", type=int, default=800)
    parser.add_argument("--tip", default=TIP, help="the workhorse's tip shape")
    args = parser.parse_args()

    config = apply_overrides(run_config(run_or_policy(BASE)),
                             [f"seed={args.seed}", f"env.tip={args.tip!r}", "env.num_envs=1"])
    torch.manual_seed(args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    log = args.out / "rounds.jsonl"
    done = [json.loads(line) for line in log.read_text().splitlines()] if log.exists() else []
    env = sim4endor_env(config.env, seed=args.seed * 1000 + len(done))
    try:
        if done:
            agent = load_agent_for(args.out / f"round_{len(done) - 1}", config, env)
        else:
            agent = build_agent(config, env.observation_spec, env.action_spec)
        data = [dict(np.load(args.out / f"data_{k}.npz")) for k in range(len(done))]
        for k in range(len(done), args.rounds + 1):
            start = time.monotonic()
            actor = agent.env_actor if k else None
            round_data, successes = collect(env, actor, episodes=args.episodes,
                                            max_steps=args.max_steps, desc=f"round {k}")
            collected = time.monotonic() - start
            buffer = io.BytesIO()
            np.savez_compressed(buffer, observation=round_data["observation"],
                                label=round_data["label"])
            atomic_write_bytes(args.out / f"data_{k}.npz", buffer.getvalue())
            data.append(round_data)
            error = clone(agent, data, steps=args.steps, batch=args.batch, lr=args.lr,
                          seed=args.seed * 100 + k)
            save_round(args.out / f"round_{k}", config, agent)
            record = {"round": k, "driver": "policy" if k else "expert",
                      "episodes": args.episodes, "successes": successes,
                      "steps": len(round_data["label"]),
                      "steps_total": sum(len(d["label"]) for d in data),
                      "collect_s": round(collected, 1),
                      "clone_s": round(time.monotonic() - start - collected, 1),
                      "squared_error": round(error, 4)}
            with log.open("a") as f:
                f.write(json.dumps(record) + "\n")
            print(json.dumps(record), flush=True)
    finally:
        env.close()


if __name__ == "__main__":
    main()
