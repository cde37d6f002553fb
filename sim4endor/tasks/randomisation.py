"""Domain randomisation for sim-to-real: the cath lab's sensors and the driver, per episode.

One switch, ``task_kwargs={"randomise": True}`` (``--randomise`` on the commands), draws at
every episode's start, from the task's own generator:

* the **tracking**: its noise, latency, lost frames, pulse rate and the roadmap's
  registration error (:class:`~sim4endor.tasks.config.CathLabConfig`'s fields), within the
  ranges the tracking literature reports;
* the **action delay**: whole control steps between a command and the driver's move;
* the **driver**: the roll's backlash (a dead band the carriage's roll lags by after the
  motor reverses) and the insertion's slip (the fraction of each commanded advance the wire
  does not make).

On the coronary domain it also gives each tree its own unit of the wire (``vary_wire``:
stiffness, friction and tip shape within the catalogue's tolerances,
:class:`~sim4endor.models.wires.WireVariation`). The ranges and their sources are in
docs/tasks/cathlab.md ("Domain randomisation").
"""

from __future__ import annotations

import collections
import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from sim4endor.tasks.config import CathLabConfig, TaskConfigError


@dataclass(frozen=True)
class Randomisation:
    """The ranges drawn per episode (each ``(lowest, highest)``, drawn uniformly).

    Attributes:
        tracking_noise: Of each tracked image coordinate's standard deviation (m).
        latency: Of the track's latency (s).
        dropout: Of the fraction of frames the tracker loses.
        frame_rates: Pulse rates to draw from (1/s).
        roadmap_error: Of the roadmap registration's standard deviation (m).
        action_delay: Of the control steps a command waits before the driver moves (whole
            steps, both ends included).
        roll_backlash: Of the roll's dead band (rad).
        insertion_slip: Of the fraction of each commanded advance lost to slip.
    """

    tracking_noise: tuple[float, float] = (0.2e-3, 1.0e-3)
    latency: tuple[float, float] = (0.05, 0.25)
    dropout: tuple[float, float] = (0.0, 0.05)
    frame_rates: tuple[float, ...] = (7.5, 15.0)
    roadmap_error: tuple[float, float] = (0.5e-3, 2.0e-3)
    action_delay: tuple[int, int] = (0, 2)
    roll_backlash: tuple[float, float] = (0.0, math.radians(2.0))
    insertion_slip: tuple[float, float] = (0.0, 0.1)

    def __post_init__(self) -> None:
        for name in ("tracking_noise", "latency", "dropout", "roadmap_error", "action_delay",
                     "roll_backlash", "insertion_slip"):
            low, high = getattr(self, name)
            if not 0 <= low <= high:
                raise TaskConfigError(f"Randomisation.{name} must be (lowest, highest) with "
                                      f"0 <= lowest <= highest, got {(low, high)!r}.")
        if self.dropout[1] >= 1.0 or self.insertion_slip[1] >= 1.0:
            raise TaskConfigError("Randomisation: dropout and insertion_slip must stay below 1.")
        if not self.frame_rates or min(self.frame_rates) <= 0:
            raise TaskConfigError(f"Randomisation.frame_rates must be positive pulse rates, "
                                  f"got {self.frame_rates!r}.")

    def cathlab(self, base: CathLabConfig, random: np.random.RandomState) -> CathLabConfig:
        """``base`` with this episode's tracking drawn."""
        return dataclasses.replace(
            base,
            tracking_noise=random.uniform(*self.tracking_noise),
            latency=random.uniform(*self.latency),
            dropout=random.uniform(*self.dropout),
            frame_rate=float(self.frame_rates[random.randint(len(self.frame_rates))]),
            roadmap_error=random.uniform(*self.roadmap_error),
        )

    def driver(self, random: np.random.RandomState) -> DriverModel:
        """This episode's driver."""
        low, high = self.action_delay
        return DriverModel(delay=int(random.randint(low, high + 1)),
                           backlash=random.uniform(*self.roll_backlash),
                           slip=random.uniform(*self.insertion_slip))


#: The ranges of ``task_kwargs={"randomise": True}``.
RANDOMISATION = Randomisation()


class DriverModel:
    """Between the robot's commands and the carriage: a delay, the roll's backlash and the
    insertion's slip. The identity when all three are zero (the default driver)."""

    def __init__(self, delay: int = 0, backlash: float = 0.0, slip: float = 0.0) -> None:
        """Args: delay in control steps, backlash in rad, slip as a fraction of advance."""
        self.delay, self.backlash, self.slip = delay, backlash, slip
        self._queue: collections.deque[tuple[float, float]] = collections.deque()
        self._insertion = self._roll = self._motor_roll = 0.0

    def reset(self, insertion: float, rotation: float) -> None:
        """Starts an episode with the carriage at ``insertion`` (m) and ``rotation`` (rad)."""
        self._queue = collections.deque([(0.0, 0.0)] * self.delay)
        self._insertion, self._roll, self._motor_roll = insertion, rotation, rotation

    def move(self, insert: float, rotate: float) -> tuple[float, float]:
        """Takes this step's commanded increments (m, rad); returns the carriage's targets."""
        self._queue.append((insert, rotate))
        insert, rotate = self._queue.popleft()
        # A slipping roller loses part of an advance; a pull-back grips (the wire is held
        # against the rollers' push, which is what slips).
        self._insertion = max(0.0, self._insertion + insert * (1.0 - self.slip if insert > 0
                                                                 else 1.0))
        self._motor_roll += rotate
        half = 0.5 * self.backlash
        self._roll = min(max(self._roll, self._motor_roll - half), self._motor_roll + half)
        return self._insertion, self._roll
