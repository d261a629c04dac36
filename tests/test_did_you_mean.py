"""A misspelled env, backend or config key gets the nearest right spelling in its one-line
error; a path that does not exist is said not to exist."""

from __future__ import annotations

from pathlib import Path

import pytest

from snnkart.backends.registry import arithmetic_for
from snnkart.envs import resolve_env_name
from snnkart.errors import ConfigError, DeployError, EnvError, did_you_mean
from snnkart.rl.config import config_keys, load_config, read_run_config


def test_the_nearest_choice_or_nothing() -> None:
    assert did_you_mean("gazbo", ["grid", "gazebo", "steer"]) == " (did you mean 'gazebo'?)"
    assert did_you_mean("moon", ["grid", "gazebo", "steer"]) == ""


def test_a_misspelled_env_and_backend() -> None:
    with pytest.raises(EnvError, match=r"unknown env 'gazbo' \(did you mean 'gazebo'\?\)"):
        resolve_env_name("gazbo")
    with pytest.raises(DeployError, match=r"'lava-simm' \(did you mean 'lava-sim'\?\)"):
        arithmetic_for("lava-simm", "fixed")


@pytest.mark.parametrize(
    ("key", "near"),
    [("ppo.learnin_rate", "ppo.learning_rate"), ("snn.hiden", "snn.hidden"), ("sed", "seed")],
)
def test_a_misspelled_set_key(key: str, near: str) -> None:
    with pytest.raises(ConfigError) as err:
        load_config(sets=[f"{key}=1"])
    assert f"unknown key {key!r} (misspelled? did you mean {near!r}?)" in str(err.value)


def test_every_config_key_is_offered() -> None:
    keys = config_keys()
    assert {"ppo.learning_rate", "ppo.rollout_steps", "snn.num_steps", "seed", "env"} <= set(keys)
    assert "ppo" not in keys  # sections are not keys


def test_a_run_directory_that_does_not_exist(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"nothing does not exist"):
        read_run_config(tmp_path / "nothing")
    with pytest.raises(ConfigError, match=r"is not a run directory \(no config.toml\)"):
        read_run_config(tmp_path)
