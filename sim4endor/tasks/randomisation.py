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

import numpy as np

from sim4endor.tasks.config import CathLabConfig, Randomisation


def draw_sensors(ranges: Randomisation, base: CathLabConfig,
                 random: np.random.RandomState) -> CathLabConfig:
    """``base`` with this episode's tracking drawn from ``ranges``."""
    return dataclasses.replace(
        base,
        tracking_noise=random.uniform(*ranges.tracking_noise),
        latency=random.uniform(*ranges.latency),
        dropout=random.uniform(*ranges.dropout),
        frame_rate=float(ranges.frame_rates[random.randint(len(ranges.frame_rates))]),
        roadmap_error=random.uniform(*ranges.roadmap_error),
    )


def draw_driver(ranges: Randomisation, random: np.random.RandomState) -> DriverModel:
    """This episode's driver, drawn from ``ranges``."""
    low, high = ranges.action_delay
    return DriverModel(delay=int(random.randint(low, high + 1)),
                       backlash=random.uniform(*ranges.roll_backlash),
                       slip=random.uniform(*ranges.insertion_slip))


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
