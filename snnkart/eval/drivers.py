"""Scripted drivers: pure-pursuit controllers that follow a track's checkpoint midpoints.

They prove that a track is solvable in every env and action mode, give the demo something to
show before any policy is trained, and are a baseline for lap times. A driver reads the env's
true state (position, heading, speed), not the observation: it is a reference, not a policy.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from snnkart.envs.base import KartEnv
from snnkart.envs.constants import PIXELS_PER_METRE
from snnkart.envs.geometry import nearest_point, point_distance
from snnkart.envs.grid import DIRECTIONS
from snnkart.eval.episodes import EpisodeResult, run_episodes


class PathFollower:
    """Tracks progress along the polyline spawn -> checkpoint midpoints and gives a look-ahead point."""

    def __init__(self, env: KartEnv, lookahead_px: float) -> None:
        self.track = env.track
        pts = [env.track.spawn_position, *(cp.midpoint for cp in env.track.checkpoints)]
        self.points = np.asarray(pts, dtype=np.float64)
        self.lookahead = lookahead_px
        self.segment = 0

    def target(self, pos: tuple[float, float]) -> np.ndarray:
        p = np.asarray(pos)
        # Move on to the next segment once the kart is at least as close to it.
        while self.segment < len(self.points) - 2 and self._distance(
            p, self.segment + 1
        ) <= self._distance(p, self.segment):
            self.segment += 1
        seg = (*self.points[self.segment], *self.points[self.segment + 1])
        remaining = self.lookahead
        point, i = np.asarray(nearest_point(seg, *p)), self.segment
        while True:
            end = self.points[i + 1]
            left = float(np.linalg.norm(end - point))
            if left >= remaining or i + 2 >= len(self.points):
                if left < 1e-9:
                    return end
                return point + (end - point) * min(remaining / left, 1.0)
            remaining -= left
            point, i = end, i + 1

    def _distance(self, p: np.ndarray, i: int) -> float:
        return point_distance((*self.points[i], *self.points[i + 1]), *p)

    def corner_ahead(self, pos: tuple[float, float], distance_px: float) -> float:
        """Largest turn angle (rad) of the path within ``distance_px`` ahead."""
        p = np.asarray(pos)
        worst = 0.0
        for i in range(self.segment + 1, len(self.points) - 1):
            if np.linalg.norm(self.points[i] - p) > distance_px:
                break
            d0 = self.points[i] - self.points[i - 1]
            d1 = self.points[i + 1] - self.points[i]
            turn = abs(_wrap(math.atan2(d1[1], d1[0]) - math.atan2(d0[1], d0[0])))
            worst = max(worst, turn)
        return worst


def _wrap(angle: float) -> float:
    return math.remainder(angle, math.tau)


class ScriptedDriver:
    """Pure pursuit for any kart env; ``act(env)`` returns an action for the env's action mode.

    Speeds are in m/s. The default cruise speed is deliberately modest so that every env
    (including the steer car with its 0.36 m minimum turning radius) makes the corners.
    """

    def __init__(self, env: KartEnv, cruise_m_s: float = 0.8, corner_m_s: float = 0.45) -> None:
        self.env = env
        self.cruise = cruise_m_s
        self.corner = corner_m_s
        self.follower = PathFollower(env, lookahead_px=45.0)

    def reset(self) -> None:
        self.follower = PathFollower(self.env, lookahead_px=self.follower.lookahead)

    def predict(self, obs: Any) -> Any:
        """The :class:`~snnkart.eval.episodes.Predictor` interface: acts on its env's state."""
        return self.act(self.env)

    def act(self, env: KartEnv | None = None) -> Any:
        env = env or self.env
        if self.follower.track is not env.track:  # track="random": a new track this episode
            self.follower = PathFollower(env, lookahead_px=self.follower.lookahead)
        pos = env.position
        tx, ty = self.follower.target(pos)
        speed_goal = self.corner if self.follower.corner_ahead(pos, 90.0) > 0.6 else self.cruise
        kind = env.env_name
        if kind == "grid":
            return self._grid(env, tx, ty, speed_goal)
        if kind == "gazebo":
            return self._gazebo(env, tx, ty, speed_goal)
        return self._steer(env, tx, ty, speed_goal)

    def _grid(self, env: Any, tx: float, ty: float, speed_goal: float) -> Any:
        x, y = env.position
        d = math.hypot(tx - x, ty - y) or 1.0
        goal = np.array([tx - x, ty - y]) / d * speed_goal * PIXELS_PER_METRE
        v = np.array(env.velocity_px)
        impulse = env.impulse_px
        if env.action_mode == "continuous":
            a = (goal - v) / impulse
            n = float(np.linalg.norm(a))
            return (a / max(n, 1.0)).astype(np.float32)
        errors = [np.linalg.norm(v + impulse * np.array(o) - goal) for o in DIRECTIONS]
        return int(np.argmin(errors))

    def _gazebo(self, env: Any, tx: float, ty: float, speed_goal: float) -> Any:
        x, y = env.position
        err = _wrap(math.atan2(ty - y, tx - x) - env.heading)
        v = env.speed_m_s
        if env.action_mode == "continuous":
            lin = speed_goal * max(math.cos(err), 0.0) ** 4 / env.config.physics.max_linear_m_s
            ang = float(np.clip(3.0 * err / env.config.physics.max_angular_rad_s, -1, 1))
            return np.array([lin, ang], dtype=np.float32)
        if abs(err) > 0.25:
            if v > 0.25:
                return 2  # brake before turning hard
            return 3 if err < 0 else 4
        if abs(err) > 0.08:
            return 3 if err < 0 else 4
        return 1 if v < speed_goal else 0

    def _steer(self, env: Any, tx: float, ty: float, speed_goal: float) -> Any:
        x, y = env.position
        p = env.config.physics
        alpha = _wrap(math.atan2(ty - y, tx - x) - env.heading)
        ld = max(math.hypot(tx - x, ty - y), 1.0)
        delta = math.atan2(2.0 * p.wheelbase_m * PIXELS_PER_METRE * math.sin(alpha), ld)
        steer = float(np.clip(delta / p.max_steer_rad, -1.0, 1.0))
        v = env.speed_m_s
        if abs(alpha) > 1.0:
            speed_goal = min(speed_goal, 0.35)
        throttle = 1.0 if v < speed_goal else (-1.0 if v > speed_goal + 0.15 else 0.0)
        if env.action_mode == "continuous":
            return np.array([throttle, steer], dtype=np.float32)
        t_idx = 2 if throttle > 0 else (0 if throttle < 0 else 1)
        s_idx = 0 if steer < -0.33 else (2 if steer > 0.33 else 1)
        return 3 * t_idx + s_idx


def drive_episode(
    env: KartEnv, seed: int = 0, driver: ScriptedDriver | None = None, on_step: Any = None
) -> EpisodeResult:
    """Run one seeded episode with the scripted driver (the shared episode loop)."""
    return run_episodes(env, driver or ScriptedDriver(env), 1, seed, on_step=on_step)[0]
