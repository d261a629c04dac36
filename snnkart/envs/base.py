"""The shared kart simulation: one step of physics, checkpoints in order, the observation and
the episode's end (the world is :mod:`snnkart.envs.world`, the reward terms
:mod:`snnkart.envs.reward`, the observation layout :mod:`snnkart.envs.observation`).

Subclasses (grid, gazebo, steer) define the action space, the vehicle dynamics and the
kinematic part of the observation.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, ClassVar, Generic, TypeVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from snnkart.envs.components import select_components
from snnkart.envs.config import EnvConfig
from snnkart.envs.constants import DT, KART_RADIUS_PX, PIXELS_PER_METRE, RENDER_FPS
from snnkart.envs.geodesic import GeodesicField, geodesic_field
from snnkart.envs.geometry import nearest_point
from snnkart.envs.kart_state import KartState
from snnkart.envs.lidar import cast_rays, ray_offsets
from snnkart.envs.observation import ObsField, observation_layout, observation_space
from snnkart.envs.reward import Stall, StandStill, step_terms
from snnkart.envs.sim2real import Sim2Real
from snnkart.envs.starts import pick_start
from snnkart.envs.trackgen import RANDOM_SEEDS, random_route, random_track
from snnkart.envs.tracks import Track, is_random, load_track
from snnkart.envs.world import build_world
from snnkart.errors import EnvError
from snnkart.faults import fault_point

ACTION_MODES = ("discrete", "continuous")

ConfigT = TypeVar("ConfigT", bound=EnvConfig)


class KartEnv(KartState, gym.Env[np.ndarray, Any], Generic[ConfigT]):
    """Base class; see :class:`GridEnv`, :class:`GazeboEnv` and :class:`SteerEnv`."""

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": RENDER_FPS}  # noqa: RUF012
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
    _checkpoint_times: list[float]
    _needs_reset: bool
    _last_action: Any
    _last_terms: dict[str, float]
    _episode_return: float
    _from_spawn: bool  # a finish is a lap only from the spawn (snnkart.envs.starts)
    env_name: ClassVar[str] = "kart"
    discrete_actions: ClassVar[int] = 0  # the size of the discrete action space
    egocentric: ClassVar[bool] = True
    start_spread: float = 0.0  # training: this share of episodes starts past a checkpoint

    def __init__(
        self,
        track: str | Path | Track = "small_S",
        action_mode: str = "discrete",
        config: ConfigT | dict[str, object] | None = None,
        render_mode: str | None = None,
    ) -> None:
        self._check_modes(action_mode, render_mode)
        resolved = self._resolve_config(config)
        self.config: ConfigT = resolved  # type: ignore[assignment]
        self.track_given = load_track(track)  # for random tracks their stand-in (tracks.py)
        self.random_tracks = is_random(self.track_given)  # a new generated track per reset
        self.action_mode = action_mode
        self.render_mode = render_mode

        lidar = self.config.lidar
        self._ray_offsets = ray_offsets(lidar.n_rays, math.radians(lidar.fov_deg))
        self._ray_range = lidar.range_m * PIXELS_PER_METRE
        self._ray_angles = np.empty_like(self._ray_offsets)
        self._lidar = np.zeros(lidar.n_rays, dtype=np.float64)
        self._dist_scale = self.config.checkpoint_distance_scale_m * PIXELS_PER_METRE

        own = observation_layout(lidar.n_rays, self._kinematic_fields())
        self._obs_dim = sum(f.size for f in own)  # the env's own layout's (the default)
        self.action_space = self._make_action_space()
        self._select = select_components(self, own, self.config.observation)  # None: own
        self.observation_layout = self._select.layout if self._select else own
        self.observation_space: spaces.Box = observation_space(self.observation_layout)

        self._renderer: Any = None
        self._use_track(self.track_given)
        self._stand_still = StandStill(self.config.reward.stand_still_radius_m * PIXELS_PER_METRE)
        self._sim2real = Sim2Real(self.config.sim2real, self.action_space, self.IDLE_ACTION)
        self._reset_state()
        self._reset_vehicle()
        np.add(self._ray_offsets, self._heading, out=self._ray_angles)
        self.activity: list[tuple[str, float]] = []  # (layer, firing rate) for the side panel
        self.overlays: list[Any] = []  # drawn last on each frame, f(surface) (play's key help)

    def _use_track(self, track: Track, route: GeodesicField | None = None) -> None:
        """Build the world, the route field and the time limit of ``track``."""
        self.track = track
        self._segments = np.ascontiguousarray(track.segments)
        self._goals = [(*cp.a, *cp.b) for cp in track.checkpoints]
        self._n_checkpoints = len(self._goals)
        if route is None:
            route = geodesic_field(track, clearance=self.route_clearance())
        self._geodesic = route
        self.max_episode_steps = self.config.max_episode_steps or math.ceil(
            track.time_limit_s * self._time_limit_factor() / DT
        )
        world = build_world(self._segments, track.checkpoints, self._on_wall, self._on_checkpoint)
        self._space, self._body = world.space, world.body
        self.close()  # a renderer draws the track it was made for

    def _draw_random_track(self) -> None:
        """Switch to the generated track of a seed drawn from ``np_random`` (``track="random"``)."""
        seed = int(self.np_random.integers(RANDOM_SEEDS))
        self._use_track(random_track(seed), random_route(seed, self.route_clearance()))

    def _check_modes(self, action_mode: str, render_mode: str | None) -> None:
        if action_mode not in ACTION_MODES:
            raise EnvError(
                f"unknown action_mode {action_mode!r}; choose one of {', '.join(ACTION_MODES)}"
            )
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise EnvError(
                f"unknown render_mode {render_mode!r}; choose one of "
                f"{', '.join(self.metadata['render_modes'])} or None"
            )

    @classmethod
    def _resolve_config(cls, config: EnvConfig | dict[str, object] | None) -> EnvConfig:
        if config is None:
            return cls.config_class()
        if isinstance(config, dict):
            return cls.config_class.model_validate(config)
        if isinstance(config, cls.config_class):
            return config
        raise TypeError(
            f"{cls.__name__} needs a {cls.config_class.__name__} or a dict, "
            f"got {type(config).__name__}"
        )

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

    @property
    def route_field(self) -> GeodesicField:
        """The current track's geodesic route field (the progress reward's potential)."""
        return self._geodesic

    def _default_route_clearance(self) -> float:
        """The kart radius, for vehicles that can turn on the spot."""
        return KART_RADIUS_PX

    @property
    def speed_m_s(self) -> float:
        """Current speed in m/s."""
        raise NotImplementedError

    # -- gymnasium API --------------------------------------------------------------------------

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, object]]:
        if self._needs_reset:
            raise RuntimeError("call reset() before step(): the episode has ended or not begun")
        x0, y0, speed0 = self._x, self._y, self.speed_m_s
        align0, align0_cp = self._align, self._geo_k  # set by the last _observe()
        self._apply_action(self._sim2real.act(action))
        self._last_action, self._touched_wall = action, False  # before _observe: previous_action
        self._space.step(DT)
        self._x, self._y = self._body.position
        self._after_physics()
        self._steps += 1

        rw = self.config.reward
        finished = self._finished
        progress_px = self._progress_px(x0, y0)
        obs = self._observe()
        # Heading: the change of the cosine between the body's heading and the way to the
        # next checkpoint (the checkpoint_cos observation), a potential-based term that pays
        # for turning towards the route, e.g. on the spot at a corner (egocentric envs only).
        turn = self._align - align0 if self.egocentric and align0_cp == self._next_cp else 0.0
        crashed = self._touched_wall and not finished
        still_steps = self._stand_still.update(self._x, self._y)
        stood_still = not (finished or crashed) and still_steps >= rw.stand_still_steps
        stalled = self._stall.update(self._next_cp, self._geo_d) > rw.stall_grace_steps
        terms = step_terms(
            rw,
            progress_px=progress_px,
            turn=turn,
            passed=self._passed_this_step,
            finished=finished,
            crashed=crashed,
            stood_still=stood_still,
            stalled=stalled,
            impact_m_s=speed0,
        )
        self._extra_reward_terms(terms)
        self._passed_this_step = 0
        terminated = finished or crashed or stood_still
        truncated = not terminated and self._steps >= self.max_episode_steps
        self._needs_reset = terminated or truncated
        reward = float(sum(terms.values()))
        self._last_terms = terms
        self._episode_return += reward

        info = self._info(crashed=crashed, stood_still=stood_still)
        if self.render_mode == "human":
            self.render()
        return obs, reward, terminated, truncated, info

    def _progress_px(self, x0: float, y0: float) -> float:
        """How much nearer the next checkpoint line the kart came this step, along the track
        (geodesic distance; see snnkart/envs/geodesic.py). NaN (inside a wall, or behind the
        checkpoint just passed) gives no progress either way."""
        k = self._next_cp
        d0 = self._geo_d if self._geo_k == k else self._geodesic.distance(k, x0, y0)
        d1 = self._geodesic.distance(k, self._x, self._y)
        self._geo_k, self._geo_d = k, d1  # the next step starts here
        progress = d0 - d1
        return 0.0 if math.isnan(progress) else progress

    def reset(
        self, *, seed: int | None = None, options: dict[str, object] | None = None
    ) -> tuple[np.ndarray, dict[str, object]]:
        super().reset(seed=seed)
        if self.random_tracks:
            self._draw_random_track()
        self._reset_state()
        start = pick_start(self.np_random, self.track, self._geodesic, self.start_spread)
        self._x, self._y, self._next_cp = start.x, start.y, start.next_cp
        self._heading = start.heading if self.egocentric else 0.0
        self._from_spawn = start.next_cp == 0
        body = self._body
        body.position, body.angle = (self._x, self._y), self._heading
        body.velocity, body.angular_velocity = (0.0, 0.0), 0.0
        self._space.reindex_shapes_for_body(body)
        self._reset_vehicle()
        self._stand_still.restart(self._x, self._y)
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

    def _on_wall(self) -> None:
        # pymunk runs this from C through cffi, which drops any exception raised here: an
        # interrupt is only safe as a flag (snnkart.faults.caught). Tests signal from here.
        fault_point("physics-callback")
        self._touched_wall = True

    def _on_checkpoint(self, idx: int) -> None:
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
        self._next_cp, self._from_spawn = 0, True
        self._finished = False
        self._geo_k, self._geo_d = -1, math.nan  # cached distance of the last position
        self._align = 0.0  # checkpoint_cos of the last observation
        self._passed_this_step, self._touched_wall, self._steps = 0, False, 0
        self._stand_still.restart(*self.track.spawn_position)
        self._stall = Stall()
        self._checkpoint_times = []
        self._needs_reset = True
        self._last_action, self._last_terms, self._episode_return = None, {}, 0.0
        self._sim2real.reset()

    def _observe(self, lidar: np.ndarray | None = None) -> np.ndarray:
        """The observation; ``lidar``: measured ray distances instead of cast ones (ROS)."""
        n = self._lidar.shape[0]
        np.add(self._ray_offsets, self._heading, out=self._ray_angles)
        if lidar is None:
            cast_rays(
                self._x, self._y, self._ray_angles, self._segments, self._ray_range, self._lidar
            )
            self._sim2real.sense(self._lidar, self._ray_range, self.np_random)
        else:
            self._lidar[:] = lidar
        obs = np.empty(self._obs_dim, dtype=np.float32)
        obs[:n] = self._lidar
        k = self._write_kinematics(obs, n)
        # The next checkpoint's way along the shortest drivable path and its geodesic distance
        # (straight-line values where undefined: touching the line, behind the one passed).
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
        return obs if self._select is None else self._select(obs)

    def _info(self, crashed: bool, stood_still: bool) -> dict[str, object]:
        elapsed = self._steps * DT
        return {
            "checkpoint": self._next_cp,
            "checkpoints_total": self._n_checkpoints,
            "checkpoint_times": tuple(self._checkpoint_times),
            "lap_finished": self.lap_finished,
            "lap_time": elapsed if self.lap_finished else None,
            "elapsed_time": elapsed,
            "crashed": crashed,
            "stood_still": stood_still,
            "speed": self.speed_m_s,
            "position": (self._x, self._y),
            "reward_terms": dict(self._last_terms),
        }

    def describe_action(self, action: Any) -> str:
        """Human-readable name of an action (for the side panel)."""
        if action is None:
            return "-"
        if self.action_mode == "discrete":
            return self.ACTION_NAMES[int(action)]
        return "[" + ", ".join(f"{float(a):+.2f}" for a in np.asarray(action).ravel()) + "]"

    ACTION_NAMES: ClassVar[tuple[str, ...]] = ()
    IDLE_ACTION: ClassVar[int] = 0  # the discrete action that does nothing
