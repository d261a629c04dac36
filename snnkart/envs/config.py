"""Typed configurations of the kart environments: physics, LIDAR, reward, episode.

Every field has a unit in its name or description. Configs are frozen pydantic models that
reject unknown keys, so a misspelled key in a TOML file or a dict fails with its name.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from snnkart.envs.constants import DRAG_PER_STEP, KART_RADIUS_M


class _Frozen(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class LidarConfig(_Frozen):
    """Ray-cast range sensor. Rays are egocentric in gazebo and steer, world-fixed in grid."""

    n_rays: int = Field(16, ge=1, le=720, description="number of rays")
    fov_deg: float = Field(360.0, gt=0.0, le=360.0, description="field of view, degrees")
    range_m: float = Field(3.0, gt=0.0, description="maximum range, metres (original: 3 m)")


class RewardConfig(_Frozen):
    """Per-step reward terms; each is reported in ``info["reward_terms"]`` under its name.

    The reward of a step is the *sum of this step's terms* (the original returned a running
    total, which rewarded slow driving).
    """

    progress: float = Field(1.0, description="per metre of progress toward the next checkpoint")
    heading: float = Field(
        0.5,
        ge=0.0,
        description="gazebo and steer: per unit rise of the cosine between the heading and the "
        "way to the next checkpoint (potential-based; turning back costs as much)",
    )
    checkpoint: float = Field(1.0, description="bonus per checkpoint passed in order")
    finish: float = Field(10.0, description="bonus for crossing the finish line")
    time: float = Field(
        0.001,
        ge=0.0,
        description="passive penalty per step (a full time limit costs less than a crash)",
    )
    wall: float = Field(1.0, ge=0.0, description="penalty for touching a wall (ends the episode)")
    wall_per_m_s: float = Field(
        0.0, ge=0.0, description="more wall penalty per m/s of the speed the kart hit it at"
    )
    stand_still: float = Field(1.0, ge=0.0, description="penalty for standing still too long")
    steering: float = Field(0.01, ge=0.0, description="steer env: penalty per step at full lock")
    stand_still_radius_m: float = Field(
        0.2, ge=0.0, description="staying within this distance of one spot = standing still"
    )
    stand_still_steps: int = Field(
        200, ge=1, description="steps standing still that end the episode"
    )
    stall: float = Field(
        0.0,
        ge=0.0,
        description="penalty per step while the kart has not come nearer the next checkpoint "
        "(along the track) for more than stall_grace_steps",
    )
    stall_grace_steps: int = Field(60, ge=0, description="steps without progress before stall")


class GridPhysics(_Frozen):
    """Free 4-direction movement: each action adds a world-frame velocity impulse."""

    impulse_m_s: float = Field(0.15, gt=0.0, description="speed change per action step, m/s")
    max_speed_m_s: float = Field(4.0, gt=0.0, description="speed cap, m/s (original: 4 m/s)")
    drag_per_step: float = Field(DRAG_PER_STEP, ge=1.0, description="velocity divisor per step")


TURTLEBOT3_PRESET: dict[str, float] = {
    "max_linear_m_s": 0.22,
    "max_angular_rad_s": 2.84,
    "linear_step_m_s": 0.01,
    "time_limit_factor": 10.0,
}
"""TurtleBot3 Burger limits: 0.22 m/s and 2.84 rad/s (ROBOTIS e-Manual)."""


class GazeboPhysics(_Frozen):
    """Differential drive: each discrete step changes the linear OR the angular velocity.

    The default keeps the original's faster scale (2 m/s; 1.53 rad/s reached after a few steps
    of holding a turn key); ``preset="turtlebot3"`` uses the real robot's limits.
    """

    preset: Literal["default", "turtlebot3"] = "default"
    max_linear_m_s: float = Field(2.0, gt=0.0, description="linear speed limit, m/s")
    linear_step_m_s: float = Field(0.03, gt=0.0, description="linear speed change per step, m/s")
    max_angular_rad_s: float = Field(
        0.18 * 3 * 2.84, gt=0.0, description="angular speed limit, rad/s (original: 1.5336)"
    )
    angular_decay: float = Field(
        1.0 / 3.0, ge=0.0, lt=1.0, description="per-step decay of the angular velocity"
    )
    drag_per_step: float = Field(DRAG_PER_STEP, ge=1.0, description="velocity divisor per step")
    time_limit_factor: float = Field(1.0, gt=0.0, description="scales the track's time limit")

    @model_validator(mode="before")
    @classmethod
    def _apply_preset(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("preset") == "turtlebot3":
            return {**TURTLEBOT3_PRESET, **data}
        return data


class SteerPhysics(_Frozen):
    """Kinematic bicycle model: the turn rate is speed * tan(steering angle) / wheelbase."""

    max_speed_m_s: float = Field(2.5, gt=0.0, description="speed limit, m/s")
    max_reverse_m_s: float = Field(
        0.5, ge=0.0, description="reverse speed limit, m/s (braking at a standstill reverses)"
    )
    throttle_m_s2: float = Field(2.4, gt=0.0, description="acceleration at full throttle, m/s^2")
    brake_m_s2: float = Field(4.8, gt=0.0, description="deceleration at full brake, m/s^2")
    wheelbase_m: float = Field(0.25, gt=0.0, description="axle distance, m")
    max_steer_deg: float = Field(
        35.0, gt=0.0, lt=90.0, description="steering lock, degrees (min turn radius 0.36 m)"
    )
    steer_rate_deg_s: float = Field(240.0, gt=0.0, description="steering speed, degrees/s")
    drag_per_step: float = Field(DRAG_PER_STEP, ge=1.0, description="velocity divisor per step")

    @property
    def max_steer_rad(self) -> float:
        return math.radians(self.max_steer_deg)


class Sim2RealConfig(_Frozen):
    """Sensor and actuator imperfections for sim-to-real robustness (all off by default)."""

    lidar_noise_m: float = Field(
        0.0, ge=0.0, description="standard deviation of Gaussian noise on each ray's distance, m"
    )
    beam_dropout: float = Field(
        0.0, ge=0.0, lt=1.0, description="probability that a ray returns nothing (reads 1)"
    )
    action_delay_steps: int = Field(
        0, ge=0, le=30, description="steps between choosing an action and its effect"
    )


class EnvConfig(_Frozen):
    """Settings shared by all kart environments."""

    REWARD_DEFAULTS: ClassVar[dict[str, float]] = {}
    """This env's reward terms that differ from :class:`RewardConfig`'s defaults; a reward
    section given without one of them keeps it."""

    @model_validator(mode="before")
    @classmethod
    def _env_reward_defaults(cls, data: Any) -> Any:
        if isinstance(data, dict) and isinstance(data.get("reward"), dict):
            data = {**data, "reward": {**cls.REWARD_DEFAULTS, **data["reward"]}}
        return data

    lidar: LidarConfig = LidarConfig()
    reward: RewardConfig = RewardConfig()
    max_episode_steps: int | None = Field(
        None, ge=1, description="time limit in steps; default: the track's time limit"
    )
    checkpoint_distance_scale_m: float = Field(
        10.0, gt=0.0, description="distance observation = min(distance / scale, 1)"
    )
    render_scale: float = Field(0.8, gt=0.0, le=4.0, description="pixels on screen per track px")
    sim2real: Sim2RealConfig | None = Field(
        None, description="LIDAR noise, beam dropout and actuation delay (None: a perfect robot)"
    )
    observation: tuple[str, ...] | None = Field(
        None,
        description="observation components in order (snnkart.envs.components); "
        "default: the env's own layout",
    )
    route_clearance_m: float | None = Field(
        None,
        ge=KART_RADIUS_M,
        description="distance the route (and the progress potential) keeps from the walls, "
        f"m, at least the kart radius {KART_RADIUS_M}; default: the kart radius, or in steer "
        "the car's turning radius",
    )


GAZEBO_REWARD = {"stall": 0.01}
"""gazebo's reward defaults: a stall term, so that seeds do not learn to park before a corner
until the stand-still limit (why: docs/decisions.md#gazebo-stall-term). The original ended an
episode that receded from its target for 30 steps ("deserting")."""

STEER_REWARD = {"stall": 0.01, "stand_still": 2.0}
"""steer's reward defaults: a stall term and a stand-still ending that costs 2 (a crash costs 1),
so that parking before a corner does not pay (why: docs/decisions.md#steer-parking)."""

GRID_REWARD = {"wall_per_m_s": 1.0, "stall": 0.01, "stand_still": 2.0}
"""grid's reward defaults: a crash costs 1 more per m/s of impact speed, which pays for braking
before a wall (grid's kart keeps its momentum), and steer's stall term and stand-still ending
(why: docs/decisions.md#grid-impact-speed)."""


class GridConfig(EnvConfig):
    REWARD_DEFAULTS = GRID_REWARD
    physics: GridPhysics = GridPhysics()
    reward: RewardConfig = RewardConfig(**GRID_REWARD)


class GazeboConfig(EnvConfig):
    REWARD_DEFAULTS = GAZEBO_REWARD
    physics: GazeboPhysics = GazeboPhysics()
    reward: RewardConfig = RewardConfig(**GAZEBO_REWARD)


class SteerConfig(EnvConfig):
    REWARD_DEFAULTS = STEER_REWARD
    physics: SteerPhysics = SteerPhysics()
    reward: RewardConfig = RewardConfig(**STEER_REWARD)
