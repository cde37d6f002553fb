"""Learning-curve figures from run folders' CSV logs (headless matplotlib)."""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sim4endor.rl.config import TrainConfig
from sim4endor.rl.table import row_label

#: Where the CSV logger of a run writes scalar ``NAME``: ``RUN_DIR/logs/scalars/NAME.csv``.
SCALARS_DIR = Path("logs") / "scalars"


def read_scalar(run_dir: Path, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Returns (frames, values) of logged scalar ``name`` (e.g. ``eval/success_rate``)."""
    path = Path(run_dir) / SCALARS_DIR / f"{name}.csv"
    if not path.is_file() or path.stat().st_size == 0:
        return np.zeros(0), np.zeros(0)
    data = np.loadtxt(path, delimiter=",", ndmin=2)
    return data[:, 0], data[:, 1]


def scalar_names(run_dirs: Sequence[Path], prefix: str) -> list[str]:
    """Names of the scalars under ``prefix`` (e.g. ``train/reward_``) logged by any run."""
    names: set[str] = set()
    for run_dir in run_dirs:
        base = Path(run_dir) / SCALARS_DIR
        names.update(
            p.relative_to(base).with_suffix("").as_posix()
            for p in base.rglob("*.csv")
            if p.relative_to(base).as_posix().startswith(prefix)
        )
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
