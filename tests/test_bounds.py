"""Observations stay inside the declared Box, rewards add up, and episodes end as documented."""

from __future__ import annotations

import math

import numpy as np
import pytest

from snnkart.envs.config import GAZEBO_REWARD, GRID_REWARD, STEER_REWARD
from snnkart.envs.gazebo import GazeboEnv
from snnkart.envs.grid import GridEnv
from snnkart.envs.steer import SteerEnv
from snnkart.envs.tracks import parse_track

ENV_CLASSES = [GridEnv, GazeboEnv, SteerEnv]
ACTION_MODES = ("discrete", "continuous")

# An empty 20 m x 20 m arena; its only checkpoint cuts off the bottom-left corner, away from
# every path driven below, so the kart can reach top speed or circle without ending the episode.
ARENA = parse_track(
    """
    name = "arena"
    time_limit_s = 600.0
    [spawn]
    position = [200, 1000]
    heading_deg = 0
    jitter = 0
    [[walls]]
    points = [[0, 0], [2000, 0], [2000, 2000], [0, 2000], [0, 0]]
    [[checkpoints]]
    a = [0, 1950]
    b = [50, 2000]
    """,
    source="arena",
)
LONG = {"max_episode_steps": 100_000}

# Discrete actions: full ahead (grid: right) and "do nothing".
FULL_AHEAD = {GridEnv: 4, GazeboEnv: 1, SteerEnv: 7}
IDLE = {GridEnv: 0, GazeboEnv: 0, SteerEnv: 4}


def action(env, discrete: int, continuous: tuple[float, float]):
    if env.action_mode == "discrete":
        return discrete
    return np.asarray(continuous, dtype=np.float32)


def assert_in_bounds(env, obs: np.ndarray, context: str) -> None:
    """``obs`` (one observation, or a stack of them) lies in the observation space; on failure
    name the first offending observation and its out-of-bounds entries."""
    space = env.observation_space
    batch = np.atleast_2d(obs)
    assert batch.dtype == space.dtype and batch.shape[1:] == space.shape, context
    inside = (batch >= space.low) & (batch <= space.high)  # False for NaN too
    if not inside.all():
        k = int(np.flatnonzero(~inside.all(axis=1))[0])
        names = [f"{f.name}[{i}]" for f in env.observation_layout for i in range(f.size)]
        bad = [
            f"{names[i]}={batch[k, i]!r} not in [{space.low[i]}, {space.high[i]}]"
            for i in np.flatnonzero(~inside[k])
        ]
        where = f"{context}, observation {k}" if obs.ndim == 2 else context
        pytest.fail(f"{where}: " + "; ".join(bad))
    if obs.ndim == 1:
        assert space.contains(obs), context


def assert_reward_adds_up(reward: float, info: dict, context: str) -> None:
    terms = info["reward_terms"]
    assert math.isclose(reward, sum(terms.values()), abs_tol=1e-12), f"{context}: {terms}"


# -- long random rollouts -------------------------------------------------------------------------


@pytest.mark.parametrize("action_mode", ACTION_MODES)
@pytest.mark.parametrize("env_class", ENV_CLASSES)
def test_random_rollout_stays_in_bounds(env_class, action_mode):
    """20,000 random steps on big_S: every observation in the Box, every reward = sum of terms."""
    env = env_class(track="big_S", action_mode=action_mode)
    env.action_space.seed(2024)
    obs, _ = env.reset(seed=2024)
    n_steps = 20_000
    seen = np.empty((2 * n_steps + 1, *obs.shape), dtype=obs.dtype)  # steps and resets
    seen[0] = obs
    k = 1
    episodes = 0
    for t in range(n_steps):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        seen[k] = obs
        k += 1
        assert_reward_adds_up(reward, info, f"step {t}")
        if terminated or truncated:
            episodes += 1
            seen[k], _ = env.reset()
            k += 1
    assert_in_bounds(env, seen[:k], "random rollout (steps and resets, in order)")
    assert episodes > 10


# -- extreme driving ----------------------------------------------------------------------------


def full_ahead_into_a_wall(env, env_class, each_step=None):
    """Hold full ahead from the spawn until the episode ends (``each_step(t, obs, reward,
    info)`` sees every step): the last observation and info, whether the end was a
    termination, and the speed the kart entered the last step with (the one it reported)."""
    env.reset(seed=0)
    go = action(env, FULL_AHEAD[env_class], (1.0, 0.0))
    speed = 0.0
    for t in range(2_000):
        obs, reward, terminated, truncated, info = env.step(go)
        if each_step is not None:
            each_step(t, obs, reward, info)
        if terminated or truncated:
            return obs, info, terminated, speed
        speed = info["speed"]
    raise AssertionError("full ahead did not end the episode in 2,000 steps")


@pytest.mark.parametrize("track", ["big_S", "small_S"])
@pytest.mark.parametrize("action_mode", ACTION_MODES)
@pytest.mark.parametrize("env_class", ENV_CLASSES)
def test_full_throttle_into_a_wall(env_class, action_mode, track):
    """Full ahead from the spawn ends in a wall crash; observations stay in bounds throughout
    and the last one shows the wall right in front (egocentric envs: the straight-ahead ray)."""
    env = env_class(track=track, action_mode=action_mode, config=LONG)

    def in_bounds(t, obs, reward, info):
        assert_in_bounds(env, obs, f"step {t}")
        assert_reward_adds_up(reward, info, f"step {t}")

    obs, info, terminated, speed = full_ahead_into_a_wall(env, env_class, in_bounds)
    assert terminated
    assert info["crashed"] and not info["lap_finished"]
    rw = env.config.reward
    assert info["reward_terms"]["wall"] == pytest.approx(-(rw.wall + rw.wall_per_m_s * speed))
    n = env.config.lidar.n_rays
    ahead = n // 2  # 0 deg: straight ahead, or +x (the grid's "right") in the grid env
    assert obs[ahead] < 0.15, f"ray ahead reads {obs[ahead]} at the crash"


@pytest.mark.parametrize("env_class", ENV_CLASSES)
def test_a_wall_hit_at_speed_costs_more_per_m_s(env_class):
    """With ``wall_per_m_s``, the crash costs the wall penalty plus that much per m/s of the
    speed the kart entered the crashing step with (the last speed it reported)."""
    config = {**LONG, "reward": {"wall": 1.0, "wall_per_m_s": 2.0}}
    env = env_class(track="small_S", config=config)
    _, info, _, speed = full_ahead_into_a_wall(env, env_class)
    assert info["crashed"] and speed > 0.5
    assert info["reward_terms"]["wall"] == pytest.approx(-(1.0 + 2.0 * speed))


@pytest.mark.parametrize(("direction", "ray"), [(1, 4), (2, 12), (3, 0), (4, 8)])
def test_grid_each_direction_into_a_wall(direction, ray):
    """Grid: holding up, down, left or right ends at a wall, observations in bounds; the
    world-fixed ray pointing that way (-90, 90, -180 or 0 deg of 16 rays) sees the wall close."""
    env = GridEnv(track="small_S", config=LONG)
    env.reset(seed=1)
    for t in range(2_000):
        obs, _, terminated, truncated, info = env.step(direction)
        assert_in_bounds(env, obs, f"step {t}")
        if terminated or truncated:
            break
    assert info["crashed"]
    assert obs[ray] < 0.15, f"ray {ray} reads {obs[ray]} at the crash"


@pytest.mark.parametrize("action_mode", ACTION_MODES)
def test_gazebo_spins_in_place(action_mode):
    """Gazebo, turn left held for 500 steps: it turns on the spot, yaw rate tends to -1,
    the heading observation follows the heading, and nothing leaves its bounds."""
    config = {"reward": {"stand_still_steps": 1_000}}
    env = GazeboEnv(track="big_S", action_mode=action_mode, config=config)
    obs, info = env.reset(seed=0)
    start = info["position"]
    left = action(env, 3, (0.0, -1.0))
    n = env.config.lidar.n_rays
    for t in range(500):
        obs, reward, terminated, truncated, info = env.step(left)
        assert_in_bounds(env, obs, f"step {t}")
        assert_reward_adds_up(reward, info, f"step {t}")
        assert not (terminated or truncated), f"episode ended at step {t}"
        assert obs[n + 2] == pytest.approx(math.cos(env.heading), abs=1e-6)
        assert obs[n + 3] == pytest.approx(math.sin(env.heading), abs=1e-6)
    assert info["position"] == pytest.approx(start)
    assert obs[n + 1] == pytest.approx(-1.0, abs=1e-6)
    expected_turn = env.config.physics.max_angular_rad_s * 500 / 60
    assert -env.heading == pytest.approx(expected_turn, rel=0.02)


@pytest.mark.parametrize("action_mode", ACTION_MODES)
def test_steer_full_lock_full_throttle(action_mode):
    """Steer, full right lock at full throttle for 500 steps in the arena: it circles at top
    speed with the steering observation at 1, all observations in bounds."""
    env = SteerEnv(track=ARENA, action_mode=action_mode, config=LONG)
    obs, _ = env.reset(seed=0)
    n = env.config.lidar.n_rays
    turn = action(env, 8, (1.0, 1.0))
    for t in range(500):
        obs, reward, terminated, truncated, info = env.step(turn)
        assert_in_bounds(env, obs, f"step {t}")
        assert_reward_adds_up(reward, info, f"step {t}")
        assert not (terminated or truncated), f"episode ended at step {t}"
        assert info["reward_terms"]["steering"] <= 0.0
    assert obs[n + 1] == pytest.approx(1.0)
    assert obs[n] > 0.99
    assert info["reward_terms"]["steering"] == pytest.approx(-env.config.reward.steering)


def test_steer_cannot_turn_in_place():
    """Steer at rest with full lock: the heading does not change (bicycle model)."""
    env = SteerEnv(track=ARENA, config=LONG)
    env.reset(seed=0)
    for _ in range(100):
        env.step(5)  # coast + right
    assert env.heading == 0.0
    assert env.position == (200.0, 1000.0)


@pytest.mark.parametrize("action_mode", ACTION_MODES)
@pytest.mark.parametrize("env_class", ENV_CLASSES)
def test_top_speed_reaches_but_never_exceeds_one(env_class, action_mode):
    """Full ahead in the empty arena: the speed observation climbs to ~1.0 and never above."""
    env = env_class(track=ARENA, action_mode=action_mode, config=LONG)
    env.reset(seed=0)
    go = action(env, FULL_AHEAD[env_class], (1.0, 0.0))
    n = env.config.lidar.n_rays
    speeds = []
    for t in range(150):
        obs, _, terminated, truncated, _ = env.step(go)
        assert_in_bounds(env, obs, f"step {t}")
        assert not (terminated or truncated), f"episode ended at step {t}"
        speeds.append(obs[n])
    assert max(speeds) <= 1.0
    assert speeds[-1] >= 0.99
    assert np.all(np.diff(speeds) >= -1e-7), "the speed should only grow"


@pytest.mark.parametrize("direction", [(1.0, 1.0), (0.3, -1.0), (5.0, 0.0)])
def test_grid_continuous_speed_norm_is_capped(direction):
    """Grid, continuous: the velocity vector's length is capped at 1 in any direction, also for
    an out-of-range action, and each component stays in [-1, 1]."""
    env = GridEnv(track=ARENA, action_mode="continuous", config=LONG)
    env.reset(seed=0)
    n = env.config.lidar.n_rays
    for t in range(120):
        obs, _, terminated, truncated, info = env.step(np.asarray(direction, dtype=np.float32))
        assert_in_bounds(env, obs, f"step {t}")
        assert not (terminated or truncated), f"episode ended at step {t}"
        assert math.hypot(obs[n], obs[n + 1]) <= 1.0 + 1e-6
    assert math.hypot(obs[n], obs[n + 1]) == pytest.approx(1.0, abs=1e-6)
    assert info["speed"] <= env.config.physics.max_speed_m_s


# -- reward terms and episode ends ----------------------------------------------------------------


@pytest.mark.parametrize("env_class", ENV_CLASSES)
def test_reward_term_names(env_class):
    """The reward terms are the documented ones; the steer env adds ``steering``."""
    env = env_class()
    env.reset(seed=0)
    *_, info = env.step(IDLE[env_class])
    expected = {
        "progress",
        "heading",
        "checkpoint",
        "finish",
        "time",
        "wall",
        "stand_still",
        "stall",
    }
    if env_class is SteerEnv:
        expected.add("steering")
    assert set(info["reward_terms"]) == expected
    assert info["reward_terms"]["time"] == -env.config.reward.time


@pytest.mark.parametrize("action_mode", ACTION_MODES)
@pytest.mark.parametrize("env_class", ENV_CLASSES)
def test_truncation_exactly_at_max_episode_steps(env_class, action_mode):
    """Standing still with max_episode_steps=50 < stand_still_steps: step 50 is truncated,
    not terminated, and no earlier step ends the episode."""
    config = {"max_episode_steps": 50, "reward": {"stand_still_steps": 60}}
    env = env_class(track="small_S", action_mode=action_mode, config=config)
    env.reset(seed=0)
    idle = action(env, IDLE[env_class], (0.0, 0.0))
    for t in range(1, 50):
        _, _, terminated, truncated, _ = env.step(idle)
        assert not (terminated or truncated), f"episode ended at step {t}"
    _, reward, terminated, truncated, info = env.step(idle)
    assert truncated and not terminated
    assert not info["stood_still"] and not info["crashed"]
    assert info["reward_terms"]["stand_still"] == 0.0
    assert info["elapsed_time"] == pytest.approx(50 / 60)
    assert_reward_adds_up(reward, info, "step 50")


@pytest.mark.parametrize("env_class", ENV_CLASSES)
def test_standing_still_terminates(env_class):
    """Standing still for stand_still_steps (< the time limit) terminates with the penalty."""
    config = {"max_episode_steps": 50, "reward": {"stand_still_steps": 30}}
    env = env_class(track="small_S", config=config)
    env.reset(seed=0)
    for t in range(1, 30):
        _, _, terminated, truncated, _ = env.step(IDLE[env_class])
        assert not (terminated or truncated), f"episode ended at step {t}"
    _, reward, terminated, truncated, info = env.step(IDLE[env_class])
    assert terminated and not truncated
    assert info["stood_still"]
    assert info["reward_terms"]["stand_still"] == -env.config.reward.stand_still
    assert_reward_adds_up(reward, info, "step 30")


@pytest.mark.parametrize("env_class", ENV_CLASSES)
def test_stalling_costs_per_step_after_the_grace(env_class):
    """Once the kart has not come nearer the next checkpoint for stall_grace_steps, every
    further step pays ``stall``; standing still is stalling, so idling pays from step 22 (the
    first step sets the distance to beat)."""
    config = {"max_episode_steps": 60, "reward": {"stall": 0.05, "stall_grace_steps": 20}}
    env = env_class(track="small_S", config=config)
    env.reset(seed=0)
    paid = []
    for _ in range(40):
        _, reward, terminated, truncated, info = env.step(IDLE[env_class])
        assert not (terminated or truncated)
        paid.append(info["reward_terms"]["stall"])
        assert_reward_adds_up(reward, info, "stall")
    assert paid[:21] == [0.0] * 21 and paid[21:] == [-0.05] * 19
    # on by default in gazebo and steer (also when a reward section leaves it out); off, it
    # is left out of the env spec, so grid runs made before it existed match
    from snnkart.envs.spec import env_spec

    default = env_class(track="small_S")
    partial = env_class(track="small_S", config={"reward": {"time": 0.002}})
    own = {GridEnv: GRID_REWARD, GazeboEnv: GAZEBO_REWARD, SteerEnv: STEER_REWARD}[env_class]
    expected = {"stall": 0.0, "stand_still": 1.0, "wall_per_m_s": 0.0, **own}
    for config in (default.config, partial.config):
        assert {k: getattr(config.reward, k) for k in expected} == expected
    assert partial.config.reward.time == 0.002
    assert ("stall" in env_spec(default)["env_config"]["reward"]) == (expected["stall"] > 0)
    assert env_spec(env)["env_config"]["reward"]["stall"] == 0.05


def test_stall_counts_steps_without_a_new_best_distance():
    from snnkart.envs.reward import Stall

    stall = Stall()
    assert stall.update(0, 500.0) == 0  # a new checkpoint starts the count
    assert [stall.update(0, d) for d in (499.5, 510.0, 498.0, 505.0)] == [1, 2, 0, 1]
    assert stall.update(0, float("nan")) == 2  # undefined distance: no progress
    assert stall.update(1, 800.0) == 0  # the next checkpoint


@pytest.mark.parametrize("env_class", ENV_CLASSES)
def test_termination_wins_over_truncation_on_the_same_step(env_class):
    """If the stand-still limit and the time limit fall on the same step, it is terminated."""
    config = {"max_episode_steps": 40, "reward": {"stand_still_steps": 40}}
    env = env_class(track="small_S", config=config)
    env.reset(seed=0)
    for _ in range(40):
        _, _, terminated, truncated, info = env.step(IDLE[env_class])
    assert terminated and not truncated and info["stood_still"]


@pytest.mark.parametrize("env_class", ENV_CLASSES)
def test_default_time_limit_comes_from_the_track(env_class):
    """Without max_episode_steps the limit is the track's time_limit_s at 60 steps per second."""
    env = env_class(track="small_S")
    factor = env.config.physics.time_limit_factor if env_class is GazeboEnv else 1.0
    assert env.max_episode_steps == math.ceil(env.track.time_limit_s * factor * 60)


def test_scripted_lap_finishes_with_checkpoint_and_finish_rewards():
    """A simple controller steering the grid kart at each checkpoint's midpoint drives a full
    lap of small_S: every checkpoint pays its bonus once, in order, and the finish line ends
    the episode as terminated (not crashed), with the finish bonus and the lap time."""
    env = GridEnv(track="small_S", action_mode="continuous", config={"max_episode_steps": 3000})
    obs, info = env.reset(seed=0)
    rw = env.config.reward
    n = env.config.lidar.n_rays
    goals = [cp.midpoint for cp in env.track.checkpoints]
    passed = []
    for t in range(3000):
        target = np.subtract(goals[info["checkpoint"]], info["position"])
        velocity = obs[n : n + 2] * env.config.physics.max_speed_m_s * 100.0
        act = np.clip(0.02 * (target - velocity), -1.0, 1.0).astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(act)
        assert_in_bounds(env, obs, f"step {t}")
        assert_reward_adds_up(reward, info, f"step {t}")
        if info["reward_terms"]["checkpoint"]:
            passed.append(info["checkpoint"])
            assert info["reward_terms"]["checkpoint"] == rw.checkpoint
        if terminated or truncated:
            break
    n_cp = len(goals)
    assert terminated and not truncated
    assert info["lap_finished"] and not info["crashed"]
    assert passed == list(range(1, n_cp))  # the finish line pays the finish bonus instead
    assert info["reward_terms"]["finish"] == rw.finish
    assert info["reward_terms"]["progress"] == 0.0
    times = info["checkpoint_times"]
    assert len(times) == n_cp and list(times) == sorted(times)
    assert info["lap_time"] == pytest.approx(info["elapsed_time"]) == pytest.approx(times[-1])
