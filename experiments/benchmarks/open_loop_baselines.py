"""Open-loop baselines and the scripted expert on the paper's tasks and their redirect variants.

What does a task demand? Per task (``registry.BENCHMARKING`` and ``registry.REDIRECT``), this
evaluates, as a trained policy is evaluated (``sim4endor.rl.baselines``):

* ``push``: the constant push ``[1, 0]``;
* ``best constant``: the best constant action of ``baselines.CONSTANT_GRID``, chosen per task
  on ``--select-episodes`` episodes of seed ``SELECTION_SEED`` and reported on the others;
* ``random``: uniform random actions (seeded);
* ``expert``: the privileged scripted expert (the reachability reference).

Reported episodes use seed ``REPORT_SEED`` (the seed-0 training run's evaluation seed). Prints
a table (task × row: successes, mean completion time); ``--json PATH`` also writes every row's
metrics, the file the bench configs' ``baselines`` key points to.

Usage:
    python experiments/benchmarks/open_loop_baselines.py [--episodes 20] [--select-episodes 10]
        [--workers 2] [--json experiments/bench/open_loop_baselines.json]
"""

from __future__ import annotations

import argparse
import concurrent.futures
import multiprocessing
import time
from pathlib import Path
from typing import Any

from sim4endor import _json as strict_json
from sim4endor import registry
from sim4endor._atomic import atomic_write_text
from sim4endor.rl import baselines as bl


def task_rows(domain: str, task: str, episodes: int, select_episodes: int) -> list[dict[str, Any]]:
    """The four rows of one task (push, best constant, random, expert)."""
    chosen, _ = bl.best_constant(domain, task, episodes=select_episodes)
    rows = []
    for role, baseline in (("push", bl.ConstantAction(1.0, 0.0)), ("best constant", chosen),
                           ("random", bl.RandomActions(seed=0)), ("expert", bl.ScriptedExpert())):
        metrics = bl.evaluate_baseline(domain, task, baseline, episodes=episodes)
        rows.append({"role": role, "baseline": baseline.label, "domain": domain, "task": task,
                     "seed": bl.REPORT_SEED, "metrics": metrics})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=20, help="reported episodes per row")
    parser.add_argument("--select-episodes", type=int, default=10,
                        help="episodes per grid action when choosing the best constant")
    parser.add_argument("--workers", type=int, default=2, help="tasks evaluated in parallel")
    parser.add_argument("--tasks", nargs="*", metavar="DOMAIN/TASK",
                        help="default: the paper's four tasks and their redirect variants")
    parser.add_argument("--json", type=Path, help="also write every row's metrics here")
    args = parser.parse_args()
    tasks = ([tuple(t.split("/")) for t in args.tasks] if args.tasks
             else [*registry.BENCHMARKING, *registry.REDIRECT])
    start = time.monotonic()
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(args.workers, mp_context=context) as pool:
        futures = [pool.submit(task_rows, d, t, args.episodes, args.select_episodes)
                   for d, t in tasks]
        rows = [row for future in futures for row in future.result()]
    print(f"| task | {' | '.join(r['role'] for r in rows[:4])} |")
    print("|---" * 5 + "|")
    for i in range(0, len(rows), 4):
        cells = [_cell(r) for r in rows[i:i + 4]]
        print(f"| {rows[i]['domain']} {rows[i]['task']} | {' | '.join(cells)} |")
    print(f"{len(tasks)} tasks in {(time.monotonic() - start) / 60:.1f} min; best constant "
          f"chosen on {args.select_episodes} episodes of seed {bl.SELECTION_SEED}")
    if args.json:
        record = {"report_seed": bl.REPORT_SEED, "episodes": args.episodes,
                  "selection_seed": bl.SELECTION_SEED, "select_episodes": args.select_episodes,
                  "grid": [list(a) for a in bl.CONSTANT_GRID], "rows": rows}
        atomic_write_text(args.json, strict_json.dumps(record, indent=1) + "\n")


def _cell(row: dict[str, Any]) -> str:
    m = row["metrics"]
    successes = round(m["success_rate"] * m["trials"])
    time_s = m["mean_completion_time_s"]
    text = f"{successes}/{m['trials']}" + ("" if time_s is None else f", {time_s:.2f} s")
    return f"{text} ({row['baseline']})" if row["role"] == "best constant" else text


if __name__ == "__main__":
    main()
