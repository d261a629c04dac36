"""What a policy needs of any gymnasium space: observations as one float32 vector, actions
as a categorical, multi-categorical or Gaussian head, and both described as JSON data.

The idea of Stable-Baselines3's ``preprocess_obs`` and ``make_proba_distribution``, in numpy:
:meth:`ObsAdapter.of` and :meth:`ActionAdapter.of` map a space to its adapter through a
``{space type: adapter}`` table, so no caller asks which space it has.

Sharp edges:

- Observations: ``Box`` (any shape, flattened), ``Discrete`` (one-hot), ``MultiBinary``
  (0/1 as floats), ``MultiDiscrete`` (one one-hot per component) and ``Dict``/``Tuple`` of
  these (nested too), in the order of :func:`gymnasium.spaces.utils.flatten`. Image
  observations and ``Text``, ``Graph``, ``Sequence``, ``OneOf`` (alone or inside a Dict or
  Tuple) are refused with an :class:`~snnkart.errors.EnvError`.
- Actions: ``Discrete``, ``MultiDiscrete`` and ``Box``; ``MultiBinary``, ``Dict``, ``Tuple``
  and the rest are refused. Box actions are clipped to the bounds (PPO without squashing).
- :func:`describe_space` writes infinite bounds as the strings ``"inf"`` and ``"-inf"``
  (JSON has no infinity; ``float("inf")`` reads them back).

Example::

    >>> import gymnasium as gym
    >>> env = gym.make("CartPole-v1")
    >>> obs = ObsAdapter.of(env.observation_space)
    >>> obs.dim, ActionAdapter.of(env.action_space).kind
    (4, 'discrete')
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypedDict

import numpy as np
from gymnasium import spaces
from typing_extensions import Required

from snnkart.errors import EnvError

OBS_SUPPORTED = "Box, Discrete, MultiBinary, MultiDiscrete and Dict/Tuple of these"
"""The observation spaces an :class:`ObsAdapter` takes, as its errors name them."""

ACTIONS_SUPPORTED = (
    "Discrete (categorical), MultiDiscrete (one categorical over the joint actions) "
    "and Box (Gaussian)"
)
"""The action spaces an :class:`ActionAdapter` takes, as its errors name them."""

IMAGE_MIN_SIDE = 8
"""Height and width (pixels) from which a (H, W, C) Box with C in {1, 3, 4} counts as an image."""


class SpaceRecord(TypedDict, total=False):
    """A space as JSON data (:func:`describe_space`): ``type`` always, the rest by type."""

    type: Required[str]
    shape: list[int]
    dtype: str
    low: list[float | str]
    high: list[float | str]
    n: int | list[int]
    start: int | list[int]
    nvec: list[int]
    spaces: dict[str, SpaceRecord] | list[SpaceRecord]
    repr: str
    kind: str  # an action adapter's (ActionAdapter.describe)


def describe_space(space: spaces.Space[Any]) -> SpaceRecord:
    """Any space as JSON data: ``type``; for a Box ``shape``, ``dtype``, ``low``/``high`` (flat
    lists in C order, ±inf as ``"inf"``/``"-inf"``); ``n`` and ``start`` for Discrete; ``nvec``
    and ``start`` for MultiDiscrete; ``n`` for MultiBinary; ``spaces`` (by key, or a list) for
    Dict and Tuple; ``repr`` for any other space."""
    if isinstance(space, spaces.Box):
        return {
            "type": "Box",
            "shape": list(space.shape),
            "dtype": str(space.dtype),
            "low": [_bound(v) for v in space.low.ravel().tolist()],
            "high": [_bound(v) for v in space.high.ravel().tolist()],
        }
    if isinstance(space, spaces.Discrete):
        return {"type": "Discrete", "n": int(space.n), "start": int(space.start)}
    if isinstance(space, spaces.MultiDiscrete):
        return {
            "type": "MultiDiscrete",
            "nvec": space.nvec.tolist(),
            "start": space.start.tolist(),
            "dtype": str(space.dtype),
        }
    if isinstance(space, spaces.MultiBinary):
        return {"type": "MultiBinary", "n": np.asarray(space.n).tolist()}
    if isinstance(space, spaces.Dict):
        return {"type": "Dict", "spaces": {k: describe_space(s) for k, s in space.spaces.items()}}
    if isinstance(space, spaces.Tuple):
        return {"type": "Tuple", "spaces": [describe_space(s) for s in space.spaces]}
    return {"type": type(space).__name__, "repr": str(space)}


def _bound(value: float) -> float | str:
    return value if math.isfinite(value) else ("inf" if value > 0 else "-inf")


def looks_like_image(space: spaces.Space[Any]) -> bool:
    """A Box of 3 dims and dtype uint8, or of shape (H, W, C) with C in {1, 3, 4} and H, W at
    least :data:`IMAGE_MIN_SIDE`."""
    if not isinstance(space, spaces.Box) or len(space.shape) != 3:
        return False
    height, width, channels = space.shape
    return space.dtype == np.uint8 or (
        channels in (1, 3, 4) and min(height, width) >= IMAGE_MIN_SIDE
    )


# --- observations ----------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class _Part:
    """How one (sub)space flattens: ``flatten(batch) -> (N, dim)`` float32."""

    dim: int
    low: np.ndarray
    high: np.ndarray
    flatten: Callable[[Any], np.ndarray]


class _Refused(Exception):
    def __init__(self, space: spaces.Space[Any], where: str) -> None:
        self.space, self.where = space, where


def _box_part(space: spaces.Box, where: str) -> _Part:
    if looks_like_image(space):
        raise _Refused(space, where)
    dim = int(np.prod(space.shape, dtype=np.int64))
    return _Part(
        dim,
        space.low.astype(np.float32).ravel(),
        space.high.astype(np.float32).ravel(),
        lambda batch: np.asarray(batch, dtype=np.float32).reshape(len(batch), dim),
    )


def _one_hot(values: Any, n: int, start: int) -> np.ndarray:
    index = np.asarray(values, dtype=np.int64).reshape(-1) - start
    if index.size and (index.min() < 0 or index.max() >= n):
        raise ValueError(f"a Discrete({n}, start={start}) observation out of range: {values}")
    out = np.zeros((index.shape[0], n), dtype=np.float32)
    out[np.arange(index.shape[0]), index] = 1.0
    return out


def _discrete_part(space: spaces.Discrete, where: str) -> _Part:
    n, start = int(space.n), int(space.start)
    return _Part(
        n,
        np.zeros(n, np.float32),
        np.ones(n, np.float32),
        lambda batch: _one_hot(batch, n, start),
    )


def _multi_binary_part(space: spaces.MultiBinary, where: str) -> _Part:
    dim = int(np.prod(space.shape, dtype=np.int64))
    return _Part(
        dim,
        np.zeros(dim, np.float32),
        np.ones(dim, np.float32),
        lambda batch: np.asarray(batch, dtype=np.float32).reshape(len(batch), dim),
    )


def _multi_discrete_part(space: spaces.MultiDiscrete, where: str) -> _Part:
    nvec, start = space.nvec.ravel().tolist(), space.start.ravel().tolist()

    def flatten(batch: Any) -> np.ndarray:
        values = np.asarray(batch, dtype=np.int64).reshape(len(batch), len(nvec))
        return np.concatenate(
            [
                _one_hot(values[:, i], n, s)
                for i, (n, s) in enumerate(zip(nvec, start, strict=True))
            ],
            axis=1,
        )

    dim = int(sum(nvec))
    return _Part(dim, np.zeros(dim, np.float32), np.ones(dim, np.float32), flatten)


def _joined(parts: list[tuple[Any, _Part]]) -> _Part:
    def flatten(batch: Any) -> np.ndarray:
        return np.concatenate([part.flatten(batch[key]) for key, part in parts], axis=1)

    return _Part(
        sum(part.dim for _, part in parts),
        np.concatenate([part.low for _, part in parts]).astype(np.float32),
        np.concatenate([part.high for _, part in parts]).astype(np.float32),
        flatten,
    )


def _dict_part(space: spaces.Dict, where: str) -> _Part:
    return _joined([(k, _part(s, f"{where}[{k!r}]")) for k, s in space.spaces.items()])


def _tuple_part(space: spaces.Tuple, where: str) -> _Part:
    return _joined([(i, _part(s, f"{where}[{i}]")) for i, s in enumerate(space.spaces)])


_OBS_PARTS: dict[type, Callable[[Any, str], _Part]] = {
    spaces.Box: _box_part,
    spaces.Discrete: _discrete_part,
    spaces.MultiBinary: _multi_binary_part,
    spaces.MultiDiscrete: _multi_discrete_part,
    spaces.Dict: _dict_part,
    spaces.Tuple: _tuple_part,
}
"""Observation space type -> how it flattens."""


def _part(space: spaces.Space[Any], where: str) -> _Part:
    for space_type, make_part in _OBS_PARTS.items():
        if isinstance(space, space_type):
            return make_part(space, where)
    raise _Refused(space, where)


def _batch_of_one(space: spaces.Space[Any], obs: Any) -> Any:
    if isinstance(space, spaces.Dict):
        return {k: _batch_of_one(s, obs[k]) for k, s in space.spaces.items()}
    if isinstance(space, spaces.Tuple):
        return tuple(_batch_of_one(s, o) for s, o in zip(space.spaces, obs, strict=True))
    return np.asarray(obs)[None]


@dataclass(frozen=True, eq=False)
class ObsAdapter:
    """Any supported observation space as one float32 vector of ``dim`` components, with
    bounds ``low``/``high`` per component (±inf where the space has none; 0 and 1 for one-hot
    parts). Same values and order as :func:`gymnasium.spaces.utils.flatten`."""

    space: spaces.Space[Any]
    dim: int
    low: np.ndarray = field(repr=False)
    high: np.ndarray = field(repr=False)
    _part: _Part = field(repr=False)

    @classmethod
    def of(cls, space: spaces.Space[Any]) -> ObsAdapter:
        """The adapter of ``space``; :class:`EnvError` naming the space (and its part) if it
        is an image or a space snnkart's policies do not take."""
        try:
            part = _part(space, "")
        except _Refused as refused:
            raise EnvError(_obs_refusal(space, refused)) from None
        return cls(space, part.dim, part.low, part.high, part)

    def flatten(self, batch: Any) -> np.ndarray:
        """A batch of observations as a vector env returns them (arrays with a leading env
        axis; dicts or tuples of such for Dict and Tuple spaces) -> ``(N, dim)`` float32."""
        return self._part.flatten(batch)

    def flatten_one(self, obs: Any) -> np.ndarray:
        """One observation (as a single env returns it) -> ``(dim,)`` float32."""
        return self._part.flatten(_batch_of_one(self.space, obs))[0]

    def describe(self) -> SpaceRecord:
        """The space as JSON data (:func:`describe_space`)."""
        return describe_space(self.space)


def _obs_refusal(space: spaces.Space[Any], refused: _Refused) -> str:
    whole = f"observation space {space}"
    if refused.where:
        whole += f": its part {refused.where} {refused.space}"
    if looks_like_image(refused.space):
        return (
            f"{whole} looks like an image; snnkart's policies take vector observations: "
            f"{OBS_SUPPORTED} (flatten or encode the image in a wrapper of your own)"
        )
    return (
        f"{whole} is not supported; snnkart's policies take vector observations: "
        f"{OBS_SUPPORTED} (turn it into one in a wrapper of your own)"
    )


# --- actions ---------------------------------------------------------------------------


class ActionAdapter:
    """What a policy head needs of an action space: ``kind`` (``"discrete"``,
    ``"multi_discrete"``, ``"box"``), ``outputs`` (the head's size: logits, or Gaussian means)
    and ``to_env(actions)``, the policy's batch as the (vector) env takes it."""

    kind: ClassVar[str]
    space: spaces.Space[Any]
    outputs: int

    @staticmethod
    def of(space: spaces.Space[Any]) -> ActionAdapter:
        """The adapter of ``space``; :class:`EnvError` naming it if it is not supported."""
        for space_type, adapter in _ACTIONS.items():
            if isinstance(space, space_type):
                return adapter(space)
        raise EnvError(
            f"action space {space} is not supported; snnkart's policies take "
            f"{ACTIONS_SUPPORTED} actions (map yours to one in a wrapper of your own)"
        )

    def to_env(self, actions: Any) -> np.ndarray:
        raise NotImplementedError

    def describe(self) -> SpaceRecord:
        """The space as JSON data (:func:`describe_space`) and the adapter's ``kind``."""
        return {**describe_space(self.space), "kind": self.kind}


class DiscreteActions(ActionAdapter):
    """Categorical over ``n`` actions; the policy picks an index in ``[0, n)``, the env gets
    ``start + index``."""

    kind = "discrete"

    def __init__(self, space: spaces.Discrete) -> None:
        self.space, self.n, self.start = space, int(space.n), int(space.start)
        self.outputs = self.n

    def to_env(self, actions: Any) -> np.ndarray:
        """``(N,)`` (or ``(N, 1)``) indices -> ``(N,)`` int64 env actions."""
        return np.asarray(actions, dtype=np.int64).reshape(-1) + self.start


class MultiDiscreteActions(ActionAdapter):
    """One categorical per component of ``nvec`` (flattened); the policy picks indices, the
    env gets ``start + index`` in the space's shape."""

    kind = "multi_discrete"

    def __init__(self, space: spaces.MultiDiscrete) -> None:
        self.space, self.shape, self.dtype = space, space.shape, space.dtype
        self.nvec = space.nvec.ravel().astype(np.int64)
        self.start = space.start.ravel().astype(np.int64)
        self.outputs = int(self.nvec.sum())

    def to_env(self, actions: Any) -> np.ndarray:
        """``(N, len(nvec))`` indices -> ``(N, *space.shape)`` env actions."""
        index = np.asarray(actions, dtype=np.int64).reshape(-1, self.nvec.size)
        return (index + self.start).reshape(-1, *self.shape).astype(self.dtype)


class BoxActions(ActionAdapter):
    """Gaussian over ``dim`` components; the env gets the sample clipped to ``low``/``high``
    (as Stable-Baselines3 does for PPO without squashing), in the space's shape and dtype."""

    kind = "box"

    def __init__(self, space: spaces.Box) -> None:
        self.space, self.shape, self.dtype = space, space.shape, space.dtype
        self.dim = int(np.prod(space.shape, dtype=np.int64))
        self.low = space.low.ravel().astype(np.float64)
        self.high = space.high.ravel().astype(np.float64)
        self.outputs = self.dim

    def to_env(self, actions: Any) -> np.ndarray:
        """``(N, dim)`` samples -> ``(N, *space.shape)`` clipped to the bounds."""
        flat = np.asarray(actions, dtype=np.float64).reshape(-1, self.dim)
        clipped = np.clip(flat, self.low, self.high)
        return clipped.reshape(-1, *self.shape).astype(self.dtype)


_ACTIONS: dict[type, Callable[[Any], ActionAdapter]] = {
    spaces.Discrete: DiscreteActions,
    spaces.MultiDiscrete: MultiDiscreteActions,
    spaces.Box: BoxActions,
}
"""Action space type -> its adapter."""


def space_words(description: SpaceRecord) -> str:
    """A :func:`describe_space` description in a few words: ``Box(4,) float32``,
    ``Discrete(2)``, ``Dict(position: Box(2,) float32, ...)``."""
    kind = description["type"]
    if kind == "Box":
        return f"Box{tuple(description['shape'])} {description['dtype']}"
    if kind == "Discrete":
        start = description["start"]
        return f"Discrete({description['n']}{f', start={start}' if start else ''})"
    if kind in ("MultiDiscrete", "MultiBinary"):
        return f"{kind}({description.get('nvec', description.get('n'))})"
    inner = description.get("spaces")
    if isinstance(inner, dict):
        parts = ", ".join(f"{k}: {space_words(s)}" for k, s in inner.items())
        return f"Dict({parts})"
    if isinstance(inner, list):
        return f"Tuple({', '.join(space_words(s) for s in inner)})"
    return str(description.get("repr", kind))
