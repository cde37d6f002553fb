"""``sim4endor evaluate RUN_DIR [--trials 10] [--json]``: the paper's metrics of a trained run."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from sim4endor.cli import args as arg_types


def register(subparsers: argparse._SubParsersAction) -> None:
    """Adds the ``evaluate`` subcommand."""
    parser = subparsers.add_parser(
        "evaluate",
        help="evaluate a trained run's deterministic policy",
        description=(
            "Run the latest policy of RUN_DIR for --trials episodes and print success_rate, "
            "mean_completion_time_s (simulated procedure time of successful episodes), "
            "mean_path_length_m, spl and max_wall_force_n, on the run's task (its evaluation "
            "split), and write RUN_DIR/evaluation.json; with task arguments (another vessel, "
            "wire or tree pool) only print them."
        ),
    )
    parser.add_argument("run_dir", type=Path, help="folder written by `sim4endor train --out`")
    parser.add_argument("--trials", type=arg_types.positive_int, default=10,
                        help="episodes (default: 10)")
    parser.add_argument("--seed", type=arg_types.seed, help="evaluation seed (default: the run's)")
    parser.add_argument("--domain", help="evaluate on another domain (default: the run's)")
    parser.add_argument("--task", help="task of --domain")
    arg_types.add_task_arguments(parser)
    parser.add_argument("--json", action="store_true", help="print one JSON line")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Evaluates and prints the metrics."""
    import torch

    from sim4endor.rl.runs import evaluate_run

    torch.set_num_threads(1)  # small networks: one thread is fastest and leaves cores free
    other_task = arg_types.task_arguments(args)
    if args.domain or args.task:
        other_task.update({k: v for k, v in (("domain", args.domain), ("task", args.task)) if v})
    metrics = evaluate_run(args.run_dir, trials=args.trials, seed=args.seed,
                           task_arguments=other_task, progress=not args.no_progress)
    if args.json:
        print(json.dumps(metrics))  # noqa: T201
    else:
        width = max(len(key) for key in metrics)
        for key, value in metrics.items():
            print(f"{key:<{width}}  {'n/a' if value is None else value}")  # noqa: T201
    return 0
