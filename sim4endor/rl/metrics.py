"""Navigation metrics of evaluation episodes (pure functions, SI units).

* ``success_rate``: fraction of episodes that reached the target.
* ``mean_completion_time_s``: mean *simulated* procedure time of the successful episodes
  (the paper's "average completion time"); None when no episode succeeded.
* ``mean_path_length_m``: mean distance travelled by the tip (sum of step displacements).
* ``spl``: success weighted by path length (Anderson et al., 2018):
  mean over episodes of S_i · l_i / max(p_i, l_i), with l_i the shortest path (the geodesic
  distance from the start tip to the target along the centerline) and p_i the tip path length.
* ``max_wall_force_n``: largest wire–wall contact force seen in any episode.
* ``max_tip_force_n``: largest wall force on the shaped tip (the safety signal whose limit
  ends an episode) seen in any episode; 0 when the environment does not report it.
  Both leave out the step that ends an episode in ``instability``: the simulation diverged
  there, and the task reports its forces as infinite, not as a measurement.
* ``mean_return``: mean sum of rewards.
* ``outcomes``: how the episodes ended, counted: ``success``, a failure reason (e.g.
  ``tip_force``) or ``timeout`` (neither before the step limit).
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sim4endor.errors import Sim4EndoRError

#: Keys of :func:`summarize`'s result, in the order the CLI prints them.
METRIC_KEYS: tuple[str, ...] = (
    "success_rate",
    "mean_completion_time_s",
    "mean_path_length_m",
    "spl",
    "max_wall_force_n",
    "max_tip_force_n",
    "mean_return",
    "outcomes",
    "trials",
)


@dataclasses.dataclass(frozen=True)
class Episode:
    """What one evaluation episode recorded.

    Attributes:
        tip_positions: (T + 1, 3) tip positions in m, from the reset state to the last step.
        success: whether the tip reached the target.
        duration_s: simulated time of the episode in s (steps × control period).
        wall_forces: (T,) wire–wall contact force per step in N.
        shortest_path_m: geodesic distance from the start tip to the target in m.
        episode_return: sum of rewards.
        failure: why the episode failed (the task's failure reason), or "" if it did not.
        tip_forces: (T,) wall force on the shaped tip per step in N (empty: not reported).
    """

    tip_positions: NDArray[np.float64]
    success: bool
    duration_s: float
    wall_forces: NDArray[np.float64]
    shortest_path_m: float
    episode_return: float = 0.0
    failure: str = ""
    tip_forces: NDArray[np.float64] = dataclasses.field(
        default_factory=lambda: np.zeros(0))

    @property
    def outcome(self) -> str:
        """``success``, the failure reason, or ``timeout``."""
        return "success" if self.success else self.failure or "timeout"

    def __post_init__(self) -> None:
        tips = np.asarray(self.tip_positions, dtype=np.float64)
        if tips.ndim != 2 or tips.shape[1] != 3 or len(tips) < 1:
            raise Sim4EndoRError(
                f"Episode.tip_positions must have shape (T + 1, 3), got {tips.shape}."
            )
        object.__setattr__(self, "tip_positions", tips)
        object.__setattr__(self, "wall_forces", np.asarray(self.wall_forces, dtype=np.float64))
        object.__setattr__(self, "tip_forces", np.asarray(self.tip_forces, dtype=np.float64))


def path_length(tip_positions: NDArray[np.float64]) -> float:
    """Distance travelled along a (T + 1, 3) polyline, in its units."""
    return float(np.linalg.norm(np.diff(tip_positions, axis=0), axis=1).sum())


def spl_term(success: bool, shortest: float, travelled: float) -> float:
    """One episode's S · l / max(p, l); 0 for failures, 1 for a success along the shortest path."""
    if not success:
        return 0.0
    longest = max(travelled, shortest)
    return 1.0 if longest <= 0.0 else shortest / longest


def episode_spl(episode: Episode) -> float:
    """One episode's SPL term (:func:`spl_term` of its travelled path)."""
    return spl_term(episode.success, episode.shortest_path_m, path_length(episode.tip_positions))


def largest_tip_force(episode: Episode) -> float:
    """One episode's largest finite step-mean tip force in N (0 when none was recorded)."""
    return _largest_finite([episode.tip_forces])


def summarize(episodes: Sequence[Episode]) -> dict[str, float | int | dict[str, int] | None]:
    """Returns the metrics of :data:`METRIC_KEYS` over ``episodes`` (see the module docstring)."""
    if not episodes:
        raise Sim4EndoRError("Cannot summarise zero evaluation episodes; use --trials >= 1.")
    lengths = [path_length(e.tip_positions) for e in episodes]
    times = [e.duration_s for e in episodes if e.success]
    return {
        "success_rate": float(np.mean([e.success for e in episodes])),
        "mean_completion_time_s": float(np.mean(times)) if times else None,
        "mean_path_length_m": float(np.mean(lengths)),
        "spl": float(np.mean([episode_spl(e) for e in episodes])),
        "max_wall_force_n": _largest_finite([e.wall_forces for e in episodes]),
        "max_tip_force_n": _largest_finite([e.tip_forces for e in episodes]),
        "mean_return": float(np.mean([e.episode_return for e in episodes])),
        "outcomes": dict(sorted(Counter(e.outcome for e in episodes).items())),
        "trials": len(episodes),
    }


def is_missing(value: float | int | None) -> bool:
    """True for a metric that could not be computed (None or NaN)."""
    return value is None or (isinstance(value, float) and math.isnan(value))


def other_outcomes(outcomes: Mapping[str, int]) -> str:
    """The outcomes other than success, e.g. ``timeout 6, tip_force 2``; "none" if all succeeded."""
    others = [f"{name} {count}" for name, count in outcomes.items() if name != "success"]
    return ", ".join(others) or "none"


def describe(metrics: Mapping[str, Any]) -> str:
    """:func:`summarize`'s result in a log line: ``6/10 successes (timeout 4), 3.42 s``."""
    trials = metrics["trials"]
    text = f"{round(metrics['success_rate'] * trials)}/{trials} successes"
    if metrics["success_rate"] < 1.0:
        text += f" ({other_outcomes(metrics['outcomes'])})"
    if not is_missing(metrics["mean_completion_time_s"]):
        text += f", {metrics['mean_completion_time_s']:.2f} s"
    return text


def _largest_finite(readings: Sequence[NDArray[np.float64]]) -> float:
    """The largest finite value of all ``readings``; 0 when there is none."""
    values = np.concatenate([np.zeros(1), *readings])
    return float(values[np.isfinite(values)].max())
