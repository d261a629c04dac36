"""LIDAR geometry against hand-computed distances: the numba kernel and the envs' ray layout."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snnkart.envs.gazebo import GazeboEnv
from snnkart.envs.grid import GridEnv
from snnkart.envs.lidar import cast_rays, ray_offsets
from snnkart.envs.steer import SteerEnv
from snnkart.envs.tracks import Checkpoint, Track, parse_track

# A 400 x 400 px box with walls at x = 100, x = 500, y = 100 and y = 500.
BOX_WALL = ((100.0, 100.0), (500.0, 100.0), (500.0, 500.0), (100.0, 500.0), (100.0, 100.0))
# Spans the box from the left wall to the right wall at y = 200 (the finish line).
BOX_CHECKPOINT = Checkpoint((100.0, 200.0), (500.0, 200.0))


def box_track(spawn: tuple[float, float], heading_deg: float = 0.0) -> Track:
    """The square box as a Track object (no jitter), validated by parsing its TOML."""
    track = Track(
        name="box",
        walls=(BOX_WALL,),
        checkpoints=(BOX_CHECKPOINT,),
        spawn_position=spawn,
        spawn_heading=math.radians(heading_deg),
        spawn_jitter=0.0,
        time_limit_s=10.0,
    )
    return parse_track(track.to_toml(), source="box")


def cast(x: float, y: float, angles_deg: list[float], segments: list, max_range: float):
    """Run the raw kernel; return the normalised distances."""
    angles = np.radians(np.asarray(angles_deg, dtype=np.float64))
    segs = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
    out = np.full(len(angles), -1.0)
    cast_rays(x, y, angles, segs, max_range, out)
    return out


# -- the numba kernel ---------------------------------------------------------------------------


def test_cast_rays_45_degree_ray_hits_vertical_segment():
    """A 45-degree ray from the origin meets the wall x = 10 at (10, 10): distance 10*sqrt(2)."""
    out = cast(0.0, 0.0, [45.0], [(10.0, -50.0, 10.0, 50.0)], 100.0)
    assert out[0] == pytest.approx(10.0 * math.sqrt(2.0) / 100.0, rel=1e-12)


def test_cast_rays_offset_origin_and_slanted_segment():
    """Origin (5, 5), ray at 0 deg, segment from (15, 0) to (25, 20): hit at x = 17.5."""
    out = cast(5.0, 5.0, [0.0], [(15.0, 0.0, 25.0, 20.0)], 50.0)
    assert out[0] == pytest.approx(12.5 / 50.0, rel=1e-12)


@pytest.mark.parametrize(
    ("angle_deg", "segment"),
    [
        (0.0, (0.0, 5.0, 100.0, 5.0)),  # exactly parallel, beside the ray
        (45.0, (0.0, 5.0, 50.0, 55.0)),  # parallel at 45 degrees
        (90.0, (5.0, 0.0, 5.0, 100.0)),  # parallel, vertical
    ],
)
def test_cast_rays_parallel_segment_is_no_hit(angle_deg, segment):
    """A segment parallel to the ray is never hit: the ray reports its full range (1.0)."""
    assert cast(0.0, 0.0, [angle_deg], [segment], 200.0)[0] == 1.0


def test_cast_rays_segment_behind_origin_is_no_hit():
    """A wall behind the sensor (x = -10 for a ray along +x) is not seen."""
    assert cast(0.0, 0.0, [0.0], [(-10.0, -50.0, -10.0, 50.0)], 100.0)[0] == 1.0


def test_cast_rays_line_hit_beyond_segment_end_is_no_hit():
    """The ray's line crosses the segment's line, but outside the segment: no hit."""
    assert cast(0.0, 0.0, [0.0], [(10.0, 1.0, 10.0, 50.0)], 100.0)[0] == 1.0


@pytest.mark.parametrize(
    "segment",
    [
        (10.0, 0.0, 10.0, 20.0),  # the ray passes exactly through end a
        (10.0, -20.0, 10.0, 0.0),  # the ray passes exactly through end b
        (10.0, 0.0, 30.0, 20.0),  # slanted, touched at end a
    ],
)
def test_cast_rays_hits_segment_end_points(segment):
    """A ray through a segment's end point counts as a hit at that point (distance 10)."""
    assert cast(0.0, 0.0, [0.0], [segment], 100.0)[0] == pytest.approx(0.1, rel=1e-12)


def test_cast_rays_keeps_nearest_hit_and_caps_at_range():
    """Of several walls the nearest counts; a wall beyond the range reads as no hit."""
    segs = [(30.0, -5.0, 30.0, 5.0), (20.0, -5.0, 20.0, 5.0), (40.0, -5.0, 40.0, 5.0)]
    assert cast(0.0, 0.0, [0.0], segs, 100.0)[0] == pytest.approx(0.2)
    assert cast(0.0, 0.0, [0.0], segs, 15.0)[0] == 1.0
    assert cast(0.0, 0.0, [180.0], segs, 100.0)[0] == 1.0


def test_cast_rays_with_no_segments_reports_full_range():
    """With no walls at all every ray reads 1.0."""
    out = cast(0.0, 0.0, [0.0, 90.0, 180.0], np.zeros((0, 4)), 10.0)
    np.testing.assert_array_equal(out, [1.0, 1.0, 1.0])


def test_ray_offsets_layout():
    """360 deg: n evenly spaced rays from straight behind; partial fov: both edges included."""
    np.testing.assert_allclose(
        np.degrees(ray_offsets(4, 2 * math.pi)), [-180.0, -90.0, 0.0, 90.0], atol=1e-12
    )
    assert ray_offsets(8, 2 * math.pi)[8 // 2] == 0.0
    np.testing.assert_allclose(
        np.degrees(ray_offsets(3, math.radians(90.0))), [-45.0, 0.0, 45.0], atol=1e-12
    )
    np.testing.assert_array_equal(ray_offsets(1, math.radians(90.0)), [0.0])


# -- the envs -----------------------------------------------------------------------------------


def lidar_config(range_m: float, n_rays: int = 4, fov_deg: float = 360.0) -> dict:
    return {"lidar": {"n_rays": n_rays, "fov_deg": fov_deg, "range_m": range_m}}


def test_grid_world_fixed_rays_in_centred_box():
    """Grid, spawn at the box centre: rays at -180, -90, 0, 90 deg all see a wall 200 px away."""
    env = GridEnv(track=box_track((300.0, 300.0)), config=lidar_config(3.0))
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(obs[:4], [200 / 300] * 4, rtol=1e-6)


def test_grid_world_fixed_rays_off_centre():
    """Grid, spawn (280, 360): left 180 px, up 260 px, right 220 px, down 140 px."""
    env = GridEnv(track=box_track((280.0, 360.0)), config=lidar_config(3.0))
    obs, _ = env.reset(seed=0)
    # ray order: -180 deg (-x), -90 deg (up, -y), 0 deg (+x), 90 deg (down, +y)
    np.testing.assert_allclose(obs[:4], np.array([180, 260, 220, 140]) / 300, rtol=1e-6)
    np.testing.assert_allclose(
        env.lidar_hits, [[100, 360], [280, 100], [500, 360], [280, 500]], atol=1e-9
    )


def test_grid_rays_out_of_range_read_one():
    """With a 1.5 m (150 px) range the walls 200 px away are out of reach: every ray reads 1.0."""
    env = GridEnv(track=box_track((300.0, 300.0)), config=lidar_config(1.5))
    obs, _ = env.reset(seed=0)
    np.testing.assert_array_equal(obs[:4], [1.0, 1.0, 1.0, 1.0])


def test_grid_rays_do_not_rotate_with_spawn_heading():
    """The grid kart never rotates: a spawn heading is ignored and rays stay world-fixed."""
    env = GridEnv(track=box_track((280.0, 360.0), heading_deg=90.0), config=lidar_config(3.0))
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(obs[:4], np.array([180, 260, 220, 140]) / 300, rtol=1e-6)


@pytest.mark.parametrize("env_class", [GazeboEnv, SteerEnv])
def test_egocentric_rays_rotate_with_heading(env_class):
    """Heading 90 deg (pointing +y, down): the straight-ahead ray measures the wall below.

    Spawn (280, 360): below 140 px, above 260 px, +x 220 px, -x 180 px. Relative to the heading
    ray k points at 90 - 180 + 90 k deg, i.e. up, +x, down, -x.
    """
    env = env_class(track=box_track((280.0, 360.0), heading_deg=90.0), config=lidar_config(3.0))
    obs, _ = env.reset(seed=0)
    n = 4
    assert obs[n // 2] == pytest.approx(140 / 300, rel=1e-6)  # straight ahead = down
    np.testing.assert_allclose(obs[:n], np.array([260, 220, 140, 180]) / 300, rtol=1e-6)


def test_egocentric_partial_fov():
    """Gazebo, 180-degree fov with 3 rays, heading 90: rays point +x, down and -x."""
    env = GazeboEnv(
        track=box_track((280.0, 360.0), heading_deg=90.0),
        config=lidar_config(3.0, n_rays=3, fov_deg=180.0),
    )
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(obs[:3], np.array([220, 140, 180]) / 300, rtol=1e-6)
