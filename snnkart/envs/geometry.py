"""Segment maths, written once: nearest points on, distances to and crossings of line segments.

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


def point_segment_distance(p: tuple[float, float], seg: np.ndarray) -> np.ndarray:
    """Distance from point ``p`` to each segment row ``(ax, ay, bx, by)`` of ``seg``."""
    return segment_distance(p[0], p[1], seg[:, 0], seg[:, 1], seg[:, 2], seg[:, 3])


def box_segment_distance(centre: tuple[float, float], half: float, seg: np.ndarray) -> float:
    """Smallest distance between the square ``centre +- half`` and the segments ``seg``.

    Two disjoint convex polygons are closest at a vertex of one of them, so it suffices to
    check the box corners against the segments and the segment ends against the box.
    """
    cx, cy = centre
    corners = [(cx + sx * half, cy + sy * half) for sx in (-1, 1) for sy in (-1, 1)]
    best = min(float(point_segment_distance(c, seg).min()) for c in corners)
    ends = seg.reshape(-1, 2)
    dx = np.maximum(np.abs(ends[:, 0] - cx) - half, 0.0)
    dy = np.maximum(np.abs(ends[:, 1] - cy) - half, 0.0)
    best = min(best, float(np.hypot(dx, dy).min()))
    if best > 0.0 and _segments_cross_box(centre, half, seg):
        return 0.0
    return best


def _segments_cross_box(centre: tuple[float, float], half: float, seg: np.ndarray) -> bool:
    cx, cy = centre
    corners = [
        (cx - half, cy - half),
        (cx + half, cy - half),
        (cx + half, cy + half),
        (cx - half, cy + half),
    ]
    for (x0, y0), (x1, y1) in zip(corners, corners[1:] + corners[:1], strict=True):
        if any(bool(segments_cross(x0, y0, x1, y1, s)) for s in seg):
            return True
    return False
