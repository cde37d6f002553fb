"""Which of the cath lab's sensor errors cost a student its teacher's successes.

A student (issue 77) reads the ``deployable`` entries, which the cath lab's sensor model
(``sim4endor.tasks.cathlab``) makes noisy, late and registered off. This runs the student on
the same held-out coronary trees under its own sensors and under the same sensors with one
error or all of them taken out, and its teacher once beside them, so that the gap between
student and teacher splits into what the sensors cost and what the student did not learn.
No case is randomised: each row changes only the sensor settings it names.

Rows (``CathLabConfig`` fields set on top of the student's own ``env.cathlab``):

* ``own sensors``: as the student's run config has them;
* ``no registration error``: ``roadmap_error=0``;
* ``no tracking noise``: ``tracking_noise=0``;
* ``no noise``: no tracking noise, lost frames, registration error or load-cell noise;
* ``fresh frames``: a pulse every control step (20 per second) with no latency, the noise
  kept;
* ``exact``: both of the last two.

Usage:
    python experiments/benchmarks/cathlab_sensors.py STUDENT [--teacher generalist] \
        [--trees 4] [--first-seed 1000] [--settings NAME ...] [--jobs 2] [--json OUT.json]

Prints one markdown row per setting: successes, the share of the teacher's, and how the
other episodes ended; the minutes it took. ``STUDENT`` is a run folder or a shipped name.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import json
import multiprocessing
import time
from pathlib import Path
from typing import Any

from sim4endor.assets import run_or_policy
from sim4endor.rl.evaluation import DEFAULT_CONTROL_TIMESTEP_S
from sim4endor.rl.generalisation import (
    CaseEnvironments,
    SuiteConfig,
    run_actor,
    run_cases,
    tree_cases,
)
from sim4endor.rl.metrics import other_outcomes, summarize
from sim4endor.rl.runs import run_config

_NOISE_OFF = {"tracking_noise": 0.0, "dropout": 0.0, "roadmap_error": 0.0,
              "load_cell_noise": 0.0}
#: A pulse every control step, its track shown at once.
_FRESH = {"frame_rate": 1.0 / DEFAULT_CONTROL_TIMESTEP_S, "latency": 0.0}
#: Each row's sensor changes on top of the student's own.
SETTINGS: dict[str, dict[str, float]] = {
    "own sensors": {},
    "no registration error": {"roadmap_error": 0.0},
    "no tracking noise": {"tracking_noise": 0.0},
    "no noise": _NOISE_OFF,
    "fresh frames": _FRESH,
    "exact": {**_NOISE_OFF, **_FRESH},
}
TEACHER_ROW = "teacher"


def _row(run: str, sensors: dict[str, float] | None, trees: int, first_seed: int
         ) -> dict[str, Any]:
    """The summary of ``run`` on every target of the trees, with ``sensors`` over its own
    cath lab (``None``: the run's observations read no cath lab, e.g. the teacher)."""
    folder = run_or_policy(run)
    run_env = run_config(folder).env
    cathlab = None if sensors is None else {**(run_env.cathlab or {}), **sensors}
    suite = SuiteConfig(trees=trees, first_seed=first_seed, cathlab=cathlab).for_run(run_env)
    cases = tree_cases(first_seed, trees, suite.base_env(run_env.observations))
    envs = CaseEnvironments()
    try:
        episodes = run_cases(cases, run_actor(folder), suite, envs)
    finally:
        envs.close()
    return summarize([episode for case in cases for episode in episodes[case.label]])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("student", help="the student's run folder or shipped name")
    parser.add_argument("--teacher", default="generalist", help="its teacher")
    parser.add_argument("--trees", type=int, default=4, help="held-out trees")
    parser.add_argument("--first-seed", type=int, default=1000, help="seed of the first tree")
    parser.add_argument("--settings", nargs="+", choices=list(SETTINGS), default=list(SETTINGS),
                        metavar="NAME", help=f"the rows to run (default all: {list(SETTINGS)})")
    parser.add_argument("--jobs", type=int, default=2, help="processes")
    parser.add_argument("--json", type=Path, default=None, help="write the rows here")
    args = parser.parse_args()

    started = time.perf_counter()
    tasks = {TEACHER_ROW: (args.teacher, None),
             **{name: (args.student, SETTINGS[name]) for name in args.settings}}
    context = multiprocessing.get_context("spawn")  # CoACD's OpenMP in builds: never fork
    with concurrent.futures.ProcessPoolExecutor(args.jobs, mp_context=context) as pool:
        futures = {name: pool.submit(_row, run, sensors, args.trees, args.first_seed)
                   for name, (run, sensors) in tasks.items()}
        rows = {name: future.result() for name, future in futures.items()}

    teacher = rows[TEACHER_ROW]
    reached = teacher["outcomes"].get("success", 0)
    print(f"| sensors | successes of {teacher['trials']} | share of the teacher's {reached} "
          "| how the others ended |")
    print("|---|---|---|---|")
    for name, row in rows.items():
        successes = row["outcomes"].get("success", 0)
        share = f"{successes / reached:.0%}" if reached else "–"
        print(f"| {name} | {successes} | {share} | {other_outcomes(row['outcomes'])} |")
    minutes = (time.perf_counter() - started) / 60.0
    print(f"\n{len(tasks)} rows on trees {args.first_seed}-{args.first_seed + args.trees - 1} "
          f"in {minutes:.1f} min with {args.jobs} processes")
    if args.json is not None:
        args.json.write_text(json.dumps({"student": args.student, "teacher": args.teacher,
                                         "trees": args.trees, "first_seed": args.first_seed,
                                         "minutes": minutes, "rows": rows}, indent=2))


if __name__ == "__main__":
    main()
