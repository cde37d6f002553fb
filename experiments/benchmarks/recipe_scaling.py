"""How `sim4endor train generalist` scales with cores: its demonstrations stage (the plain
expert's episodes, most of the recipe's time) on the same ``--episodes`` once per ``--envs K``
worker processes and once per Ray run, each into a fresh folder; prints wall-clock seconds,
episodes/s and the speed-up over one worker.

    python experiments/benchmarks/recipe_scaling.py [--episodes 20] [--envs 1 2]
        [--ray] [--ray-address HOST:PORT] [--chunk-episodes 10] [--json]

Every run collects the same episodes (a chunk's episodes depend on its seed only), so the runs
differ in scheduling alone. Chunks are the unit of work: with K workers and C chunks the stage
takes about ceil(C / K) chunk times, so ``--episodes`` should be a multiple of K x
``--chunk-episodes`` (the recipe's: 10) for the figures to show the scaling rather than the
last, lone chunk. An untimed pass first builds the coronary trees these episodes use (the tree
cache, ~/.cache/sim4endor), so no timed run pays for building them; ``--no-warm-up`` skips it
when the cache is warm. The stage also includes starting the workers (spawned processes that
import torch and MuJoCo: a few seconds each) or Ray.
"""

from __future__ import annotations

import argparse
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from sim4endor import _json as strict_json
from sim4endor.rl.recipe import RecipeRun, load_recipe


def stage_seconds(episodes: int, chunk: int, envs: int, backend: str, address: str | None,
                  overrides: Sequence[str] = ()) -> float:
    """Wall-clock seconds of the demonstrations stage of ``episodes`` coronary episodes
    (``overrides``: more recipe fields, e.g. ``max_steps=20``)."""
    recipe = load_recipe("generalist", [
        f"demonstrations=[{{domain: coronary, episodes: {episodes}}}]",
        "rounds=0", "clone.steps=1", "clone.successful_only=false",
        f"chunk_episodes={chunk}", f"envs={envs}", *overrides])
    with tempfile.TemporaryDirectory() as scratch:
        summary = RecipeRun(recipe, Path(scratch) / "run", progress=False, backend=backend,
                            ray_address=address).run()
    return float(next(r["seconds"] for r in summary["stages"] if r["stage"] == "demonstrations"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--envs", type=int, nargs="+", default=[1, 2],
                        help="worker process counts to time (local backend)")
    parser.add_argument("--ray", action="store_true",
                        help="also time the Ray backend (every chunk a one-CPU task)")
    parser.add_argument("--ray-address", help="a running cluster's head (default: start one "
                        "here with this machine's CPUs)")
    parser.add_argument("--chunk-episodes", type=int, default=10)
    parser.add_argument("--no-warm-up", action="store_true")
    parser.add_argument("--json", action="store_true", help="print one JSON line")
    args = parser.parse_args()

    if not args.no_warm_up:
        stage_seconds(args.episodes, args.chunk_episodes, max(args.envs), "local", None)
    runs: list[dict[str, Any]] = [
        {"backend": "local", "envs": k,
         "seconds": stage_seconds(args.episodes, args.chunk_episodes, k, "local", None)}
        for k in args.envs]
    if args.ray:
        runs.append({"backend": "ray", "envs": None,
                     "seconds": stage_seconds(args.episodes, args.chunk_episodes, 1, "ray",
                                              args.ray_address)})
    one = next((r["seconds"] for r in runs if r["envs"] == 1), None)
    for run in runs:
        run["episodes_per_s"] = round(args.episodes / run["seconds"], 3)
        run["speed_up"] = None if one is None else round(one / run["seconds"], 2)
    load = os.getloadavg()
    report = {"episodes": args.episodes, "chunk_episodes": args.chunk_episodes,
              "cpus": os.cpu_count(), "load_average": load, "runs": runs}
    if args.json:
        print(strict_json.dumps(report))
        return
    print(f"demonstrations stage, {args.episodes} coronary episodes in chunks of "
          f"{args.chunk_episodes}, {os.cpu_count()} CPUs, load {load[0]:.1f}")
    for run in runs:
        workers = "ray" if run["backend"] == "ray" else f"--envs {run['envs']}"
        speed_up = "" if run["speed_up"] is None else f", x{run['speed_up']:.2f}"
        print(f"  {workers:>9}: {run['seconds']:7.1f} s, "
              f"{run['episodes_per_s']:.3f} episodes/s{speed_up}")


if __name__ == "__main__":
    main()
