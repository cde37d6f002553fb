"""Training cost per algorithm: environment steps/s through the trainer's collector,
gradient steps/s, and the extrapolated wall-clock of one 100k-step run with the paper's
settings (one torch thread; ``--envs K`` steps K environments in K worker processes, as
``sim4endor train --envs K`` does, so ``--envs 2`` is a run given both cores of a 2-core
machine; with ``--backend ray`` the K environments are Ray actors, as with ``sim4endor train
--backend ray``, on the cluster RAY_ADDRESS names or a Ray instance started here). Periodic
evaluation is not included in the extrapolation.

    python experiments/benchmarks/training_speed.py [--domain simplified_phantom]
        [--task task_a] [--envs 1] [--backend local] [--frames 1000] [--updates 300] [--json]

Timings taken while other jobs share the CPU are pessimistic; the script prints the load.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import os
import time

import torch
from torchrl.envs import ExplorationType, set_exploration_type

from sim4endor.rl import ray_backend
from sim4endor.rl.algorithms import build_agent
from sim4endor.rl.config import ALGORITHMS, TrainConfig, default_config
from sim4endor.rl.envs import env_factory
from sim4endor.rl.trainer import _replay_buffer, make_collector

# Frames per collected batch while timing; the first batch (worker start-up) is not timed.
_BATCH = 200


def env_steps_per_s(config: TrainConfig, env, frames: int) -> float:
    """Environment steps/s of the trainer's collector under the exploration policy
    (``env`` gives the specs of the policy; the collector builds its own environments)."""
    batches = max(frames // _BATCH, 1)
    config = dataclasses.replace(
        config,
        collector=dataclasses.replace(
            config.collector, frames_per_batch=_BATCH, total_frames=_BATCH * (batches + 1),
            init_random_frames=0,
        ),
    )
    agent = build_agent(config, env.observation_spec, env.action_spec)
    collector = make_collector(config, env_factory(config.env), agent, frames_done=0)
    start = 0.0
    try:
        for index, _ in enumerate(collector):
            # Sent after every batch, as the trainer does. (Never sending them also hangs the
            # interpreter at exit in torchrl 0.14.1: the unused weight queues are shut down in
            # a __del__ that must start a thread.)
            collector.update_policy_weights_()
            if index == 0:
                start = time.perf_counter()
        return batches * _BATCH / (time.perf_counter() - start)
    finally:
        collector.shutdown()


def gradient_steps_per_s(config: TrainConfig, env, updates: int) -> float:
    """Gradient steps/s on batches drawn from a random-policy replay (PPO: minibatches)."""
    agent = build_agent(config, env.observation_spec, env.action_spec)
    with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):
        data = env.rollout(max(config.optim.batch_size, config.ppo.minibatch_size) * 2,
                           agent.exploration_policy, break_when_any_done=False)
    if config.algorithm == "ppo":
        with torch.no_grad():
            agent.advantage(data)
        sample = lambda: data[torch.randint(data.numel(), (config.ppo.minibatch_size,))]  # noqa: E731
    else:
        replay = _replay_buffer(config)
        replay.extend(data)
        sample = replay.sample
    start = time.perf_counter()
    for _ in range(updates):
        agent.update(sample(), config.optim.max_grad_norm)
    return updates / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--domain", default="simplified_phantom")
    parser.add_argument("--task", default="task_a")
    parser.add_argument("--envs", type=int, default=1, help="environment worker processes")
    parser.add_argument("--backend", choices=("local", "ray"), default="local",
                        help="where the environment workers step (collector.backend)")
    parser.add_argument("--frames", type=int, default=1000, help="env steps timed")
    parser.add_argument("--updates", type=int, default=300, help="gradient steps timed")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(0)
    base = default_config("ddpg")
    env_config = dataclasses.replace(
        base.env, domain=args.domain, task=args.task, num_envs=args.envs
    )
    env = env_factory(env_config)(0)
    collector_config = dataclasses.replace(base.collector, backend=args.backend)
    timed = dataclasses.replace(base, env=env_config, collector=collector_config)
    ray = ray_backend.connected() if args.backend == "ray" else contextlib.nullcontext()
    with ray:
        env_rate = env_steps_per_s(timed, env, args.frames)
    report = {
        "load_average_1min": os.getloadavg()[0],
        "envs": args.envs,
        "backend": args.backend,
        "env_steps_per_s": round(env_rate, 1),
    }
    for algorithm in ALGORITHMS:
        config = default_config(algorithm)
        rate = gradient_steps_per_s(config, env, args.updates)
        frames = config.collector.total_frames
        if algorithm == "ppo":
            batches = frames / config.collector.frames_per_batch
            steps = batches * config.ppo.epochs * config.collector.frames_per_batch
            updates = steps / config.ppo.minibatch_size
        else:
            updates = frames - config.collector.init_random_frames
        report[f"{algorithm}_grad_steps_per_s"] = round(rate, 1)
        report[f"{algorithm}_100k_run_min"] = round((frames / env_rate + updates / rate) / 60, 1)
    env.close()
    if args.json:
        print(json.dumps(report))
    else:
        for key, value in report.items():
            print(f"{key:<28} {value}")


if __name__ == "__main__":
    main()
