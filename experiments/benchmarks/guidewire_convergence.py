"""Are the wire's trajectories converged in its artificial mass and its time step? (issue 66)

    python experiments/benchmarks/guidewire_convergence.py [--cases full|quick] [--json]
    python experiments/benchmarks/guidewire_convergence.py --sweep [--json]   # trade-off
    python experiments/benchmarks/guidewire_convergence.py --wire '{"mass_scale": 100, ...}'

A mass-scaled wire (``GuidewireConfig.mass_scale``, ``armature_time``) is a numerical device:
a real 0.014" wire weighs a tenth of a gram and moves quasi-statically. Its trajectories are
only worth something if they do not depend on the device. For every case this script:

1. records an action sequence at the shipped settings (the scripted ``CenterlineExpert``
   closed loop until its episode ends, or a fixed script of full-speed rolls);
2. replays it open loop twice: at the shipped settings of the domain's wire, and at the
   *reference*: 10x less mass scale, 10x less armature (``armature_time`` / sqrt(10), since
   armature = stiffness x time²) and half the physics time step;
3. compares the two: the tip's distance after every 50 ms control step (mm, and in lumen
   radii at the shipped tip), and the total wall force averaged over each control step (N).

Targets (issue 66): the largest tip difference over every case at most 0.5 mm and the mean
over the cases' means at most 0.1 mm. The cases (``full``): the expert on four coronary trees
(pool seeds 0-3, one tree each) and on both targets of both phantoms, and full-speed rolls on
a coronary tree and in the vascular phantom; ``quick`` is two coronary trees and one phantom.
``--sweep`` repeats the coronary cases at other settings (mass scale 1e4 / 1e3 / 1e2 with the
armature scaled alike, time step 5 / 2.5 / 1.25 ms), each against its own reference, and
prints the CPU cost of each as env steps per second: the trade-off curve of
docs/guidewire.md (``experiments/figures/convergence_figure.py`` draws it from the JSON).
``--wire`` changes fields of every case's wire (``GuidewireConfig`` fields as JSON, e.g.
another ``integrator``, ``damping_time`` or ``contact_margin``) before anything is recorded.

Replays step the physics directly (no episode ends), so both runs see every action. The
cases run in spawned worker processes, one per core.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import multiprocessing
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sim4endor import _json as strict_json
from sim4endor import suite
from sim4endor.models import fidelity as fidelities
from sim4endor.models.guidewire import GuidewireConfig
from sim4endor.tasks.expert import CenterlineExpert

#: Issue 66's targets against the reference (mm).
MAX_TARGET_MM = 0.5
MEAN_TARGET_MM = 0.1
#: The scene's step where the wire sets none (mjcf/options.xml).
SCENE_TIMESTEP = 0.005
#: How much lighter and finer the reference is.
MASS_FACTOR = 10.0
STEP_FACTOR = 2.0


@dataclass(frozen=True)
class Case:
    """One replayed episode.

    Attributes:
        name: Label in the report.
        domain: Suite domain.
        task: Suite task.
        task_kwargs: Besides ``wire`` (set by the run).
        policy: ``"expert"`` (the closed-loop scripted expert) or ``"rolls"`` (:func:`rolls`).
    """

    name: str
    domain: str
    task: str
    task_kwargs: Mapping[str, Any]
    policy: str = "expert"


def coronary_case(pool_seed: int, policy: str = "expert") -> Case:
    """The coronary tree of ``pool_seed`` alone in its pool, a target drawn by seed 0."""
    return Case(f"coronary_{pool_seed}" + ("_rolls" if policy == "rolls" else ""),
                "coronary", "navigate", {"pool_seed": pool_seed, "pool_size": 1, "random": 0},
                policy)


def phantom_case(domain: str, task: str, policy: str = "expert") -> Case:
    return Case(f"{domain}_{task}" + ("_rolls" if policy == "rolls" else ""), domain, task,
                {"random": 0}, policy)


CASES: Mapping[str, tuple[Case, ...]] = {
    "full": (
        *(coronary_case(seed) for seed in range(4)),
        phantom_case("simplified_phantom", "task_a"), phantom_case("simplified_phantom", "task_b"),
        phantom_case("vascular_phantom", "task_a"), phantom_case("vascular_phantom", "task_b"),
        coronary_case(0, "rolls"), phantom_case("vascular_phantom", "task_b", "rolls"),
    ),
    "quick": (coronary_case(0), coronary_case(1), phantom_case("vascular_phantom", "task_b")),
}
#: --sweep: (mass scale, physics step in s) of the coronary wire, each against its reference.
SWEEP = tuple((mass, step) for mass in (1e4, 1e3, 1e2) for step in (0.005, 0.0025, 0.00125))


def rolls() -> NDArray[np.float64]:
    """Normalised actions: 1 s of full-speed insertion, then three back-and-forth turns of
    0.6 s each way at the driver's full roll speed (180°/s) while inserting slowly, then 1 s
    more of insertion."""
    insert = [[1.0, 0.0]] * 20
    turns = ([[0.2, 1.0]] * 12 + [[0.2, -1.0]] * 12) * 3
    return np.array(insert + turns + insert, dtype=np.float64)


def reference(wire: GuidewireConfig, timestep: float) -> GuidewireConfig:
    """The wire ``MASS_FACTOR`` times lighter (mass scale and armature) at ``timestep`` /
    ``STEP_FACTOR``."""
    return dataclasses.replace(
        wire, mass_scale=wire.mass_scale / MASS_FACTOR,
        armature_time=wire.armature_time / math.sqrt(MASS_FACTOR),
        max_timestep=timestep / STEP_FACTOR)


def shipped_wire(case: Case, fidelity: str | None = None) -> GuidewireConfig:
    """The wire the case's domain uses by default, at ``fidelity`` (``None``: the domain's
    default, :func:`sim4endor.suite.default_fidelity`)."""
    return suite.wire_config(case.domain, {} if fidelity is None else {"fidelity": fidelity})


def physics_step(wire: GuidewireConfig) -> float:
    """The physics time step a scene with ``wire`` runs at."""
    return min(SCENE_TIMESTEP, wire.max_timestep or SCENE_TIMESTEP)


def _env(case: Case, wire: GuidewireConfig) -> suite.NavigationEnvironment:
    return suite.load(case.domain, case.task, {**case.task_kwargs, "wire": wire})


def record(case: Case, wire: GuidewireConfig) -> NDArray[np.float64]:
    """The case's action sequence with ``wire`` (the expert closed loop until its episode
    ends)."""
    if case.policy == "rolls":
        return rolls()
    env = _env(case, wire)
    expert = CenterlineExpert()
    expert.reset()
    timestep = env.reset()
    actions = []
    while not timestep.last():
        action = expert(env.physics, env.task)
        actions.append(action)
        timestep = env.step(action)
    return np.array(actions, dtype=np.float64)


@dataclass
class Trace:
    """A replay: per control step, the tip (m), the lumen radius at it (m) and the total wall
    force averaged over the step's physics steps (N); the deepest overlap of a wire capsule
    with a wall hull at any physics step (m, MuJoCo's contact distance); the thread CPU
    seconds of stepping."""

    tips: NDArray[np.float64]
    radii: NDArray[np.float64]
    wall_force: NDArray[np.float64]
    penetration: float
    cpu_s: float
    unstable: bool


def replay(case: Case, wire: GuidewireConfig, actions: NDArray[np.float64]) -> Trace:
    """Runs ``actions`` open loop from the case's first episode start with ``wire``."""
    env = _env(case, wire)
    env.reset()
    physics, task = env.physics, env.task
    substeps = round(task.config.action.control_timestep / physics.model.opt.timestep)
    graph = task.anatomy.vessel.centerline
    tips, radii, forces = [], [], []
    unstable = False
    penetration = 0.0
    start = time.thread_time()
    for action in actions:
        task.before_step(action, physics)
        force = 0.0
        for _ in range(substeps):
            physics.step()
            force += physics.wall_contact_force()
            penetration = max(penetration, -float(physics.wall_contact_distances().min(
                initial=0.0)))
        if physics.warnings() or not physics.is_finite():
            unstable = True
            break
        tip = physics.tip_position()
        tips.append(tip)
        radii.append(graph.radius_at_projection(graph.project(tip)))
        forces.append(force / substeps)
    return Trace(np.array(tips).reshape(-1, 3), np.array(radii), np.array(forces),
                 penetration, time.thread_time() - start, unstable)


def compare(case: Case, wire: GuidewireConfig | None = None) -> dict[str, Any]:
    """One case: its actions recorded with ``wire`` (default: the domain's), replayed with it
    and with its :func:`reference`; the differences and costs."""
    wire = wire or shipped_wire(case)
    actions = record(case, wire)
    shipped = replay(case, wire, actions)
    light = replay(case, reference(wire, physics_step(wire)), actions)
    steps = min(len(shipped.tips), len(light.tips))
    gap = np.linalg.norm(shipped.tips[:steps] - light.tips[:steps], axis=1)
    force_gap = np.abs(shipped.wall_force[:steps] - light.wall_force[:steps])
    radii = shipped.radii[:steps]
    return {
        "case": case.name, "steps": len(actions), "compared_steps": steps,
        "unstable": {"shipped": shipped.unstable, "reference": light.unstable},
        "tip_mean_mm": float(gap.mean() * 1e3) if steps else math.nan,
        "tip_max_mm": float(gap.max() * 1e3) if steps else math.nan,
        "tip_mean_radii": float((gap / radii).mean()) if steps else math.nan,
        "tip_max_radii": float((gap / radii).max()) if steps else math.nan,
        "wall_force_mean_n": float(shipped.wall_force.mean()) if steps else math.nan,
        "wall_force_diff_mean_n": float(force_gap.mean()) if steps else math.nan,
        "wall_force_diff_max_n": float(force_gap.max()) if steps else math.nan,
        "penetration_over_radius": {"shipped": shipped.penetration / wire.radius,
                                    "reference": light.penetration / wire.radius},
        "env_steps_per_cpu_s": len(shipped.tips) / shipped.cpu_s if shipped.cpu_s else math.nan,
        "reference_env_steps_per_cpu_s": (len(light.tips) / light.cpu_s if light.cpu_s
                                          else math.nan),
    }


def summary(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """The worst and mean figures over cases, and whether they meet the targets."""
    worst = max(row["tip_max_mm"] for row in rows)
    mean = float(np.mean([row["tip_mean_mm"] for row in rows]))
    unstable = [row["case"] for row in rows if any(row["unstable"].values())]
    return {
        "tip_max_mm": worst, "tip_mean_mm": mean,
        "tip_max_radii": max(row["tip_max_radii"] for row in rows),
        "wall_force_diff_max_n": max(row["wall_force_diff_max_n"] for row in rows),
        "wall_force_diff_mean_n": float(np.mean([row["wall_force_diff_mean_n"] for row in rows])),
        "env_steps_per_cpu_s": float(np.mean([row["env_steps_per_cpu_s"] for row in rows])),
        "penetration_over_radius": max(row["penetration_over_radius"]["shipped"]
                                       for row in rows),
        "unstable_cases": unstable,
        "converged": worst <= MAX_TARGET_MM and mean <= MEAN_TARGET_MM and not unstable,
    }


def _compare_job(job: tuple[Case, GuidewireConfig | None]) -> dict[str, Any]:
    return compare(*job)


def run_jobs(jobs: Sequence[tuple[Case, GuidewireConfig | None]], workers: int
             ) -> list[dict[str, Any]]:
    """The cases in spawned workers (a fork after MuJoCo or CoACD started threads can hang)."""
    if workers <= 1:
        return [_compare_job(job) for job in jobs]
    with multiprocessing.get_context("spawn").Pool(workers) as pool:
        return pool.map(_compare_job, jobs, chunksize=1)


def sweep_wire(wire: GuidewireConfig, mass_scale: float, timestep: float) -> GuidewireConfig:
    """``wire`` at ``mass_scale`` (armature scaled alike) and ``timestep``."""
    factor = mass_scale / wire.mass_scale
    return dataclasses.replace(wire, mass_scale=mass_scale,
                               armature_time=wire.armature_time * math.sqrt(factor),
                               max_timestep=timestep)


def wire_overrides(text: str) -> dict[str, Any]:
    """``--wire``: a JSON object of GuidewireConfig fields."""
    fields = {f.name for f in dataclasses.fields(GuidewireConfig)}
    value = json.loads(text)
    if not isinstance(value, dict) or not set(value) <= fields:
        raise argparse.ArgumentTypeError(
            f"--wire takes a JSON object of GuidewireConfig fields ({sorted(fields)}), "
            f"got {text!r}")
    return value


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cases", choices=sorted(CASES), default="full")
    parser.add_argument("--fidelity", choices=fidelities.names(), default=None,
                        help="every case's wire at this fidelity (default: each domain's, "
                             "sim4endor.suite.default_fidelity)")
    parser.add_argument("--wire", type=wire_overrides, default={},
                        help="GuidewireConfig fields (JSON) changed on every case's wire")
    parser.add_argument("--sweep", action="store_true",
                        help="the coronary cases at every setting of SWEEP (the trade-off)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    cases = CASES[args.cases]

    def wire(case: Case) -> GuidewireConfig:
        return dataclasses.replace(shipped_wire(case, args.fidelity), **args.wire)

    if args.sweep:
        coronary = [case for case in cases if case.domain == "coronary"]
        for mass, step in SWEEP:
            rows = run_jobs([(case, sweep_wire(wire(case), mass, step)) for case in coronary],
                            args.workers)
            result = {"mass_scale": mass, "timestep_s": step, "fidelity": args.fidelity,
                      "wire": args.wire,
                      **summary(rows), "cases": rows}
            _print(result, args.json)
        return
    rows = run_jobs([(case, wire(case)) for case in cases], args.workers)
    _print({"fidelity": args.fidelity, "wire": args.wire, **summary(rows), "cases": rows},
           args.json)


def _print(result: Mapping[str, Any], as_json: bool) -> None:
    if as_json:
        print(strict_json.dumps(result), flush=True)
        return
    head = (f"mass scale {result['mass_scale']:g}, dt {result['timestep_s'] * 1e3:g} ms: "
            if "mass_scale" in result else "shipped settings: ")
    print(f"{head}tip difference max {result['tip_max_mm']:.3f} mm (target "
          f"{MAX_TARGET_MM}), mean {result['tip_mean_mm']:.3f} mm (target {MEAN_TARGET_MM}); "
          f"wall force difference max {result['wall_force_diff_max_n']:.3f} N; "
          f"{result['env_steps_per_cpu_s']:.0f} env steps per CPU s; deepest hull overlap "
          f"{result['penetration_over_radius']:.2f} wire radii; "
          f"converged: {result['converged']}", flush=True)
    for row in result["cases"]:
        print(f"  {row['case']:34s} {row['compared_steps']:4d} steps  tip mean "
              f"{row['tip_mean_mm']:.3f} max {row['tip_max_mm']:.3f} mm ({row['tip_max_radii']:.2f}"
              f" radii)  wall force {row['wall_force_mean_n']:.3f} N, diff mean "
              f"{row['wall_force_diff_mean_n']:.3f} max {row['wall_force_diff_max_n']:.3f} N, "
              f"overlap {row['penetration_over_radius']['shipped']:.2f} r"
              + ("  UNSTABLE" if any(row["unstable"].values()) else ""), flush=True)


if __name__ == "__main__":
    sys.exit(main())
