"""``sim4endor evaluate RUN_DIR [--trials 10] [--json]``: the paper's metrics of a trained run."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING

from sim4endor import _json as strict_json
from sim4endor import assets
from sim4endor.cli import args as arg_types
from sim4endor.errors import Sim4EndoRError
from sim4endor.rl.metrics import describe

if TYPE_CHECKING:  # imported by the commands that run: it loads torch
    from sim4endor.rl.generalisation import SuiteConfig


def _run_or_policy(spec: str) -> Path | str:
    return spec if spec in arg_types.REFERENCE_POLICIES else assets.run_or_policy(spec)


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
    parser.add_argument("run_dir", type=_run_or_policy, metavar="RUN_OR_POLICY",
                        help="folder written by `sim4endor train --out`, a shipped "
                             "pretrained policy's name: "
                             f"{', '.join(assets.policy_names()) or 'none'}; or, with "
                             "--vessel, a reference on every target: a privileged scripted "
                             "expert, 'expert' (reactive) or 'probing-expert' (simulates aims "
                             "ahead where it is stuck: is every target within the wire's "
                             "reach?), or an open-loop one, 'insert' (the constant push [1, "
                             "0]) or 'random' (uniform random actions)")
    parser.add_argument("--trials", type=arg_types.positive_int,
                        help="episodes (default: 10 on the run's task or one --target; per "
                             "case with --suite, per target with --vessel alone: 1)")
    parser.add_argument("--seed", type=arg_types.seed, help="evaluation seed (default: the run's)")
    parser.add_argument("--domain", help="evaluate on another domain (default: the run's)")
    parser.add_argument("--task", help="task of --domain")
    arg_types.add_task_arguments(parser)
    suite = parser.add_argument_group(
        "generalisation suite",
        "--suite generalisation runs the policy zero-shot on held-out generated coronary trees "
        "(every distal target), as many wide ones (tortuous, stenosed, narrower), the "
        "evaluation-only implicit family, the --real vessel folders, both phantoms' targets "
        "and the stEVE anatomy, each a group of its own, beside the scripted expert and "
        "open-loop baselines (docs/training.md); with --motion each group but the phantoms "
        "runs again on a beating and breathing heart (GROUP moving), with --randomise every "
        "case draws the domain randomisation")
    suite.add_argument("--suite", choices=("generalisation",),
                       help="run the named evaluation suite instead of the run's task")
    suite.add_argument("--trees", type=arg_types.positive_int, default=20,
                       help="held-out coronary trees (default: 20)")
    suite.add_argument("--first-seed", type=arg_types.seed, default=1000,
                       help="seed of the first held-out tree (default: 1000)")
    suite.add_argument("--wide-trees", type=arg_types.non_negative_int, default=10,
                       help="held-out wide coronary trees, the same seeds (default: 10)")
    suite.add_argument("--implicit-trees", type=arg_types.non_negative_int, default=6,
                       help="trees of the evaluation-only implicit family, seeds 0 on, each "
                            "built once into the cache (default: 6)")
    suite.add_argument("--real", type=Path, action="append", default=[], metavar="DIR",
                       help="a vessel folder of a real patient's mesh (`sim4endor vessel "
                            "build` output); repeat for more")
    suite.add_argument("--steve", type=Path, default=None, metavar="DIR",
                       help="stEVE anatomy folder (default: $SIM4ENDOR_SHARED/data/"
                            "steve_bench_dualdevicenav, or ../shared/...; skipped if absent)")
    suite.add_argument("--max-steps", type=arg_types.positive_int, default=800,
                       help="step cap per episode (default: 800, the coronary domain's 40 s)")
    suite.add_argument("--no-baselines", action="store_true",
                       help="only the policy, no reference rows")
    suite.add_argument("--beside", type=assets.run_or_policy, action="append", default=[],
                       metavar="RUN_OR_POLICY",
                       help="also run this policy on the same cases, a row after the "
                            "evaluated one's (e.g. a student's teacher: --beside generalist); "
                            "repeat for more")
    parser.add_argument("--json", action="store_true", help="print one JSON line")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Evaluates and prints the metrics."""
    import torch

    from sim4endor.rl.runs import evaluate_run

    torch.set_num_threads(1)  # small networks: one thread is fastest and leaves cores free
    if args.run_dir in arg_types.REFERENCE_POLICIES:
        if args.vessel is None or args.target is not None or args.suite:
            raise Sim4EndoRError(
                f"RUN_OR_POLICY '{args.run_dir}' runs on every target of a vessel: give "
                "--vessel NAME_OR_DIR, without --target or --suite (the suite has the "
                "reference rows).")
        return _run_vessel(args)
    if args.suite:
        return _run_suite(args)
    if args.vessel is not None and args.target is None:
        return _run_vessel(args)
    other_task = arg_types.task_arguments(args)
    if args.domain or args.task:
        other_task.update({k: v for k, v in (("domain", args.domain), ("task", args.task)) if v})
    if args.vessel is not None and not (args.domain or args.task):
        other_task.update(domain="vessel", task="navigate")  # a vessel folder's own domain
    metrics = evaluate_run(args.run_dir, trials=args.trials or 10, seed=args.seed,
                           task_arguments=other_task, progress=not args.no_progress,
                           record=args.run_dir.parent != assets.policies_dir())
    if args.json:
        print(strict_json.dumps(metrics))  # noqa: T201
    else:
        width = max(len(key) for key in metrics)
        for key, value in metrics.items():
            print(f"{key:<{width}}  {_shown(value)}")  # noqa: T201
    return 0


def _shown(value: object) -> str:
    """A metric as the table prints it: floats to 4 significant digits (a sum of episode
    times read 3.7000000000000006), None as n/a; the JSON output keeps every digit."""
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _run_suite(args: argparse.Namespace) -> int:
    """Runs the generalisation suite and prints its table (or one JSON line)."""
    from sim4endor.rl import generalisation

    config = _with_flags(generalisation.SuiteConfig(
        trees=args.trees, first_seed=args.first_seed, trials=args.trials or 1,
        max_steps=args.max_steps, wide_trees=args.wide_trees,
        implicit_trees=args.implicit_trees, real=tuple(args.real)), args)
    if args.steve is not None:
        config = dataclasses.replace(config, steve_dir=args.steve)
    result = generalisation.evaluate_suite(
        args.run_dir, config, with_baselines=not args.no_baselines, beside=args.beside,
        progress=not args.no_progress)
    if args.json:
        print(strict_json.dumps(result))  # noqa: T201
    else:
        print(generalisation.markdown(result))  # noqa: T201
    return 0


def _run_vessel(args: argparse.Namespace) -> int:
    """Every target of ``--vessel`` (``--trials`` each): the metrics over all of them and per
    target, as a table or one JSON line."""
    from sim4endor.rl import generalisation
    from sim4endor.rl.baselines import Baseline, ConstantAction, RandomActions, ScriptedExpert

    config = _with_flags(generalisation.SuiteConfig(trials=args.trials or 1), args)
    references: dict[str, Baseline] = {arg_types.INSERT: ConstantAction(1.0, 0.0),
                  arg_types.RANDOM: RandomActions(config.seed),
                  arg_types.EXPERT: ScriptedExpert(),
                  arg_types.PROBING_EXPERT: ScriptedExpert(probing=True)}
    policy: Path | Baseline = references.get(args.run_dir) or args.run_dir
    metrics = generalisation.evaluate_vessel(policy, args.vessel, config,
                                             progress=not args.no_progress)
    if args.json:
        print(strict_json.dumps(metrics))  # noqa: T201
        return 0
    for target, row in metrics["targets"].items():
        print(f"{target:<12}  {describe(row)}")  # noqa: T201
    print(f"{'all':<12}  {describe(metrics)}")  # noqa: T201
    return 0


def _with_flags(config: SuiteConfig, args: argparse.Namespace) -> SuiteConfig:
    """``config`` with the ``--wire``, ``--tip``, ``--fidelity``, ``--motion``,
    ``--randomise`` and ``--seed`` given on the command line."""
    given = {name: getattr(args, name)
             for name in ("wire", "tip", "fidelity", "motion", "randomise")
             if getattr(args, name)}
    if args.seed is not None:
        given["seed"] = args.seed
    return dataclasses.replace(config, **given)
