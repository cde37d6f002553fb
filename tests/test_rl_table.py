"""Table I: pooling seeds and the markdown the `table` command prints."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sim4endor.cli import main
from sim4endor.errors import Sim4EndoRError
from sim4endor.rl.config import apply_overrides, default_config, save_config
from sim4endor.rl.table import (
    Cell,
    Reference,
    RunResult,
    markdown_table,
    per_run_table,
    pool,
    read_baselines,
)


def _result(algorithm: str, reward: str, task: str, seed: int, successes: int, time: float | None):
    return RunResult(algorithm, reward, "simplified_phantom", task, seed, 10, successes, time)


def test_pool_weights_completion_times_by_successes() -> None:
    cell = pool(
        [
            _result("ddpg", "manifold", "task_a", 0, 8, 5.0),
            _result("ddpg", "manifold", "task_a", 1, 2, 10.0),
            _result("ddpg", "manifold", "task_a", 2, 0, None),
        ]
    )
    assert (cell.trials, cell.successes, cell.seeds) == (30, 10, 3)
    assert cell.mean_completion_time_s == pytest.approx((8 * 5.0 + 2 * 10.0) / 10)


def test_markdown_table_rows_and_cells() -> None:
    results = [
        _result("ddpg", "manifold", "task_a", 0, 8, 5.27),
        _result("ddpg", "euclidean", "task_a", 0, 3, 5.39),
        _result("ddpg", "manifold", "task_b", 0, 0, None),
    ]
    lines = markdown_table(results).splitlines()
    assert len(lines) == 2 + 2  # header, rule, two rows
    assert lines[2].startswith("| DDPG (manifold distance reward) | 10 (1) | 80% (8/10) | 5.27 |")
    assert lines[2].endswith("| 10 (1) | 0% (0/10) | – |")
    assert "| DDPG (euclidean distance reward) | 10 (1) | 30% (3/10) | 5.39 | – | – | – |" in lines


def test_reference_rows_sit_under_their_measured_rows() -> None:
    results = [
        _result("ddpg", "manifold", "task_a", 0, 9, 3.1),
        _result("ddpg", "manifold", "task_b", 0, 10, 3.0),
        _result("ppo", "manifold", "task_a", 0, 10, 3.2),
    ]
    reference = Reference(
        "paper (Table I)",
        {
            ("ddpg", "manifold", "simplified_phantom", "task_a"): Cell(10, 8, 5.27, None),
            ("ddpg", "euclidean", "simplified_phantom", "task_a"): Cell(10, 3, 5.39, None),
        },
    )
    lines = markdown_table(results, reference).splitlines()
    assert len(lines) == 2 + 3  # two measured rows, one published row (PPO has none)
    assert lines[2].startswith("| DDPG (manifold distance reward) | 10 (1) | 90% (9/10) |")
    # Published cells show their trials without a seed count; unreported cells are dashes.
    assert lines[3] == "| ↳ paper (Table I) | 10 | 80% (8/10) | 5.27 | – | – | – |"
    assert lines[4].startswith("| PPO (manifold distance reward) |")
    assert markdown_table(results) == markdown_table(results, None)


def _baseline_row(role: str, label: str, task: str, successes: int, time: float | None
                  ) -> dict[str, object]:
    metrics = {"trials": 20, "success_rate": successes / 20, "mean_completion_time_s": time}
    return {"role": role, "baseline": label, "domain": "simplified_phantom", "task": task,
            "metrics": metrics}


def test_baseline_rows_follow_the_measured_rows(tmp_path: Path) -> None:
    path = tmp_path / "baselines.json"
    path.write_text(json.dumps({"rows": [
        _baseline_row("push", "constant [1, 0]", "task_a", 20, 3.05),
        _baseline_row("best constant", "constant [1, 0.5]", "task_a", 20, 3.0),
        _baseline_row("best constant", "constant [0.5, -1]", "task_a_redirect", 0, None),
        _baseline_row("expert", "scripted expert (privileged)", "task_a", 19, 5.1),
    ]}))
    baselines = read_baselines(path)
    results = [_result("sac", "manifold", "task_a", 0, 10, 3.1),
               _result("sac", "manifold", "task_b", 0, 10, 3.2)]
    lines = markdown_table(results, None, baselines).splitlines()
    assert lines[3:] == [
        "| open loop: constant push [1, 0] | 20 | 100% (20/20) | 3.05 | – | – | – |",
        "| open loop: best constant action | 20, constant [1, 0.5] | 100% (20/20) | 3.00 "
        "| – | – | – |",
        "| scripted expert (privileged state) | 20 | 95% (19/20) | 5.10 | – | – | – |",
    ]
    path.write_text(json.dumps({"rows": [{"role": "push"}]}))
    with pytest.raises(Sim4EndoRError, match=r"open_loop_baselines\.py --json"):
        read_baselines(path)


def test_shipped_baselines_cover_every_task_of_the_shipped_benches() -> None:
    from sim4endor.rl.bench import load_bench_config

    for name in ("table1", "complex_phantom"):
        bench = load_bench_config(Path(__file__).resolve().parents[1] / "experiments" / "bench"
                                  / f"{name}.yaml")
        assert bench.baselines is not None
        for cells in bench.baselines.cells.values():
            assert set(bench.tasks) <= set(cells)


def _fake_run(run_dir: Path, algorithm: str, seed: int, success_rate: float) -> None:
    config = apply_overrides(default_config(algorithm), [f"seed={seed}"])
    save_config(config, run_dir / "config.yaml")
    evaluation = {"trials": 10, "success_rate": success_rate, "mean_completion_time_s": 6.0}
    (run_dir / "evaluation.json").write_text(json.dumps(evaluation))


def test_table_command_finds_runs_below_a_folder(tmp_path: Path, capsys) -> None:
    _fake_run(tmp_path / "runs" / "sac-0", "sac", 0, 0.8)
    _fake_run(tmp_path / "runs" / "sac-1", "sac", 1, 0.9)
    _fake_run(tmp_path / "runs" / "sac-1" / "best", "sac", 1, 1.0)  # that run's best weights
    (tmp_path / "runs" / "unfinished").mkdir()
    assert main(["table", str(tmp_path), "--out", str(tmp_path / "table.md")]) == 0
    printed = capsys.readouterr().out
    assert "| SAC (manifold distance reward) | 20 (2) | 85% (17/20) | 6.00 |" in printed
    assert (tmp_path / "table.md").read_text() == printed


def test_table_command_prints_the_papers_cells_from_a_bench_config(
    tmp_path: Path, capsys
) -> None:
    _fake_run(tmp_path / "sac-0", "sac", 0, 0.9)
    bench = Path(__file__).resolve().parents[1] / "experiments" / "bench" / "table1.yaml"
    assert main(["table", str(tmp_path), "--reference", str(bench)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[2] == "| SAC (manifold distance reward) | 10 (1) | 90% (9/10) | 6.00 |"
    assert printed[3] == "| ↳ paper (Table I) | 10 | 80% (8/10) | 5.69 |"
    assert printed[4].startswith("| open loop: constant push [1, 0] | 20 | ")
    bare = tmp_path / "grid.yaml"
    bare.write_text("rows: []\ntasks: []\n")
    assert main(["table", str(tmp_path), "--reference", str(bare)]) == 2
    assert f"{bare} has neither a 'reference' nor a 'baselines' section" in (
        capsys.readouterr().err)


def test_table_command_without_runs_is_a_one_line_error(tmp_path: Path, capsys) -> None:
    assert main(["table", str(tmp_path)]) == 2
    assert "No evaluated runs" in capsys.readouterr().err


def test_per_run_table_shows_each_run_in_readable_units() -> None:
    evaluation = {"trials": 10, "success_rate": 0.2, "mean_completion_time_s": None,
                  "mean_path_length_m": 0.24, "spl": 0.1323, "max_wall_force_n": 1.196,
                  "train_wall_clock_s": 2433.0}
    older = per_run_table([("ddpg-s2", evaluation)]).splitlines()
    assert older[0].startswith("| Run | success | other outcomes | time (s) | path (mm) |")
    assert older[2] == "| ddpg-s2 | 2/10 | – | – | 240.0 | 0.13 | 1.20 | 40.5 |"
    evaluation["outcomes"] = {"success": 2, "timeout": 6, "tip_force": 2}
    assert "| 2/10 | timeout 6, tip_force 2 | – |" in per_run_table([("s2", evaluation)])
