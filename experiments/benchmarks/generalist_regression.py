"""Would a candidate generalist ship? Each candidate against the shipped policy, every family.

Runs the shipped generalist (or ``--reference``) and every candidate on the same cases of the
generalisation suite (held-out and wide generated trees, the evaluation-only implicit family,
the ``--real`` patients' vessel folders, the phantoms and stEVE) and prints, per candidate and
group, the successes beside the reference's and the paired SPL and tip-force differences with
their standard errors (:mod:`sim4endor.rl.regression`). A candidate ships only if it is worse
on no group.

Usage:
    python experiments/benchmarks/generalist_regression.py RUN [RUN ...] [--reference POLICY]
        [--trees 20] [--wide-trees 10] [--implicit-trees 6] [--real DIR ...] [--jobs 2]
        [--student] [--motion] [--randomise] [--json PATH]

``--student`` judges each candidate as a student distilled from the reference (issue 77: at
least 90 % of its teacher's successes and no more tip-force stops in every group).
``--motion`` also runs every group but the phantoms on a beating and breathing heart (each a
group ``GROUP moving``); ``--randomise`` draws the domain randomisation in every case.
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

from sim4endor import _json as strict_json
from sim4endor import assets
from sim4endor._atomic import atomic_write_text
from sim4endor.rl import regression
from sim4endor.rl.generalisation import SuiteConfig


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("candidates", nargs="+", type=assets.run_or_policy, metavar="RUN",
                        help="candidate run folders (or a recipe run's policy/ folder)")
    parser.add_argument("--reference", type=assets.run_or_policy, default="generalist",
                        help="the policy a candidate would replace (default: generalist)")
    parser.add_argument("--trees", type=int, default=20, help="held-out generated trees")
    parser.add_argument("--wide-trees", type=int, default=10, help="wide generated trees")
    parser.add_argument("--implicit-trees", type=int, default=6, help="implicit-family trees")
    parser.add_argument("--real", type=Path, action="append", default=[], metavar="DIR",
                        help="a real patient's vessel folder (repeatable)")
    parser.add_argument("--steve", type=Path, help="the stEVE anatomy's folder")
    parser.add_argument("--trials", type=int, default=1, help="episodes per case")
    parser.add_argument("--student", action="store_true",
                        help="judge the candidates as students of the reference, their teacher")
    parser.add_argument("--motion", action="store_true",
                        help="also every case but the phantoms' on a moving heart")
    parser.add_argument("--randomise", action="store_true",
                        help="domain randomisation in every case")
    parser.add_argument("--jobs", type=int, default=2, help="processes")
    parser.add_argument("--json", type=Path, help="also write the verdicts and rows here")
    args = parser.parse_args()
    config = SuiteConfig(trees=args.trees, wide_trees=args.wide_trees,
                         implicit_trees=args.implicit_trees, real=tuple(args.real),
                         trials=args.trials, motion=args.motion, randomise=args.randomise)
    if args.steve is not None:
        config = dataclasses.replace(config, steve_dir=args.steve)
    start = time.monotonic()
    result = regression.regression(args.candidates, args.reference, config, jobs=args.jobs,
                                   progress=True)
    minutes = (time.monotonic() - start) / 60
    print(regression.student_markdown(result) if args.student else regression.markdown(result))
    print(f"{len(args.candidates)} candidates against {result['reference']} in {minutes:.1f} "
          f"min with {args.jobs} processes")
    if args.json:
        record = {"command": "experiments/benchmarks/generalist_regression.py",
                  "config": dataclasses.asdict(config) | {
                      "real": [str(folder) for folder in config.real],
                      "steve_dir": str(config.steve_dir)},
                  "minutes": minutes,
                  "reference": result["reference"], "ships": result["ships"],
                  "keeps": result["keeps"],
                  "verdicts": {name: [dataclasses.asdict(v) | {"worse": list(v.worse)}
                                      for v in verdicts]
                               for name, verdicts in result["verdicts"].items()},
                  "rows": result["rows"], "outcomes": result["outcomes"]}
        atomic_write_text(args.json, strict_json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
