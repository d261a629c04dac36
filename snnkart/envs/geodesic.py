"""Geodesic distance to each checkpoint line through the track's free space.

The progress reward is the decrease of this distance: how much nearer the kart came to
touching the next checkpoint line, measured along the shortest path a kart centre can take
(around corners, never through walls). The straight-line distance to the line, used before,
is flat or even rising along the way around a corner, which left policies parked at corners.
As a potential-based shaping term (Ng, Harada and Russell, 1999) it cannot be farmed: over a
stretch between two checkpoints it sums to the distance driven towards the next one.

The field is computed once per track (and cached) by Dijkstra's algorithm on a grid of
``CELL_PX`` cells with 16-neighbour moves (within ~1 % of Euclidean length in open space).

Paths run on the *road*: where the kart centre is at least a clearance from every wall, so
the way around a corner is one the vehicle can drive, not one that scrapes the corner. The
clearance is the kart radius, or for a car that cannot turn on the spot (steer) its turning
radius: a shortest path bends only around wall corners, on circles of the clearance's
radius, so the car can follow it. A route that hugged corners more tightly than the car can
turn led steer policies into spots from which the next turn could not be made.

Cells nearer a wall, down to ``FREE_CLEARANCE_PX``, form a *margin*: each takes the value of
its nearest road cell plus the straight way there (or, where a wall lies in between, the way
through the margin), so the bilinear lookup has four corners even when the kart grazes a
wall, and no way along the margin cuts a corner more tightly than the road. No move between
two cells of at least that clearance can cross a wall, because a wall crossing a move of
length L would leave one end within L/2 of it.

The sources of field k are the road cells where the kart touches checkpoint line k (within
one kart radius of it), and moves across line k-1 are removed, so the distance never takes a
way back through the checkpoint just passed (it would on a loop whose checkpoints are more
than half a lap apart); cells behind that line then get the way back across it. On a loop,
the cells behind the line are not cut off: they reach line k the way round the other way.
Those just before line k-1, where a kart touching it has passed it with its centre still
short of it, take the way forward across it instead (:func:`_just_passed`); else the
distance would jump by most of a lap as the centre crosses, a windfall of progress at every
checkpoint that kept grid karts from ever finishing the ring track (issue 17).
"""

from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.ndimage import distance_transform_edt
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from snnkart.envs.constants import KART_RADIUS_PX
from snnkart.envs.geometry import segment_distance, segments_cross
from snnkart.envs.tracks import Track, TrackError

CELL_PX = 4.0
"""Grid spacing, px (4 cm)."""

FREE_CLEARANCE_PX = 0.6 * KART_RADIUS_PX
"""A cell centre this far from every wall is free (see the module docstring for the bound)."""

_MOVES = ((1, 0), (0, 1), (1, 1), (1, -1), (1, 2), (2, 1), (1, -2), (2, -1))
"""Half of the 16 neighbour moves (di, dj); the graph is undirected."""


@dataclass(frozen=True, eq=False)
class GeodesicField:
    """Distances (px) from grid cells to each checkpoint line and their gradients; NaN where
    a cell is not free or cannot reach the line."""

    origin: tuple[float, float]  # centre of cell [0, 0], px
    cell: float
    dist: np.ndarray  # [n_checkpoints, rows (y), cols (x)]
    grad: np.ndarray  # [n_checkpoints, 2 (d/dx, d/dy), rows, cols], px per px

    def distance(self, k: int, x: float, y: float) -> float:
        """Geodesic distance (px) from (x, y) to checkpoint line ``k``, bilinear between cells.

        Corners that are not free (or unreachable) are left out of the interpolation; NaN when
        none of the four is usable (the kart is inside a wall, or cannot reach the line).
        """
        return self._sample(self.dist[k], x, y)

    def route(self, k: int, x: float, y: float) -> tuple[float, float] | None:
        """Unit vector (x, y) along the shortest path to checkpoint line ``k`` (the distance's
        steepest descent); None where it is undefined (touching the line, inside a wall)."""
        gx = self._sample(self.grad[k, 0], x, y)
        gy = self._sample(self.grad[k, 1], x, y)
        norm = math.hypot(gx, gy)
        if not norm > 0.1:  # also NaN; |grad| is 1 along a path, ~0 on the line itself
            return None
        return (-gx / norm, -gy / norm)

    def _sample(self, grid: np.ndarray, x: float, y: float) -> float:
        return _bilinear(grid, self.origin[0], self.origin[1], self.cell, x, y)  # type: ignore[no-any-return]


@njit(cache=True, nogil=True)
def _bilinear(grid: np.ndarray, ox: float, oy: float, cell: float, x: float, y: float) -> float:
    """Bilinear interpolation of ``grid`` (cell [0, 0] centred at (ox, oy)) at (x, y), over
    the corners that are not NaN; NaN when none is."""
    fx = (x - ox) / cell
    fy = (y - oy) / cell
    i = math.floor(fx)
    j = math.floor(fy)
    tx = fx - i
    ty = fy - j
    rows, cols = grid.shape
    total = 0.0
    weight = 0.0
    for dj in range(2):
        for di in range(2):
            w = (tx if di else 1.0 - tx) * (ty if dj else 1.0 - ty)
            r = j + dj
            c = i + di
            if 0 <= r < rows and 0 <= c < cols and w > 0.0:
                v = grid[r, c]
                if v == v:  # not NaN
                    total += w * v
                    weight += w
    return total / weight if weight > 0.0 else math.nan


def _gradient(d: np.ndarray, cell: float) -> np.ndarray:
    """[2, rows, cols] finite-difference gradient of ``d``: central where both neighbours are
    defined, one-sided where one is, NaN where neither is or ``d`` itself is NaN."""
    p = np.pad(d, 1, constant_values=np.nan)
    out = np.empty((2, *d.shape))
    for axis, (lo, hi) in enumerate(((p[1:-1, :-2], p[1:-1, 2:]), (p[:-2, 1:-1], p[2:, 1:-1]))):
        central = (hi - lo) / (2.0 * cell)
        forward = (hi - d) / cell
        backward = (d - lo) / cell
        g = np.where(np.isnan(central), np.where(np.isnan(forward), backward, forward), central)
        g[np.isnan(d)] = np.nan
        out[axis] = g
    return out


def _extend(d: np.ndarray, a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Distances continued from the cells where ``d`` is finite (starting at their values)
    over the edges (a, b, w): Dijkstra from one extra node joined to each of those cells by
    an edge as long as its distance."""
    n = d.shape[0]
    reached = np.flatnonzero(np.isfinite(d))
    graph = coo_matrix(
        (
            np.concatenate([w, d[reached] + 1e-9]),  # + 1e-9: a zero weight is no edge
            (np.concatenate([a, np.full(reached.size, n)]), np.concatenate([b, reached])),
        ),
        shape=(n + 1, n + 1),
    )
    return dijkstra(graph.tocsr(), directed=False, indices=n)[:n]  # type: ignore[no-any-return]


PASSED_BAND_PX = 2.0 * KART_RADIUS_PX
"""How far before a checkpoint line the next line's field takes the way forward across it: a
kart touching the line is within one radius of it, and the step before, and the cells of the
bilinear lookup, lie within another (a kart at the default top speed, 4 m/s, moves 7 px a
step). A kart that touches the line and then backs out of the band is measured the way
round the loop again: a drop in progress it wins back on return, never a net gain."""


def _nearest(
    fx: np.ndarray, fy: np.ndarray, drive: np.ndarray, p: tuple[float, float]
) -> np.ndarray:
    """The road cell nearest to point ``p``, as an index array of one."""
    d2 = np.where(drive, (fx - p[0]) ** 2 + (fy - p[1]) ** 2, np.inf)
    return np.array([int(np.argmin(d2))])


def _just_passed(
    track: Track,
    k: int,
    cells: tuple[np.ndarray, np.ndarray, np.ndarray],
    sources: np.ndarray,
    start: np.ndarray,
    edges: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> tuple[np.ndarray | None, np.ndarray]:
    """The road cells just before checkpoint line ``k``, on the side the kart comes from
    (from the cells ``start``, over ``edges``), within :data:`PASSED_BAND_PX` of the line and
    not behind a wall from it, the cells on the line included; and the road cells just
    beyond it, where the way to the line after it starts (the line's ``sources``, the cells
    touching it, where no side can be told: then None for the first, with a warning).

    The kart passes a line when it touches it, with its centre up to a radius before it. The
    next line's field takes no way across the line just passed, so on a loop these cells
    would get the way round the other way (most of a lap, and a windfall of progress once the
    centre crosses); they take the way forward across the line instead. The side the kart
    comes from is the one whose touching cells are nearer ``start`` on average (the nearest
    ones tie where the way arrives along the line, just after a corner).
    """
    fx, fy, drive = cells
    cp = track.checkpoints[k]
    (ax, ay), (bx, by) = cp.a, cp.b
    dx, dy = bx - ax, by - ay
    side = np.sign(dx * (fy - ay) - dy * (fx - ax))
    t = ((fx - ax) * dx + (fy - ay) * dy) / max(dx * dx + dy * dy, 1e-12)
    gap = segment_distance(fx, fy, ax, ay, bx, by)
    band = np.flatnonzero(drive & (t >= 0.0) & (t <= 1.0) & (gap <= PASSED_BAND_PX))
    px, py = ax + t[band] * dx, ay + t[band] * dy
    walled = np.zeros(band.shape, dtype=bool)
    for wall in track.segments:
        walled |= segments_cross(fx[band], fy[band], px, py, tuple(wall))
    band = band[~walled]
    seed = np.full(fx.shape, np.inf)
    seed[start] = 0.0
    from_start = _extend(seed, *edges)
    touching = band[gap[band] <= KART_RADIUS_PX]
    ways = [from_start[touching[side[touching] == s]] for s in (1.0, -1.0)]
    means = [float(w[np.isfinite(w)].mean()) if np.isfinite(w).any() else np.inf for w in ways]
    if not np.isfinite(min(means)) or means[0] == means[1]:
        warnings.warn(
            f"track {track.name!r} ({track.source}): cannot tell from which side the kart "
            f"reaches checkpoint {k + 1}; on a loop its progress may jump as the kart passes it",
            stacklevel=3,
        )
        return None, sources
    approach = 1.0 if means[0] < means[1] else -1.0
    beyond = band[side[band] == -approach]
    return band[side[band] != -approach], beyond if beyond.size else sources


def _touching(
    track: Track, k: int, fx: np.ndarray, fy: np.ndarray, drive: np.ndarray, clearance: float
) -> np.ndarray:
    """The road cells where the kart touches checkpoint line ``k`` (the sources of its field)."""
    cp = track.checkpoints[k]
    touching = (segment_distance(fx, fy, *cp.a, *cp.b) <= KART_RADIUS_PX) & drive
    if not touching.any():
        raise TrackError(
            f"track {track.name!r} ({track.source}): checkpoint {k + 1} leaves no room for "
            f"the kart to touch it {clearance:.1f} px from every wall (the kart's radius, "
            "or the car's turning radius in steer); move the line away from the walls or "
            "widen the track there"
        )
    return np.flatnonzero(touching)


@functools.lru_cache(maxsize=8)
def geodesic_field(
    track: Track, cell: float = CELL_PX, clearance: float = KART_RADIUS_PX
) -> GeodesicField:
    """Compute (once per track, cell size and clearance) the geodesic distance fields of
    ``track``. Paths keep ``clearance`` (px, at least the kart radius) from every wall; a
    shortest path bends only around wall corners, on circles of that radius, so a vehicle
    whose turning radius is ``clearance`` can drive it (see :meth:`KartEnv.route_clearance`).
    """
    if clearance < KART_RADIUS_PX:
        raise ValueError(
            f"clearance {clearance} px is less than the kart radius {KART_RADIUS_PX} px"
        )
    xmin, ymin, xmax, ymax = track.bounds
    xs = np.arange(xmin, xmax + cell, cell)
    ys = np.arange(ymin, ymax + cell, cell)
    gx, gy = np.meshgrid(xs, ys)  # [rows, cols]
    wall_distance = np.full(gx.shape, np.inf)
    for seg in track.segments:
        np.minimum(wall_distance, segment_distance(gx, gy, *seg), out=wall_distance)
    free = wall_distance >= FREE_CLEARANCE_PX
    index = np.full(gx.shape, -1, dtype=np.int64)
    index[free] = np.arange(int(free.sum()))
    rows, cols = gx.shape

    # Undirected edges between free cells: one array per move.
    edges = []
    for di, dj in _MOVES:
        r0 = slice(max(0, -dj), rows - max(0, dj))
        c0 = slice(max(0, -di), cols - max(0, di))
        r1 = slice(max(0, dj), rows - max(0, -dj))
        c1 = slice(max(0, di), cols - max(0, -di))
        a, b = index[r0, c0].ravel(), index[r1, c1].ravel()
        ok = (a >= 0) & (b >= 0)
        edges.append((a[ok], b[ok], cell * math.hypot(di, dj)))
    a = np.concatenate([e[0] for e in edges])
    b = np.concatenate([e[1] for e in edges])
    w = np.concatenate([np.full(e[0].shape, e[2]) for e in edges])
    fx, fy, fc = gx[free], gy[free], wall_distance[free]
    drive = fc >= clearance

    # Each margin cell's nearest road cell (index among the free cells) and the way there.
    drive_grid = np.zeros(gx.shape, dtype=bool)
    drive_grid[free] = drive
    if not drive_grid.any():
        raise TrackError(
            f"track {track.name!r} ({track.source}): nowhere {clearance:.1f} px from every "
            "wall (the kart's radius, or the car's turning radius in steer); widen the track"
        )
    steps, (ri, ci) = distance_transform_edt(~drive_grid, return_indices=True)
    margin_cells = np.flatnonzero(~drive)
    nearest = index[ri[free][margin_cells], ci[free][margin_cells]]
    extra = steps[free][margin_cells] * cell
    mx, my = fx[margin_cells], fy[margin_cells]
    blocked = np.zeros(margin_cells.shape, dtype=bool)
    for seg in track.segments:
        blocked |= segments_cross(mx, my, fx[nearest], fy[nearest], tuple(seg))
    # The path itself runs where the kart centre can be (``clearance`` from every wall).
    road = drive[a] & drive[b]

    n = int(free.sum())
    dist = np.full((len(track.checkpoints), rows, cols), np.nan)
    start = _nearest(fx, fy, drive, track.spawn_position)  # where the way to line 0 starts
    passed: np.ndarray | None = None  # cells where the kart has just touched line k-1
    for k in range(len(track.checkpoints)):
        sources = _touching(track, k, fx, fy, drive, clearance)
        keep = np.ones(a.shape, dtype=bool)
        if k > 0:
            prev = track.checkpoints[k - 1]
            keep = ~segments_cross(fx[a], fy[a], fx[b], fy[b], (*prev.a, *prev.b))
        ok = keep & road
        start_d = np.full(n, np.inf)
        start_d[sources] = 0.0
        d = _extend(start_d, a[ok], b[ok], w[ok])
        if passed is not None:
            d[passed] = np.inf  # on a loop, the way round the other way: see _just_passed
        # Behind the checkpoint just passed, the way leads back across it: a kart that
        # overshoots still has a distance to shrink (and a direction to follow).
        d = np.where(np.isfinite(d), d, _extend(d, a[road], b[road], w[road]))
        if k + 1 < len(track.checkpoints):
            kept = (a[ok], b[ok], w[ok])
            passed, start = _just_passed(track, k, (fx, fy, drive), sources, start, kept)
        # The margin (free, but nearer a wall than the clearance) takes the distance of its
        # nearest road cell plus the straight way there, so the bilinear lookup has four
        # corners even when the kart grazes a wall. No way runs along the margin: it would
        # cut corners more tightly than the road. Where a wall lies between a margin cell
        # and its nearest road cell, the way through the margin is taken instead.
        near = d[nearest] + extra
        if blocked.any():
            near[blocked] = _extend(d, a[~road], b[~road], w[~road])[margin_cells[blocked]]
        d[margin_cells] = near
        d = d - d[sources].min()  # 0 on the sources (less _extend's 1e-9 offset)
        dist[k][free] = np.where(np.isinf(d), np.nan, d)
    grad = np.stack([_gradient(d, cell) for d in dist])
    return GeodesicField(origin=(float(xs[0]), float(ys[0])), cell=cell, dist=dist, grad=grad)
