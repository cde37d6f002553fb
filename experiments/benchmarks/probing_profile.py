"""Where the probing expert's time goes: its look-ahead against the episode itself.

    python experiments/benchmarks/probing_profile.py --vessel DIR [--wire PRESET]
        [--tip L,A] [--targets T1 T2 ...] [--max-steps 800] [--json]

Runs what ``sim4endor evaluate probing-expert --vessel DIR`` runs (one episode per target:
the same environments, seed and policy) and splits each episode's process CPU time into

* ``probe``: :meth:`~sim4endor.tasks.expert.ProbingExpert.plan`, every aim simulated ahead on
  a copy of the physics where the expert is stuck;
* ``screen``: the other calls of :func:`~sim4endor.tasks.expert.lookahead`, each action the
  episode takes outside a plan simulated one control step ahead first;
* ``episode``: the rest, the episode itself (its physics, the environment, the steering).

Per part it counts the control and physics steps simulated and their physics CPU time; and
the copies of the physics with their CPU time, and a digest of the episode's actions, so
that two versions of the code can be shown to decide alike. The environments are built
before timing. docs/performance.md ("The probing expert: where the time goes") has figures.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import hashlib
import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any
from unittest import mock

import numpy as np
import torch

from sim4endor import _json as strict_json
from sim4endor import vessels
from sim4endor.physics import GuidewirePhysics
from sim4endor.rl import baselines, generalisation
from sim4endor.rl.config import EnvConfig
from sim4endor.rl.runs import evaluation_env
from sim4endor.tasks import expert as expert_module

#: The parts an episode's time is split into.
PARTS = ("probe", "screen", "episode")


def _per_part() -> dict[str, float]:
    return dict.fromkeys(PARTS, 0.0)


@dataclass
class Counts:
    """What one episode spent, per part of :data:`PARTS` (CPU seconds, steps)."""

    cpu_s: dict[str, float] = field(default_factory=_per_part)
    physics_cpu_s: dict[str, float] = field(default_factory=_per_part)
    control_steps: dict[str, float] = field(default_factory=_per_part)
    physics_steps: dict[str, float] = field(default_factory=_per_part)
    probes: int = 0
    copies: int = 0
    copy_cpu_s: float = 0.0
    actions: list[list[float]] = field(default_factory=list)
    part: str = "episode"  # the part running now


@contextlib.contextmanager
def counting(counts: Counts) -> Iterator[None]:
    """Counts into ``counts`` while the probing expert runs, by wrapping its planning, its
    look-ahead and its own calls, and the physics' step and copy."""
    step, copy = GuidewirePhysics.step, GuidewirePhysics.copy
    plan, act = expert_module.ProbingExpert.plan, expert_module.ProbingExpert.__call__
    lookahead = expert_module.lookahead

    def charged(part: str, inner: Callable[..., Any]) -> Callable[..., Any]:
        def run(*args: Any) -> Any:
            outer, counts.part = counts.part, part
            start = time.process_time()
            try:
                return inner(*args)
            finally:
                counts.cpu_s[part] += time.process_time() - start
                counts.part = outer
        return run

    def physics_step(physics: GuidewirePhysics, nstep: int = 1) -> None:
        start = time.process_time()
        step(physics, nstep)
        counts.physics_cpu_s[counts.part] += time.process_time() - start
        counts.physics_steps[counts.part] += nstep
        counts.control_steps[counts.part] += 1  # every caller steps one control step a call

    def physics_copy(physics: GuidewirePhysics, share_model: bool = False) -> GuidewirePhysics:
        start = time.process_time()
        copied = copy(physics, share_model)
        counts.copy_cpu_s += time.process_time() - start
        counts.copies += 1
        return copied

    def probe(*args: Any) -> Any:
        counts.probes += 1
        return charged("probe", plan)(*args)

    def screen(*args: Any) -> Any:
        return (lookahead if counts.part == "probe" else charged("screen", lookahead))(*args)

    def recorded(*args: Any) -> Any:
        action = act(*args)  # the episode's own calls only: a plan's aims are other experts
        counts.actions.append([float(a) for a in action])
        return action

    with (mock.patch.object(GuidewirePhysics, "step", physics_step),
          mock.patch.object(GuidewirePhysics, "copy", physics_copy),
          mock.patch.object(expert_module.ProbingExpert, "plan", probe),
          mock.patch.object(expert_module.ProbingExpert, "__call__", recorded),
          mock.patch.object(expert_module, "lookahead", screen)):
        yield


def profile_target(case: generalisation.Case, config: generalisation.SuiteConfig,
                   envs: generalisation.CaseEnvironments) -> dict[str, Any]:
    """One episode of the probing expert on ``case``, its environment built untimed."""
    envs[case]  # built here, so that its build is not timed
    counts = Counts()
    expert = baselines.ScriptedExpert(probing=True)
    with counting(counts):
        start = time.process_time()
        runs = generalisation.run_cases([case], lambda env: baselines.policy(expert, env),
                                        config, envs)
        total = time.process_time() - start
    counts.cpu_s["episode"] = total - counts.cpu_s["probe"] - counts.cpu_s["screen"]
    episode = runs[case.label][0]
    return {
        "target": case.label,
        "outcome": "success" if episode.success else episode.failure or "not reached",
        "simulated_s": episode.duration_s, "cpu_s": total, "probes": counts.probes,
        "cpu_s_by_part": counts.cpu_s, "physics_cpu_s_by_part": counts.physics_cpu_s,
        "control_steps_by_part": counts.control_steps,
        "physics_steps_by_part": counts.physics_steps,
        "copies": counts.copies, "copy_cpu_s": counts.copy_cpu_s,
        "actions_sha1": hashlib.sha1(np.array(counts.actions).tobytes()).hexdigest(),
    }


def profile_vessel(vessel: str, targets: Sequence[str] | None = None,
                   config: generalisation.SuiteConfig | None = None) -> list[dict[str, Any]]:
    """:func:`profile_target` on every target of ``vessel`` (or ``targets``), the
    environments as ``evaluate probing-expert --vessel`` builds them from ``config``."""
    config = config or generalisation.SuiteConfig(trials=1)
    loaded = vessels.load(vessel)
    base = evaluation_env(EnvConfig(), {"domain": "vessel", "task": "navigate",
                                        "vessel": str(loaded.root), "wire": config.wire,
                                        "tip": config.tip, "fidelity": config.fidelity})
    envs = generalisation.CaseEnvironments()
    try:
        return [profile_target(generalisation.Case(
            "vessel", target, dataclasses.replace(base, target=target)), config, envs)
            for target in targets or sorted(loaded.targets)]
    finally:
        envs.close()


def total(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """The rows' sums, labelled ``all``."""
    summed: dict[str, Any] = {"target": "all", "outcome": f"{len(rows)} episodes"}
    for key, value in rows[0].items():
        if isinstance(value, dict):
            summed[key] = {part: sum(row[key][part] for row in rows) for part in value}
        elif isinstance(value, int | float) and not isinstance(value, bool):
            summed[key] = sum(row[key] for row in rows)
    return summed


def describe(row: dict[str, Any]) -> str:
    """One table row: steps, probes, CPU and its split, cost per physics step and copy."""
    cpu, parts = row["cpu_s"], row["cpu_s_by_part"]
    physics = sum(row["physics_cpu_s_by_part"].values())
    physics_steps = sum(row["physics_steps_by_part"].values())
    steps = row["control_steps_by_part"]
    return (f"| {row['target']} | {row['outcome']} | {row['simulated_s']:.1f} | "
            f"{steps['episode']:.0f} | {row['probes']} | {steps['probe']:.0f} | "
            f"{steps['screen']:.0f} | {cpu:.1f} | "
            + " / ".join(f"{100 * parts[p] / cpu:.0f}" for p in PARTS)
            + f" | {100 * physics / cpu:.0f} | {1e6 * physics / physics_steps:.0f} | "
            f"{1e3 * row['copy_cpu_s'] / max(row['copies'], 1):.1f} | "
            f"{row.get('actions_sha1', '')[:8]} |")


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--vessel", required=True, help="vessel folder or name")
    parser.add_argument("--wire", help="wire preset (default: the vessel domain's)")
    parser.add_argument("--tip", help="tip shape, e.g. 2,60,7,40 (needs --wire)")
    parser.add_argument("--targets", nargs="+", help="only these targets")
    parser.add_argument("--max-steps", type=int, default=800, help="step cap per episode")
    parser.add_argument("--json", action="store_true", help="one JSON line per target")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)  # as `sim4endor evaluate` runs
    config = generalisation.SuiteConfig(trials=1, wire=args.wire, tip=args.tip,
                                        max_steps=args.max_steps)
    load = os.getloadavg()
    rows = profile_vessel(args.vessel, args.targets, config)
    if args.json:
        for row in rows:
            print(strict_json.dumps(row))
        return
    print(f"load average {load[0]:.2f} at the start, {os.getloadavg()[0]:.2f} at the end")
    print("| target | outcome | simulated s | control steps | probes | probe steps | "
          "screen steps | CPU s | probe / screen / episode % | physics % | µs per "
          "physics step | ms per copy | actions |\n|" + "---|" * 13)
    for row in [*rows, total(rows)]:
        print(describe(row))


if __name__ == "__main__":
    main()
