"""Learning-curve figures from run folders' logs, CSV or TensorBoard (headless matplotlib)."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sim4endor.rl.config import TrainConfig
from sim4endor.rl.table import row_label

#: The loggers' folder in a run: TensorBoard event files, and the CSV logger's
#: ``scalars/NAME.csv`` (one ``frames,value`` line per point).
LOGS_DIR = Path("logs")
SCALARS_DIR = LOGS_DIR / "scalars"

Curve = tuple[np.ndarray, np.ndarray]


def read_scalars(run_dir: Path) -> dict[str, Curve]:
    """Returns every logged scalar of a run as ``name -> (frames, values)``, whichever logger
    (``logger.backend`` csv or tensorboard) wrote them."""
    curves = _csv_scalars(Path(run_dir) / SCALARS_DIR)
    logs = Path(run_dir) / LOGS_DIR
    if any(logs.glob("events.out.tfevents.*")):
        curves.update(_tensorboard_scalars(logs))
    return curves


def _csv_scalars(folder: Path) -> dict[str, Curve]:
    return {path.relative_to(folder).with_suffix("").as_posix(): _csv_curve(path)
            for path in sorted(folder.rglob("*.csv")) if path.stat().st_size}


def _csv_curve(path: Path) -> Curve:
    data = np.loadtxt(path, delimiter=",", ndmin=2)
    return data[:, 0], data[:, 1]


def _tensorboard_scalars(folder: Path) -> dict[str, Curve]:
    # TensorBoard's own reader (in the tensorboard extra, which that logger needs anyway); a
    # resumed run's several event files are read in order.
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    events = EventAccumulator(str(folder), size_guidance={"scalars": 0})
    events.Reload()
    curves = {}
    for name in events.Tags()["scalars"]:
        points = events.Scalars(name)
        curves[name] = (np.array([p.step for p in points], dtype=np.float64),
                        np.array([p.value for p in points], dtype=np.float64))
    return curves


def read_scalar(run_dir: Path, name: str) -> Curve:
    """Returns (frames, values) of logged scalar ``name`` (e.g. ``eval/success_rate``)."""
    # A CSV run logs each scalar to its own file: read that one, not the whole log.
    path = Path(run_dir) / SCALARS_DIR / f"{name}.csv"
    if path.is_file() and path.stat().st_size:
        return _csv_curve(path)
    return read_scalars(run_dir).get(name, (np.zeros(0), np.zeros(0)))


def scalar_names(run_dirs: Sequence[Path], prefix: str) -> list[str]:
    """Names of the scalars under ``prefix`` (e.g. ``train/reward_``) logged by any run."""
    names: set[str] = set()
    for run_dir in run_dirs:
        names.update(name for name in read_scalars(run_dir) if name.startswith(prefix))
    return sorted(names)


def learning_curve_figure(
    runs: Sequence[tuple[TrainConfig, Path]], name: str, title: str, out_path: Path
) -> Path:
    """Plots scalar ``name`` vs frames, one line per (algorithm, reward): the mean over seeds,
    shaded between the lowest and highest seed (with 3 seeds a ± std band would leave the
    metric's range, e.g. success rates above 1).

    Seeds are aligned on the frames they have in common (runs evaluate at the same frames).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups: dict[str, list[tuple[np.ndarray, np.ndarray]]] = defaultdict(list)
    for config, run_dir in runs:
        frames, values = read_scalar(run_dir, name)
        if frames.size:
            groups[row_label(config.algorithm, config.env.reward)].append((frames, values))
    fig, ax = plt.subplots(figsize=(6, 3.6))
    for label, curves in groups.items():
        length = min(len(f) for f, _ in curves)
        frames = curves[0][0][:length]
        values = np.stack([v[:length] for _, v in curves])
        ax.plot(frames, values.mean(axis=0), label=f"{label} (n={len(curves)})")
        ax.fill_between(frames, values.min(axis=0), values.max(axis=0), alpha=0.2)
    ax.set_xlabel("environment steps (frames)")
    ax.set_ylabel(name)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    if groups:
        ax.legend(fontsize=7)
    fig.tight_layout()
    out_path = Path(out_path)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_path, dpi=120)
    plt.close(fig)
    return out_path
