"""``sim4endor train ALGO --domain D --task T ... --out RUN_DIR``: train one agent;
``sim4endor train generalist --out DIR``: a shipped policy's recipe."""

from __future__ import annotations

import argparse
from pathlib import Path

from sim4endor import _json as strict_json
from sim4endor.assets import recipe_names
from sim4endor.cli import args as arg_types
from sim4endor.rl.config import ALGORITHMS

#: Flags of ``train ALGO`` that a recipe refuses: it sets these itself.
_ALGORITHM_FLAGS = ("domain", "task", "reward", "frames", "device", "config")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Adds the ``train`` subcommand."""
    parser = subparsers.add_parser(
        "train",
        help="train DDPG, SAC or PPO on a navigation task, or reproduce a shipped policy "
             "(resumes an interrupted run)",
        description=(
            "Train an agent with the paper's hyper-parameters (overridable). Writes config.yaml, "
            "resumable checkpoints, CSV logs and evaluations under --out; rerunning the same "
            "command resumes from the last checkpoint. With a shipped policy's name (e.g. "
            "generalist), runs its recipe (its recipe.yaml; --seed, --envs, --set FIELD=VALUE "
            "override it) and writes the policy to --out/policy."
        ),
    )
    parser.add_argument("algorithm", choices=(*ALGORITHMS, *recipe_names()),
                        help="learning algorithm, or a shipped policy whose recipe to run")
    parser.add_argument("--domain", help="suite domain (default: simplified_phantom)")
    parser.add_argument("--task", help="task of the domain (default: task_a)")
    parser.add_argument("--reward", choices=("manifold", "euclidean"), help="progress distance")
    parser.add_argument("--frames", type=arg_types.positive_int,
                        help="total environment steps (default: 100000)")
    parser.add_argument("--seed", type=arg_types.seed, help="random seed (default: 0)")
    parser.add_argument("--envs", type=arg_types.positive_int,
                        help="parallel environments (default: 1)")
    parser.add_argument(
        "--backend", choices=("local", "ray"),
        help="where the --envs environments step: worker processes here (local, the default) "
             "or Ray actors on a cluster, learning in this process (ray)",
    )
    parser.add_argument(
        "--ray-address", metavar="HOST:PORT",
        help="--backend ray: the cluster's head node, as `ray start --head` prints it "
             "(default: RAY_ADDRESS, else Ray on this machine)",
    )
    parser.add_argument("--device", choices=("auto", "cpu", "cuda"),
                        help="where the learner runs (default: auto, a CUDA GPU if torch sees "
                        "one); the environments always run on the CPU")
    arg_types.add_task_arguments(parser, evaluation_split=True)
    parser.add_argument("--config", type=Path, help="YAML config file (e.g. experiments/sac/)")
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="SECTION.FIELD=VALUE",
        help="override any config field, e.g. --set optim.lr=3e-4 (repeatable)",
    )
    parser.add_argument("--out", type=Path, required=True, help="run folder to write")
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Builds the config from defaults, file, flags and overrides; trains; prints the result."""
    if args.algorithm not in ALGORITHMS:
        return run_recipe(args)
    from sim4endor.rl.config import ConfigError, apply_overrides, default_config, load_config
    from sim4endor.rl.trainer import train

    flags = {
        "env.domain": args.domain,
        "env.task": args.task,
        "env.reward": args.reward,
        "collector.total_frames": args.frames,
        "seed": args.seed,
        "env.num_envs": args.envs,
        "collector.backend": args.backend,
        "device": args.device,
    }
    overrides = [f"{key}={value}" for key, value in flags.items() if value is not None]
    overrides += arg_types.env_overrides(arg_types.task_arguments(args))
    overrides += args.overrides
    if args.config:
        config = load_config(args.config, overrides, algorithm=args.algorithm)
    else:
        config = apply_overrides(default_config(args.algorithm), overrides)
    if config.algorithm != args.algorithm:
        source = args.config or "--set algorithm=..."
        raise ConfigError(
            f"{source} configures {config.algorithm}, not {args.algorithm}: run `sim4endor "
            f"train {config.algorithm} ...` or pass a {args.algorithm} configuration."
        )
    metrics = train(config, args.out, progress=not args.no_progress, ray_address=args.ray_address)
    print(strict_json.dumps(metrics))  # noqa: T201
    return 0


def run_recipe(args: argparse.Namespace) -> int:
    """Runs the recipe of the shipped policy ``args.algorithm``; prints the run's summary."""
    from sim4endor.rl.config import ConfigError
    from sim4endor.rl.recipe import RecipeRun, load_recipe

    # These flags default to None: one that is set was given.
    given = [name for name in _ALGORITHM_FLAGS if getattr(args, name) is not None]
    extra = sorted(f"--{name.replace('_', '-')}"
                   for name in (*given, *arg_types.task_arguments(args)))
    if extra:
        raise ConfigError(
            f"{' '.join(extra)}: the {args.algorithm} recipe sets these itself; it takes "
            "--seed, --envs, --backend, --ray-address, --set FIELD=VALUE, --out and "
            "--no-progress.")
    overrides = [f"{key}={value}" for key, value in (("seed", args.seed), ("envs", args.envs))
                 if value is not None]
    recipe = load_recipe(args.algorithm, [*overrides, *args.overrides])
    backend = args.backend or "local"
    if args.ray_address and backend != "ray":
        raise ConfigError(f"--ray-address {args.ray_address}: episodes are collected by local "
                          "worker processes; add --backend ray or drop the address.")
    summary = RecipeRun(recipe, args.out, progress=not args.no_progress, backend=backend,
                        ray_address=args.ray_address).run()
    print(strict_json.dumps(summary))  # noqa: T201
    return 0


def experiment_script(config_path: Path) -> None:
    """Entry point of the ``experiments/<algorithm>/train.py`` scripts.

    Parses ``--out RUN_DIR`` and ``section.field=value`` overrides, trains the YAML config
    ``config_path`` and prints the final metrics as one JSON line.
    """
    algorithm = config_path.parent.name
    parser = argparse.ArgumentParser(
        description=f"Train {algorithm.upper()} with {config_path} "
        "(overrides: section.field=value).",
    )
    parser.add_argument("--out", type=Path, default=Path("runs") / algorithm, help="run folder")
    parser.add_argument("overrides", nargs="*", help="section.field=value overrides")
    args = parser.parse_args()
    from sim4endor.rl.trainer import train_from_file

    print(strict_json.dumps(train_from_file(config_path, args.out, tuple(args.overrides))))  # noqa: T201
