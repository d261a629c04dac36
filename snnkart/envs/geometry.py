"""Segment maths, written once: nearest points on and distances to line segments.

A segment is ``(ax, ay, bx, by)``. :func:`nearest_point` works on plain floats (it runs every
env step, where numpy's per-call overhead would cost more than the arithmetic);
:func:`segment_distance` broadcasts over numpy arrays of points or of segments.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np


def nearest_point(seg: Sequence[float], x: float, y: float) -> tuple[float, float]:
    """The point of segment ``seg`` nearest to (x, y)."""
    ax, ay, bx, by = seg
    dx, dy = bx - ax, by - ay
    dd = dx * dx + dy * dy
    t = ((x - ax) * dx + (y - ay) * dy) / dd if dd > 0.0 else 0.0
    t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
    return ax + t * dx, ay + t * dy


def point_distance(seg: Sequence[float], x: float, y: float) -> float:
    """Distance from (x, y) to segment ``seg``."""
    qx, qy = nearest_point(seg, x, y)
    return math.hypot(x - qx, y - qy)


def segment_distance(
    px: np.ndarray | float,
    py: np.ndarray | float,
    ax: np.ndarray | float,
    ay: np.ndarray | float,
    bx: np.ndarray | float,
    by: np.ndarray | float,
) -> np.ndarray:
    """Distance from points (px, py) to segments (ax, ay, bx, by), broadcast (many points to
    one segment, or one point to many segments)."""
    dx, dy = np.subtract(bx, ax), np.subtract(by, ay)
    dd = dx * dx + dy * dy
    t = np.clip(((px - ax) * dx + (py - ay) * dy) / np.maximum(dd, 1e-12), 0.0, 1.0)
    return np.hypot(px - (ax + t * dx), py - (ay + t * dy))  # type: ignore[no-any-return]


def segments_cross(
    x0: np.ndarray | float,
    y0: np.ndarray | float,
    x1: np.ndarray | float,
    y1: np.ndarray | float,
    seg: Sequence[float],
) -> np.ndarray:
    """Whether each segment (x0, y0) -> (x1, y1) intersects the segment ``seg`` (broadcast;
    touching counts, collinear overlap does not)."""
    ax, ay, bx, by = seg

    def side(px: Any, py: Any, qx: Any, qy: Any, rx: Any, ry: Any) -> np.ndarray:
        return np.sign((qx - px) * (ry - py) - (qy - py) * (rx - px))  # type: ignore[no-any-return]

    return (side(ax, ay, bx, by, x0, y0) != side(ax, ay, bx, by, x1, y1)) & (
        side(x0, y0, x1, y1, ax, ay) != side(x0, y0, x1, y1, bx, by)
    )
