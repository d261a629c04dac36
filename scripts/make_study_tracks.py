"""Write the study's held-out tracks (``benchmarks/tracks/*.toml``) from centrelines.

Each track is a corridor of constant width around a centreline (metres, x right, y down):
walls are the centreline offset by half the width on either side (mitred corners), checkpoints
cross the corridor at the middle of every leg, and the finish line crosses the end of the last
leg (an open track) or the start (a closed loop: the lap ends where it began). The spawn sits
0.6 m into the first leg (1.0 m on a loop, clear of the finish line), facing along it. These tracks exist to measure whether training
defaults generalise: nobody tunes on them (issue 17).

    python scripts/make_study_tracks.py            # rewrites benchmarks/tracks/*.toml
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "tracks"
PX = 100.0  # pixels per metre, as the built-in tracks
WORLD_PX = 1000.0  # the renderer shows 0..1000 px on each axis (snnkart.envs.render)
MARGIN_M = 1.0  # canvas margin around the walls
BEVEL_COS = math.cos(math.radians(100))  # turns sharper than 100 degrees are bevelled outside
SECONDS_PER_METRE = 3.5  # time limit per metre of centreline (small_S: 30 s for about 8 m)


@dataclass(frozen=True)
class Design:
    name: str
    description: str
    centreline: list[tuple[float, float]]  # metres
    width: float  # metres
    closed: bool = False


DESIGNS = [
    Design(
        "ring",
        "a square ring: four 90-degree left corners, 1.2 m corridors, one lap (a user's first "
        "track in issue 17, where a steer SNN seed learned to stand still)",
        [(0, 0), (5, 0), (5, -5), (0, -5)],
        1.2,
        closed=True,
    ),
    Design(
        "zigzag",
        "sharp corners: a 60-degree right, a 120-degree left and a 60-degree right turn, "
        "1.0 m corridors",
        [(0, 0), (2.2, 0), (3.6, 2.4), (5.0, 0.0), (7.2, 0.0)],
        1.0,
    ),
    Design(
        "hairpins",
        "two U-turns of two 90-degree corners each, long straights, wide 1.6 m corridors",
        [(0, 0), (6, 0), (6, 2.6), (0, 2.6), (0, 5.2), (4, 5.2)],
        1.6,
    ),
    Design(
        "bends",
        "gentle 45-degree bends turning right through 180 degrees, 1.3 m corridors",
        [(0, 0), (3, 0), (5.1, 2.1), (5.1, 5.1), (3.0, 7.2), (0.0, 7.2)],
        1.3,
    ),
]


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


def track_toml(design: Design) -> str:
    pts = np.array(design.centreline, dtype=float)
    half = design.width / 2
    left, right = offsets(pts, half, design.closed)
    legs = [
        (pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts) - (0 if design.closed else 1))
    ]
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
    length = sum(float(np.linalg.norm(b - a)) for a, b in legs)
    all_pts = np.vstack([*walls, *(np.array(c) for c in checkpoints)])
    shift = -all_pts.min(axis=0) + MARGIN_M

    def px(p: np.ndarray) -> str:
        x, y = (p + shift) * PX
        if max(x, y) > WORLD_PX:
            raise SystemExit(f"{design.name}: ({x:.0f}, {y:.0f}) px is off screen; shrink it")
        return f"[{round(x)}, {round(y)}]"

    heading = math.degrees(math.atan2(start_dir[1], start_dir[0]))
    lines = [
        f"# {design.name}: {design.description}",
        "# Written by scripts/make_study_tracks.py for the study's held-out tracks; do not tune on it.",
        'schema = "snnkart/track/v1"',
        f'name = "{design.name}"',
        f'description = "{design.description}"',
        f"pixels_per_metre = {PX}  # x right, y down, px",
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


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for design in DESIGNS:
        path = OUT / f"{design.name}.toml"
        path.write_text(track_toml(design))
        print(f"wrote {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
