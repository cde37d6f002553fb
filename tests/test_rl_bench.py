"""The bench job on a tiny grid (Pendulum-v1): runs, table, figures, skipping finished runs."""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

import pytest
from rl_testing import TINY, pendulum_env
from torchrl.envs import EnvBase

from sim4endor.errors import Sim4EndoRError
from sim4endor.rl.bench import (
    BenchConfig,
    BenchConfigError,
    BenchRunError,
    bench_config_from_dict,
    load_bench_config,
    plan,
    run_bench,
    write_report,
)
from sim4endor.rl.table import BaselineRows, Cell, Reference
from sim4endor.rl.trainer import EVAL_SEED_OFFSET

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def _tiny_bench(workers: int = 1) -> BenchConfig:
    return BenchConfig(
        rows=(("ddpg", "manifold"), ("ppo", "manifold")),
        tasks=(("simplified_phantom", "task_a"),),
        seeds=(0, 1),
        overrides=TINY,
        workers=workers,
    )


def test_shipped_bench_configs_plan_the_papers_grids() -> None:
    table1 = load_bench_config(EXPERIMENTS / "bench" / "table1.yaml")
    runs = plan(table1)
    assert len(runs) == 4 * 2 * 3  # rows × tasks × seeds
    assert runs[0][0] == "ddpg-manifold-simplified_phantom-task_a-s0"
    assert {c.env.reward for _, c in runs if c.algorithm == "ddpg"} == {"manifold", "euclidean"}
    assert all(c.collector.total_frames == 100_000 and c.eval.trials == 10 for _, c in runs)
    # The paper's figures to print beside ours: Table I's eight cells, the complex phantom's two.
    assert table1.reference is not None and len(table1.reference.cells) == 8
    paper_ddpg_a = table1.reference.cells[("ddpg", "euclidean", "simplified_phantom", "task_a")]
    assert (paper_ddpg_a.successes, paper_ddpg_a.trials) == (3, 10)
    complex_bench = load_bench_config(EXPERIMENTS / "bench" / "complex_phantom.yaml")
    complex_runs = plan(complex_bench)
    assert {c.env.domain for _, c in complex_runs} == {"vascular_phantom"}
    assert complex_bench.reference is not None
    assert {k[2:] for k in complex_bench.reference.cells} == set(complex_bench.tasks)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"rows": [], "tasks": [], "seed": [1]}, "unknown keys"),
        ({"rows": [{"algorithm": "ddpg"}], "tasks": []}, "'rows' must list"),
        ({"rows": [{"algorithm": "a2c", "reward": "manifold"}], "tasks": []}, "unknown algorithm"),
        ({"rows": [], "tasks": [], "reference": {"cells": []}}, "'reference' must have a 'label'"),
        (
            {"rows": [], "tasks": [], "reference": {"label": "x", "cells": [{"task": "t"}]}},
            "'reference' must have",
        ),
        (
            {
                "rows": [],
                "tasks": [],
                "reference": {
                    "label": "x",
                    "cells": [{"algorithm": "ddpg", "reward": "manifold", "domain": "d",
                               "task": "t", "successes": 11, "trials": 10}],
                },
            },
            "reference cell ddpg/manifold/d/t: successes must lie in 0..trials",
        ),
        (
            {
                "rows": [],
                "tasks": [],
                "reference": {
                    "label": "x",
                    "cells": [{"algorithm": "ddpg", "reward": "manifold", "domain": "d",
                               "task": "t", "successes": 1, "trials": 10, "time": 5.0}],
                },
            },
            r"unknown keys \['time'\]",
        ),
    ],
)
def test_bad_bench_configs_name_the_problem(data: dict, message: str) -> None:
    with pytest.raises(BenchConfigError, match=message):
        bench_config_from_dict(data)


def test_bench_writes_runs_table_figures_and_skips_finished_runs(tmp_path: Path) -> None:
    results = run_bench(_tiny_bench(), tmp_path, make_env=pendulum_env)
    assert results == tmp_path / "results.md"
    runs = sorted(p.name for p in (tmp_path / "runs").iterdir())
    assert len(runs) == 4
    table = (tmp_path / "table.md").read_text()
    assert "DDPG (manifold distance reward) | 4 (2)" in table  # 2 seeds × 2 trials
    assert "PPO (manifold distance reward)" in table
    figures = sorted(p.name for p in (tmp_path / "figures").glob("*.png"))
    assert "simplified_phantom-task_a-eval_success_rate.png" in figures
    assert "simplified_phantom-task_a-train_reward.png" in figures
    text = results.read_text()
    assert table in text and "logical CPUs" in text and "wall-clock" in text
    stamp = (tmp_path / "runs" / runs[0] / "evaluation.json").stat().st_mtime_ns
    run_bench(_tiny_bench(), tmp_path, make_env=pendulum_env)
    assert (tmp_path / "runs" / runs[0] / "evaluation.json").stat().st_mtime_ns == stamp
    assert "Runs finished: 4 of 4." in text
    assert "| ddpg-manifold-simplified_phantom-task_a-s0 | " in text  # the per-run table


def test_report_of_an_unfinished_grid_names_the_missing_runs(tmp_path: Path) -> None:
    run_bench(dataclasses.replace(_tiny_bench(), rows=(("ppo", "manifold"),)), tmp_path,
              make_env=pendulum_env)
    text = write_report(_tiny_bench(), tmp_path, None, "local").read_text()
    assert ("Runs finished: 2 of 4; not in the tables yet: ddpg-manifold-simplified_phantom-"
            "task_a-s0, ddpg-manifold-simplified_phantom-task_a-s1.") in text
    assert "DDPG" not in (tmp_path / "table.md").read_text()
    # Runs short of a longer grid's frames are unfinished there, whatever evaluation.json
    # they hold (`sim4endor evaluate` writes one mid-training too).
    longer = dataclasses.replace(_tiny_bench(), overrides=(*TINY, "collector.total_frames=400"))
    with pytest.raises(Sim4EndoRError, match="No run"):
        write_report(longer, tmp_path, None, "local")
    assert "this invocation" not in text  # only the report was written


def test_report_prints_the_published_reference_under_its_row(tmp_path: Path) -> None:
    bench = dataclasses.replace(_tiny_bench(), rows=(("ppo", "manifold"),))
    run_bench(bench, tmp_path, make_env=pendulum_env)
    paper = Reference("paper (Table I)", {
        ("ppo", "manifold", "simplified_phantom", "task_a"): Cell(10, 7, 5.43, None),
    })
    text = write_report(dataclasses.replace(bench, reference=paper), tmp_path, None, "local")
    table = (tmp_path / "table.md").read_text()
    assert "| ↳ paper (Table I) | 10 | 70% (7/10) | 5.43 |" in table
    assert table in text.read_text()
    assert "↳ rows: paper (Table I)" in text.read_text()


def test_report_shows_the_baseline_rows_under_the_table(tmp_path: Path) -> None:
    bench = dataclasses.replace(_tiny_bench(), rows=(("ppo", "manifold"),))
    run_bench(bench, tmp_path, make_env=pendulum_env)
    baselines = BaselineRows(
        "open_loop_baselines.json",
        {"open loop: constant push [1, 0]": {("simplified_phantom", "task_a"): Cell(20, 20, 3.05,
                                                                                  None)}},
        {},
    )
    text = write_report(dataclasses.replace(bench, baselines=baselines), tmp_path, None,
                        "local").read_text()
    assert "| open loop: constant push [1, 0] | 20 | 100% (20/20) | 3.05 |" in text
    assert "measured references from `open_loop_baselines.json`" in text


def test_a_bench_config_reads_its_baselines_beside_it(tmp_path: Path) -> None:
    (tmp_path / "rows.json").write_text(
        '{"rows": [{"role": "random", "baseline": "uniform random", "domain": "d", '
        '"task": "t", "metrics": {"trials": 4, "success_rate": 0.25, '
        '"mean_completion_time_s": 9.0}}]}')
    config = tmp_path / "grid.yaml"
    config.write_text("rows: []\ntasks: []\nbaselines: rows.json\n")
    bench = load_bench_config(config)
    assert bench.baselines is not None
    assert bench.baselines.cells["open loop: uniform random actions"][("d", "t")] == Cell(
        4, 1, 9.0, None)
    config.write_text("rows: []\ntasks: []\nbaselines: missing.json\n")
    with pytest.raises(BenchConfigError, match="'baselines': Cannot read baseline rows"):
        load_bench_config(config)


def _pendulum_failing_seed_1(seed: int) -> EnvBase:
    # The evaluation env of training seed 1 is built first (seed 1 + EVAL_SEED_OFFSET).
    if seed == 1 + EVAL_SEED_OFFSET:
        raise RuntimeError("broken env for seed 1")
    return pendulum_env(seed)


def test_a_failing_run_is_named_and_the_rest_of_the_grid_still_trains(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    bench = dataclasses.replace(_tiny_bench(), rows=(("ddpg", "manifold"),))
    with caplog.at_level(logging.INFO, logger="sim4endor.rl.bench"):
        with pytest.raises(BenchRunError, match=r"1 of 2 runs failed.*task_a-s1 \(RuntimeError: "
                           r"broken env for seed 1\).*results\.md"):
            run_bench(bench, tmp_path, make_env=_pendulum_failing_seed_1, progress=False)
    # Pendulum has no target: 0 successes.
    assert "run ddpg-manifold-simplified_phantom-task_a-s0 finished (1/2): 0/2 successes" in (
        caplog.text
    )
    assert "run ddpg-manifold-simplified_phantom-task_a-s1 failed" in caplog.text
    text = (tmp_path / "results.md").read_text()
    assert "Runs finished: 1 of 2; not in the tables yet: ddpg-manifold-simplified_phantom-" \
        "task_a-s1." in text
    # Rerunning retries only the failed run.
    run_bench(bench, tmp_path, make_env=pendulum_env, progress=False)
    assert "Runs finished: 2 of 2." in (tmp_path / "results.md").read_text()


def test_a_grid_whose_every_run_fails_says_so(tmp_path: Path) -> None:
    bench = dataclasses.replace(_tiny_bench(), rows=(("ddpg", "manifold"),), seeds=(1,))
    with pytest.raises(BenchRunError, match=r"Every run of the bench failed: .*broken env"):
        run_bench(bench, tmp_path, make_env=_pendulum_failing_seed_1, progress=False)
    assert not (tmp_path / "results.md").exists()


def test_bench_on_a_local_ray_cluster(tmp_path: Path) -> None:
    # Ray's core is in the dev extra: a local one-CPU instance, a two-run grid (two seeds).
    import ray
    bench = BenchConfig(
        rows=(("sac", "manifold"),),
        tasks=(("simplified_phantom", "task_a"),),
        seeds=(0, 1),
        overrides=TINY,
    )
    # Ray workers import the env factory from this folder.
    here = str(Path(__file__).resolve().parent)
    ray.init(
        num_cpus=1,
        object_store_memory=100 * 2**20,  # bounded: the runs only return small dicts
        include_dashboard=False,
        log_to_driver=False,
        runtime_env={"env_vars": {"PYTHONPATH": here}},
    )
    try:
        run_bench(bench, tmp_path, backend="ray", make_env=pendulum_env)
    finally:
        ray.shutdown()
    assert "SAC (manifold distance reward) | 4 (2)" in (tmp_path / "table.md").read_text()
