"""Training cost per algorithm: gradient steps/s of each learner, environment frames/s through
the trainer's collector with 1 and 2 worker processes, and the extrapolated wall-clock of one
100k-frame run with the paper's settings for each (periodic evaluation not included). With
``--backend ray`` the environments are Ray actors, as with ``sim4endor train --backend ray``,
on the cluster RAY_ADDRESS names or a Ray instance started here.

    python experiments/benchmarks/training_speed.py [--domain simplified_phantom]
        [--task task_a] [--envs 1 2] [--backend local] [--frames 1000] [--updates 300]
        [--device auto] [--json]

The learner runs one torch thread (the trainer's default); its gradient steps/s are measured
in thread CPU time (the median of ``--repeats`` chunks), so other jobs on the machine inflate
them little. Collection is timed in wall-clock (its work is in the worker processes): with
other jobs sharing the CPU it is pessimistic; the script prints the load average. A run
collects and learns in turn, so its wall-clock is frames / frames-per-s + updates /
updates-per-s.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import statistics
import time
from collections.abc import Callable
from typing import Any

import torch
from tensordict import TensorDictBase
from torchrl.envs import EnvBase, ExplorationType, set_exploration_type

from sim4endor import _json as strict_json
from sim4endor.rl import ray_backend
from sim4endor.rl.algorithms import Agent, build_agent, learner_device
from sim4endor.rl.config import ALGORITHMS, TrainConfig, default_config
from sim4endor.rl.envs import env_factory
from sim4endor.rl.trainer import _replay_buffer, make_collector

# Frames per collected batch while timing; the first batch (worker start-up) is not timed.
_BATCH = 200


def env_frames_per_s(config: TrainConfig, env: EnvBase, frames: int) -> float:
    """Environment frames/s of the trainer's collector under the exploration policy, with
    ``config.env.num_envs`` worker processes (``env`` gives the specs of the policy)."""
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
        threads = torch.get_num_threads()
        collector.shutdown()
        # A multi-process collector's shutdown raises this process's torch threads by its
        # worker count; with two threads the learner's steps collapse on a busy machine.
        torch.set_num_threads(threads)


def _batches(config: TrainConfig, agent: Agent, env: EnvBase) -> Callable[[], TensorDictBase]:
    """Draws training batches as the trainer does: from a replay of random-policy transitions,
    or PPO minibatches of a rollout with its advantages."""
    with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):
        data = env.rollout(
            max(config.optim.batch_size, config.ppo.minibatch_size) * 4,
            agent.exploration_policy,
            break_when_any_done=False,
        )
    if agent.advantage is not None:
        with torch.no_grad():
            flat = agent.transitions(agent.advantage(data.to(agent.device)))
        size = config.ppo.minibatch_size
        return lambda: flat[torch.randint(flat.numel(), (size,))]
    replay = _replay_buffer(config, agent.device)
    assert replay is not None
    replay.extend(agent.transitions(data))
    return replay.sample


def gradient_steps_per_s(
    config: TrainConfig, env: EnvBase, updates: int, repeats: int, device: torch.device
) -> float:
    """Gradient steps per second of thread CPU time, the median of ``repeats`` chunks of
    ``updates`` steps (on a GPU, in wall-clock)."""
    agent = build_agent(config, env.observation_spec, env.action_spec, device)
    sample = _batches(config, agent, env)
    clock = time.thread_time if device.type == "cpu" else time.perf_counter
    for _ in range(min(updates, 50)):  # warm-up: allocator, lazy initialisation
        agent.update(sample(), config.optim.max_grad_norm)
    chunks = []
    for _ in range(repeats):
        start = clock()
        for _ in range(updates):
            agent.update(sample(), config.optim.max_grad_norm)
        chunks.append(updates / (clock() - start))
    return statistics.median(chunks)


def run_updates(config: TrainConfig) -> float:
    """Gradient steps of one run of ``config``."""
    frames = config.collector.total_frames
    if config.algorithm == "ppo":
        return frames * config.ppo.epochs / config.ppo.minibatch_size
    return frames - config.collector.init_random_frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--domain", default="simplified_phantom")
    parser.add_argument("--task", default="task_a")
    parser.add_argument("--envs", type=int, nargs="+", default=[1, 2],
                        help="environment worker counts to time")
    parser.add_argument("--backend", choices=("local", "ray"), default="local",
                        help="where the environment workers step (collector.backend)")
    parser.add_argument("--frames", type=int, default=1000, help="env frames timed per count")
    parser.add_argument("--updates", type=int, default=300, help="gradient steps per chunk")
    parser.add_argument("--repeats", type=int, default=5, help="chunks timed per algorithm")
    parser.add_argument("--device", default="auto", choices=("auto", "cpu", "cuda"),
                        help="learner device, as `sim4endor train --device`")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    torch.set_num_threads(1)
    torch.manual_seed(0)
    device = learner_device(args.device)
    base = default_config("ddpg")
    base = dataclasses.replace(
        base, collector=dataclasses.replace(base.collector, backend=args.backend)
    )
    env_config = dataclasses.replace(base.env, domain=args.domain, task=args.task)
    env = env_factory(env_config)(0)
    report: dict[str, Any] = {"load_average_1min": round(os.getloadavg()[0], 2),
                              "learner_device": str(device), "backend": args.backend}
    env_rates = {}
    ray = ray_backend.connected() if args.backend == "ray" else contextlib.nullcontext()
    with ray:
        for count in args.envs:
            config = dataclasses.replace(
                base, env=dataclasses.replace(env_config, num_envs=count)
            )
            env_rates[count] = env_frames_per_s(config, env, args.frames)
            report[f"env_frames_per_s_envs{count}"] = round(env_rates[count], 1)
    if 1 in env_rates and 2 in env_rates:
        report["envs2_over_envs1"] = round(env_rates[2] / env_rates[1], 2)
    for algorithm in ALGORITHMS:
        config = default_config(algorithm)
        rate = gradient_steps_per_s(config, env, args.updates, args.repeats, device)
        report[f"{algorithm}_grad_steps_per_s"] = round(rate, 1)
        for count, env_rate in env_rates.items():
            seconds = config.collector.total_frames / env_rate + run_updates(config) / rate
            report[f"{algorithm}_100k_run_min_envs{count}"] = round(seconds / 60, 1)
    report["load_average_1min_end"] = round(os.getloadavg()[0], 2)
    env.close()
    if args.json:
        print(strict_json.dumps(report))
    else:
        for key, value in report.items():
            print(f"{key:<28} {value}")


if __name__ == "__main__":
    main()
