"""The progress potential: geodesic distance to the next checkpoint line through free space."""

from __future__ import annotations

import dataclasses
import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from snnkart.envs.constants import KART_RADIUS_PX
from snnkart.envs.gazebo import GazeboEnv
from snnkart.envs.geodesic import geodesic_field
from snnkart.envs.geometry import segment_distance
from snnkart.envs.grid import GridEnv
from snnkart.envs.steer import SteerEnv
from snnkart.envs.tracks import Checkpoint, Track, TrackError, load_track, parse_track

R = KART_RADIUS_PX
ROOT = Path(__file__).resolve().parents[1]


def make_track(walls, checkpoints, spawn, name="t") -> Track:
    track = Track(
        name=name,
        walls=tuple(tuple(map(tuple, w)) for w in walls),
        checkpoints=tuple(Checkpoint(tuple(a), tuple(b)) for a, b in checkpoints),
        spawn_position=spawn,
        spawn_heading=0.0,
        spawn_jitter=0.0,
        time_limit_s=10.0,
    )
    return parse_track(track.to_toml(), source=name)


# A straight corridor 100 px wide from x = 0 to x = 600, finish line at x = 500.
CORRIDOR = make_track(
    walls=[[(0, 100), (600, 100)], [(0, 200), (600, 200)], [(0, 100), (0, 200)]],
    checkpoints=[((500, 100), (500, 200))],
    spawn=(60.0, 150.0),
    name="corridor",
)

# An L: east along y in [100, 200] to x = 400, then south along x in [300, 400] to y = 600.
# The finish line crosses the south leg at y = 500.
L_TRACK = make_track(
    walls=[
        [(0, 100), (400, 100), (400, 600)],  # outer wall
        [(0, 200), (300, 200), (300, 600)],  # inner wall, corner at (300, 200)
        [(0, 100), (0, 200)],
    ],
    checkpoints=[((300, 500), (400, 500))],
    spawn=(60.0, 150.0),
    name="L",
)


def test_straight_corridor_distance_is_euclidean_to_touching_the_line():
    """In open space the distance is the straight distance to where the kart touches the line
    (its centre one radius before it), within the grid's 16-neighbour error."""
    field = geodesic_field(CORRIDOR)
    for x in (60.0, 150.0, 333.3, 420.0):
        for y in (130.0, 150.0, 171.0):
            expected = 500.0 - R - x
            assert field.distance(0, x, y) == pytest.approx(expected, abs=4.0, rel=0.02)


def test_distance_goes_around_corners_not_through_walls():
    """In the L, a point in the east leg is measured around the inner corner: longer than
    the straight line through the wall, and as long as the corner path (to ~2 %)."""
    field = geodesic_field(L_TRACK)
    x, y = 100.0, 150.0
    target_y = 500.0 - R  # where the kart touches the finish line
    straight = math.hypot(350.0 - x, target_y - y)
    # The shortest path keeps one kart radius c from the inner corner (300, 200): straight
    # to (300, 200 - c), a quarter circle of radius c, then straight down at x = 300 + c.
    c = R
    around = math.hypot(300.0 - x, 200.0 - c - y) + math.pi / 2 * c + (target_y - 200.0)
    d = field.distance(0, x, y)
    assert d > straight + 20.0
    assert d == pytest.approx(around, rel=0.03)


def test_distance_falls_steadily_along_the_centreline_around_a_corner():
    """Driving the L (east, across the corner square, then south) lowers the distance at every
    step: no flat stretch or rise before the corner where a policy could park for free."""
    field = geodesic_field(L_TRACK)
    east = [(x, 150.0) for x in np.arange(60.0, 300.0, 5.0)]
    corner = [(300.0 + t, 150.0 + t) for t in np.arange(0.0, 50.0, 5.0)]
    south = [(350.0, y) for y in np.arange(200.0, 500.0 - R, 5.0)]
    d = [field.distance(0, x, y) for x, y in east + corner + south]
    assert all(np.isfinite(d))
    assert np.all(np.diff(d) < 0.0), np.diff(d)


def test_behind_the_checkpoint_just_passed_the_way_leads_back_across_it():
    """On small_S, field 2 (the second checkpoint) at the start area, behind checkpoint 1:
    the distance is the way back across checkpoint 1 (longer than the way to checkpoint 1
    itself) and the route points to checkpoint 1, so a kart that overshoots is not lost."""
    track = load_track("small_S")
    field = geodesic_field(track)
    sx, sy = track.spawn_position
    d0, d1 = field.distance(0, sx, sy), field.distance(1, sx, sy)
    assert math.isfinite(d0) and math.isfinite(d1)
    assert d1 > d0 + 100.0
    r0, r1 = field.route(0, sx, sy), field.route(1, sx, sy)
    assert r0 is not None and r1 is not None
    assert r0[0] * r1[0] + r0[1] * r1[1] > 0.9


def test_steer_route_bends_no_tighter_than_the_car_can_turn():
    """The steer car cannot turn on the spot: its route keeps its turning radius (0.36 m at
    full lock), not just its body radius, from the walls, so around the L's inner corner the
    path is a quarter circle of that radius, which the car can drive. Vehicles that turn on
    the spot (gazebo) keep the body radius."""
    steer, gazebo = SteerEnv(track=L_TRACK), GazeboEnv(track=L_TRACK)
    p = steer.config.physics
    c = p.wheelbase_m / math.tan(math.radians(p.max_steer_deg)) * 100.0
    assert steer.route_clearance() == pytest.approx(c) and c > R + 10.0
    assert gazebo.route_clearance() == R
    x, y, target_y = 100.0, 150.0, 500.0 - R
    around = math.hypot(300.0 - x, 200.0 - c - y) + math.pi / 2 * c + (target_y - 200.0)
    assert steer._geodesic.distance(0, x, y) == pytest.approx(around, rel=0.03)
    # The route passes the corner at least the turning radius from it.
    x, y = 100.0, 150.0
    closest = math.inf
    for _ in range(400):
        r = steer._geodesic.route(0, x, y)
        if r is None:
            break
        x, y = x + 2.0 * r[0], y + 2.0 * r[1]
        closest = min(closest, math.hypot(x - 300.0, y - 200.0))
    assert y > 450.0  # reached the finish
    assert closest == pytest.approx(c, abs=4.0)
    with pytest.raises(ValueError, match="less than the kart radius"):
        geodesic_field(L_TRACK, clearance=R - 1.0)


def test_route_clearance_can_be_set_in_the_env_config():
    """``route_clearance_m`` widens the route of any env (gazebo here), and values below the
    kart radius are refused by the config."""
    wide = GazeboEnv(track=L_TRACK, config={"route_clearance_m": 0.3})
    assert wide.route_clearance() == pytest.approx(30.0)
    assert GazeboEnv(track=L_TRACK).route_clearance() == R
    x, y, c = 100.0, 150.0, 30.0
    around = math.hypot(300.0 - x, 200.0 - c - y) + math.pi / 2 * c + (500.0 - R - 200.0)
    assert wide._geodesic.distance(0, x, y) == pytest.approx(around, rel=0.03)
    with pytest.raises(ValueError, match="route_clearance_m"):
        GazeboEnv(track=L_TRACK, config={"route_clearance_m": 0.1})


def test_checkpoint_without_room_for_the_kart_is_refused():
    """A checkpoint line with no free space within one kart radius (a wall lies along it) is a
    track error that names the checkpoint, not a silent zero reward."""
    track = make_track(
        walls=[[(0, 100), (600, 100)], [(0, 200), (600, 200)], [(0, 100), (0, 200)]],
        checkpoints=[((100, 100), (500, 100))],  # lies on the wall
        spawn=(60.0, 150.0),
        name="bad",
    )
    with pytest.raises(TrackError, match="checkpoint 1"):
        geodesic_field(track)


@pytest.mark.parametrize("env_class", [GridEnv, GazeboEnv])
def test_progress_reward_is_the_drop_in_geodesic_distance(env_class):
    """Each step's progress term equals the decrease of the geodesic distance to the next
    checkpoint (per metre), so the terms of a stretch add up to the distance made good."""
    env = env_class(track="small_S", action_mode="discrete")
    field = geodesic_field(env.track)
    env.reset(seed=3)
    env.action_space.seed(0)
    for _ in range(150):
        k_before = env.next_checkpoint
        x0, y0 = env.position
        _, _, terminated, truncated, info = env.step(env.action_space.sample())
        if terminated or truncated:
            break
        if env.next_checkpoint != k_before:
            continue
        x1, y1 = env.position
        expected = (field.distance(k_before, x0, y0) - field.distance(k_before, x1, y1)) / 100.0
        assert info["reward_terms"]["progress"] == pytest.approx(
            env.config.reward.progress * expected, abs=1e-12
        )


def test_route_follows_the_corridor_and_turns_at_the_corner():
    """The route (steepest descent of the distance) points along the east leg, down-right
    near the inner corner, and straight down the south leg."""
    field = geodesic_field(L_TRACK)
    east = field.route(0, 100.0, 150.0)
    corner = field.route(0, 280.0, 140.0)  # heads for the inner corner at (300, 200)
    south = field.route(0, 350.0, 350.0)
    assert east is not None and corner is not None and south is not None
    assert east[0] > 0.95  # east (slightly down, towards the corner)
    assert corner[0] > 0.2 and corner[1] > 0.5  # down-right, around the corner
    assert south == pytest.approx((0.0, 1.0), abs=0.05)
    assert field.route(0, 350.0, 495.0) is None  # touching the line: no path left


def test_observation_gives_the_way_around_the_corner_not_through_the_wall():
    """In the L, the grid kart at the start sees the next checkpoint to the east (the way
    round the corner), although the line itself lies to the south-east behind a wall; the
    distance observation is the path length."""
    env = GridEnv(track=L_TRACK, config={"checkpoint_distance_scale_m": 10.0})
    obs, _ = env.reset(seed=0)
    names = [f.name for f in env.observation_layout for _ in range(f.size)]
    cos, sin = obs[names.index("checkpoint_cos")], obs[names.index("checkpoint_sin")]
    dist = obs[names.index("checkpoint_distance")]
    assert cos > 0.95 and abs(sin) < 0.3
    x, y = env.position
    assert dist == pytest.approx(geodesic_field(L_TRACK).distance(0, x, y) / 1000.0, rel=1e-6)
    straight = math.atan2(500.0 - y, 300.0 - x)  # to the line's nearest point: 56° south of east
    assert math.cos(straight) < 0.6


def test_turning_on_the_spot_towards_the_route_pays_the_heading_term():
    """Gazebo on the L, spinning right on the spot from facing north: each step's heading term
    is the change of checkpoint_cos times its weight, so over a full turn they add up to
    nothing (potential-based), and they are positive while the kart turns towards the route."""
    env = GazeboEnv(track=L_TRACK, config={"reward": {"stand_still_steps": 10_000}})
    weight = env.config.reward.heading
    obs, _ = env.reset(seed=0)
    names = [f.name for f in env.observation_layout for _ in range(f.size)]
    icos = names.index("checkpoint_cos")
    right = 4
    cos_prev, total, gained = float(obs[icos]), 0.0, []
    steps = 0
    while env.heading < 2 * math.pi or steps < 10:
        obs, _, terminated, truncated, info = env.step(right)
        steps += 1
        assert not (terminated or truncated)
        term = info["reward_terms"]["heading"]
        assert term == pytest.approx(weight * (float(obs[icos]) - cos_prev), abs=1e-6)
        total += term
        gained.append(term)
        cos_prev = float(obs[icos])
    assert max(gained) > 0.0 and min(gained) < 0.0
    # A full turn and a little: the sum is the change of cos since the start.
    assert total == pytest.approx(weight * (cos_prev - float(env.reset(seed=0)[0][icos])), abs=1e-6)


def test_grid_has_no_heading_term():
    """The grid kart does not rotate; its heading term is always zero."""
    env = GridEnv(track=L_TRACK)
    env.reset(seed=0)
    env.action_space.seed(1)
    for _ in range(100):
        *_, terminated, truncated, info = env.step(env.action_space.sample())
        assert info["reward_terms"]["heading"] == 0.0
        if terminated or truncated:
            env.reset()


RING = "benchmarks/tracks/ring.toml"
# the ring's corridor centreline from the spawn (anticlockwise on screen), a lap and a bit
RING_LAP = [(260, 660), (660, 660), (660, 160), (160, 160), (160, 660), (340, 660)]


def ring_variant(x: float) -> Track:
    """The ring with one more line at ``x``, just after its last corner, where the nearest
    cells on either side are equally far from the way there, and the finish beyond the
    spawn."""
    ring = load_track(ROOT / RING)
    lines = (((x, 600.0), (x, 720.0)), ((320.0, 600.0), (320.0, 720.0)))
    cps = ring.checkpoints[:4] + tuple(Checkpoint(a, b) for a, b in lines)
    variant = dataclasses.replace(ring, checkpoints=cps, name="ring-variant")
    return parse_track(variant.to_toml(), source="ring-variant")


@pytest.mark.parametrize(
    "variant", [None, 198.0, 200.0], ids=["ring", "line-off-grid", "line-on-grid"]
)
@pytest.mark.parametrize("env_class", [GridEnv, SteerEnv])
def test_on_a_loop_passing_a_checkpoint_pays_no_windfall(env_class, variant):
    """Along the ring's centreline, as the env counts it (a line is passed when the kart
    touches it; the progress of a step is the drop in the distance to the next line, the old
    position measured on the new line's field), no step earns more progress than its length.
    Before the fix, the kart touching a line with its centre short of it was measured the way
    round the loop: about -1 step per step, then +8 m or more as the centre crossed. The
    variants add a line just after a corner, between the field's 4 px cells or on them."""
    track = load_track(ROOT / RING) if variant is None else ring_variant(variant)
    env = env_class(track=track)
    field = geodesic_field(track, clearance=env.route_clearance())
    step = 4.0
    points = []
    for (x0, y0), (x1, y1) in itertools.pairwise(RING_LAP):
        n = int(math.hypot(x1 - x0, y1 - y0) / step)
        points += [(x0 + (x1 - x0) * i / n, y0 + (y1 - y0) * i / n) for i in range(n)]
    k, passed, worst = 0, 0, 0.0
    for (x0, y0), (x1, y1) in itertools.pairwise(points):
        cp = track.checkpoints[k]
        if k < len(track.checkpoints) - 1 and segment_distance(x1, y1, *cp.a, *cp.b) <= R:
            k, passed = k + 1, passed + 1
        progress = field.distance(k, x0, y0) - field.distance(k, x1, y1)
        worst = max(worst, abs(progress))
    assert passed == len(track.checkpoints) - 1
    assert worst <= step * 1.1, f"a step of {step} px earned {worst:.1f} px of progress"
