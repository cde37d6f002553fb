"""``sim4endor table RUN_DIR ...``: the paper's Table I (markdown) from training runs."""

from __future__ import annotations

import argparse
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    """Adds the ``table`` subcommand."""
    parser = subparsers.add_parser(
        "table",
        help="print Table I (markdown) from evaluated runs",
        description=(
            "Pool the final evaluations (evaluation.json) of run folders, or of every run found "
            "under the given folders, into Table I: success rate and mean completion time per "
            "algorithm/reward row and task."
        ),
    )
    parser.add_argument("paths", type=Path, nargs="+", help="run folders or folders of runs")
    parser.add_argument("--out", type=Path, help="also write the table to this file")
    parser.add_argument(
        "--reference",
        type=Path,
        metavar="BENCH_YAML",
        help="print the published cells of this bench config's `reference` under the measured "
        "rows, and its `baselines` rows under the table (experiments/bench/table1.yaml holds "
        "the paper's Table I and the open-loop baselines)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Prints (and optionally writes) the table."""
    from sim4endor._atomic import atomic_write_text
    from sim4endor.errors import Sim4EndoRError
    from sim4endor.rl.bench import BenchConfigError, load_bench_config
    from sim4endor.rl.table import collect_results, find_runs, markdown_table

    reference = baselines = None
    if args.reference:
        bench = load_bench_config(args.reference)
        reference, baselines = bench.reference, bench.baselines
        if reference is None and baselines is None:
            raise BenchConfigError(
                f"{args.reference} has neither a 'reference' nor a 'baselines' section."
            )
    results = collect_results(find_runs(args.paths))
    if not results:
        raise Sim4EndoRError(
            f"No evaluated runs under {[str(p) for p in args.paths]}: train with `sim4endor "
            "train` (or evaluate with `sim4endor evaluate RUN_DIR`) first."
        )
    table = markdown_table(results, reference, baselines)
    if args.out:
        atomic_write_text(args.out, table)
    print(table, end="")  # noqa: T201
    return 0
