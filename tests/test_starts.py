"""Training starts spread along the track (snnkart.envs.starts): the spawn is unchanged without
them, a spread start is a safe pose headed along the route, and its finish is not a lap."""

from __future__ import annotations

import math

import pytest
from gymnasium.utils import seeding

from snnkart.envs.spec import make_env
from snnkart.eval.drivers import ScriptedDriver
from snnkart.rl.config import load_config
from snnkart.rl.rollout import Rollout

RING = "benchmarks/tracks/ring.toml"


def _starts(env_name: str, track: str, spread: float, seeds: range) -> list[tuple]:
    env = make_env(env_name, track)
    kart = env.unwrapped
    kart.start_spread = spread
    out = []
    for seed in seeds:
        _, info = env.reset(seed=seed)
        out.append((*kart.position, kart.heading, info["checkpoint"]))
    return out


@pytest.mark.parametrize("env_name", ["grid", "gazebo", "steer"])
def test_without_spread_every_episode_starts_at_the_spawn_as_before(env_name: str) -> None:
    """The track's spawn plus its jitter, drawn from the env's generator exactly as before the
    option existed, so every run trained without it is reproduced bit for bit."""
    env = make_env(env_name, "small_S")
    track = env.unwrapped.track
    starts = _starts(env_name, "small_S", 0.0, range(20))
    for seed, (x, y, heading, cp) in enumerate(starts):
        rng, _ = seeding.np_random(seed)
        j = track.spawn_jitter
        dx, dy = rng.uniform(-j, j, size=2)
        assert (x, y, cp) == (track.spawn_position[0] + dx, track.spawn_position[1] + dy, 0)
        assert heading == (track.spawn_heading if env_name != "grid" else 0.0)


@pytest.mark.parametrize(
    ("env_name", "track"), [("steer", "small_S"), ("gazebo", "big_S"), ("grid", RING)]
)
def test_spread_starts_reach_every_checkpoint_on_a_safe_pose_headed_along_the_route(
    env_name: str, track: str
) -> None:
    env = make_env(env_name, track)
    kart = env.unwrapped
    kart.start_spread = 0.75
    n = len(kart.track.checkpoints)
    seen = set()
    for seed in range(80):
        _, info = env.reset(seed=seed)
        k = info["checkpoint"]
        seen.add(k)
        if k == 0:
            continue
        # on the line just passed, where the way to line k is defined, and headed along it
        assert math.isfinite(kart._geodesic.distance(k, *kart.position))
        if kart.egocentric:
            route = kart._geodesic.route(k, *kart.position)
            assert route is not None
            assert math.cos(math.atan2(route[1], route[0]) - kart.heading) > 0.999
        # at rest, clear of the walls: standing still for a step touches nothing
        _, _, terminated, _, info = env.step(0)  # one step from rest moves under 1 px
        assert not terminated and not info["crashed"], (seed, k)
    assert seen == set(range(n)), f"starts seen {sorted(seen)} of {n} checkpoints"


def test_a_finish_from_a_spread_start_pays_its_bonus_but_is_not_a_lap() -> None:
    env = make_env("gazebo", "small_S")
    kart = env.unwrapped
    kart.start_spread = 0.9
    last = len(kart.track.checkpoints) - 1
    seed = next(s for s in range(200) if env.reset(seed=s)[1]["checkpoint"] == last)
    env.reset(seed=seed)
    driver = ScriptedDriver(kart)
    for _ in range(kart.max_episode_steps):
        _, _, terminated, truncated, info = env.step(driver.act())
        if terminated or truncated:
            break
    assert terminated and not info["crashed"] and not info["stood_still"]
    assert info["reward_terms"]["finish"] > 0  # the finish line was crossed and paid for
    assert info["lap_finished"] is False and info["lap_time"] is None


def test_training_envs_take_start_spread_from_the_ppo_config() -> None:
    cfg = load_config(sets=["env=grid", "policy=ann", "ppo.num_envs=2", "ppo.start_spread=0.3"])
    rollout = Rollout(cfg, make_env("grid", "small_S").unwrapped.track)
    try:
        assert [k.start_spread for k in rollout.karts] == [0.3, 0.3]
    finally:
        rollout.close()
