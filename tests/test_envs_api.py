"""The gymnasium API of the three envs: check_env, registration, names, argument errors, spaces."""

from __future__ import annotations

import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pydantic
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

import snnkart
import snnkart.envs
from snnkart.envs.config import GazeboConfig, GridConfig, SteerConfig
from snnkart.envs.gazebo import GazeboEnv
from snnkart.envs.grid import GridEnv
from snnkart.envs.steer import SteerEnv

ENV_CLASSES = {"grid": GridEnv, "gazebo": GazeboEnv, "steer": SteerEnv}
ENV_IDS = {"grid": "snnkart/Grid-v0", "gazebo": "snnkart/Gazebo-v0", "steer": "snnkart/Steer-v0"}
TRACKS = ("big_S", "small_S")
ACTION_MODES = ("discrete", "continuous")
KINEMATIC_SIZE = {"grid": 2, "gazebo": 4, "steer": 4}
DISCRETE_ACTIONS = {"grid": 5, "gazebo": 5, "steer": 9}


@pytest.mark.parametrize("action_mode", ACTION_MODES)
@pytest.mark.parametrize("track", TRACKS)
@pytest.mark.parametrize("name", ENV_IDS)
def test_check_env(name, track, action_mode):
    """gymnasium's env checker passes, without a single warning, for every env x track x mode."""
    env = gym.make(ENV_IDS[name], track=track, action_mode=action_mode)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_registered_ids():
    """Importing snnkart registers exactly the three documented ids."""
    assert snnkart.ENV_IDS == ENV_IDS
    for env_id in ENV_IDS.values():
        assert env_id in gym.registry


@pytest.mark.parametrize("name", ENV_IDS)
def test_gym_make_with_kwargs(name):
    """gymnasium.make passes track, action_mode and a config dict through to the env."""
    env = gym.make(
        ENV_IDS[name],
        track="big_S",
        action_mode="continuous",
        config={"lidar": {"n_rays": 8, "fov_deg": 180.0}, "max_episode_steps": 77},
    )
    inner = env.unwrapped
    assert isinstance(inner, ENV_CLASSES[name])
    assert inner.track.name == "big_S"
    assert inner.action_mode == "continuous"
    assert inner.config.lidar.n_rays == 8
    assert inner.max_episode_steps == 77
    assert env.observation_space.shape == (8 + KINEMATIC_SIZE[name] + 3,)
    assert isinstance(env.action_space, spaces.Box) and env.action_space.shape == (2,)
    obs, _ = env.reset(seed=3)
    assert obs.shape == env.observation_space.shape
    env.close()


@pytest.mark.parametrize("name", ENV_IDS)
def test_defaults(name):
    """Defaults: small_S, discrete actions, 16 rays, no rendering."""
    env = gym.make(ENV_IDS[name]).unwrapped
    assert env.track.name == "small_S"
    assert env.action_mode == "discrete"
    assert env.render_mode is None
    assert env.action_space == spaces.Discrete(DISCRETE_ACTIONS[name])
    assert env.observation_space.shape == (16 + KINEMATIC_SIZE[name] + 3,)


@pytest.mark.parametrize("name", ENV_IDS)
def test_config_object_accepted(name):
    """A typed config object of the env's own class is accepted as is."""
    config_class = {"grid": GridConfig, "gazebo": GazeboConfig, "steer": SteerConfig}[name]
    config = config_class(max_episode_steps=12)
    env = ENV_CLASSES[name](config=config)
    assert env.config is config
    assert env.max_episode_steps == 12


def test_config_of_the_wrong_env_is_rejected():
    """A GazeboConfig handed to the steer env is a TypeError naming the needed class."""
    with pytest.raises(TypeError, match="SteerConfig"):
        SteerEnv(config=GazeboConfig())


@pytest.mark.parametrize(
    ("alias", "name"),
    [
        ("grid", "grid"),
        ("grid_env", "grid"),
        ("gazebo_env", "gazebo"),
        ("steer_env", "steer"),
        ("snnkart/Steer-v0", "steer"),
        ("Steer", "steer"),
        ("latenv", "grid"),
    ],
)
def test_resolve_env_name(alias, name):
    """All accepted spellings, including the original project's names, resolve to one env."""
    assert snnkart.envs.resolve_env_name(alias) == name


@pytest.mark.parametrize("alias", ["grid_env", "gazebo_env", "steer_env"])
def test_snnkart_make_accepts_original_names(alias):
    """snnkart.envs.make builds the env for the original project's names."""
    env = snnkart.envs.make(alias, track="big_S")
    assert isinstance(env.unwrapped, ENV_CLASSES[alias.removesuffix("_env")])
    assert env.unwrapped.track.name == "big_S"
    env.close()


@pytest.mark.parametrize("bad", ["drive_env", "car", "", "snnkart/Grid-v1"])
def test_make_rejects_unknown_names(bad):
    """An unknown env name is a ValueError that names it and lists the choices."""
    with pytest.raises(ValueError) as excinfo:
        snnkart.make(bad)
    msg = str(excinfo.value)
    assert repr(bad) in msg
    for choice in ("grid", "gazebo", "steer", "steer_env"):
        assert choice in msg


@pytest.mark.parametrize("name", ENV_IDS)
def test_bad_action_mode(name):
    """A misspelled action_mode is a ValueError naming it and the valid modes."""
    with pytest.raises(ValueError, match=r"action_mode 'continous'.*discrete, continuous"):
        gym.make(ENV_IDS[name], action_mode="continous")


@pytest.mark.parametrize("name", ENV_IDS)
def test_bad_display_mode(name):
    """An unknown render_mode is a ValueError naming it and the valid modes."""
    with pytest.raises(ValueError, match=r"render_mode 'rgb'.*human, rgb_array"):
        ENV_CLASSES[name](render_mode="rgb")


@pytest.mark.parametrize(
    ("config", "key"),
    [
        ({"lidar": {"n_ray": 5}}, "n_ray"),
        ({"lidar_config": {}}, "lidar_config"),
        ({"reward": {"progres": 2.0}}, "progres"),
        ({"physics": {"max_sped_m_s": 1.0}}, "max_sped_m_s"),
    ],
)
@pytest.mark.parametrize("name", ENV_IDS)
def test_misspelled_config_key(name, config, key):
    """A misspelled config key fails (as a ValueError) with the key in the message."""
    with pytest.raises(ValueError) as excinfo:
        gym.make(ENV_IDS[name], config=config)
    assert isinstance(excinfo.value, pydantic.ValidationError)
    assert key in str(excinfo.value)


@pytest.mark.parametrize(
    ("config", "field"),
    [
        ({"lidar": {"n_rays": 0}}, "n_rays"),
        ({"lidar": {"fov_deg": 400}}, "fov_deg"),
        ({"lidar": {"range_m": -1.0}}, "range_m"),
        ({"max_episode_steps": 0}, "max_episode_steps"),
        ({"reward": {"stand_still_steps": "many"}}, "stand_still_steps"),
    ],
)
def test_out_of_range_config_value(config, field):
    """An invalid config value fails with the field's name in the message."""
    with pytest.raises(ValueError, match=field):
        GazeboEnv(config=config)


def test_configs_are_frozen():
    """Configs cannot be changed after the env has read them."""
    env = GridEnv()
    with pytest.raises(pydantic.ValidationError):
        env.config.lidar.n_rays = 3  # type: ignore[misc]


@pytest.mark.parametrize("action_mode", ACTION_MODES)
@pytest.mark.parametrize("name", ENV_IDS)
def test_observation_space_matches_layout(name, action_mode):
    """float32 Box whose size and per-index bounds follow ``observation_layout``."""
    env = ENV_CLASSES[name](action_mode=action_mode, config={"lidar": {"n_rays": 10}})
    space = env.observation_space
    assert isinstance(space, spaces.Box)
    assert space.dtype == np.float32
    layout = env.observation_layout
    assert space.shape == (sum(f.size for f in layout),)
    assert layout[0].name == "lidar" and layout[0].size == 10
    assert [f.name for f in layout[-3:]] == [
        "checkpoint_cos",
        "checkpoint_sin",
        "checkpoint_distance",
    ]
    start = 0
    for f in layout:
        block = slice(start, start + f.size)
        np.testing.assert_array_equal(space.low[block], f.low, err_msg=f.name)
        np.testing.assert_array_equal(space.high[block], f.high, err_msg=f.name)
        assert f.description
        start += f.size
    obs, _ = env.reset(seed=0)
    assert obs.dtype == np.float32 and obs.shape == space.shape
    obs, *_ = env.step(env.action_space.sample())
    assert obs.dtype == np.float32 and obs.shape == space.shape


@pytest.mark.parametrize("name", ENV_IDS)
def test_step_before_reset_raises(name):
    """Stepping a fresh env (or a finished episode) without reset is an error, not silent."""
    env = ENV_CLASSES[name](config={"max_episode_steps": 1})
    with pytest.raises(RuntimeError, match="reset"):
        env.step(env.action_space.sample())
    env.reset(seed=0)
    _, _, terminated, truncated, _ = env.step(env.action_space.sample())
    assert terminated or truncated
    with pytest.raises(RuntimeError, match="reset"):
        env.step(env.action_space.sample())


@pytest.mark.parametrize("name", ENV_IDS)
def test_info_keys(name):
    """reset and step return the documented info keys."""
    env = ENV_CLASSES[name]()
    _, info = env.reset(seed=0)
    keys = {
        "checkpoint",
        "checkpoints_total",
        "checkpoint_times",
        "lap_finished",
        "lap_time",
        "elapsed_time",
        "crashed",
        "stood_still",
        "speed",
        "position",
        "reward_terms",
    }
    assert keys <= set(info)
    _, _, _, _, info = env.step(env.action_space.sample())
    assert keys <= set(info)
    assert info["checkpoints_total"] == len(env.track.checkpoints)


def test_import_does_not_load_the_simulator():
    """Importing snnkart registers the envs without importing pymunk, pygame or torch."""
    code = (
        "import sys, gymnasium, snnkart\n"
        "assert 'snnkart/Steer-v0' in gymnasium.registry\n"
        "print(sorted(m for m in ('pymunk', 'pygame', 'torch', 'numba') if m in sys.modules))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60
    )
    assert out.stdout.strip() == "[]"
