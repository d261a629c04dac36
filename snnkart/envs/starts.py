"""Where an episode starts: the track's spawn, or, for training, a checkpoint along the way.

A policy that only ever starts at the spawn meets the track's corners one after another: it
reaches corner k only once it drives corner k-1. Grid's kart, whose actions push it in fixed
world directions, has to learn every corner of a loop as a new manoeuvre, and on the held-out
ring it learned them about 25k-75k steps apart. Starting some training episodes just past a
random checkpoint shows it every corner from the first iteration (``start_spread``; why:
docs/decisions.md#grid-spread-starts).

Such an episode is not a lap: the env reports ``lap_finished`` only for episodes that started
at the spawn, so the first finish and the cumulative finishes of a study count laps alone.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from snnkart.envs.geodesic import GeodesicField
from snnkart.envs.tracks import Track

LINE_SAMPLES = 33
"""Points tried along a checkpoint line to find the free part of it."""


class Start(NamedTuple):
    x: float  # px
    y: float  # px
    heading: float  # radians, clockwise on screen from +x
    next_cp: int  # the first checkpoint still to pass


def pick_start(
    rng: np.random.Generator, track: Track, field: GeodesicField, spread: float
) -> Start:
    """The track's spawn (with its jitter), or with probability ``spread`` the middle of the
    free part of a random checkpoint line ``k - 1`` (k in 1 .. n-1), headed along the route to
    line ``k``. ``spread = 0`` draws exactly what it always did from ``rng``."""
    n = len(track.checkpoints)
    spread_draw = rng.random() < spread if spread > 0.0 and n > 1 else False
    jitter = track.spawn_jitter
    dx, dy = rng.uniform(-jitter, jitter, size=2) if jitter > 0 else (0.0, 0.0)
    if not spread_draw:
        sx, sy = track.spawn_position
        return Start(sx + float(dx), sy + float(dy), track.spawn_heading, 0)
    k = int(rng.integers(1, n))
    x, y = _free_middle(track, field, k)
    route = field.route(k, x, y)
    if route is None:  # on the line itself: head for the next line's middle
        mx, my = track.checkpoints[k].midpoint
        route = (mx - x, my - y)
    return Start(x, y, math.atan2(route[1], route[0]), k)


def _free_middle(track: Track, field: GeodesicField, k: int) -> tuple[float, float]:
    """The middle of the longest stretch of checkpoint line ``k - 1`` from which line ``k``
    can be reached (a line drawn past the walls has its ends inside them, or in another
    corridor)."""
    line = track.checkpoints[k - 1]
    (ax, ay), (bx, by) = line.a, line.b
    points = [(ax + t * (bx - ax), ay + t * (by - ay)) for t in np.linspace(0, 1, LINE_SAMPLES)]
    free = [math.isfinite(field.distance(k, *p)) for p in points]
    best, start = (0, 0), None  # (length, first index) of the longest free stretch
    for i, ok in enumerate([*free, False]):
        if ok and start is None:
            start = i
        elif not ok and start is not None:
            best, start = max(best, (i - start, start)), None
    if best[0] == 0:
        raise ValueError(f"checkpoint {k} cannot be reached from any point of line {k - 1}")
    return points[best[1] + best[0] // 2]
