"""Training starts spread along the track (snnkart.envs.starts): the spawn is unchanged without
them, a spread start is a safe pose headed along the route, and its finish is not a lap."""

from __future__ import annotations

import math

import pytest
from gymnasium.utils import seeding

from snnkart.envs.constants import KART_RADIUS_PX
from snnkart.envs.geometry import segment_distance
from snnkart.envs.spec import make_env
from snnkart.eval.drivers import ScriptedDriver
from snnkart.rl.config import PPOConfig, load_config, read_run_config
from snnkart.rl.rollout import Rollout

TRACKS = ["small_S", "big_S", *(f"benchmarks/tracks/{t}.toml" for t in ("ring", "zigzag", "hairpins", "bends"))]  # fmt: skip


@pytest.mark.parametrize("env_name", ["grid", "gazebo", "steer"])
def test_without_spread_every_episode_starts_at_the_spawn_as_before(env_name: str) -> None:
    """The track's spawn plus its jitter, drawn from the env's generator exactly as before the
    option existed (and nothing more drawn), so every run trained without it is reproduced."""
    env = make_env(env_name, "small_S")
    kart = env.unwrapped
    track = kart.track
    for seed in range(20):
        env.reset(seed=seed)
        rng, _ = seeding.np_random(seed)
        j = track.spawn_jitter
        dx, dy = rng.uniform(-j, j, size=2)
        assert kart.position == (track.spawn_position[0] + dx, track.spawn_position[1] + dy)
        assert kart.next_checkpoint == 0
        assert kart.heading == (track.spawn_heading if env_name != "grid" else 0.0)
        assert kart.np_random.bit_generator.state == rng.bit_generator.state


@pytest.mark.parametrize("env_name", ["grid", "steer"])  # gazebo's route clearance is grid's
@pytest.mark.parametrize("track", TRACKS)
def test_spread_starts_reach_every_checkpoint_on_a_safe_pose_headed_along_the_route(
    env_name: str, track: str
) -> None:
    env = make_env(env_name, track)
    kart = env.unwrapped
    kart.start_spread = 0.75
    n = len(kart.track.checkpoints)
    seen = set()
    for seed in range(30 * n):
        _, info = env.reset(seed=seed)
        k = info["checkpoint"]
        seen.add(k)
        if k == 0:
            continue
        x, y = kart.position
        # clear of every wall by more than the kart's radius
        clearance = min(segment_distance(x, y, *seg) for seg in kart.track.segments)
        assert clearance > 1.5 * KART_RADIUS_PX, (seed, k, clearance)
        # and the way to line k gets shorter along the start's heading (the route's direction)
        route = kart._geodesic.route(k, x, y)
        assert route is not None
        d0 = kart._geodesic.distance(k, x, y)
        d1 = kart._geodesic.distance(k, x + 5.0 * route[0], y + 5.0 * route[1])
        assert d0 - d1 > 4.0, (seed, k, d0, d1)
        if kart.egocentric:
            assert math.cos(math.atan2(route[1], route[0]) - kart.heading) > 0.999
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


def test_a_spread_start_never_leaks_into_an_env_made_later() -> None:
    """Evaluation and deployment build their own envs: they start at the spawn."""
    cfg = load_config(sets=["env=grid", "policy=snn", "ppo.num_envs=2"])
    assert cfg.ppo.start_spread == 0.5  # grid's default
    rollout = Rollout(cfg, make_env("grid", "small_S").unwrapped.track)
    try:
        assert cfg.make_env().unwrapped.start_spread == 0.0
    finally:
        rollout.close()


def test_a_run_saved_before_start_spread_existed_resumes_without_it(tmp_path) -> None:
    cfg = load_config(sets=["env=grid", "policy=ann"])
    text = cfg.to_toml()
    assert "start_spread = 0.5" in text
    (tmp_path / "config.toml").write_text(text.replace("start_spread = 0.5\n", ""))
    assert read_run_config(tmp_path).ppo.start_spread == 0.0
    (tmp_path / "config.toml").write_text(text)
    assert read_run_config(tmp_path) == cfg


def test_a_saved_run_config_keeps_plain_defaults_for_keys_it_lacks(tmp_path) -> None:
    """A saved config is resolved: per-env and per-policy defaults are not merged in again."""
    cfg = load_config(sets=["env=gazebo", "policy=snn"])
    assert (cfg.ppo.ent_coef, cfg.ppo.num_envs, cfg.ppo.learning_rate) == (0.02, 16, 1e-3)
    text = cfg.to_toml()
    for key in ("ent_coef", "num_envs", "learning_rate"):
        text = "\n".join(line for line in text.splitlines() if not line.startswith(f"{key} ="))
    (tmp_path / "config.toml").write_text(text)
    saved = read_run_config(tmp_path).ppo
    plain = PPOConfig()
    assert (saved.ent_coef, saved.num_envs, saved.learning_rate) == (
        plain.ent_coef,
        plain.num_envs,
        plain.learning_rate,
    )
    # the same keys given by a user still get the env's and the policy's defaults
    assert load_config(tmp_path / "config.toml").ppo == cfg.ppo
