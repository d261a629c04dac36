"""``snnkart track show``'s figure: a track with its walls, checkpoints, spawn and the geodesic
route field to one checkpoint line (PNG bytes; matplotlib through :mod:`snnkart.report.plots`).

The route field is :class:`~snnkart.envs.geodesic.GeodesicField` for one env's geometry (its
clearance: the kart radius, or the steer car's turning radius): colour is the distance left to
the chosen checkpoint line along the shortest drivable path, arrows its direction; blank cells
are too near a wall or cannot reach the line.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from snnkart.envs.constants import PIXELS_PER_METRE
from snnkart.envs.geodesic import GeodesicField
from snnkart.envs.tracks import Track
from snnkart.report.plots import _figure, _png

ARROW_EVERY = 6
"""One route arrow per this many grid cells on each axis."""


def track_png(track: Track, field: GeodesicField, checkpoint: int, env_name: str) -> bytes:
    """The figure of ``track`` with the route field to checkpoint line ``checkpoint``."""
    fig, axes = _figure(7.5, 7.5)
    ax = axes[0][0]
    _route_field(ax, field, checkpoint)
    for line in track.walls:
        xs, ys = zip(*line, strict=True)
        ax.plot(xs, ys, color="black", linewidth=2.2)
    n = len(track.checkpoints)
    for i, cp in enumerate(track.checkpoints):
        finish = i == n - 1
        colour = "#d62728" if finish else ("#ff7f0e" if i == checkpoint else "#2ca02c")
        ax.plot([cp.a[0], cp.b[0]], [cp.a[1], cp.b[1]], color=colour, linewidth=2.5)
        mx, my = cp.midpoint
        ax.annotate(
            "finish" if finish else str(i),
            (mx, my),
            color=colour,
            fontsize=9,
            xytext=(4, 4),
            textcoords="offset points",
            weight="bold",
        )
    _spawn(ax, track)
    xmin, ymin, xmax, ymax = track.bounds
    pad = 0.3 * PIXELS_PER_METRE
    ax.set_xlim(xmin - pad, xmax + pad)
    ax.set_ylim(ymax + pad, ymin - pad)  # y down, as on screen
    ax.set_aspect("equal")
    ax.set_xlabel("x (px, 100 px = 1 m)")
    ax.set_ylabel("y (px, down)")
    target = "the finish line" if checkpoint == n - 1 else f"checkpoint {checkpoint}"
    ax.set_title(f"{track.name} ({env_name} geometry): the route to {target}", fontsize=10)
    return _png(fig)


def _route_field(ax: Any, field: GeodesicField, k: int) -> None:
    dist = field.dist[k] / PIXELS_PER_METRE
    rows, cols = dist.shape
    x0, y0 = field.origin
    half = field.cell / 2
    extent = (x0 - half, x0 + (cols - 0.5) * field.cell, y0 + (rows - 0.5) * field.cell, y0 - half)
    image = ax.imshow(np.ma.masked_invalid(dist), extent=extent, cmap="viridis_r", alpha=0.85)
    cbar = ax.figure.colorbar(image, ax=ax, shrink=0.7)
    cbar.set_label("distance along the route (m)")
    r, c = np.mgrid[0:rows:ARROW_EVERY, 0:cols:ARROW_EVERY]
    gx, gy = field.grad[k, 0][r, c], field.grad[k, 1][r, c]
    norm = np.hypot(gx, gy)
    ok = np.isfinite(norm) & (norm > 0.1)
    ax.quiver(
        x0 + c[ok] * field.cell,
        y0 + r[ok] * field.cell,
        -gx[ok] / norm[ok],
        gy[ok] / norm[ok],
        color="white",
        scale=40,
        width=0.003,
    )


def _spawn(ax: Any, track: Track) -> None:
    x, y = track.spawn_position
    j = track.spawn_jitter
    ax.plot(
        [x - j, x + j, x + j, x - j, x - j],
        [y - j, y - j, y + j, y + j, y - j],
        color="#1f77b4",
        linewidth=1,
    )
    length = 0.5 * PIXELS_PER_METRE
    dx, dy = length * np.cos(track.spawn_heading), length * np.sin(track.spawn_heading)
    ax.annotate(
        "", (x + dx, y + dy), (x, y), arrowprops={"arrowstyle": "->", "color": "#1f77b4", "lw": 2}
    )
    ax.plot([x], [y], "o", color="#1f77b4", markersize=7)
    ax.annotate("spawn", (x, y), color="#1f77b4", xytext=(-10, -14), textcoords="offset points")
