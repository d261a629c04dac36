"""Sim-to-real options of the envs (env_config.sim2real): off, nothing changes and nothing is
drawn; on, the LIDAR is noisy and drops beams, and actions take effect steps late."""

from __future__ import annotations

import numpy as np
import pytest

from snnkart.envs import make
from snnkart.envs.spec import env_spec

NOISY = {"lidar_noise_m": 0.05, "beam_dropout": 0.2}


def test_off_by_default_and_left_out_of_the_spec() -> None:
    env = make("gazebo", track="small_S")
    noisy = make("gazebo", track="small_S", config={"sim2real": NOISY})
    try:
        assert "sim2real" not in env_spec(env.unwrapped)["env_config"]
        assert env_spec(noisy.unwrapped)["env_config"]["sim2real"]["beam_dropout"] == 0.2
        env.reset(seed=3)
        state = env.unwrapped.np_random.bit_generator.state
        env.step(1)
        assert env.unwrapped.np_random.bit_generator.state == state  # no draws when off
    finally:
        env.close()
        noisy.close()


def test_noise_and_dropout_change_the_rays_as_configured() -> None:
    clean = make("gazebo", track="small_S", config={"lidar": {"n_rays": 720}})
    noisy = make("gazebo", track="small_S",
                 config={"lidar": {"n_rays": 720}, "sim2real": NOISY})  # fmt: skip
    try:
        a, _ = clean.reset(seed=1)
        b, _ = noisy.reset(seed=1)
        rays_a, rays_b = a[:720], b[:720]
        dropped = rays_b == 1.0
        assert 0.15 < dropped.mean() - (rays_a == 1.0).mean() < 0.25  # about 20 % more
        keep = ~dropped & (rays_a < 0.9) & (rays_a > 0.1)
        range_m = noisy.unwrapped.ray_geometry[1] / 100
        std = np.std((rays_b - rays_a)[keep]) * range_m
        assert std == pytest.approx(0.05, rel=0.15)  # 5 cm of noise
    finally:
        clean.close()
        noisy.close()


@pytest.mark.parametrize(("env_name", "idle"), [("gazebo", 0), ("steer", 4), ("grid", 0)])
def test_actions_take_effect_late(env_name: str, idle: int) -> None:
    delay = 3
    late = make(env_name, track="small_S", config={"sim2real": {"action_delay_steps": delay}})
    now = make(env_name, track="small_S")
    rng = np.random.default_rng(0)
    actions = [int(a) for a in rng.integers(0, late.action_space.n, 60)]
    try:
        late.reset(seed=2)
        now.reset(seed=2)
        for t, action in enumerate(actions):
            late.step(action)
            now.step(idle if t < delay else actions[t - delay])
            assert late.unwrapped.position == now.unwrapped.position, t
    finally:
        late.close()
        now.close()
