"""Any gymnasium env by name (snnkart.envs.resolve): kart names, registered ids, ``module:EnvId``
and entry points resolve and make; unknown ids, failed imports and missing Box2D/MuJoCo get
one-line errors naming the fix; ``--env-kwargs`` parse; the spec record and its comparison."""

from __future__ import annotations

import importlib.metadata
import json
import sys
import types

import gymnasium as gym
import my_envs
import numpy as np
import pytest
from gymnasium.envs.registration import EnvSpec
from gymnasium.error import DependencyNotInstalled

from snnkart.envs import ENV_IDS
from snnkart.envs.resolve import EnvRef, parse_env_kwargs, resolve_env, spec_problems
from snnkart.errors import EnvError


@pytest.mark.parametrize(
    ("name", "short"),
    [("steer", "steer"), ("steer_env", "steer"), ("snnkart/Grid-v0", "grid"), ("latenv", "grid")],
)
def test_kart_names_still_resolve(name: str, short: str) -> None:
    ref = resolve_env(name)
    assert ref == EnvRef(name, ENV_IDS[short], ref.entry_point, kart=True)
    assert ref.entry_point == f"snnkart.envs.{short}:{short.capitalize()}Env"


@pytest.mark.parametrize(
    ("env_id", "action_space"),
    [("CartPole-v1", gym.spaces.Discrete(2)), ("Pendulum-v1", gym.spaces.Box(-2.0, 2.0, (1,)))],
)
def test_registered_gymnasium_ids_resolve_and_make(env_id: str, action_space: object) -> None:
    ref = resolve_env(env_id)
    assert (ref.id, ref.kart) == (env_id, False)
    assert ref.entry_point.startswith("gymnasium.envs.classic_control.")
    env = ref.make()
    assert env.action_space == action_space
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    env.step(env.action_space.sample())
    env.close()


def _episode(env: gym.Env, seed: int, action: np.ndarray) -> tuple[list[float], int, bool]:
    env.reset(seed=seed)
    rewards, terminated, truncated = [], False, False
    while not (terminated or truncated):
        _, reward, terminated, truncated, _ = env.step(action)
        rewards.append(float(reward))
    return rewards, len(rewards), bool(truncated)


def test_module_env_id_imports_the_module_that_registers_it(monkeypatch) -> None:
    monkeypatch.delitem(sys.modules, "my_envs")
    monkeypatch.delitem(gym.registry, "MyDictEnv-v0")
    ref = resolve_env("my_envs:MyDictEnv-v0")
    assert "MyDictEnv-v0" in gym.registry
    assert ref == EnvRef("my_envs:MyDictEnv-v0", "MyDictEnv-v0", "my_envs:MyDictEnv")
    env = ref.make()
    assert "TimeLimit" in ref.spec_record(env)["wrappers"]
    still = np.zeros(2, np.float32)
    rewards, steps, truncated = _episode(env, 3, still)
    assert (steps, truncated) == (20, True)
    assert _episode(env, 3, still)[0] == rewards  # deterministic given the seed
    assert _episode(env, 4, still)[0] != rewards
    assert (
        _episode(env, 3, np.ones(2, np.float32))[0] != rewards
    )  # the reward depends on the action


def test_an_entry_point_is_made_directly() -> None:
    ref = resolve_env("my_envs:MyDictEnv")
    assert ref == EnvRef("my_envs:MyDictEnv", None, "my_envs:MyDictEnv")
    env = ref.make()
    assert isinstance(env.unwrapped, my_envs.MyDictEnv)
    assert "TimeLimit" not in ref.spec_record(env)["wrappers"]
    assert _episode(env, 0, np.zeros(2, np.float32))[1:] == (20, True)  # the env's own limit
    limited = ref.make({"max_episode_steps": 5, "step_size": 0.0})
    assert ref.spec_record(limited)["wrappers"][0] == "TimeLimit"
    assert _episode(limited, 0, np.ones(2, np.float32))[1:] == (5, True)


def test_an_unknown_id_names_the_close_registered_ones() -> None:
    with pytest.raises(
        EnvError, match=r"unknown env 'CartPol-v1' \(close registered ids: CartPole-v1"
    ):
        resolve_env("CartPol-v1")
    with pytest.raises(EnvError, match=r"unknown env 'moon'; give a snnkart env \(grid, gazebo"):
        resolve_env("moon")
    with pytest.raises(
        EnvError, match=r"registers no env 'MyDictEnv-v1'.*close ids and classes: MyDictEnv-v0"
    ):
        resolve_env("my_envs:MyDictEnv-v1")
    with pytest.raises(EnvError, match=r"my_envs.np is a module, not a gymnasium.Env subclass"):
        resolve_env("my_envs:np")


def test_a_module_that_fails_to_import_is_named_with_its_error(tmp_path, monkeypatch) -> None:
    with pytest.raises(
        EnvError,
        match=r"cannot import module 'no_such_envs' \(ModuleNotFoundError: No module named 'no_such_envs'\)",
    ):
        resolve_env("no_such_envs:Env-v0")
    (tmp_path / "broken_envs.py").write_text("import not_installed_dependency\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(
        EnvError,
        match=r"env 'broken_envs:Env-v0': cannot import module 'broken_envs' "
        r"\(ModuleNotFoundError: No module named 'not_installed_dependency'\)",
    ):
        resolve_env("broken_envs:Env-v0")


@pytest.mark.parametrize(
    ("env_id", "module", "extra"),
    [
        ("LunarLander-v3", "Box2D", "box2d"),
        ("BipedalWalker-v3", "Box2D", "box2d"),
        ("CarRacing-v3", "Box2D", "box2d"),
        ("Hopper-v5", "mujoco", "mujoco"),
        ("HalfCheetah-v5", "mujoco", "mujoco"),
        ("Humanoid-v5", "mujoco", "mujoco"),
    ],
)
def test_a_missing_box2d_or_mujoco_names_the_extra(monkeypatch, env_id, module, extra) -> None:
    monkeypatch.setitem(sys.modules, module, None)  # the import fails, installed or not
    with pytest.raises(EnvError) as caught:
        resolve_env(env_id)
    assert str(caught.value) == (
        f"env {env_id!r} needs {module}, which is not installed: pip install 'snnkart[{extra}]'"
    )


def _needs_mujoco(**kwargs: object) -> gym.Env:
    raise DependencyNotInstalled('MuJoCo is not installed, run `pip install "gymnasium[mujoco]"`')


def _needs_other(**kwargs: object) -> gym.Env:
    raise DependencyNotInstalled("frobnicator is not installed")


def test_a_missing_dependency_when_made_names_the_extra(monkeypatch) -> None:
    monkeypatch.setitem(gym.registry, "Needs-v0", EnvSpec("Needs-v0", entry_point=_needs_mujoco))
    with pytest.raises(
        EnvError, match=r"needs mujoco, which is not installed: pip install 'snnkart\[mujoco\]'$"
    ):
        resolve_env("Needs-v0").make()
    monkeypatch.setitem(gym.registry, "Needs-v0", EnvSpec("Needs-v0", entry_point=_needs_other))
    with pytest.raises(EnvError, match=r"needs a package that is not installed: frobnicator"):
        resolve_env("Needs-v0").make()


def test_an_argument_the_env_does_not_take() -> None:
    with pytest.raises(
        EnvError, match=r"'CartPole-v1' takes no argument 'gravity'.*sutton_barto_reward"
    ):
        resolve_env("CartPole-v1").make({"gravity": 1.0})


def test_env_kwargs_parse_as_literals_else_strings() -> None:
    items = [
        "g=9.8",
        "n=3",
        "on=true",
        "xs=[1, 2]",
        'q="a b"',
        "s=hello",
        "none=null",
        "day=2024-01-01",
        "e=",
    ]
    assert parse_env_kwargs(items) == {
        "g": 9.8,
        "n": 3,
        "on": True,
        "xs": [1, 2],
        "q": "a b",
        "s": "hello",
        "none": None,
        "day": "2024-01-01",  # a TOML date is not JSON data: kept as written
        "e": "",
    }
    assert parse_env_kwargs([]) == {}


@pytest.mark.parametrize("item", ["gravity", "=3", "1x=2", "a b=1"])
def test_a_malformed_env_kwarg(item: str) -> None:
    with pytest.raises(EnvError, match=rf"env kwarg {item!r} is not key=value"):
        parse_env_kwargs([item])


def test_an_env_kwarg_given_twice() -> None:
    with pytest.raises(EnvError, match=r"env kwarg 'a' is given twice"):
        parse_env_kwargs(["a=1", "a=2"])


def test_the_spec_record_of_cartpole() -> None:
    ref = resolve_env("CartPole-v1")
    record = ref.spec_record(
        ref.make({"sutton_barto_reward": False}), {"sutton_barto_reward": False}
    )
    assert json.loads(json.dumps(record, allow_nan=False)) == record
    assert record["id"] == "CartPole-v1"
    assert record["entry_point"] == "gymnasium.envs.classic_control.cartpole:CartPoleEnv"
    assert record["kwargs"] == {"sutton_barto_reward": False}
    assert record["wrappers"] == ["TimeLimit", "OrderEnforcing", "PassiveEnvChecker"]
    assert (record["reward_threshold"], record["max_episode_steps"]) == (475.0, 500)
    assert record["render_fps"] == 50
    assert record["observation_space"]["shape"] == [4]
    assert record["observation_space"]["high"][1] == "inf"
    assert record["action_space"] == {"type": "Discrete", "n": 2, "start": 0}
    assert (record["package"], record["package_version"]) == ("gymnasium", gym.__version__)
    assert record["gymnasium_version"] == gym.__version__


def test_the_spec_record_of_an_env_outside_any_distribution() -> None:
    ref = resolve_env("my_envs:MyDictEnv-v0")
    record = ref.spec_record(ref.make())
    assert (record["package"], record["package_version"]) == (None, None)
    assert record["max_episode_steps"] == 20
    assert record["observation_space"]["type"] == "Dict"


@pytest.mark.skipif(
    "tests" not in importlib.metadata.packages_distributions(),
    reason="no installed distribution ships a top-level 'tests' package here (lava-nc does)",
)
def test_a_distribution_shipping_the_same_top_level_name_elsewhere_is_not_taken(
    tmp_path, monkeypatch
) -> None:
    module = types.ModuleType("tests.fake_envs")
    module.__file__ = str(tmp_path / "tests" / "fake_envs.py")
    monkeypatch.setitem(sys.modules, "tests.fake_envs", module)
    fake = type("FakeEnv", (my_envs.MyDictEnv,), {"__module__": "tests.fake_envs"})
    record = EnvRef("tests.fake_envs:FakeEnv", None, "tests.fake_envs:FakeEnv").spec_record(fake())
    assert (record["package"], record["package_version"]) == (None, None)


def _cartpole_record() -> dict:
    ref = resolve_env("CartPole-v1")
    return dict(ref.spec_record(ref.make()))


def test_spec_problems_refuse_other_spaces_and_ids_and_warn_of_versions() -> None:
    saved = _cartpole_record()
    assert spec_problems(saved, _cartpole_record()) == ([], [])  # type: ignore[arg-type]
    now = {**saved, "gymnasium_version": "9.9.9"}
    assert spec_problems(saved, now) == ([], [f"gymnasium version {gym.__version__!r} vs '9.9.9'"])  # type: ignore[arg-type]
    wider = {**saved["observation_space"], "shape": [6], "low": [0.0] * 6, "high": [1.0] * 6}
    refusals, _ = spec_problems(saved, {**saved, "observation_space": wider})  # type: ignore[arg-type]
    assert refusals == ["observation space Box(4,) float32 vs Box(6,) float32"]
    bounds = {**saved["observation_space"], "high": [2.4, *saved["observation_space"]["high"][1:]]}
    refusals, _ = spec_problems(saved, {**saved, "observation_space": bounds})  # type: ignore[arg-type]
    assert refusals == ["observation space Box(4,) float32: high[0] 4.800000190734863 vs 2.4"]
    three = {"type": "Discrete", "n": 3, "start": 0}
    other = {**saved, "id": "CartPole-v0", "action_space": three, "package_version": "0.1"}
    assert spec_problems(saved, other) == (  # type: ignore[arg-type]
        ["env id 'CartPole-v1' vs 'CartPole-v0'", "action space Discrete(2) vs Discrete(3)"],
        [],  # gymnasium's own envs: the gymnasium version says it
    )
    mine = {**saved, "package": "my_envs", "package_version": "1.0"}
    assert spec_problems(mine, {**mine, "package_version": "1.1"}) == (  # type: ignore[arg-type]
        [],
        ["package version '1.0' vs '1.1'"],
    )
