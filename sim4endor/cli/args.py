"""Argument types shared by the subcommands: argparse rejects a bad value with its name.

The plain number types are :mod:`sim4endor._argtypes`' (the vessel library's own command takes
them too), re-exported here so that every subcommand finds its types in one place.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from sim4endor._argtypes import non_negative_int as non_negative_int
from sim4endor._argtypes import positive_float as positive_float
from sim4endor._argtypes import positive_int as positive_int
from sim4endor._argtypes import seed as seed
from sim4endor.models.fidelity import FIDELITIES
from sim4endor.observations import OBSERVATION_SETS
from sim4endor.rl.config import EnvConfig

#: The policy names of the privileged scripted experts (``sim4endor.tasks.expert``), taken by
#: ``render``, ``view`` and ``evaluate``: the reactive one, and the probing one, the
#: reachability check of an anatomy.
EXPERT, PROBING_EXPERT = "expert", "probing-expert"
EXPERT_POLICIES = (EXPERT, PROBING_EXPERT)
#: The open-loop reference policies, by the names ``render``, ``view`` and ``evaluate`` take:
#: the constant push ``[1, 0]`` and uniform random actions (seeded by ``--seed``).
INSERT, RANDOM = "insert", "random"
REFERENCE_POLICIES = (INSERT, RANDOM, *EXPERT_POLICIES)


def tip_shape(text: str) -> str:
    """A tip shape, ``LENGTH_MM,ANGLE_DEG`` with an optional secondary curve's
    ``,DISTANCE_MM,ANGLE_DEG``, or ``J`` (:func:`sim4endor.models.wires.parse_tip`), kept as
    written: it is stored so in a run's config."""
    from sim4endor.models.wires import WireCatalogueError, parse_tip  # loads MuJoCo

    try:
        parse_tip(text)
    except WireCatalogueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def add_task_arguments(parser: argparse.ArgumentParser, *, evaluation_split: bool = False) -> None:
    """Adds the domain-specific task arguments (each is left out unless given).

    Args:
        parser: The subcommand's parser.
        evaluation_split: Also add ``--eval-pool-seed`` (commands that train and evaluate).
    """
    group = parser.add_argument_group(
        "task arguments", "given only where the domain takes them (the error lists the valid ones)"
    )
    group.add_argument("--vessel", metavar="NAME_OR_DIR",
                       help="domain vessel: a vessel name or a folder `sim4endor vessel build` "
                            "wrote")
    group.add_argument("--target", help="domain vessel: the target label, e.g. T1")
    group.add_argument("--wire", metavar="PRESET|JSON",
                       help="guidewire preset, e.g. workhorse, or a JSON object of its fields, "
                            "e.g. '{\"preset\": \"paper\", \"chain_bodies\": 6}' (default: "
                            "the domain's wire)")
    group.add_argument("--tip", type=tip_shape, metavar="LENGTH_MM,ANGLE_DEG[,MM,DEG]|J",
                       help="shape the --wire preset's tip as a cardiologist does: the distal "
                            "1-5 mm bent through 30-90 deg (e.g. 3,75), optionally with a "
                            "secondary curve of 15-60 deg centred 4-10 mm from the end (e.g. "
                            "2,60,7,40), or J (default: the tip a given run or policy was "
                            "trained with, else the preset's shape)")
    group.add_argument("--fidelity", choices=list(FIDELITIES),
                       help="the wire's numerical settings: converged (default: trajectories "
                            "that do not depend on the wire's artificial mass) or fast (the "
                            "x1e4 wire, about twice as fast, for exploring; for the paper wire "
                            "the published model of Table I)")
    group.add_argument("--pool-seed", type=seed, metavar="SEED",
                       help="generated trees: seed of the first training tree")
    group.add_argument("--pool-size", type=positive_int, metavar="N",
                       help="generated trees: number of training trees")
    group.add_argument("--observations", choices=sorted(OBSERVATION_SETS), metavar="SET",
                       help="observation set: paper (default; tip position and velocity), "
                            "generalist (tip-frame entries, for any anatomy) or deployable "
                            "(what a robot in a cath lab measures)")
    group.add_argument("--motion", action="store_const", const=True,
                       help="coronary trees and vessel folders: a beating and breathing "
                            "heart moves the vessel walls (heart and breathing rates, "
                            "amplitudes and phases drawn per episode; docs/tasks/cathlab.md)")
    group.add_argument("--randomise", action="store_const", const=True,
                       help="domain randomisation for sim-to-real: the tracking's noise, "
                            "latency and lost frames, the action delay, the driver's backlash "
                            "and slip, and on coronary trees a wire unit per tree, drawn per "
                            "episode (docs/tasks/cathlab.md)")
    if evaluation_split:
        group.add_argument("--eval-pool-seed", type=seed, metavar="SEED",
                           help="generated trees: seed of the first evaluation tree (held out "
                                "when at least --pool-size away from --pool-seed)")


def task_arguments(args: argparse.Namespace) -> dict[str, Any]:
    """Returns the task arguments given on the command line, as ``EnvConfig`` field values.

    A vessel given as an existing folder is stored as an absolute path, so a run's saved
    config still finds it from another working directory.
    """
    names = ("vessel", "target", "wire", "tip", "fidelity", "pool_seed", "pool_size",
             "eval_pool_seed", "observations", "randomise", "motion")
    given = {name: getattr(args, name, None) for name in names}
    if given["vessel"] is not None and Path(given["vessel"]).exists():
        given["vessel"] = str(Path(given["vessel"]).resolve())
    return {name: value for name, value in given.items() if value is not None}


def env_overrides(values: dict[str, Any]) -> list[str]:
    """``env.FIELD=VALUE`` overrides of ``values``; JSON-quoted, so a path stays text."""
    return [f"env.{name}={json.dumps(value)}" for name, value in values.items()]


def env_config(args: argparse.Namespace, base: EnvConfig | None = None) -> EnvConfig:
    """The environment a viewing command names: ``base`` (e.g. a run's) with the flags given.

    Reads ``args.domain``, ``args.task``, ``args.reward`` and the task arguments; a flag left
    out keeps ``base``'s value (default: :class:`~sim4endor.rl.config.EnvConfig`'s), as a run
    is evaluated elsewhere (:func:`sim4endor.rl.runs.evaluation_env`: another domain keeps
    the wire and observations but none of the run's tree pool or vessel).
    """
    from sim4endor.rl.runs import evaluation_env

    fields = task_arguments(args)
    if args.domain is not None:
        fields.update(domain=args.domain, task=args.task)
    if args.reward is not None:
        fields["reward"] = args.reward
    return evaluation_env(base or EnvConfig(), fields)
