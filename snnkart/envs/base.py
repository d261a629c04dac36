"""The shared kart simulation: pymunk world, checkpoints, LIDAR, reward and episode logic.

Subclasses (grid, gazebo, steer) define the action space, the vehicle dynamics and the
kinematic part of the observation. One pymunk Space is built per env at construction and
reused for every episode (the original leaked the whole track into the space on each reset).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Generic, TypeVar

import gymnasium as gym
import numpy as np
import pymunk
from gymnasium import spaces

from snnkart.envs.config import EnvConfig
from snnkart.envs.constants import (
    DT,
    KART_MASS_KG,
    KART_RADIUS_PX,
    PIXELS_PER_METRE,
    RENDER_FPS,
)
from snnkart.envs.geodesic import geodesic_field
from snnkart.envs.geometry import nearest_point
from snnkart.envs.lidar import cast_rays, ray_offsets
from snnkart.envs.tracks import Track, load_track
from snnkart.errors import EnvError
from snnkart.faults import fault_point

_KART, _WALL, _CHECKPOINT = 1, 2, 3
ACTION_MODES = ("discrete", "continuous")

ENV_REVISION = 3
"""Revision of what the observations and rewards mean, recorded with every checkpoint and
NIR export, so a policy is never run on observations whose meaning changed under it (the
layout and bounds alone do not show that):

1. progress and the checkpoint observation measured straight at the next checkpoint line;
2. both along the shortest drivable path (geodesic); heading reward term;
3. steer's path keeps the car's turning radius from the walls.
"""


def revision_mismatch(saved: Any) -> str | None:
    """What to tell a user whose policy was made on env revision ``saved`` (None when it is
    the current one); the caller adds what to do."""
    if saved == ENV_REVISION:
        return None
    return (
        f"env revision {saved if saved is not None else '1 or 2'}, and this snnkart's envs "
        f"are revision {ENV_REVISION}: what the observations and rewards mean has changed "
        "since (snnkart.envs.base.ENV_REVISION)"
    )


ConfigT = TypeVar("ConfigT", bound=EnvConfig)


@dataclass(frozen=True)
class ObsField:
    """One named block of the observation vector, with its true bounds."""

    name: str
    size: int
    low: float
    high: float
    description: str


class KartEnv(gym.Env[np.ndarray, Any], Generic[ConfigT]):
    """Base class; see :class:`GridEnv`, :class:`GazeboEnv` and :class:`SteerEnv`."""

    metadata = {  # noqa: RUF012  (gymnasium's convention)
        "render_modes": ["human", "rgb_array"],
        "render_fps": RENDER_FPS,
    }
    config_class: ClassVar[type[EnvConfig]] = EnvConfig
    # Per-episode state, set by _reset_state() and reset().
    _x: float
    _y: float
    _heading: float
    _next_cp: int
    _geo_k: int
    _geo_d: float
    _align: float
    _finished: bool
    _passed_this_step: int
    _touched_wall: bool
    _steps: int
    _still_steps: int
    _anchor: tuple[float, float]
    _checkpoint_times: list[float]
    _needs_reset: bool
    _last_action: Any
    _last_terms: dict[str, float]
    _episode_return: float
    env_name: ClassVar[str] = "kart"
    discrete_actions: ClassVar[int] = 0  # the size of the discrete action space
    egocentric: ClassVar[bool] = True

    def __init__(
        self,
        track: str | Path | Track = "small_S",
        action_mode: str = "discrete",
        config: ConfigT | dict[str, Any] | None = None,
        render_mode: str | None = None,
    ) -> None:
        if action_mode not in ACTION_MODES:
            raise EnvError(
                f"unknown action_mode {action_mode!r}; choose one of {', '.join(ACTION_MODES)}"
            )
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise EnvError(
                f"unknown render_mode {render_mode!r}; choose one of "
                f"{', '.join(self.metadata['render_modes'])} or None"
            )
        if config is None:
            resolved = self.config_class()
        elif isinstance(config, dict):
            resolved = self.config_class.model_validate(config)
        elif isinstance(config, self.config_class):
            resolved = config
        else:
            raise TypeError(
                f"{type(self).__name__} needs a {self.config_class.__name__} or a dict, "
                f"got {type(config).__name__}"
            )
        self.config: ConfigT = resolved  # type: ignore[assignment]
        self.track = load_track(track)
        self.action_mode = action_mode
        self.render_mode = render_mode

        lidar = self.config.lidar
        self._ray_offsets = ray_offsets(lidar.n_rays, math.radians(lidar.fov_deg))
        self._ray_range = lidar.range_m * PIXELS_PER_METRE
        self._ray_angles = np.empty_like(self._ray_offsets)
        self._lidar = np.zeros(lidar.n_rays, dtype=np.float64)
        self._segments = np.ascontiguousarray(self.track.segments)
        self._goals = [(*cp.a, *cp.b) for cp in self.track.checkpoints]
        self._n_checkpoints = len(self._goals)
        self._dist_scale = self.config.checkpoint_distance_scale_m * PIXELS_PER_METRE
        self._geodesic = geodesic_field(self.track, clearance=self.route_clearance())
        self.max_episode_steps = self.config.max_episode_steps or math.ceil(
            self.track.time_limit_s * self._time_limit_factor() / DT
        )

        self.observation_layout: tuple[ObsField, ...] = (
            ObsField("lidar", lidar.n_rays, 0.0, 1.0, "ray distance / range, 1 = no hit"),
            *self._kinematic_fields(),
            ObsField("checkpoint_cos", 1, -1.0, 1.0, "cos of the way to the next checkpoint"),
            ObsField("checkpoint_sin", 1, -1.0, 1.0, "sin of the way to the next checkpoint"),
            ObsField("checkpoint_distance", 1, 0.0, 1.0, "min(path distance / scale, 1)"),
        )
        low = np.concatenate([np.full(f.size, f.low) for f in self.observation_layout])
        high = np.concatenate([np.full(f.size, f.high) for f in self.observation_layout])
        self.observation_space: spaces.Box = spaces.Box(
            low.astype(np.float32), high.astype(np.float32)
        )
        self._obs_dim = int(low.shape[0])
        self.action_space = self._make_action_space()

        self._build_world()
        self._still_radius = self.config.reward.stand_still_radius_m * PIXELS_PER_METRE
        self._reset_state()
        self._reset_vehicle()
        np.add(self._ray_offsets, self._heading, out=self._ray_angles)
        self._renderer: Any = None

    # -- subclass interface ---------------------------------------------------------------------

    def _make_action_space(self) -> spaces.Space[Any]:
        """``Discrete(discrete_actions)``, or a 2-vector in [-1, 1] (continuous)."""
        if self.action_mode == "discrete":
            return spaces.Discrete(self.discrete_actions)
        return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)

    def _kinematic_fields(self) -> tuple[ObsField, ...]:
        raise NotImplementedError

    def _reset_vehicle(self) -> None:
        """Reset the vehicle state (speeds, steering) for a new episode."""
        raise NotImplementedError

    def _apply_action(self, action: Any) -> None:
        """Set the body velocity and angular velocity for this step from the action."""
        raise NotImplementedError

    def _after_physics(self) -> None:
        """Update the vehicle state after ``space.step`` (drag, heading)."""
        raise NotImplementedError

    def _write_kinematics(self, out: np.ndarray, start: int) -> int:
        """Write the kinematic observation block at ``start``; return the next index."""
        raise NotImplementedError

    def _extra_reward_terms(self, terms: dict[str, float]) -> None:
        """Add env-specific reward terms (steering penalty)."""

    def _time_limit_factor(self) -> float:
        return 1.0

    def route_clearance(self) -> float:
        """Distance (px) the route, and so the progress potential, keeps from the walls:
        ``config.route_clearance_m`` if set, else the vehicle's own default."""
        if self.config.route_clearance_m is not None:
            return self.config.route_clearance_m * PIXELS_PER_METRE  # >= the radius
        return self._default_route_clearance()

    def _default_route_clearance(self) -> float:
        """The kart radius, for vehicles that can turn on the spot."""
        return KART_RADIUS_PX

    @property
    def speed_m_s(self) -> float:
        """Current speed in m/s."""
        raise NotImplementedError

    # -- gymnasium API --------------------------------------------------------------------------

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if self._needs_reset:
            raise RuntimeError("call reset() before step(): the episode has ended or not begun")
        x0, y0 = self._x, self._y
        align0, align0_cp = self._align, self._geo_k  # set by the last _observe()
        self._apply_action(action)
        self._touched_wall = False
        self._space.step(DT)
        self._x, self._y = self._body.position
        self._after_physics()
        self._steps += 1

        rw = self.config.reward
        finished = self._finished
        # Progress = how much nearer the kart came to the next checkpoint line along the
        # track (geodesic distance; see snnkart/envs/geodesic.py). NaN (inside a wall, or
        # behind the checkpoint just passed) gives no progress either way.
        k = self._next_cp
        d0 = self._geo_d if self._geo_k == k else self._geodesic.distance(k, x0, y0)
        d1 = self._geodesic.distance(k, self._x, self._y)
        self._geo_k, self._geo_d = k, d1  # the next step starts here
        progress_px = d0 - d1
        if math.isnan(progress_px):
            progress_px = 0.0
        obs = self._observe()
        # Heading: the change of the cosine between the body's heading and the way to the
        # next checkpoint (the checkpoint_cos observation), a potential-based term that pays
        # for turning towards the route, e.g. on the spot at a corner (egocentric envs only).
        turn = self._align - align0 if self.egocentric and align0_cp == k else 0.0
        terms = {
            "progress": rw.progress * progress_px / PIXELS_PER_METRE,
            "heading": rw.heading * turn,
            "checkpoint": rw.checkpoint * self._passed_this_step,
            "finish": rw.finish if finished else 0.0,
            "time": -rw.time,
            "wall": 0.0,
            "stand_still": 0.0,
        }
        if finished:
            terms["progress"] = terms["heading"] = 0.0
        self._extra_reward_terms(terms)
        self._passed_this_step = 0

        crashed = self._touched_wall and not finished
        if crashed:
            terms["wall"] = -rw.wall
        # Standing still = staying within a small circle, so hovering back and forth counts.
        if math.hypot(self._x - self._anchor[0], self._y - self._anchor[1]) > self._still_radius:
            self._anchor = (self._x, self._y)
            self._still_steps = 0
        else:
            self._still_steps += 1
        stood_still = not (finished or crashed) and self._still_steps >= rw.stand_still_steps
        if stood_still:
            terms["stand_still"] = -rw.stand_still
        terminated = finished or crashed or stood_still
        truncated = not terminated and self._steps >= self.max_episode_steps
        self._needs_reset = terminated or truncated
        reward = float(sum(terms.values()))
        self._last_action = action
        self._last_terms = terms
        self._episode_return += reward

        info = self._info(crashed=crashed, stood_still=stood_still)
        if self.render_mode == "human":
            self.render()
        return obs, reward, terminated, truncated, info

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self._reset_state()
        jitter = self.track.spawn_jitter
        dx, dy = self.np_random.uniform(-jitter, jitter, size=2) if jitter > 0 else (0.0, 0.0)
        sx, sy = self.track.spawn_position
        self._x, self._y = sx + float(dx), sy + float(dy)
        self._heading = self.track.spawn_heading if self.egocentric else 0.0
        body = self._body
        body.position = (self._x, self._y)
        body.angle = self._heading
        body.velocity = (0.0, 0.0)
        body.angular_velocity = 0.0
        self._space.reindex_shapes_for_body(body)
        self._reset_vehicle()
        self._anchor = (self._x, self._y)
        self._needs_reset = False
        obs = self._observe()
        if self.render_mode == "human":
            self.render()
        return obs, self._info(crashed=False, stood_still=False)

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode= at creation")
            return None
        if self._renderer is None:
            from snnkart.envs.render import Renderer

            self._renderer = Renderer(self, human=self.render_mode == "human")
        return self._renderer.draw()

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # -- internals ------------------------------------------------------------------------------

    def _build_world(self) -> None:
        space = pymunk.Space()
        space.gravity = (0.0, 0.0)
        body = pymunk.Body(KART_MASS_KG, pymunk.moment_for_circle(KART_MASS_KG, 0, KART_RADIUS_PX))
        kart = pymunk.Circle(body, KART_RADIUS_PX)
        kart.collision_type = _KART
        kart.filter = pymunk.ShapeFilter(categories=0b001, mask=0b110)
        space.add(body, kart)
        for ax, ay, bx, by in self._segments:
            seg = pymunk.Segment(space.static_body, (ax, ay), (bx, by), 0.0)
            seg.sensor = True
            seg.collision_type = _WALL
            seg.filter = pymunk.ShapeFilter(categories=0b010)
            space.add(seg)
        self._checkpoint_index: dict[pymunk.Shape, int] = {}
        for i, cp in enumerate(self.track.checkpoints):
            seg = pymunk.Segment(space.static_body, cp.a, cp.b, 0.0)
            seg.sensor = True
            seg.collision_type = _CHECKPOINT
            seg.filter = pymunk.ShapeFilter(categories=0b100)
            space.add(seg)
            self._checkpoint_index[seg] = i
        space.on_collision(_KART, _WALL, pre_solve=self._on_wall)
        space.on_collision(_KART, _CHECKPOINT, pre_solve=self._on_checkpoint)
        self._space = space
        self._body = body

    def _on_wall(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: Any) -> None:
        # pymunk runs this from C through cffi, which drops any exception raised here: an
        # interrupt is only safe as a flag (snnkart.faults.caught). Tests signal from here.
        fault_point("physics-callback")
        self._touched_wall = True

    def _on_checkpoint(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: Any) -> None:
        idx = self._checkpoint_index[arbiter.shapes[1]]
        if idx != self._next_cp or self._finished:
            return  # checkpoints count only in order
        self._checkpoint_times.append((self._steps + 1) * DT)
        if idx == self._n_checkpoints - 1:
            self._finished = True
        else:
            self._next_cp += 1
            self._passed_this_step += 1

    def _reset_state(self) -> None:
        self._x, self._y = self.track.spawn_position
        self._heading = 0.0
        self._next_cp = 0
        self._finished = False
        self._geo_k, self._geo_d = -1, math.nan  # cached distance of the last position
        self._align = 0.0  # checkpoint_cos of the last observation
        self._passed_this_step = 0
        self._touched_wall = False
        self._steps = 0
        self._still_steps = 0
        self._anchor = self.track.spawn_position
        self._checkpoint_times = []
        self._needs_reset = True
        self._last_action = None
        self._last_terms = {}
        self._episode_return = 0.0

    def _observe(self) -> np.ndarray:
        n = self._lidar.shape[0]
        np.add(self._ray_offsets, self._heading, out=self._ray_angles)
        cast_rays(self._x, self._y, self._ray_angles, self._segments, self._ray_range, self._lidar)
        obs = np.empty(self._obs_dim, dtype=np.float32)
        obs[:n] = self._lidar
        k = self._write_kinematics(obs, n)
        # The next checkpoint's direction along the shortest drivable path (around corners)
        # and its geodesic distance; straight-line values where those are undefined (the
        # kart touching the line, or behind the checkpoint it just passed).
        cp = self._next_cp
        if self._geo_k != cp:
            self._geo_k, self._geo_d = cp, self._geodesic.distance(cp, self._x, self._y)
        route = self._geodesic.route(cp, self._x, self._y)
        gx, gy = nearest_point(self._goals[cp], self._x, self._y)
        dx, dy = route if route is not None else (gx - self._x, gy - self._y)
        dist = self._geo_d if self._geo_d == self._geo_d else math.hypot(gx - self._x, gy - self._y)
        rel = math.atan2(dy, dx) - (self._heading if self.egocentric else 0.0)
        self._align = math.cos(rel)
        obs[k] = self._align
        obs[k + 1] = math.sin(rel)
        obs[k + 2] = min(dist / self._dist_scale, 1.0)
        return obs

    def _info(self, crashed: bool, stood_still: bool) -> dict[str, Any]:
        elapsed = self._steps * DT
        return {
            "checkpoint": self._next_cp,
            "checkpoints_total": self._n_checkpoints,
            "checkpoint_times": tuple(self._checkpoint_times),
            "lap_finished": self._finished,
            "lap_time": elapsed if self._finished else None,
            "elapsed_time": elapsed,
            "crashed": crashed,
            "stood_still": stood_still,
            "speed": self.speed_m_s,
            "position": (self._x, self._y),
            "reward_terms": dict(self._last_terms),
        }

    # -- state for renderers and drivers --------------------------------------------------------

    @property
    def position(self) -> tuple[float, float]:
        """Kart centre, px."""
        return (self._x, self._y)

    @property
    def heading(self) -> float:
        """Heading (rad, clockwise on screen from +x); 0 in the grid env."""
        return self._heading

    @property
    def next_checkpoint(self) -> int:
        """Index of the checkpoint to pass next (0-based)."""
        return self._next_cp

    @property
    def lap_finished(self) -> bool:
        return self._finished

    @property
    def elapsed_time(self) -> float:
        """Simulated seconds since the episode began."""
        return self._steps * DT

    @property
    def episode_steps(self) -> int:
        return self._steps

    @property
    def lidar_distances(self) -> np.ndarray:
        """Normalised ray distances of the last observation, in [0, 1] (1 = no hit)."""
        return self._lidar

    @property
    def last_action(self) -> Any:
        return self._last_action

    @property
    def last_reward_terms(self) -> dict[str, float]:
        return self._last_terms

    @property
    def episode_return(self) -> float:
        return self._episode_return

    @property
    def lidar_hits(self) -> np.ndarray:
        """Ray end points of the last observation, px, shape ``[n_rays, 2]``."""
        d = self._lidar * self._ray_range
        return np.stack(
            [self._x + d * np.cos(self._ray_angles), self._y + d * np.sin(self._ray_angles)], 1
        )

    def describe_action(self, action: Any) -> str:
        """Human-readable name of an action (for the side panel)."""
        if action is None:
            return "-"
        if self.action_mode == "discrete":
            return self.ACTION_NAMES[int(action)]
        return "[" + ", ".join(f"{float(a):+.2f}" for a in np.asarray(action).ravel()) + "]"

    ACTION_NAMES: ClassVar[tuple[str, ...]] = ()
