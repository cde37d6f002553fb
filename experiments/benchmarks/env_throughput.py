"""Environment throughput: env steps/s, overhead of the env loop over bare physics, reset cost.

Runs random actions (seeded) on a suite task, then replays the same driver commands on a bare
``GuidewirePhysics`` (same model, same sub-steps, no task logic) so the two loops simulate the
same trajectory and the difference is the environment's own cost (observation, reward,
termination, action checks). Pin to one core with ``--cpu 0`` (or ``taskset -c 0``).
Env and gymnasium steps/s are wall clock; the bare-physics rate and both overhead figures use
thread CPU time, so time the process spends descheduled by other jobs counts in neither.

Issue 4 targets: >= 100 env steps/s on one core on the simplified phantom; env overhead
<= 10 % over the physics alone; a reset costs milliseconds. Issue 16: >= 400 env steps/s on
one core on every shipped anatomy and on generated coronary trees (``--all``).

Usage:
    python experiments/benchmarks/env_throughput.py [--domain D --task T] [--steps 400]
        [--cpu 0] [--json]
    python experiments/benchmarks/env_throughput.py --all [--cpu 0] [--json] [--motion]

``--all`` measures every task of ``suite.ALL_TASKS`` (the shipped phantoms, the random and
the coronary trees) and prints one table row per task (``--json``: one line per task).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim4endor import _json as strict_json
from sim4endor import registry, suite
from sim4endor.envs.gym import NavigationEnv
from sim4endor.models import fidelity as fidelities
from sim4endor.physics import GuidewirePhysics

#: A step of the bare-physics replay: a copy of the physics just after a reset (None within an
#: episode) and the driver targets (insertion m, rotation rad).
Command = tuple[GuidewirePhysics | None, tuple[float, float]]
#: Task arguments besides the seed: ``wire`` (a preset name or a mapping of fields),
#: ``fidelity`` and ``motion``, where given (the domain's defaults otherwise).
Extra = dict[str, Any]
#: Resets before the timed loops: a pool of 8 trees drawn 40 times misses one with
#: probability 8 x (7/8)^40 = 0.4 %.
_WARM_RESETS = 40


def _random_actions(steps: int, seed: int) -> np.ndarray:
    # Biased forward so the wire spends the run inside the vessel, in contact, as in training.
    rng = np.random.default_rng(seed)
    actions = rng.uniform(-1.0, 1.0, size=(steps, 2))
    actions[:, 0] = np.clip(actions[:, 0] + 0.5, -1.0, 1.0)
    return actions


@dataclass
class EnvRun:
    """One timed run of the env loop.

    Attributes:
        wall_s: Wall-clock seconds of the loop.
        cpu_s: Thread CPU seconds of the loop.
        physics_cpu_s: Thread CPU seconds inside ``physics.step`` (timed in the same run, so
            ``cpu_s - physics_cpu_s`` is the env's own cost; time the process spends
            descheduled by other jobs counts in neither).
        commands: per step, a copy of the physics at a reset (else None) and the driver
            targets, for the bare-physics replay.
        n_sub_steps: Physics steps per env step.
        timestep: Physics time step (s).
        mean_contacts: Active contacts after an env step, averaged over the steps.
    """

    wall_s: float
    cpu_s: float
    physics_cpu_s: float
    commands: list[Command]
    n_sub_steps: int
    timestep: float
    mean_contacts: float


def _kwargs(extra: Extra) -> dict[str, Any]:
    return {"random": 0, **extra}


def env_loop(domain: str, task: str, actions: np.ndarray, extra: Extra) -> EnvRun:
    """Runs the dm_control env on ``actions``."""
    env = suite.load(domain, task, _kwargs(extra))
    # A pool domain builds each tree the first time an episode draws it (about 0.7 s for a
    # cached coronary tree, printed as first_load_s); draw them before timing, so the loop
    # measures stepping and resets as a long training run sees them.
    for _ in range(_WARM_RESETS):
        env.reset()
    physics = env.physics
    inner = [0.0]
    step = physics.step

    def timed_step(nstep: int = 1) -> None:
        start = time.thread_time()
        try:
            step(nstep)
        finally:
            inner[0] += time.thread_time() - start

    physics.step = timed_step  # instance attribute: only this benchmark's physics is timed
    # (state after a reset or None, driver targets) per step: the replay starts each episode
    # from a copy of the env's state after its reset (anatomy, start pose, solver warm start),
    # so both loops simulate the same trajectory. A copy, not the reset's driver targets: the
    # _redirect tasks' reset drives the wire down another branch, and placing it straight at
    # that insertion put it through the wall (mjWARN_BADQACC in the replay).
    commands: list[Command] = [(physics.copy(share_model=True), physics.driver_targets())]
    contacts = 0
    untimed_wall = untimed_cpu = 0.0  # the copies are the benchmark's work, not the env's
    start, cpu_start = time.perf_counter(), time.thread_time()
    for action in actions:
        reset = env.step(action).last()
        contacts += physics.data.ncon
        commands.append((None, physics.driver_targets()))
        if reset:
            env.reset()
            copy_start, copy_cpu_start = time.perf_counter(), time.thread_time()
            commands.append((physics.copy(share_model=True), physics.driver_targets()))
            untimed_wall += time.perf_counter() - copy_start
            untimed_cpu += time.thread_time() - copy_cpu_start
    cpu = time.thread_time() - cpu_start - untimed_cpu
    wall = time.perf_counter() - start - untimed_wall
    return EnvRun(wall, cpu, inner[0], commands, env._n_sub_steps, physics.timestep(),
                  contacts / len(actions))


def physics_loop(commands: list[Command], n_sub_steps: int) -> float:
    """Returns the CPU seconds to replay the same episodes' driver targets on the bare physics
    (the steps only: restoring the state at a reset is not timed)."""
    physics = None
    elapsed = 0.0
    for snapshot, (insertion, rotation) in commands:
        if snapshot is not None:
            # Copied again: the next repeat replays the same snapshots.
            physics = snapshot.copy(share_model=True)
            continue
        assert physics is not None, "the commands start with a reset"
        start = time.thread_time()
        physics.set_driver_targets(insertion, rotation)
        with physics.suppress_physics_errors():
            physics.step(n_sub_steps)
        elapsed += time.thread_time() - start
    return elapsed


def gym_loop(domain: str, task: str, actions: np.ndarray, extra: Extra) -> float:
    """Returns the seconds of the same actions through the gymnasium adapter."""
    env = NavigationEnv(domain, task, _kwargs(extra))
    env.reset(seed=0)
    for _ in range(_WARM_RESETS):
        env.reset()
    start = time.perf_counter()
    for action in actions.astype(np.float32):
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return time.perf_counter() - start


def reset_cost(domain: str, task: str, count: int, extra: Extra) -> float:
    """Returns the median seconds of a reset after a few steps."""
    env = suite.load(domain, task, _kwargs(extra))
    times = []
    for _ in range(count):
        env.reset()
        for _ in range(5):
            env.step([1.0, 0.3])
        start = time.perf_counter()
        env.reset()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def measure(domain: str, task: str, steps: int, repeats: int, extra: Extra | None = None
            ) -> dict[str, Any]:
    """Times one task (env, bare physics, gymnasium, reset) and returns its figures;
    ``extra`` task arguments (``wire``: a preset name or a mapping, ``fidelity``) replace the
    task's defaults."""
    extra = extra or {}
    actions = _random_actions(steps, seed=0)
    t_load = time.perf_counter()
    suite.load(domain, task, _kwargs(extra))
    load_s = time.perf_counter() - t_load
    # Alternating the loops and keeping the fastest run of each cancels most of the noise
    # of a shared machine.
    runs: list[EnvRun] = []
    physics_runs, gym_runs, overheads = [], [], []
    for _ in range(repeats):
        run = env_loop(domain, task, actions, extra)
        runs.append(run)
        overheads.append(100.0 * (run.cpu_s - run.physics_cpu_s) / run.physics_cpu_s)
        physics_runs.append(physics_loop(run.commands, run.n_sub_steps))
        gym_runs.append(gym_loop(domain, task, actions, extra))
    env_s = min(run.wall_s for run in runs)
    physics_s, gym_s = min(physics_runs), min(gym_runs)
    run = runs[0]
    return {
        "domain": domain,
        "task": task,
        "wire": extra.get("wire"),
        "fidelity": extra.get("fidelity"),
        "motion": bool(extra.get("motion")),
        "env_steps": steps,
        "physics_steps_per_env_step": run.n_sub_steps,
        "timestep_ms": 1e3 * run.timestep,
        "env_steps_per_s": steps / env_s,
        "gym_steps_per_s": steps / gym_s,
        "physics_only_env_steps_per_s": steps / physics_s,
        # Env CPU time outside physics.step over CPU time inside it, median of the repeats.
        "env_overhead_percent": statistics.median(overheads),
        # CPU time of the whole env loop over the bare-physics replay, fastest runs of each.
        "env_vs_replay_percent": 100.0 * (min(r.cpu_s for r in runs) - physics_s) / physics_s,
        "realtime_factor": steps * run.n_sub_steps * run.timestep / env_s,
        "mean_contacts": run.mean_contacts,
        "reset_ms": 1e3 * reset_cost(domain, task, 20, extra),
        "first_load_s": load_s,
        "load_average_1min": os.getloadavg()[0],
    }


#: Columns of the ``--all`` table: (heading, key, format).
_TABLE = (
    ("domain", "domain", "{}"), ("task", "task", "{}"),
    ("env steps/s", "env_steps_per_s", "{:.0f}"),
    ("physics only", "physics_only_env_steps_per_s", "{:.0f}"),
    ("x real time", "realtime_factor", "{:.1f}"),
    ("mean contacts", "mean_contacts", "{:.1f}"),
    ("reset ms", "reset_ms", "{:.2f}"),
    ("first load s", "first_load_s", "{:.2f}"),
)


def _wire(text: str) -> str | dict[str, Any]:
    return json.loads(text) if text.lstrip().startswith("{") else text


def main() -> None:
    """Runs the benchmark and prints the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--domain", default="simplified_phantom")
    parser.add_argument("--task", default="task_a")
    parser.add_argument("--all", action="store_true",
                        help="every task of suite.ALL_TASKS, one table row each")
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--cpu", type=int, default=None, help="pin to this core")
    parser.add_argument("--repeats", type=int, default=3,
                        help="alternate the loops this often and keep each one's fastest run")
    parser.add_argument("--json", action="store_true", help="print one JSON line per task")
    parser.add_argument("--fidelity", choices=fidelities.names(), default=None,
                        help="the wire's numerical settings (default: each domain's)")
    parser.add_argument("--motion", action="store_true",
                        help="a beating and breathing heart (coronary trees and vessel "
                             "folders; with --all, the tasks that take it)")
    parser.add_argument(
        "--wire", type=_wire, default=None,
        help="the wire of every task instead of its default: a preset name, or a JSON "
             'mapping such as \'{"preset": "paper", "chain_bodies": 6}\'')
    args = parser.parse_args()
    if args.cpu is not None:
        os.sched_setaffinity(0, {args.cpu})
    extra = {key: value for key, value in (("wire", args.wire), ("fidelity", args.fidelity),
                                           ("motion", args.motion or None))
             if value is not None}
    if not args.all:
        result = measure(args.domain, args.task, args.steps, args.repeats, extra)
        if args.json:
            print(strict_json.dumps(result))
            return
        for key, value in result.items():
            print(f"{key:30s} {value:.3f}" if isinstance(value, float) else f"{key:30s} {value}")
        return
    if not args.json:
        print("| " + " | ".join(heading for heading, _, _ in _TABLE) + " |")
        print("|" + "---|" * len(_TABLE))
    for domain, task in suite.ALL_TASKS:
        if args.motion and registry.TAG_PHANTOM in registry.find(domain, task).tags:
            continue  # a phantom lies on a table
        result = measure(domain, task, args.steps, args.repeats, extra)
        if args.json:
            print(strict_json.dumps(result), flush=True)
        else:
            cells = (fmt.format(result[key]) for _, key, fmt in _TABLE)
            print("| " + " | ".join(cells) + " |", flush=True)
    if not args.json:
        print(f"\n{args.steps} random env steps per task, fastest of {args.repeats} runs, "
              f"fidelity {args.fidelity or 'each domain default'}; "
              f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
