"""What a policy needs of any space (snnkart.envs.spaces): observations flatten as gymnasium
flattens them, one env or a vector env's batch; images and other spaces are refused in words;
actions map to categorical, multi-categorical or clipped Gaussian heads."""

from __future__ import annotations

import json

import gymnasium as gym
import my_envs
import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.spaces.utils import flatdim, flatten
from gymnasium.vector.utils import batch_space, iterate

from snnkart.envs.spaces import (
    ActionAdapter,
    BoxActions,
    DiscreteActions,
    MultiDiscreteActions,
    ObsAdapter,
    describe_space,
    space_words,
)
from snnkart.errors import EnvError

BOX = spaces.Box(-1.0, 1.0, (2,), np.float32)
VECTOR_SPACES = {
    "box 1-d": spaces.Box(
        np.array([-1.0, -np.inf], np.float32), np.array([2.0, np.inf], np.float32)
    ),
    "box 2-d": spaces.Box(-3.0, 3.0, (2, 3), np.float64),
    "discrete": spaces.Discrete(3, start=-1),
    "multi binary": spaces.MultiBinary(4),
    "multi discrete": spaces.MultiDiscrete([2, 3], start=[1, 0]),
    "dict": spaces.Dict({"b": BOX, "a": spaces.Discrete(4)}),
    "tuple": spaces.Tuple((spaces.Discrete(2), BOX)),
    "nested": spaces.Dict({"x": spaces.Tuple((BOX, spaces.Discrete(3))), "y": BOX}),
}


@pytest.mark.parametrize("name", VECTOR_SPACES)
def test_observations_flatten_as_gymnasium_flattens_them(name: str) -> None:
    space = VECTOR_SPACES[name]
    space.seed(0)
    adapter = ObsAdapter.of(space)
    assert adapter.dim == flatdim(space)
    assert adapter.low.shape == adapter.high.shape == (adapter.dim,)
    batched = batch_space(space, 5)
    batched.seed(1)
    batch = batched.sample()
    flat = adapter.flatten(batch)
    assert flat.dtype == np.float32 and flat.shape == (5, adapter.dim)
    for row, obs in zip(flat, iterate(batched, batch), strict=True):
        expected = flatten(space, obs).astype(np.float32)
        np.testing.assert_array_equal(row, expected)
        np.testing.assert_array_equal(adapter.flatten_one(obs), expected)
        assert np.all((adapter.low <= row) & (row <= adapter.high))


def test_bounds_per_flat_component() -> None:
    adapter = ObsAdapter.of(spaces.Dict({"b": BOX, "a": spaces.Discrete(2)}))  # keys sorted: a, b
    np.testing.assert_array_equal(adapter.low, [0, 0, -1, -1])
    np.testing.assert_array_equal(adapter.high, [1, 1, 1, 1])
    np.testing.assert_array_equal(
        adapter.flatten_one({"a": 1, "b": [0.5, -0.5]}), [0, 1, 0.5, -0.5]
    )
    unbounded = ObsAdapter.of(VECTOR_SPACES["box 1-d"])
    np.testing.assert_array_equal(unbounded.high, [2.0, np.inf])
    np.testing.assert_array_equal(
        ObsAdapter.of(spaces.Discrete(3, start=-1)).flatten_one(-1), [1, 0, 0]
    )


def test_a_vector_envs_dict_batch_flattens_per_env() -> None:
    envs = gym.vector.SyncVectorEnv([lambda: gym.make(my_envs.ENV_ID) for _ in range(3)])
    adapter = ObsAdapter.of(envs.single_observation_space)
    batch, _ = envs.reset(seed=7)
    batch, *_ = envs.step(envs.action_space.sample())
    flat = adapter.flatten(batch)
    assert flat.shape == (3, 4)
    for i in range(3):
        one = {key: values[i] for key, values in batch.items()}
        np.testing.assert_array_equal(flat[i], flatten(envs.single_observation_space, one))
    assert len({tuple(row) for row in flat}) == 3  # three envs, three observations
    envs.close()


def test_a_description_is_json_data_with_infinities_as_strings() -> None:
    description = ObsAdapter.of(VECTOR_SPACES["nested"]).describe()
    assert json.loads(json.dumps(description, allow_nan=False)) == description
    assert describe_space(VECTOR_SPACES["box 1-d"]) == {
        "type": "Box",
        "shape": [2],
        "dtype": "float32",
        "low": [-1.0, "-inf"],
        "high": [2.0, "inf"],
    }
    assert describe_space(VECTOR_SPACES["multi discrete"])["nvec"] == [2, 3]
    assert description["spaces"]["x"]["spaces"][1] == {"type": "Discrete", "n": 3, "start": 0}
    assert space_words(description) == (
        "Dict(x: Tuple(Box(2,) float32, Discrete(3)), y: Box(2,) float32)"
    )


IMAGES = {
    "rgb uint8": spaces.Box(0, 255, (96, 96, 3), np.uint8),
    "channels first uint8": spaces.Box(0, 255, (3, 64, 64), np.uint8),
    "gray float": spaces.Box(0.0, 1.0, (84, 84, 1), np.float32),
}


@pytest.mark.parametrize("name", IMAGES)
def test_an_image_is_refused_in_words(name: str) -> None:
    space = IMAGES[name]
    with pytest.raises(EnvError) as caught:
        ObsAdapter.of(space)
    assert str(caught.value) == (
        f"observation space {space} looks like an image; snnkart's policies take vector "
        "observations: Box, Discrete, MultiBinary, MultiDiscrete and Dict/Tuple of these "
        "(flatten or encode the image in a wrapper of your own)"
    )


def test_an_image_inside_a_dict_is_named_by_its_key() -> None:
    with pytest.raises(
        EnvError,
        match=r": its part \['pixels'\] Box\(0, 255, \(96, 96, 3\), uint8\) looks like an image",
    ):
        ObsAdapter.of(spaces.Dict({"pixels": IMAGES["rgb uint8"], "speed": BOX}))


def test_a_small_3d_box_is_not_an_image() -> None:
    assert ObsAdapter.of(spaces.Box(-1.0, 1.0, (4, 3, 2), np.float32)).dim == 24
    assert ObsAdapter.of(spaces.Box(-1.0, 1.0, (4, 4, 3), np.float32)).dim == 48  # sides < 8


UNSUPPORTED_OBS = {
    "text": spaces.Text(8),
    "graph": spaces.Graph(node_space=BOX, edge_space=None),
    "sequence": spaces.Sequence(BOX),
    "dict of text": spaces.Dict({"name": spaces.Text(8), "pos": BOX}),
}


@pytest.mark.parametrize("name", UNSUPPORTED_OBS)
def test_other_observation_spaces_are_refused_in_words(name: str) -> None:
    space = UNSUPPORTED_OBS[name]
    with pytest.raises(EnvError) as caught:
        ObsAdapter.of(space)
    message = str(caught.value)
    assert message.startswith(f"observation space {space}")
    assert message.endswith(
        " is not supported; snnkart's policies take vector observations: Box, Discrete, "
        "MultiBinary, MultiDiscrete and Dict/Tuple of these (turn it into one in a wrapper of your own)"
    )
    if name == "dict of text":
        assert ": its part ['name'] Text(" in message


def test_discrete_actions_are_categorical_and_shifted_by_start() -> None:
    adapter = ActionAdapter.of(spaces.Discrete(3, start=-1))
    assert isinstance(adapter, DiscreteActions)
    assert (adapter.kind, adapter.n, adapter.outputs) == ("discrete", 3, 3)
    np.testing.assert_array_equal(adapter.to_env(np.array([0, 2, 1])), [-1, 1, 0])
    assert adapter.describe() == {"type": "Discrete", "n": 3, "start": -1, "kind": "discrete"}


def test_multi_discrete_actions_are_one_categorical_per_component() -> None:
    space = spaces.MultiDiscrete([2, 5], start=[0, 10])
    adapter = ActionAdapter.of(space)
    assert isinstance(adapter, MultiDiscreteActions)
    assert adapter.kind == "multi_discrete" and adapter.outputs == 7
    np.testing.assert_array_equal(adapter.nvec, [2, 5])
    env_actions = adapter.to_env(np.array([[1, 4], [0, 0]]))
    np.testing.assert_array_equal(env_actions, [[1, 14], [0, 10]])
    assert all(space.contains(a) for a in env_actions)


def test_box_actions_are_gaussian_clipped_to_the_bounds() -> None:
    space = spaces.Box(np.array([-2.0, 0.0], np.float32), np.array([2.0, 1.0], np.float32))
    adapter = ActionAdapter.of(space)
    assert isinstance(adapter, BoxActions)
    assert (adapter.kind, adapter.dim, adapter.outputs) == ("box", 2, 2)
    np.testing.assert_array_equal(adapter.low, [-2.0, 0.0])
    env_actions = adapter.to_env(np.array([[3.0, -0.5], [-0.5, 0.25], [-9.0, 7.0]]))
    np.testing.assert_array_equal(env_actions, [[2.0, 0.0], [-0.5, 0.25], [-2.0, 1.0]])
    assert env_actions.dtype == np.float32
    square = ActionAdapter.of(spaces.Box(-1.0, 1.0, (2, 2), np.float32))
    assert square.to_env(np.full((3, 4), 5.0)).shape == (3, 2, 2)


@pytest.mark.parametrize(
    "space",
    [spaces.MultiBinary(3), spaces.Dict({"a": BOX}), spaces.Tuple((BOX,)), spaces.Text(4)],
    ids=["multi binary", "dict", "tuple", "text"],
)
def test_other_action_spaces_are_refused_in_words(space: spaces.Space) -> None:
    with pytest.raises(EnvError) as caught:
        ActionAdapter.of(space)
    assert str(caught.value) == (
        f"action space {space} is not supported; snnkart's policies take Discrete (categorical), "
        "MultiDiscrete (one categorical over the joint actions) and Box (Gaussian) actions "
        "(map yours to one in a wrapper of your own)"
    )
