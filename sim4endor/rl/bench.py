"""The headless benchmark job: a grid of training runs, Table I and learning curves.

A bench config (YAML) lists the rows (algorithm × reward), the tasks, the seeds and config
overrides applied to every run, and optionally a published ``reference`` (e.g. the paper's
Table I) to print beside the measured cells. :func:`run_bench` trains every grid point into
``OUT/runs/<algorithm>-<reward>-<domain>-<task>-s<seed>/`` with a local process pool (or on a
Ray cluster), skipping runs that already finished and resuming interrupted ones, then writes
``OUT/table.md``, ``OUT/figures/*.png`` (success rate and each reward term vs frames) and
``OUT/results.md`` (table, figures, hardware and wall-clock), all generated, never typed.
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import logging
import multiprocessing
import os
import platform
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Literal

import yaml
from tqdm.auto import tqdm
from tqdm.contrib.logging import logging_redirect_tqdm

from sim4endor._atomic import atomic_write_text
from sim4endor.errors import Sim4EndoRError
from sim4endor.rl import checkpoint, ray_backend
from sim4endor.rl.config import ALGORITHMS, TrainConfig, apply_overrides, default_config
from sim4endor.rl.envs import EnvFactory
from sim4endor.rl.metrics import describe
from sim4endor.rl.plots import learning_curve_figure, scalar_names
from sim4endor.rl.runs import read_evaluation
from sim4endor.rl.table import (
    BaselineRows,
    Cell,
    Reference,
    RunResult,
    markdown_table,
    per_run_table,
    read_baselines,
)
from sim4endor.rl.trainer import train

Backend = Literal["local", "ray"]

_LOG = logging.getLogger(__name__)


class BenchConfigError(Sim4EndoRError, ValueError):
    """A bench config file is malformed; the message names the field."""


@dataclasses.dataclass(frozen=True)
class BenchConfig:
    """A benchmark grid.

    Attributes:
        rows: (algorithm, reward) pairs, e.g. the paper's four Table I rows.
        tasks: (domain, task) pairs.
        seeds: training seeds of every (row, task).
        overrides: ``section.field=value`` strings applied to every run's config.
        workers: parallel runs of the local process pool.
        reference: published results shown under the measured rows of the table (transcribed
            into the config, never measured here).
        baselines: measured open-loop and expert rows shown under the table (the YAML names
            the JSON file of ``experiments/benchmarks/open_loop_baselines.py``, relative to
            the YAML).
    """

    rows: tuple[tuple[str, str], ...]
    tasks: tuple[tuple[str, str], ...]
    seeds: tuple[int, ...] = (0, 1, 2)
    overrides: tuple[str, ...] = ()
    workers: int = 2
    reference: Reference | None = None
    baselines: BaselineRows | None = None


def load_bench_config(path: Path) -> BenchConfig:
    """Reads a bench YAML file (keys: rows, tasks, seeds, overrides, workers, reference,
    baselines)."""
    try:
        data = yaml.safe_load(Path(path).read_text()) or {}
    except (OSError, yaml.YAMLError) as exc:
        raise BenchConfigError(f"Cannot read bench config {path}: {exc}") from exc
    return bench_config_from_dict(data, source=str(path), root=Path(path).parent)


def bench_config_from_dict(data: Mapping[str, Any], *, source: str = "bench",
                           root: Path = Path()) -> BenchConfig:
    """Validates and converts a bench mapping (see :class:`BenchConfig`); a relative
    ``baselines`` path is read from ``root``."""
    known = {f.name for f in dataclasses.fields(BenchConfig)}
    unknown = set(data) - known
    if unknown:
        raise BenchConfigError(f"{source}: unknown keys {sorted(unknown)}; valid: {sorted(known)}")
    try:
        rows = tuple((str(r["algorithm"]), str(r["reward"])) for r in data["rows"])
        tasks = tuple((str(t["domain"]), str(t["task"])) for t in data["tasks"])
    except (KeyError, TypeError) as exc:
        raise BenchConfigError(
            f"{source}: 'rows' must list {{algorithm, reward}} and 'tasks' {{domain, task}} "
            f"mappings ({exc})."
        ) from exc
    for algorithm, _ in rows:
        if algorithm not in ALGORITHMS:
            raise BenchConfigError(f"{source}: unknown algorithm {algorithm!r}; use {ALGORITHMS}.")
    return BenchConfig(
        rows=rows,
        tasks=tasks,
        seeds=tuple(int(s) for s in data.get("seeds", (0, 1, 2))),
        overrides=tuple(str(o) for o in data.get("overrides", ())),
        workers=int(data.get("workers", 2)),
        reference=_reference(data.get("reference"), source),
        baselines=None if data.get("baselines") is None
        else _baselines(root / str(data["baselines"]), source),
    )


def _baselines(path: Path, source: str) -> BaselineRows:
    try:
        return read_baselines(path)
    except Sim4EndoRError as exc:
        raise BenchConfigError(f"{source}: 'baselines': {exc}") from exc


_REFERENCE_CELL_KEYS = {"algorithm", "reward", "domain", "task", "successes", "trials", "time_s"}


def _reference(data: Any, source: str) -> Reference | None:
    """The ``reference`` mapping: a label and cells of published successes/trials (time_s)."""
    if data is None:
        return None
    try:
        label, entries = str(data["label"]), list(data["cells"])
        cells = {
            (str(c["algorithm"]), str(c["reward"]), str(c["domain"]), str(c["task"])): Cell(
                trials=int(c["trials"]),
                successes=int(c["successes"]),
                mean_completion_time_s=None if c.get("time_s") is None else float(c["time_s"]),
                seeds=None,
            )
            for c in entries
        }
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise BenchConfigError(
            f"{source}: 'reference' must have a 'label' and 'cells' of {{algorithm, reward, "
            f"domain, task, successes, trials, time_s (optional)}} ({exc!r})."
        ) from exc
    for entry in entries:
        # A misspelt key (e.g. `time`) would otherwise drop its value without a word.
        unknown = sorted(set(entry) - _REFERENCE_CELL_KEYS)
        if unknown:
            raise BenchConfigError(
                f"{source}: reference cell {entry}: unknown keys {unknown}; "
                f"valid: {sorted(_REFERENCE_CELL_KEYS)}."
            )
    for key, cell in cells.items():
        if not 0 <= cell.successes <= cell.trials:
            raise BenchConfigError(
                f"{source}: reference cell {'/'.join(key)}: successes must lie in 0..trials."
            )
    return Reference(label, cells)


def plan(bench: BenchConfig) -> list[tuple[str, TrainConfig]]:
    """Every grid point as (run folder name, config), in a stable order."""
    runs = []
    for algorithm, reward in bench.rows:
        for domain, task in bench.tasks:
            for seed in bench.seeds:
                point = [
                    f"env.domain={domain}",
                    f"env.task={task}",
                    f"env.reward={reward}",
                    f"seed={seed}",
                ]
                config = apply_overrides(default_config(algorithm), [*bench.overrides, *point])
                runs.append((f"{algorithm}-{reward}-{domain}-{task}-s{seed}", config))
    return runs


def _train_one(
    config: TrainConfig, run_dir: Path, make_env: EnvFactory | None, progress: bool
) -> dict[str, Any] | str:
    """Trains one grid point; returns its final evaluation, or what went wrong."""
    try:
        return train(config, run_dir, make_env=make_env, progress=progress)
    except Exception as exc:  # one broken run must not end a night-long grid
        _LOG.exception("run %s failed", run_dir.name)
        return f"{type(exc).__name__}: {exc}"


def _final_evaluation(config: TrainConfig, run_dir: Path) -> dict[str, Any] | None:
    """The run's final evaluation, or None while it is short of its frames (`sim4endor
    evaluate` also writes an evaluation mid-training)."""
    if checkpoint.load_progress(run_dir).frames < config.collector.total_frames:
        return None
    return read_evaluation(run_dir)


class BenchRunError(Sim4EndoRError):
    """Some runs of a grid failed; the others finished and are in the report."""


def run_bench(
    bench: BenchConfig,
    out_dir: Path,
    *,
    backend: Backend = "local",
    make_env: EnvFactory | None = None,
    progress: bool = True,
) -> Path:
    """Trains the grid into ``out_dir`` and writes the table, figures and ``results.md``.

    A run that raises is logged and left out; the rest of the grid still trains.

    Args:
        bench: the grid.
        out_dir: output folder; rerunning skips finished runs and resumes interrupted ones.
        backend: ``local`` (process pool of ``bench.workers``; 1 = in this process) or ``ray``
            (one task per run on the cluster RAY_ADDRESS names, else on a Ray instance
            started on this machine; :func:`sim4endor.rl.ray_backend.connected`).
        make_env: ``seed -> env`` factory (picklable); defaults to each run's sim4endor task.
        progress: show a progress bar of the grid's runs (and, in this process, of each run).

    Returns:
        The path of ``results.md``.

    Raises:
        BenchRunError: after the report is written, when runs failed; it names them.
    """
    out_dir = Path(out_dir)
    start = time.monotonic()
    runs = plan(bench)
    todo = [
        (config, out_dir / "runs" / name)
        for name, config in runs
        if _final_evaluation(config, out_dir / "runs" / name) is None
    ]
    # Log lines go through the bar, so they do not tear it.
    with (
        logging_redirect_tqdm(tqdm_class=tqdm),
        _GridProgress(len(runs), len(runs) - len(todo), progress) as tracker,
    ):
        if backend == "ray":
            _run_ray(todo, make_env, tracker)
        elif bench.workers <= 1:
            for config, run_dir in todo:
                tracker.finished(run_dir, _train_one(config, run_dir, make_env, progress))
        else:
            context = multiprocessing.get_context("spawn")
            with concurrent.futures.ProcessPoolExecutor(bench.workers, mp_context=context) as pool:
                futures = {
                    pool.submit(_train_one, config, run_dir, make_env, False): run_dir
                    for config, run_dir in todo
                }
                for future in concurrent.futures.as_completed(futures):
                    tracker.finished(futures[future], future.result())
    failures = tracker.failures
    if len(failures) == len(runs):
        raise BenchRunError(f"Every run of the bench failed: {_listing(failures)}")
    path = write_report(bench, out_dir, time.monotonic() - start, backend)
    if failures:
        raise BenchRunError(
            f"{len(failures)} of {len(runs)} runs failed (their logs say why; rerunning the "
            f"bench retries them and skips the finished ones): {_listing(failures)}. "
            f"The report of the others is {path}."
        )
    return path


def _listing(failures: Mapping[str, str]) -> str:
    return "; ".join(f"{name} ({error})" for name, error in failures.items())


class _GridProgress:
    """A progress bar over the grid's runs, and a log line as each run ends."""

    def __init__(self, total: int, done: int, enabled: bool) -> None:
        self.total = total
        self.done = done
        self.failures: dict[str, str] = {}
        self.bar = tqdm(total=total, initial=done, unit="run", desc="bench", disable=not enabled)

    def __enter__(self) -> _GridProgress:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.bar.close()

    def finished(self, run_dir: Path, outcome: dict[str, Any] | str) -> None:
        """Counts a run that ended: its final evaluation, or the error that ended it."""
        self.done += 1
        self.bar.update(1)
        if isinstance(outcome, str):
            self.failures[run_dir.name] = outcome
            _LOG.error("run %s failed (%d/%d): %s", run_dir.name, self.done, self.total, outcome)
            return
        summary = describe(outcome)
        self.bar.set_postfix_str(f"{run_dir.name}: {summary}")
        _LOG.info(
            "run %s finished (%d/%d): %s, %.1f min",
            run_dir.name,
            self.done,
            self.total,
            summary,
            outcome["train_wall_clock_s"] / 60,
        )


def _run_ray(
    todo: Sequence[tuple[TrainConfig, Path]], make_env: EnvFactory | None, tracker: _GridProgress
) -> None:
    with ray_backend.connected() as ray:
        remote = ray.remote(_train_one)
        # A run steps env.num_envs environment processes (one in-process): it reserves that
        # many CPUs, so the scheduler never packs more simulations on a node than it has cores.
        pending = {
            remote.options(num_cpus=config.env.num_envs).remote(config, run_dir, make_env, False):
                run_dir
            for config, run_dir in todo
        }
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            tracker.finished(pending.pop(ready[0]), ray.get(ready[0]))


def write_report(
    bench: BenchConfig, out_dir: Path, wall_clock_s: float | None, backend: str
) -> Path:
    """Writes ``table.md``, the learning-curve figures and ``results.md`` for ``bench``.

    ``wall_clock_s`` is the training time of this invocation (None: only the report).
    """
    runs = [(config, out_dir / "runs" / name) for name, config in plan(bench)]
    finished: list[tuple[TrainConfig, Path]] = []
    results, evaluations, missing = [], [], []
    clocks: dict[str, list[float]] = {}
    for config, run_dir in runs:
        evaluation = _final_evaluation(config, run_dir)
        if evaluation is None:
            missing.append(run_dir.name)
            continue
        finished.append((config, run_dir))
        results.append(RunResult.from_run(config, evaluation))
        clocks.setdefault(config.algorithm, []).append(evaluation.get("train_wall_clock_s", 0.0))
        evaluations.append((run_dir.name, evaluation))
    if not results:
        raise Sim4EndoRError(f"No run of the bench under {out_dir} has an evaluation yet.")
    table = markdown_table(results, bench.reference, bench.baselines)
    atomic_write_text(out_dir / "table.md", table)
    figures = []
    for domain, task in bench.tasks:
        # Finished runs only, like the tables: a run still training would cut the curves short.
        task_runs = [(c, d) for c, d in finished if (c.env.domain, c.env.task) == (domain, task)]
        if not task_runs:
            continue
        names = ["eval/success_rate", *scalar_names([d for _, d in task_runs], "train/reward")]
        for name in names:
            slug = name.replace("/", "_")
            path = out_dir / "figures" / f"{domain}-{task}-{slug}.png"
            learning_curve_figure(task_runs, name, f"{domain} {task}: {name}", path)
            figures.append(path.relative_to(out_dir))
    report = _Report(table, per_run_table(evaluations), missing, figures, clocks)
    text = _results_markdown(bench, runs[0][0], report, wall_clock_s, backend)
    atomic_write_text(out_dir / "results.md", text)
    return out_dir / "results.md"


@dataclasses.dataclass(frozen=True)
class _Report:
    """What ``results.md`` shows besides the grid and the machine."""

    table: str
    per_run: str
    missing: Sequence[str]
    figures: Sequence[Path]
    clocks: Mapping[str, Sequence[float]]  # training wall-clock (s) of each run, by algorithm


def _results_markdown(
    bench: BenchConfig,
    example: TrainConfig,
    report: _Report,
    wall_clock_s: float | None,
    backend: str,
) -> str:
    import torch

    done = sum(len(c) for c in report.clocks.values())
    finished = f"Runs finished: {done} of {done + len(report.missing)}"
    if report.missing:
        finished += f"; not in the tables yet: {', '.join(report.missing)}"
    lines = [
        "# Results (generated by `sim4endor bench`; do not edit by hand)",
        "",
        f"Grid: {len(bench.rows)} rows × {len(bench.tasks)} tasks × {len(bench.seeds)} seeds "
        f"(seeds {list(bench.seeds)}), {example.collector.total_frames} frames per run, "
        f"{example.eval.trials} evaluation trials per seed. Overrides: {list(bench.overrides)}.",
        f"{finished}.",
        "",
        report.table,
        "Success rate: successful evaluation episodes / trials, pooled over seeds. Time: mean "
        "simulated procedure time of the successful episodes. Each run is evaluated with its "
        "final policy."
        + (
            f" ↳ rows: {bench.reference.label}, as transcribed in the bench config's "
            "`reference` (published, not measured here)."
            if bench.reference
            else ""
        )
        + (f" {baselines_note(bench.baselines)}" if bench.baselines else ""),
        "",
        "## Every run",
        "",
        report.per_run,
        "Path: mean tip path length over the trials; SPL: success weighted by "
        "(shortest path / path taken); max wall force: largest total contact force of the wire "
        "on the wall over all trials; training: wall-clock including periodic evaluation.",
        "",
        "## Hardware and wall-clock",
        "",
        f"- machine: {_cpu_model()}, {platform.machine()}, {os.cpu_count()} logical CPUs, "
        f"{platform.platform()}; torch {torch.__version__} (CPU)",
        f"- backend: {backend}, {bench.workers} parallel runs",
        "- mean training wall-clock per run (includes periodic evaluation): "
        + ", ".join(
            f"{algorithm.upper()} {sum(c) / len(c) / 60:.1f} min ({len(c)} run{'s' * (len(c) > 1)})"
            for algorithm, c in report.clocks.items()
        ),
    ]
    if wall_clock_s is not None:
        lines.append(
            f"- this invocation: {wall_clock_s / 60:.1f} min (finished runs are skipped on reruns)"
        )
    lines += ["", "## Learning curves (mean over seeds, shaded from the lowest to the highest)", ""]
    lines += [f"![{path.stem}]({path.as_posix()})" for path in report.figures]
    return "\n".join(lines) + "\n"


def baselines_note(baselines: BaselineRows) -> str:
    """The sentence under the table that says what the baseline rows are."""
    return (
        f"Rows without an algorithm: measured references from `{baselines.source}` "
        "(`experiments/benchmarks/open_loop_baselines.py`), evaluated as the trained policies "
        "are: open-loop policies that never read the observation (the constant push `[1, 0]`; "
        "the best constant action of `sim4endor.rl.baselines.CONSTANT_GRID`, chosen per task "
        "on other seeds than those reported and shown beside its trials; uniform "
        "random actions) and the scripted expert, which reads privileged state (the wire's "
        "shape and the centerline). A task an open-loop row solves does not show steering."
    )


def _cpu_model() -> str:
    """The CPU's model name (Linux), else what ``platform`` knows."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"
