"""Reachability: how often the scripted centerline expert reaches each phantom target.

The expert (``sim4endor.tasks.expert.CenterlineExpert``) rolls the J-tip towards the path's
next turn and pushes when aligned. A target it never reaches is out of the wire's reach in that
geometry (the vascular phantom's target B was, before it was regenerated); a learnt policy's
success rate is only meaningful on targets the expert reaches. Prints, per task, successes out
of the seeded episodes, how the others ended, and the mean procedure time of the successes.

Usage:
    python experiments/benchmarks/expert_reachability.py [--episodes 8] [--json]
"""

from __future__ import annotations

import argparse
import collections
import json

from sim4endor import suite
from sim4endor.tasks.expert import CenterlineExpert, run_expert

TASKS = (("simplified_phantom", "task_a"), ("simplified_phantom", "task_b"),
         ("vascular_phantom", "task_a"), ("vascular_phantom", "task_b"))


def reachability(domain: str, task: str, episodes: int) -> dict[str, object]:
    """Runs ``episodes`` seeded expert episodes (seeds 0..episodes-1) and counts outcomes."""
    expert = CenterlineExpert()
    outcomes: collections.Counter[str] = collections.Counter()
    times = []
    for seed in range(episodes):
        env = suite.load(domain, task, {"random": seed})
        info = run_expert(env, expert)
        if info["is_success"]:
            outcomes["success"] += 1
            times.append(env.physics.time())
        else:
            outcomes[str(info["failure"] or "timeout")] += 1
        env.close()
    return {
        "domain": domain, "task": task, "episodes": episodes,
        "successes": outcomes.pop("success", 0), "other_outcomes": dict(outcomes),
        "mean_time_s": sum(times) / len(times) if times else None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=8, help="seeded episodes per task")
    parser.add_argument("--json", action="store_true", help="one JSON line per task")
    args = parser.parse_args()
    for domain, task in TASKS:
        row = reachability(domain, task, args.episodes)
        if args.json:
            print(json.dumps(row), flush=True)
            continue
        others = ", ".join(f"{k} {v}" for k, v in row["other_outcomes"].items()) or "none"
        time = "--" if row["mean_time_s"] is None else f"{row['mean_time_s']:.2f} s"
        print(f"{domain}/{task}: {row['successes']}/{row['episodes']} reached "
              f"(others: {others}); mean procedure time {time}", flush=True)


if __name__ == "__main__":
    main()
