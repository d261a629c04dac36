"""Renamed config keys: the old name still loads (saved runs, old config files, ``--set``), a
user who types it is warned, and both names at once are refused."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from snnkart.errors import ConfigError
from snnkart.rl.config import load_config, read_run_config

GOLDEN = Path(__file__).parent / "golden"


def test_the_rollout_length_is_ppo_rollout_steps_and_the_old_name_still_sets_it() -> None:
    assert load_config(sets=["ppo.rollout_steps=64"]).ppo.rollout_steps == 64
    with pytest.warns(FutureWarning, match=r"ppo\.num_steps is deprecated.*ppo\.rollout_steps"):
        cfg = load_config(sets=["ppo.num_steps=64"])
    assert cfg.ppo.rollout_steps == 64
    assert "num_steps = 64" not in cfg.to_toml().split("[snn]")[0]  # written under the new name


def test_the_old_name_beats_a_per_env_default_as_the_new_name_does() -> None:
    """gazebo's SNN defaults to 128 rollout steps: a user's old-name value still wins."""
    base = ["env=gazebo", "policy=snn"]
    assert load_config(sets=base).ppo.rollout_steps == 128
    with pytest.warns(FutureWarning):
        assert load_config(sets=[*base, "ppo.num_steps=32"]).ppo.rollout_steps == 32


def test_both_names_at_once_are_refused() -> None:
    with pytest.raises(ConfigError, match=r"ppo\.num_steps is the old name of ppo\.rollout_steps"):
        load_config(sets=["ppo.num_steps=64", "ppo.rollout_steps=32"])


@pytest.mark.parametrize("name", ["train-ann.toml", "train-snn.toml"])
def test_golden_configs_written_with_the_old_name_keep_loading(name: str) -> None:
    text = (GOLDEN / name).read_text()
    assert "num_steps = 128" in text.split("[ann]")[0]  # the [ppo] section uses the old name
    with pytest.warns(FutureWarning):
        assert load_config(GOLDEN / name).ppo.rollout_steps == 128


def test_a_saved_run_with_the_old_name_loads_silently(tmp_path: Path) -> None:
    """A run's own config.toml was written by snnkart, not typed: no warning to act on."""
    (tmp_path / "config.toml").write_text((GOLDEN / "train-ann.toml").read_text())
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert read_run_config(tmp_path).ppo.rollout_steps == 128
