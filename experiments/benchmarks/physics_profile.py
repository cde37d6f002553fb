"""Where a physics step goes: MuJoCo's own timers over the expert's episodes.

    python experiments/benchmarks/physics_profile.py [--cases coronary_0 coronary_1 ...]
        [--fidelity converged|fast] [--json]

For each case of ``guidewire_convergence.py`` (default: the four coronary trees) it records
the scripted expert's episode at the case's wire (as that benchmark does), replays the
actions on the bare physics, one ``mj_step`` at a time, and sums ``mjData.timer`` per stage.
It prints, per case, env steps per CPU second, microseconds per physics step, the model's
size (``nv``, constraint rows), the contacts per step (with the vessel wall and with the
rest, i.e. the introducer sheath), the Newton iterations and each stage's share of the step.
Pin it to one core (``taskset -c 0``) for figures to quote; docs/performance.md has them.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from typing import Any

import guidewire_convergence as convergence  # the benchmark beside this one
import mujoco

from sim4endor import _json as strict_json
from sim4endor.models import fidelity as fidelities

#: The stages reported, by MuJoCo's timer.
STAGES = {
    "solver": mujoco.mjtTimer.mjTIMER_CONSTRAINT,
    "collision": mujoco.mjtTimer.mjTIMER_POS_COLLISION,
    "kinematics": mujoco.mjtTimer.mjTIMER_POS_KINEMATICS,
    "inertia": mujoco.mjtTimer.mjTIMER_POS_INERTIA,
    "make_constraints": mujoco.mjtTimer.mjTIMER_POS_MAKE,
    "velocity": mujoco.mjtTimer.mjTIMER_VELOCITY,
}


def profile(case: convergence.Case, fidelity: str | None) -> dict[str, Any]:
    """Replays the case's expert episode and returns its per-step figures."""
    wire = convergence.shipped_wire(case, fidelity)
    actions = convergence.record(case, wire)
    env = convergence._env(case, wire)
    env.reset()
    physics, task = env.physics, env.task
    model, data = physics.model.ptr, physics.data.ptr
    substeps = round(task.config.action.control_timestep / model.opt.timestep)
    wire_or_wall = physics._indices().geom_class
    totals = dict.fromkeys([*STAGES, "step"], 0.0)
    steps = iterations = rows = wall = other = 0
    start = time.thread_time()
    for action in actions:
        task.before_step(action, physics)
        for _ in range(substeps):
            mujoco.mj_step(model, data)
            for name, timer in (*STAGES.items(), ("step", mujoco.mjtTimer.mjTIMER_STEP)):
                totals[name] += data.timer[timer].duration
            steps += 1
            iterations += int(data.solver_niter[0])
            rows += data.nefc
            pairs = (wire_or_wall[data.contact.geom1[:data.ncon]]
                     * wire_or_wall[data.contact.geom2[:data.ncon]])
            wall += int((pairs == 2).sum())
            other += int((pairs != 2).sum())
    cpu = time.thread_time() - start
    return {
        "case": case.name, "fidelity": fidelity, "env_steps": len(actions),
        "env_steps_per_cpu_s": len(actions) / cpu, "us_per_physics_step": 1e6 * cpu / steps,
        "nv": model.nv, "constraint_rows": rows / steps, "wall_contacts": wall / steps,
        "other_contacts": other / steps, "newton_iterations": iterations / steps,
        "share_percent": {name: 100.0 * totals[name] / totals["step"] for name in STAGES},
    }


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    cases = {case.name: case for case in convergence.CASES["full"]}
    parser.add_argument("--cases", nargs="+", choices=sorted(cases),
                        default=[f"coronary_{seed}" for seed in range(4)])
    parser.add_argument("--fidelity", choices=fidelities.names(), default=None,
                        help="the wire's numerics (default: each domain's)")
    parser.add_argument("--json", action="store_true", help="one JSON line per case")
    args = parser.parse_args(argv)
    for name in args.cases:
        row = profile(cases[name], args.fidelity)
        if args.json:
            print(strict_json.dumps(row), flush=True)
            continue
        shares = ", ".join(f"{k} {v:.0f} %" for k, v in row["share_percent"].items())
        print(f"{name}: {row['env_steps_per_cpu_s']:.0f} env steps/CPU s, "
              f"{row['us_per_physics_step']:.0f} us per step, nv {row['nv']}, "
              f"{row['constraint_rows']:.0f} rows, contacts {row['wall_contacts']:.1f} wall / "
              f"{row['other_contacts']:.1f} other, {row['newton_iterations']:.2f} Newton "
              f"iterations; {shares}", flush=True)


if __name__ == "__main__":
    main()
