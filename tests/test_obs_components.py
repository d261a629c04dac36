"""Selectable observation components (env_config.observation): the default is today's
observation, other layouts have true bounds, and they travel with a policy from training
through export to deployment, where another layout is refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from tiny_runs import train_tiny

from snnkart.envs.components import COMPONENTS, default_components
from snnkart.envs.spec import env_spec, layout_problem, make_env
from snnkart.errors import DeployError
from snnkart.eval.closed_loop import DeployRequest, run_deploy
from snnkart.export.nir_export import export_nir
from snnkart.rl.trained import load_run

DEFAULTS = {
    "steer": ("lidar", "velocity", "steering", "heading", "checkpoint"),
    "gazebo": ("lidar", "velocity", "angular_velocity", "heading", "checkpoint"),
    "grid": ("lidar", "velocity", "checkpoint"),
}
CUSTOM = ["position", "heading", "previous_action", "angular_velocity", "lidar", "checkpoint"]


@pytest.mark.parametrize("name", sorted(DEFAULTS))
def test_the_default_layout_spelled_out_is_todays_observation(name: str) -> None:
    own = make_env(name, "small_S").unwrapped
    spelled = make_env(name, "small_S", config={"observation": list(DEFAULTS[name])}).unwrapped
    assert default_components(own.observation_layout) == DEFAULTS[name]
    assert "observation" not in env_spec(own)["env_config"]  # old files: the same spec hash
    assert spelled.observation_layout == own.observation_layout
    a, _ = own.reset(seed=5)
    b, _ = spelled.reset(seed=5)
    rng = np.random.default_rng(0)
    for _ in range(120):
        action = int(rng.integers(own.action_space.n))
        np.testing.assert_array_equal(a, b)
        a, _, term, trunc, _ = own.step(action)
        b, *_ = spelled.step(action)
        if term or trunc:
            a, _ = own.reset()
            b, _ = spelled.reset()


@pytest.mark.parametrize(("name", "mode"), [("steer", "discrete"), ("steer", "continuous"),
                                            ("gazebo", "discrete"), ("gazebo", "continuous")])  # fmt: skip
def test_a_chosen_layout_has_its_components_in_order_within_true_bounds(
    name: str, mode: str
) -> None:
    env = make_env(name, "small_S", mode, config={"observation": CUSTOM}).unwrapped
    names = [f.name for f in env.observation_layout]
    assert names[:3] == ["position", "heading_cos", "heading_sin"]
    assert names[3:5] == ["previous_action", "angular_velocity"]
    n_actions = env.observation_layout[3].size
    env.action_space.seed(1)
    obs, _ = env.reset(seed=1)
    seen = [obs]
    for _ in range(200):
        action = env.action_space.sample()
        obs, _, term, trunc, _ = env.step(action)
        seen.append(obs)
        action_part = obs[4 : 4 + n_actions]
        expected = np.eye(env.action_space.n)[action] if mode == "discrete" else action
        np.testing.assert_allclose(action_part, expected, atol=1e-6)  # the action just taken
        x, y = env.position
        np.testing.assert_allclose(obs[:2], [x / 1000, y / 1000], atol=1e-6)
        if term or trunc:
            obs, _ = env.reset()
    values = np.array(seen)
    assert all(env.observation_space.contains(v) for v in values)
    turn = 4 + n_actions
    assert np.ptp(values[:, turn]) > 0.01  # the angular velocity moves (not a constant)


def test_an_unknown_component_is_refused_naming_the_choices() -> None:
    with pytest.raises(ValueError, match=r"unknown observation component.*choose from lidar"):
        make_env("steer", "small_S", config={"observation": ["lidar", "gps"]})
    with pytest.raises(ValueError, match="list each once"):
        make_env("steer", "small_S", config={"observation": ["lidar", "lidar"]})
    assert set(DEFAULTS["steer"]) | set(CUSTOM) == set(COMPONENTS)
    with pytest.raises(ValueError, match="env 'grid' has no observation component 'angular_"):
        make_env("grid", "small_S", config={"observation": ["lidar", "angular_velocity"]})


def test_a_layout_round_trips_through_train_export_and_deploy(tmp_path: Path) -> None:
    sets = ["env_config.observation=['lidar','position','previous_action','checkpoint']"]
    run = load_run(train_tiny(tmp_path / "run", "steer", "snn", total_steps=256, extra_sets=sets))
    spec = run.meta["env_spec"]
    assert spec["env_config"]["observation"] == ["lidar", "position", "previous_action",
                                                 "checkpoint"]  # fmt: skip
    assert [f[0] for f in spec["observation_layout"]] == [
        "lidar", "position", "previous_action", "checkpoint_cos", "checkpoint_sin",
        "checkpoint_distance",
    ]  # fmt: skip
    nir_path, manifest = export_nir(run, tmp_path / "exp" / "policy.nir")
    assert '"observation": [' in manifest.read_text()
    record = run_deploy(DeployRequest(nir_path, "nir-ref", "float32", episodes=1))
    assert record.episodes and len(record.episodes) == 1
    # the same policy on an env with the default layout: refused, the difference named
    with pytest.raises(DeployError, match=r"observes \[lidar, position, previous_action"):
        run_deploy(DeployRequest(nir_path, "nir-ref", "float32", episodes=1, env="gazebo"))
    default_env = make_env("steer", "small_S")
    problem = layout_problem(spec, default_env)
    assert problem is not None and "env_config.observation = ['lidar', 'position'" in problem
