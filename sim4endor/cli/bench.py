"""``sim4endor bench CONFIG``: train a grid of runs and generate Table I and learning curves."""

from __future__ import annotations

import argparse
from pathlib import Path

from sim4endor.cli import args as arg_types


def register(subparsers: argparse._SubParsersAction) -> None:
    """Adds the ``bench`` subcommand."""
    parser = subparsers.add_parser(
        "bench",
        help="run a benchmark grid (algorithm × reward × task × seed) and write its report",
        description=(
            "Train every grid point of CONFIG (YAML: rows, tasks, seeds, overrides, workers) "
            "under OUT/runs/, then write OUT/table.md, OUT/figures/ and OUT/results.md. "
            "Rerunning skips finished runs and resumes interrupted ones."
        ),
    )
    parser.add_argument("config", type=Path, help="bench YAML, e.g. experiments/bench/table1.yaml")
    parser.add_argument("--out", type=Path, default=Path("runs/bench"), help="output folder")
    parser.add_argument("--backend", choices=("local", "ray"), default="local")
    parser.add_argument("--workers", type=arg_types.positive_int,
                        help="parallel runs (local backend)")
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="SECTION.FIELD=VALUE",
        help="override a field of every run's config after CONFIG's overrides, e.g. "
             "--set env.wire=workhorse (repeatable)",
    )
    parser.add_argument(
        "--report-only", action="store_true", help="only regenerate the table and figures"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Runs the grid (or just the report) and prints the path of results.md."""
    import dataclasses

    from sim4endor.rl.bench import load_bench_config, run_bench, write_report

    bench = load_bench_config(args.config)
    if args.workers is not None:
        bench = dataclasses.replace(bench, workers=args.workers)
    if args.overrides:
        bench = dataclasses.replace(bench, overrides=(*bench.overrides, *args.overrides))
    if args.report_only:
        path = write_report(bench, args.out, None, args.backend)
    else:
        path = run_bench(bench, args.out, backend=args.backend)
    print(path)  # noqa: T201
    return 0
