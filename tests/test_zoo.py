"""The RL Zoo's PPO settings (snnkart.rl.zoo): the shipped transcription, its v5 fallback, the
translation to snnkart's config keys, the ``--set`` overrides through snnkart's own loader, and
the SB3 defaults against stable_baselines3's source."""

from __future__ import annotations

import inspect
import sys
from pathlib import Path

import pytest
import torch

from snnkart.errors import ConfigError
from snnkart.rl import zoo
from snnkart.rl.config import load_config, parse_override
from snnkart.rl.ppo_loss import value_loss

ZOO_COMMIT = "22e3ff2450fd92033f7f032915e1f64894a09584"
TASKS = [
    "CartPole-v1",
    "Acrobot-v1",
    "Pendulum-v1",
    "MountainCarContinuous-v0",
    "LunarLander-v3",
    "LunarLanderContinuous-v3",
    "HalfCheetah-v4",
    "Hopper-v4",
    "Walker2d-v4",
]
V5 = {"HalfCheetah-v5": "HalfCheetah-v4", "Hopper-v5": "Hopper-v4", "Walker2d-v5": "Walker2d-v4"}


@pytest.fixture
def shipped(monkeypatch: pytest.MonkeyPatch) -> None:
    """Read the shipped table even where rl_zoo3 is installed."""
    monkeypatch.setattr(zoo, "installed_zoo_file", lambda: None)


def _field(cfg: object, dotted: str) -> object:
    for part in dotted.split("."):
        cfg = getattr(cfg, part)
    return list(cfg) if isinstance(cfg, tuple) else cfg


@pytest.mark.usefixtures("shipped")
def test_the_shipped_table_names_its_commit_and_has_every_task() -> None:
    settings = zoo.zoo_settings("CartPole-v1")
    assert "zoo_ppo.toml" in settings.source and ZOO_COMMIT[:7] in settings.source
    table = zoo._shipped()
    assert table["source"]["commit"] == ZOO_COMMIT
    assert table["source"]["file"] == "hyperparams/ppo.yml"
    assert sorted(table["ppo"]) == sorted(TASKS)
    assert table["fallback"] == V5


@pytest.mark.usefixtures("shipped")
def test_cartpole_translates_to_snnkart_keys() -> None:
    settings = zoo.zoo_settings("CartPole-v1")
    assert (settings.key, settings.note) == ("CartPole-v1", None)
    assert settings.values["learning_rate"] == "lin_0.001"  # as the zoo writes it
    t = zoo.to_snnkart(settings)
    expected = {
        "env": "CartPole-v1",
        "total_steps": 100_000,
        "ppo.num_envs": 8,
        "ppo.rollout_steps": 32,
        "ppo.num_minibatches": 1,  # 8 * 32 / 256
        "ppo.update_epochs": 20,
        "ppo.gamma": 0.98,
        "ppo.gae_lambda": 0.8,
        "ppo.learning_rate": 1e-3,
        "ppo.anneal_lr": True,
        "ppo.clip_coef": 0.2,
        "ppo.ent_coef": 0.0,
        "ppo.anneal_ent": False,
        "ppo.vf_coef": 1.0,  # SB3's default 0.5, doubled
        "ppo.norm_obs": False,
        "ann.hidden": [64, 64],
        "ann.activation": "tanh",
    }
    assert {k: t.config[k] for k in expected} == expected
    assert any(u.startswith("clip_range lin_0.2") for u in t.unexpressible)
    assert any(d.startswith("vf_coef = 0.5 (SB3's default)") for d in t.defaulted)
    overrides = zoo.as_overrides(t)
    for text in ("ppo.gamma=0.98", "ann.hidden=[64, 64]", 'ann.activation="tanh"'):
        assert text in overrides


@pytest.mark.usefixtures("shipped")
def test_a_constant_learning_rate_is_not_annealed() -> None:
    t = zoo.to_snnkart(zoo.zoo_settings("Pendulum-v1"))
    assert (t.config["ppo.learning_rate"], t.config["ppo.anneal_lr"]) == (1e-3, False)
    assert t.config["ppo.num_minibatches"] == 4 * 1024 // 64  # SB3's default batch_size
    assert any(u.startswith("use_sde") for u in t.unexpressible)
    assert "ppo.init_log_std" not in t.config  # gSDE's log std is not an action's


@pytest.mark.usefixtures("shipped")
@pytest.mark.parametrize(("v5", "v4"), sorted(V5.items()))
def test_a_v5_task_uses_the_v4_settings_and_says_so(v5: str, v4: str) -> None:
    settings = zoo.zoo_settings(v5)
    assert settings.key == v4
    assert settings.values == zoo.zoo_settings(v4).values
    assert settings.note is not None and v5 in settings.note and v4 in settings.note
    t = zoo.to_snnkart(settings)
    assert t.config["env"] == v5
    assert t.notes[0] == settings.note
    # normalize: true is VecNormalize's default: observations and rewards, both clipped at 10
    assert t.config["ppo.norm_reward"] is True and t.config["ppo.clip_reward"] == 10.0
    assert not any(u.startswith("normalize") for u in t.unexpressible)


@pytest.mark.usefixtures("shipped")
def test_hopper_v5_translates_the_hopper_v4_entry() -> None:
    t = zoo.to_snnkart(zoo.zoo_settings("Hopper-v5"))
    assert t.config["ann.hidden"] == [256, 256] and t.config["ann.activation"] == "relu"
    assert t.config["ppo.init_log_std"] == -2.0
    assert t.config["ppo.num_minibatches"] == 512 // 32
    assert t.config["ppo.norm_obs"] is True and t.config["ppo.clip_obs"] == 10.0
    assert t.config["ppo.vf_coef"] == pytest.approx(2 * 0.835671)
    assert any(u.startswith("ortho_init=False") for u in t.unexpressible)


@pytest.mark.usefixtures("shipped")
def test_a_batch_larger_than_the_rollout_is_one_minibatch_of_it() -> None:
    t = zoo.to_snnkart(zoo.zoo_settings("MountainCarContinuous-v0"))
    assert (t.config["ppo.rollout_steps"], t.config["ppo.num_minibatches"]) == (8, 1)
    assert any(n.startswith("batch_size 256 > n_envs * n_steps = 8") for n in t.notes)


@pytest.mark.usefixtures("shipped")
def test_an_id_without_an_entry_is_an_error_listing_the_ids_that_have_one() -> None:
    with pytest.raises(ConfigError, match="no entry for 'Humanoid-v5'") as info:
        zoo.zoo_settings("Humanoid-v5")
    for known in [*TASKS, *V5]:
        assert known in str(info.value)
    assert "untuned" in str(info.value) and "'default' entry" in str(info.value)


def test_settings_snnkart_cannot_express_are_listed_not_dropped() -> None:
    settings = zoo.ZooSettings(
        "X-v0",
        "X-v0",
        {
            "n_timesteps": 1000.0,
            "n_steps": 100,
            "batch_size": 30,
            "frame_stack": 4,
            "target_kl": 0.02,
            "policy_kwargs": "dict(activation_fn=nn.ELU, net_arch=dict(pi=[32], vf=[64]))",
        },
        "test",
    )
    t = zoo.to_snnkart(settings)
    found = " | ".join(t.unexpressible)
    for part in ("frame_stack = 4", "target_kl 0.02", "activation_fn 'elu'", "net_arch pi=[32]"):
        assert part in found
    assert "batch_size 30 does not divide n_envs * n_steps = 100" in found
    assert t.config["ann.hidden"] == [32] and "ann.activation" not in t.config


@pytest.mark.usefixtures("shipped")
@pytest.mark.parametrize("env_id", [*TASKS[:6], *V5])
def test_the_overrides_load_with_snnkarts_config_loader_into_their_fields(env_id: str) -> None:
    t = zoo.to_snnkart(zoo.zoo_settings(env_id))
    overrides = zoo.as_overrides(t)
    assert [parse_override(text) for text in overrides] == list(t.config.items())
    cfg = load_config(sets=[*overrides, "policy=ann"])
    for key, value in t.config.items():
        assert _field(cfg, key) == value, key


def test_the_vf_coef_doubling_gives_sb3s_value_loss() -> None:
    sb3 = pytest.importorskip("stable_baselines3", reason="optional: stable-baselines3 (bench)")
    assert "value_loss = F.mse_loss(rollout_data.returns, values_pred)" in inspect.getsource(
        sb3.PPO.train
    )
    gen = torch.Generator().manual_seed(0)
    values, returns = torch.randn(50, generator=gen), torch.randn(50, generator=gen)
    zoo_vf = 0.835671
    ours = 2 * zoo_vf * value_loss(values, values, returns, 0.2, clip_vloss=False)
    assert ours.item() == pytest.approx(
        zoo_vf * torch.nn.functional.mse_loss(returns, values).item()
    )


def test_the_sb3_defaults_are_stable_baselines3s() -> None:
    sb3 = pytest.importorskip("stable_baselines3", reason="optional: stable-baselines3 (bench)")
    from gymnasium import spaces
    from stable_baselines3.common.policies import ActorCriticPolicy
    from stable_baselines3.common.vec_env import VecNormalize

    ppo = inspect.signature(sb3.PPO.__init__).parameters
    assert {k: ppo[k].default for k in zoo.SB3_PPO_DEFAULTS} == dict(zoo.SB3_PPO_DEFAULTS)
    pol = inspect.signature(ActorCriticPolicy.__init__).parameters
    assert f"nn.{pol['activation_fn'].default.__name__}" == zoo.SB3_POLICY_DEFAULTS["activation_fn"]
    for key in ("ortho_init", "log_std_init"):
        assert pol[key].default == zoo.SB3_POLICY_DEFAULTS[key]
    box = spaces.Box(-1.0, 1.0, (3,))
    policy = ActorCriticPolicy(box, box, lambda _: 3e-4)
    assert policy.net_arch == zoo.SB3_POLICY_DEFAULTS["net_arch"]
    assert policy.optimizer.defaults["eps"] == 1e-5  # the same Adam as snnkart's
    vec = inspect.signature(VecNormalize.__init__).parameters
    assert {k: vec[k].default for k in zoo.VEC_NORMALIZE_DEFAULTS} == dict(
        zoo.VEC_NORMALIZE_DEFAULTS
    )


def test_an_installed_rl_zoo3s_ppo_yml_is_read_instead(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("yaml", reason="optional: PyYAML (rl_zoo3's dependency)")
    package = tmp_path / "rl_zoo3"
    (package / "hyperparams").mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "hyperparams" / "ppo.yml").write_text(
        "default:\n  n_timesteps: !!float 1e6\n"
        "CartPole-v1:\n  n_envs: 4\n  n_timesteps: !!float 2e4\n  learning_rate: lin_0.002\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "rl_zoo3", raising=False)
    assert zoo.installed_zoo_file() == package / "hyperparams" / "ppo.yml"
    settings = zoo.zoo_settings("CartPole-v1")
    assert settings.source.startswith("rl_zoo3 ") and str(package) in settings.source
    assert dict(settings.values) == {"n_envs": 4, "n_timesteps": 2e4, "learning_rate": "lin_0.002"}
    with pytest.raises(ConfigError, match="entries: CartPole-v1\\."):  # 'default' is no task
        zoo.zoo_settings("Acrobot-v1")
