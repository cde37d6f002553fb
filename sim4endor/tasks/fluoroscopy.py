"""Fluoroscopy-like images: an orthographic X-ray-style projection of vessel and wire.

A fluoroscope shows the contrast-filled lumen as a grey shadow and the metal wire as a dark
line on a bright field. This module draws exactly that, in numpy, without OpenGL: the lumen
silhouette (centerline tubes projected on the image plane) is rasterised once per anatomy
and the wire polyline once per step. It needs no display or GL context, so the ``pixels``
observation works headless, in CI and inside parallel workers, and costs well under a
millisecond per step.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sim4endor.tasks.config import PixelsConfig
from sim4endor.vessels.centerline import CenterlineGraph

FloatArray = NDArray[np.float64]

BACKGROUND, LUMEN, WIRE = 255, 120, 0


def _segment_distances(pixels: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """Returns (P, S) distances from 2D pixel centres to 2D segments a→b."""
    ab = b - a
    denom = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-30)
    t = np.clip(((pixels[:, None, :] - a[None]) * ab[None]).sum(-1) / denom, 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(pixels[:, None, :] - closest, axis=-1)


class Fluoroscope:
    """Projects one anatomy and its wire onto a fixed image plane."""

    def __init__(self, graph: CenterlineGraph, config: PixelsConfig) -> None:
        """Frames the centerline graph (with a margin) and rasterises the lumen.

        Args:
            graph: The anatomy's centerline graph (m).
            config: Image size and viewing direction.
        """
        self.config = config
        view = np.asarray(config.view_direction, dtype=np.float64)
        view /= np.linalg.norm(view)
        up = np.asarray(config.up, dtype=np.float64)
        up = up - view * np.dot(up, view)
        up /= np.linalg.norm(up)
        self._basis = np.stack([np.cross(view, up), up])  # image x (right), image y (up)
        nodes = graph.nodes @ self._basis.T
        margin = float(graph.radii.max()) * 2.0
        low, high = nodes.min(axis=0) - margin, nodes.max(axis=0) + margin
        scale = float(np.max((high - low) / np.array([config.width, config.height])))
        centre = 0.5 * (low + high)
        cols = (np.arange(config.width) + 0.5 - config.width / 2) * scale + centre[0]
        rows = (config.height / 2 - np.arange(config.height) - 0.5) * scale + centre[1]
        grid_x, grid_y = np.meshgrid(cols, rows)
        self._pixels = np.stack([grid_x.ravel(), grid_y.ravel()], axis=1)
        self.metres_per_pixel = scale
        self._top_left = np.array([centre[0] - 0.5 * config.width * scale,
                                   centre[1] + 0.5 * config.height * scale])
        a, b = nodes[graph.edges[:, 0]], nodes[graph.edges[:, 1]]
        radius = 0.5 * (graph.radii[graph.edges[:, 0]] + graph.radii[graph.edges[:, 1]])
        inside = (_segment_distances(self._pixels, a, b) <= radius[None]).any(axis=1)
        self._background = np.where(inside, LUMEN, BACKGROUND).astype(np.uint8)

    def image(self, wire_points: FloatArray) -> NDArray[np.uint8]:
        """Returns the (H, W, 1) uint8 image with the wire drawn as a one-pixel line."""
        points = np.asarray(wire_points, dtype=np.float64) @ self._basis.T
        # Sample the polyline every half pixel and blacken the pixels hit: O(wire length).
        steps = np.linalg.norm(np.diff(points, axis=0), axis=1)
        counts = np.maximum(1, np.ceil(steps / (0.5 * self.metres_per_pixel)).astype(int))
        samples = np.concatenate([
            a + np.linspace(0.0, 1.0, n, endpoint=False)[:, None] * (b - a)
            for a, b, n in zip(points[:-1], points[1:], counts, strict=True)
        ] + [points[-1:]])
        col = np.floor((samples[:, 0] - self._top_left[0]) / self.metres_per_pixel).astype(int)
        row = np.floor((self._top_left[1] - samples[:, 1]) / self.metres_per_pixel).astype(int)
        keep = (col >= 0) & (col < self.config.width) & (row >= 0) & (row < self.config.height)
        image = self._background.reshape(self.config.height, self.config.width).copy()
        image[row[keep], col[keep]] = WIRE
        return image[:, :, None]
