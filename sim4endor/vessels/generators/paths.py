"""Vessel axis paths built like turtle graphics: straight runs and circular arcs in 3D.

A path starts from a :class:`Frame` (position, unit tangent, unit normal) and is traced
segment by segment. The normal is carried along without twisting (rotation-minimising), so an
arc's ``roll_deg`` (the direction it bends, measured about the tangent from the normal) means
the same thing wherever the arc sits; a run of arcs with changing roll makes a 3D (non-planar)
curve. All lengths are in metres.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim4endor.errors import Sim4EndoRError

FloatArray = NDArray[np.float64]


class GeneratorConfigError(Sim4EndoRError, ValueError):
    """Raised for a generator configuration that cannot give a valid vessel; names the field."""


def _unit(vector: FloatArray) -> FloatArray:
    return vector / np.linalg.norm(vector)


def rotate(vectors: FloatArray, axis: FloatArray, angle: float) -> FloatArray:
    """Rotates ``vectors`` (…, 3) about the unit ``axis`` by ``angle`` radians (Rodrigues)."""
    cos, sin = math.cos(angle), math.sin(angle)
    dot = vectors @ axis
    return (
        vectors * cos
        + np.cross(axis, vectors) * sin
        + np.multiply.outer(dot, axis) * (1.0 - cos)
    )


@dataclass(frozen=True, eq=False)
class Frame:
    """Position and orientation of a path's end.

    Attributes:
        position: Point on the axis (m).
        tangent: Unit direction of travel.
        normal: Unit vector perpendicular to ``tangent``: the zero of ``roll_deg``.
    """

    position: FloatArray
    tangent: FloatArray
    normal: FloatArray

    @classmethod
    def start(cls, position: Sequence[float], tangent: Sequence[float],
              normal: Sequence[float]) -> Frame:
        """Returns an orthonormalised frame (``normal`` is made perpendicular to ``tangent``)."""
        t = _unit(np.asarray(tangent, dtype=np.float64))
        n = np.asarray(normal, dtype=np.float64)
        n = _unit(n - (n @ t) * t)
        return cls(np.asarray(position, dtype=np.float64), t, n)

    def bend_direction(self, roll_deg: float) -> FloatArray:
        """Returns the unit vector perpendicular to the tangent at ``roll_deg`` from the normal."""
        roll = math.radians(roll_deg)
        return math.cos(roll) * self.normal + math.sin(roll) * np.cross(self.tangent, self.normal)

    def turned(self, angle_deg: float, roll_deg: float = 0.0) -> Frame:
        """Returns the frame turned on the spot by ``angle_deg`` towards ``roll_deg``."""
        if angle_deg == 0.0:
            return self
        axis = _unit(np.cross(self.tangent, self.bend_direction(roll_deg)))
        angle = math.radians(angle_deg)
        return Frame(
            self.position,
            _unit(rotate(self.tangent, axis, angle)),
            _unit(rotate(self.normal, axis, angle)),
        )


@dataclass(frozen=True)
class Straight:
    """A straight run.

    Attributes:
        length: Length along the axis (m).
    """

    length: float

    def trace(self, frame: Frame, spacing: float) -> tuple[FloatArray, Frame]:
        """Returns the points after ``frame.position``, ``spacing`` apart at most, and the end."""
        steps = max(1, math.ceil(self.length / spacing - 1e-9))
        s = self.length * np.arange(1, steps + 1) / steps
        points = frame.position + np.multiply.outer(s, frame.tangent)
        end = Frame(points[-1], frame.tangent, frame.normal)
        return points, end


@dataclass(frozen=True)
class Arc:
    """A circular arc.

    Attributes:
        angle_deg: How far the direction of travel turns (degrees, > 0).
        radius: Radius of curvature of the axis (m); keep it >= 2 lumen radii so the swept
            tube does not fold on the inside of the bend.
        roll_deg: Direction of the bend about the tangent, measured from the frame's normal.
    """

    angle_deg: float
    radius: float
    roll_deg: float = 0.0

    @property
    def length(self) -> float:
        """Arc length (m)."""
        return math.radians(self.angle_deg) * self.radius

    def trace(self, frame: Frame, spacing: float) -> tuple[FloatArray, Frame]:
        """Returns the points after ``frame.position``, ``spacing`` apart at most, and the end."""
        steps = max(1, math.ceil(self.length / spacing - 1e-9))
        phi = math.radians(self.angle_deg) * np.arange(1, steps + 1) / steps
        t, b = frame.tangent, frame.bend_direction(self.roll_deg)
        points = frame.position + self.radius * (
            np.multiply.outer(np.sin(phi), t) + np.multiply.outer(1.0 - np.cos(phi), b)
        )
        axis = _unit(np.cross(t, b))
        angle = float(phi[-1])
        end = Frame(
            points[-1], _unit(rotate(t, axis, angle)), _unit(rotate(frame.normal, axis, angle))
        )
        return points, end


Segment = Straight | Arc


def path_length(segments: Sequence[Segment]) -> float:
    """Returns the summed length of ``segments`` (m)."""
    return float(sum(segment.length for segment in segments))


def trace(start: Frame, segments: Sequence[Segment], spacing: float) -> tuple[FloatArray, Frame]:
    """Samples a path.

    Args:
        start: Frame at the first point.
        segments: Straight runs and arcs, in order.
        spacing: Largest distance between consecutive samples along the axis (m).

    Returns:
        ``(points, end)``: the (N, 3) samples including ``start.position`` and the end frame.
    """
    if spacing <= 0:
        raise GeneratorConfigError(f"Sample spacing must be positive, got {spacing} m.")
    pieces = [start.position[None, :]]
    frame = start
    for segment in segments:
        if segment.length < 0:
            raise GeneratorConfigError(f"Path segment {segment} has a negative length.")
        if segment.length == 0:
            continue
        points, frame = segment.trace(frame, spacing)
        pieces.append(points)
    return np.vstack(pieces), frame
