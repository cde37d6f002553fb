"""Table I of the paper (success rate and completion time per algorithm and task) from runs.

Rows are (algorithm, reward) pairs, column groups are (domain, task) pairs. Each cell pools
the final evaluations of every seed: trials add up, the success rate is successes / trials
and the completion time is the mean over all successful episodes (seeds weighted by their
number of successes).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from sim4endor.errors import Sim4EndoRError
from sim4endor.rl.config import TrainConfig
from sim4endor.rl.metrics import other_outcomes
from sim4endor.rl.runs import read_evaluation, run_config
from sim4endor.rl.trainer import CONFIG_FILE

_ALGORITHM_NAMES = {"ddpg": "DDPG", "sac": "SAC", "ppo": "PPO"}


@dataclasses.dataclass(frozen=True)
class RunResult:
    """One run's identity and final evaluation."""

    algorithm: str
    reward: str
    domain: str
    task: str
    seed: int
    trials: int
    successes: int
    mean_completion_time_s: float | None

    @classmethod
    def from_run(cls, config: TrainConfig, evaluation: dict[str, Any]) -> RunResult:
        """Builds a result from a run's config and its ``evaluation.json`` contents."""
        trials = int(evaluation["trials"])
        return cls(
            algorithm=config.algorithm,
            reward=config.env.reward,
            domain=config.env.domain,
            task=config.env.task,
            seed=config.seed,
            trials=trials,
            successes=round(float(evaluation["success_rate"]) * trials),
            mean_completion_time_s=evaluation["mean_completion_time_s"],
        )


@dataclasses.dataclass(frozen=True)
class Cell:
    """Pooled result of one (row, task) over seeds (``seeds`` None: not reported)."""

    trials: int
    successes: int
    mean_completion_time_s: float | None
    seeds: int | None


CellKey = tuple[str, str, str, str]
"""(algorithm, reward, domain, task) of a table cell."""


@dataclasses.dataclass(frozen=True)
class Reference:
    """Published results printed under the measured rows, e.g. the paper's Table I.

    Attributes:
        label: names the source in the table, e.g. ``paper (Table I)``.
        cells: the published cell of each (algorithm, reward, domain, task) it reports.
    """

    label: str
    cells: Mapping[CellKey, Cell]


#: Row label of each role the open-loop benchmark writes
#: (``experiments/benchmarks/open_loop_baselines.py``), in table order.
BASELINE_LABELS: Mapping[str, str] = {
    "push": "open loop: constant push [1, 0]",
    "best constant": "open loop: best constant action",
    "random": "open loop: uniform random actions",
    "expert": "scripted expert (privileged state)",
}


@dataclasses.dataclass(frozen=True)
class BaselineRows:
    """Measured reference rows printed under the table: open-loop policies and the expert.

    Attributes:
        source: the file they were read from, named in the report.
        cells: each row label's cell per (domain, task).
        notes: a note per (row label, domain, task), e.g. the constant action chosen there.
    """

    source: str
    cells: Mapping[str, Mapping[tuple[str, str], Cell]]
    notes: Mapping[tuple[str, str, str], str]


def read_baselines(path: Path) -> BaselineRows:
    """Reads the ``--json`` file of ``experiments/benchmarks/open_loop_baselines.py``.

    Raises:
        Sim4EndoRError: if it cannot be read or lacks a field; the message names it.
    """
    try:
        data = json.loads(Path(path).read_text())
        cells: dict[str, dict[tuple[str, str], Cell]] = {}
        notes: dict[tuple[str, str, str], str] = {}
        for row in data["rows"]:
            label = BASELINE_LABELS[row["role"]]
            metrics = row["metrics"]
            trials = int(metrics["trials"])
            cells.setdefault(label, {})[(row["domain"], row["task"])] = Cell(
                trials=trials,
                successes=round(float(metrics["success_rate"]) * trials),
                mean_completion_time_s=metrics["mean_completion_time_s"],
                seeds=None,
            )
            if row["role"] == "best constant":
                notes[(label, row["domain"], row["task"])] = row["baseline"]
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise Sim4EndoRError(
            f"Cannot read baseline rows from {path} ({exc!r}); write them with "
            "`python experiments/benchmarks/open_loop_baselines.py --json PATH`."
        ) from exc
    ordered = {label: cells[label] for label in BASELINE_LABELS.values() if label in cells}
    return BaselineRows(str(path), ordered, notes)


def find_runs(paths: Iterable[Path]) -> list[Path]:
    """Run folders among ``paths``, searching inside folders that are not runs themselves.

    A run's own subfolders are not runs of their own: ``RUN/best`` holds the same run's best
    weights, which the table must not count as another seed.
    """
    found: list[Path] = []
    for path in map(Path, paths):
        if (path / CONFIG_FILE).is_file():
            found.append(path)
        else:
            runs = sorted(p.parent for p in path.rglob(CONFIG_FILE))
            found.extend(r for r in runs if not any(other in r.parents for other in runs))
    return found


def collect_results(run_dirs: Iterable[Path]) -> list[RunResult]:
    """Results of the runs that have a final evaluation (others are still training)."""
    results = []
    for run_dir in run_dirs:
        evaluation = read_evaluation(run_dir)
        if evaluation is not None:
            results.append(RunResult.from_run(run_config(run_dir), evaluation))
    return results


def pool(results: Sequence[RunResult]) -> Cell:
    """Pools the results of several seeds of one cell."""
    successes = sum(r.successes for r in results)
    timed = [(r.successes, r.mean_completion_time_s) for r in results if r.successes]
    mean_time = (
        sum(n * t for n, t in timed if t is not None) / sum(n for n, _ in timed) if timed else None
    )
    return Cell(sum(r.trials for r in results), successes, mean_time, len(results))


def row_label(algorithm: str, reward: str) -> str:
    """E.g. ``DDPG (manifold distance reward)``, as in the paper."""
    return f"{_ALGORITHM_NAMES.get(algorithm, algorithm.upper())} ({reward} distance reward)"


def markdown_table(results: Sequence[RunResult], reference: Reference | None = None,
                   baselines: BaselineRows | None = None) -> str:
    """Table I as GitHub markdown: one row per (algorithm, reward), three columns per task.

    With a ``reference``, a row ``↳ LABEL`` under each measured row shows its published cells;
    with ``baselines``, their rows follow the measured ones (a chosen action in the trials
    cell).
    """
    rows = list(dict.fromkeys((r.algorithm, r.reward) for r in results))
    tasks = list(dict.fromkeys((r.domain, r.task) for r in results))
    header = ["Algorithm"]
    for domain, task in tasks:
        name = f"{domain} {task}"
        header += [f"{name}: trials (seeds)", f"{name}: success rate", f"{name}: time (s)"]
    lines = [_markdown_row(header), "|" + "---|" * len(header)]
    for algorithm, reward in rows:
        cells = [row_label(algorithm, reward)]
        for domain, task in tasks:
            group = [
                r
                for r in results
                if (r.algorithm, r.reward, r.domain, r.task) == (algorithm, reward, domain, task)
            ]
            cells += _format_cell(pool(group)) if group else ["–", "–", "–"]
        lines.append(_markdown_row(cells))
        published = [
            reference.cells.get((algorithm, reward, domain, task)) if reference else None
            for domain, task in tasks
        ]
        if reference and any(published):
            cells = [f"↳ {reference.label}"]
            for cell in published:
                cells += _format_cell(cell) if cell else ["–", "–", "–"]
            lines.append(_markdown_row(cells))
    if baselines:
        lines += baseline_rows(baselines, tasks)
    return "\n".join(lines) + "\n"


def baseline_rows(baselines: BaselineRows, tasks: Sequence[tuple[str, str]]) -> list[str]:
    """The markdown rows of ``baselines`` for the table's ``tasks`` columns."""
    lines = []
    for label, by_task in baselines.cells.items():
        cells = [label]
        for domain, task in tasks:
            cell = by_task.get((domain, task))
            formatted = _format_cell(cell) if cell else ["–", "–", "–"]
            note = baselines.notes.get((label, domain, task))
            if note:
                formatted[0] += f", {note}"
            cells += formatted
        lines.append(_markdown_row(cells))
    return lines


def _markdown_row(cells: Sequence[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def _format_cell(cell: Cell) -> list[str]:
    rate = cell.successes / cell.trials if cell.trials else 0.0
    time = "–" if cell.mean_completion_time_s is None else f"{cell.mean_completion_time_s:.2f}"
    return [
        f"{cell.trials}" if cell.seeds is None else f"{cell.trials} ({cell.seeds})",
        f"{rate:.0%} ({cell.successes}/{cell.trials})",
        time,
    ]


def per_run_table(evaluations: Sequence[tuple[str, dict[str, Any]]]) -> str:
    """One markdown row per (run name, final evaluation): the spread that pooling hides."""
    lines = [
        "| Run | success | other outcomes | time (s) | path (mm) | SPL | max wall force (N) "
        "| training (min) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, ev in evaluations:
        trials = int(ev["trials"])
        successes = round(float(ev["success_rate"]) * trials)
        cells = [
            name,
            f"{successes}/{trials}",
            # "–": an evaluation written before outcomes were counted.
            "–" if ev.get("outcomes") is None else other_outcomes(ev["outcomes"]),
            _number(ev.get("mean_completion_time_s"), "{:.2f}"),
            _number(ev.get("mean_path_length_m"), "{:.1f}", 1e3),
            _number(ev.get("spl"), "{:.2f}"),
            _number(ev.get("max_wall_force_n"), "{:.2f}"),
            _number(ev.get("train_wall_clock_s"), "{:.1f}", 1 / 60),
        ]
        lines.append(_markdown_row(cells))
    return "\n".join(lines) + "\n"


def _number(value: float | None, fmt: str, scale: float = 1.0) -> str:
    return "–" if value is None else fmt.format(float(value) * scale)

