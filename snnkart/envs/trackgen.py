"""Tracks built from centrelines: the study's held-out tracks and procedurally generated ones.

A track here is a corridor of constant width around a centreline (metres, x right, y down):
walls are the centreline offset by half the width on either side (mitred corners, sharp turns
bevelled outside), checkpoints cross the corridor at the middle of every leg, and the finish
line crosses the end of the last leg (a *course*) or the start (a closed *loop*: the lap ends
where it began). The spawn sits 0.6 m into the first leg (1.0 m on a loop, clear of the finish
line), facing along it. :func:`track_toml` writes the documented TOML format
(:mod:`snnkart.envs.tracks`).

:func:`generate_track` draws a centreline from a seed (deterministic per seed) and keeps the
first draw that fits: legs at least :data:`MIN_LEG_M` long, turns of at most
:data:`MAX_TURN_DEG` per corner (the steer car's 0.36 m turning circle and the 0.192 m gazebo
robot fit round every corner of a corridor at least :data:`WIDTH_RANGE_M` ``[0]`` wide), no two
non-adjacent corridors closer than :data:`GAP_M`, everything inside the
renderer's 10 m x 10 m world with a margin, and the loader's validation passed.

    >>> from snnkart.envs.trackgen import generate_track
    >>> generate_track(7, kind="loop").name
    'loop-7'
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np

from snnkart.envs.constants import PIXELS_PER_METRE
from snnkart.envs.geodesic import GeodesicField, geodesic_field
from snnkart.envs.tracks import RANDOM_DESCRIPTION, RANDOM_TRACK, Track, parse_track
from snnkart.errors import TrackError

WORLD_PX = 1000.0
"""The renderer shows 0..1000 px on each axis (:mod:`snnkart.envs.render`)."""
MARGIN_M = 1.0
"""Canvas margin around the walls, metres."""
BEVEL_COS = math.cos(math.radians(100))
"""Turns sharper than 100 degrees are bevelled on the outside."""
SECONDS_PER_METRE = 3.5
"""Time limit per metre of centreline (small_S: 30 s for about 8 m)."""
KINDS = ("loop", "course")
"""Generated track kinds: a closed circuit (one lap) or a point-to-point course."""
WIDTH_RANGE_M = (1.0, 2.0)
"""Allowed corridor widths, metres (the steer car turns on a 0.36 m radius at full lock)."""
LENGTH_RANGE_M = {"loop": (14.0, 20.0), "course": (12.0, 18.0)}
"""Allowed centreline lengths per kind, metres (shorter tracks leave no room for a start
straight and gentle corners, longer ones rarely fit the 10 m world)."""
MIN_LEG_M = 1.4
"""Shortest leg between two corners, metres."""
MAX_TURN_DEG = 90.0
"""Sharpest turn at one corner, degrees."""
GAP_M = 0.4
"""Least wall-to-wall gap between non-adjacent legs, metres."""
START_LEG_M = {"loop": 3.0, "course": 2.4}
"""Shortest first leg, metres: the spawn (1.0 m or 0.6 m in, jittered) stays behind the first
checkpoint, which crosses the middle of the first leg."""
START_SPAN = 1.5
"""A loop's start straight spans this many times an average leg's share of the circle."""
MAX_TRIES = 400


@dataclass(frozen=True)
class Design:
    """A track to build: a centreline (metres), a corridor width (metres), closed or not."""

    name: str
    description: str
    centreline: list[tuple[float, float]]
    width: float
    closed: bool = False
    header: str = "Written by scripts/make_study_tracks.py for the study's held-out tracks; do not tune on it."
    cap_start: bool = False  # a course: a wall across the corridor behind the start


def _left_normal(d: np.ndarray) -> np.ndarray:
    return np.array([d[1], -d[0]])  # y down: the kart's left


def offsets(points: np.ndarray, half: float, closed: bool) -> tuple[np.ndarray, np.ndarray]:
    """The corridor's left and right walls: mitred offsets of ``points`` by ``half``."""
    n = len(points)
    left, right = [], []
    for i in range(n):
        prev = points[i - 1] if (closed or i > 0) else None
        nxt = points[(i + 1) % n] if (closed or i < n - 1) else None
        normals = []
        if prev is not None:
            d = points[i] - prev
            normals.append(_left_normal(d / np.linalg.norm(d)))
        if nxt is not None:
            d = nxt - points[i]
            normals.append(_left_normal(d / np.linalg.norm(d)))
        if len(normals) == 1:
            left.append(points[i] + half * normals[0])
            right.append(points[i] - half * normals[0])
            continue
        n0, n1 = normals
        m = (n0 + n1) / (1.0 + float(n0 @ n1))
        if float(n0 @ n1) >= BEVEL_COS:
            left.append(points[i] + half * m)
            right.append(points[i] - half * m)
            continue
        # a sharp turn: the inside keeps its mitre, the outside is bevelled (no long wedge)
        turns_left = float(np.cross(points[i] - prev, nxt - points[i])) < 0  # y down
        inner, outer = (left, right) if turns_left else (right, left)
        sign = 1.0 if turns_left else -1.0
        inner.append(points[i] + sign * half * m)
        outer.extend([points[i] - sign * half * n0, points[i] - sign * half * n1])
    return np.array(left), np.array(right)


def _across(p: np.ndarray, d: np.ndarray, half: float) -> tuple[np.ndarray, np.ndarray]:
    n = _left_normal(d / np.linalg.norm(d))
    return p + half * n, p - half * n


def _legs(design: Design, pts: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    n = len(pts)
    return [(pts[i], pts[(i + 1) % n]) for i in range(n - (0 if design.closed else 1))]


def track_toml(design: Design) -> str:
    """The TOML text of ``design``'s track; raises :class:`TrackError` if it leaves the world."""
    pts = np.array(design.centreline, dtype=float)
    half = design.width / 2
    left, right = offsets(pts, half, design.closed)
    legs = _legs(design, pts)
    start_dir = legs[0][1] - legs[0][0]
    start_dir = start_dir / np.linalg.norm(start_dir)
    spawn = pts[0] + (1.0 if design.closed else 0.6) * start_dir
    checkpoints = [_across((a + b) / 2, b - a, half) for a, b in legs]
    if design.closed:  # the lap ends 0.3 m into the first leg, behind the spawn point
        finish = _across(pts[0] + 0.3 * start_dir, start_dir, half)
        walls = [np.vstack([left, left[:1]]), np.vstack([right, right[:1]])]
    else:
        finish = _across(pts[-1], pts[-1] - pts[-2], half)
        back = _across(pts[0], start_dir, half)
        walls = [np.vstack([back[0], left]), np.vstack([back[1], right])]
        if design.cap_start:  # else a kart can leave backwards (the study's tracks do)
            walls.append(np.vstack([back[0], back[1]]))
    length = sum(float(np.linalg.norm(b - a)) for a, b in legs)
    all_pts = np.vstack([*walls, *(np.array(c) for c in checkpoints)])
    shift = -all_pts.min(axis=0) + MARGIN_M

    def px(p: np.ndarray) -> str:
        x, y = (p + shift) * PIXELS_PER_METRE
        if max(x, y) > WORLD_PX:
            raise TrackError(f"{design.name}: ({x:.0f}, {y:.0f}) px is off screen; shrink it")
        return f"[{round(x)}, {round(y)}]"

    heading = math.degrees(math.atan2(start_dir[1], start_dir[0]))
    lines = [
        f"# {design.name}: {design.description}",
        f"# {design.header}",
        'schema = "snnkart/track/v1"',
        f'name = "{design.name}"',
        f'description = "{design.description}"',
        f"pixels_per_metre = {PIXELS_PER_METRE}  # x right, y down, px",
        f"time_limit_s = {max(30.0, round(SECONDS_PER_METRE * length)):.1f}"
        f"  # {length:.1f} m of centreline",
        "",
        "[spawn]",
        f"position = {px(spawn)}  # px",
        f"heading_deg = {round(heading) % 360}  # 0 = +x (east), clockwise on screen",
        "jitter = 20  # px, uniform per axis",
    ]
    for wall in walls:
        lines += ["", "[[walls]]", "points = [" + ", ".join(px(p) for p in wall) + "]"]
    for i, (a, b) in enumerate([*checkpoints, finish]):
        tag = "  # finish line" if i == len(checkpoints) else ""
        lines += ["", f"[[checkpoints]]{tag}", f"a = {px(a)}", f"b = {px(b)}"]
    return "\n".join(lines) + "\n"


def generated_toml(
    seed: int, kind: str = "loop", length_m: float | None = None, width_m: float | None = None
) -> str:
    """The TOML text of the track generated from ``seed`` (see the module docstring).

    ``length_m`` (centreline, metres) and ``width_m`` (corridor, metres) are drawn from the
    seed when not given. The same arguments give the same text on every machine.
    """
    return track_toml(generated_design(seed, kind, length_m, width_m))


def generated_design(
    seed: int, kind: str = "loop", length_m: float | None = None, width_m: float | None = None
) -> Design:
    """The :class:`Design` behind :func:`generated_toml`: the first draw that fits."""
    _check_request(seed, kind, length_m, width_m)
    rng = np.random.default_rng([seed, KINDS.index(kind)])
    for _ in range(MAX_TRIES):
        width = width_m if width_m is not None else float(rng.uniform(1.2, 1.6))
        length = length_m if length_m is not None else float(rng.uniform(*LENGTH_RANGE_M[kind]))
        centre = _loop(rng, length) if kind == "loop" else _course(rng, length)
        if centre is None or not _clear(centre, width, kind == "loop"):
            continue
        design = Design(
            f"{kind}-{seed}",
            f"generated {kind}, seed {seed}: {len(centre)} corners, {width:.2f} m corridors",
            [(round(float(x), 3), round(float(y), 3)) for x, y in centre],
            round(width, 3),
            closed=kind == "loop",
            cap_start=kind == "course",
            header=f"Written by snnkart track generate --seed {seed} --kind {kind}.",
        )
        try:
            parse_track(track_toml(design), source=design.name)
        except TrackError:
            continue
        return design
    raise TrackError(
        f"no {kind} (seed {seed}, length {length_m or 'drawn'} m, width {width_m or 'drawn'} m) "
        f"fits the 10 m world in {MAX_TRIES} tries; ask for a shorter track or narrower corridors"
    )


def generate_track(
    seed: int, kind: str = "loop", length_m: float | None = None, width_m: float | None = None
) -> Track:
    """The validated :class:`Track` generated from ``seed`` (see :func:`generated_toml`)."""
    text = generated_toml(seed, kind, length_m, width_m)
    return parse_track(text, source=f"generated track (seed {seed}, {kind})")


def _check_request(seed: int, kind: str, length_m: float | None, width_m: float | None) -> None:
    if kind not in KINDS:
        raise TrackError(f"unknown track kind {kind!r}; choose one of {', '.join(KINDS)}")
    if seed < 0:
        raise TrackError(f"track seed {seed} is negative; use a seed >= 0")
    low, high = LENGTH_RANGE_M[kind]
    if length_m is not None and not low <= length_m <= high:
        raise TrackError(
            f"track length {length_m} m is outside {low}..{high} m for a {kind}; "
            "choose a length in that range"
        )
    if width_m is not None and not WIDTH_RANGE_M[0] <= width_m <= WIDTH_RANGE_M[1]:
        raise TrackError(
            f"corridor width {width_m} m is outside {WIDTH_RANGE_M[0]}..{WIDTH_RANGE_M[1]} m "
            "(narrower does not fit the steer car's turns); choose a width in that range"
        )


def _loop(rng: np.random.Generator, length: float) -> np.ndarray | None:
    """A closed centreline: corners spread round a circle of circumference ``length`` (radii
    and angles jittered), starting on its longest leg (the start straight, :data:`START_SPAN`)."""
    n = int(rng.integers(5, 9))
    span = np.concatenate([[START_SPAN], rng.uniform(0.8, 1.2, n - 1)])  # per leg
    angles = 2 * np.pi * np.concatenate([[0.0], np.cumsum(span)[:-1]]) / span.sum()
    radius = length / (2 * np.pi) * rng.uniform(0.8, 1.2, n)
    pts = np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)
    legs = np.linalg.norm(np.roll(pts, -1, axis=0) - pts, axis=1)
    pts *= length / legs.sum()  # the polygon's perimeter is the length asked for
    legs *= length / legs.sum()
    pts = np.roll(pts, -int(legs.argmax()), axis=0)
    ok = legs.max() >= START_LEG_M["loop"] and _shape_ok(pts, closed=True)
    return pts if ok else None


def _course(rng: np.random.Generator, length: float) -> np.ndarray | None:
    """An open centreline: a walk of legs with turns of at most :data:`MAX_TURN_DEG`."""
    n = int(rng.integers(4, 8))
    legs = rng.uniform(0.6, 1.4, n)
    legs[0] = max(legs[0] * length / legs.sum(), START_LEG_M["course"])
    legs[1:] *= (length - legs[0]) / legs[1:].sum()  # the legs add up to the length asked for
    turns = np.radians(rng.uniform(-MAX_TURN_DEG, MAX_TURN_DEG, n - 1))
    heading = np.concatenate([[0.0], np.cumsum(turns)])
    steps = np.stack([legs * np.cos(heading), legs * np.sin(heading)], axis=1)
    pts = np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)])
    return pts if _shape_ok(pts, closed=False) else None


def _shape_ok(pts: np.ndarray, closed: bool) -> bool:
    """Every leg long enough, every corner's turn gentle enough."""
    seq = np.vstack([pts, pts[:1]]) if closed else pts
    d = np.diff(seq, axis=0)
    if (np.linalg.norm(d, axis=1) < MIN_LEG_M).any():
        return False
    d_next = np.roll(d, -1, axis=0) if closed else d[1:]
    d_prev = d if closed else d[:-1]
    cos = (d_prev * d_next).sum(1) / np.linalg.norm(d_prev, axis=1) / np.linalg.norm(d_next, axis=1)
    return bool((cos >= math.cos(math.radians(MAX_TURN_DEG))).all())


def _clear(pts: np.ndarray, width: float, closed: bool) -> bool:
    """No two non-adjacent legs closer than 1.5 corridor widths plus :data:`GAP_M` (centreline
    to centreline: half a width for each corridor, and half more for a mitred corner or a
    course's square end that sticks out towards another leg)."""
    seq = np.vstack([pts, pts[:1]]) if closed else pts
    n = len(seq) - 1
    t = np.linspace(0.0, 1.0, 25)[:, None]
    samples = [seq[i] + t * (seq[i + 1] - seq[i]) for i in range(n)]
    for i in range(n):
        for j in range(i + 2, n):
            if closed and i == 0 and j == n - 1:
                continue  # the first and last legs meet at the start corner
            gap = np.linalg.norm(samples[i][:, None] - samples[j][None], axis=2).min()
            if gap < 1.5 * width + GAP_M:
                return False
    return True


RANDOM_SEEDS = 2**31
"""Generator seeds a random-track env draws from (``[0, RANDOM_SEEDS)``)."""


def random_marker_toml() -> str:
    """The text of ``snnkart/tracks/random.toml``: the track ``track = "random"`` stands for in
    checkpoints and manifests (generator seed 0, named ``random``; an env shows it until its
    first reset)."""
    design = dataclasses.replace(
        generated_design(0, "loop"),
        name=RANDOM_TRACK,
        description=RANDOM_DESCRIPTION,
        header="Written by snnkart.envs.trackgen.random_marker_toml; do not edit.",
    )
    return track_toml(design)


def random_track(seed: int) -> Track:
    """The track of generator seed ``seed`` as ``track = "random"`` uses it: a loop for an
    even seed, a course for an odd one, length and width drawn from the seed."""
    return _random_track(seed)


@functools.lru_cache(maxsize=64)
def _random_track(seed: int) -> Track:
    return generate_track(seed, KINDS[seed % 2])


@functools.lru_cache(maxsize=64)
def random_route(seed: int, clearance: float) -> GeodesicField:
    """The geodesic route field of :func:`random_track` ``(seed)`` (cached: an env that meets a
    track again, as evaluation over a seed range does, reuses it)."""
    return geodesic_field(random_track(seed), clearance=clearance)


REPORTING_SEEDS: tuple[int, ...] = tuple(RANDOM_SEEDS + k for k in range(20))
"""The generator seeds of the generalisation study's reporting tracks (10 loops, 10 courses:
``KINDS[seed % 2]``), committed before any result: at and above :data:`RANDOM_SEEDS`, outside
the range ``track="random"`` draws from, so no policy ever trains on them. Written to
``benchmarks/tracks/generated/`` by ``scripts/make_study_tracks.py``."""


def reporting_track_names() -> tuple[str, ...]:
    """The names (file stems) of the reporting tracks of :data:`REPORTING_SEEDS`."""
    return tuple(f"{KINDS[s % 2]}-{s}" for s in REPORTING_SEEDS)
