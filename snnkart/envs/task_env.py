"""Any env as snnkart's policies take it, and the spec a trained policy records of it.

A kart env (``grid``, ``gazebo``, ``steer``) is made as ever (:func:`snnkart.envs.spec.make_env`,
on a track) and recorded by :func:`snnkart.envs.spec.env_spec` (revision, track and its hash,
layout, env config). Any other gymnasium env (:func:`snnkart.envs.resolve.resolve_env`) is made
by gymnasium and given the wrappers a policy needs, each recorded by name in its spec:

- observations: a flat float32 ``Box`` passes as it is; any other supported space (a ``Box``
  of another shape or dtype, ``Dict``/``Tuple`` of boxes, ``Discrete``) is flattened with
  gymnasium's ``FlattenObservation`` (``Discrete`` one-hot) and cast to float32;
- actions: ``Discrete`` (from 0) passes; a ``Box`` with finite bounds other than [-1, 1] is
  rescaled from [-1, 1] by gymnasium's ``RescaleAction``, so the policy's actions are clipped
  to [-1, 1] (the deployment contract's) and reach the env clipped to its own bounds, as
  Stable-Baselines3 clips them. ``MultiDiscrete`` (up to :data:`MAX_JOINT_ACTIONS` joint
  actions) and ``Discrete`` with a non-zero start become one ``Discrete`` from 0 by
  :class:`JointDiscrete`: the policy's categorical head is over the joint actions.

Image observations and unsupported spaces are refused by :mod:`snnkart.envs.spaces`.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.wrappers import DtypeObservation, FlattenObservation, RescaleAction

from snnkart.envs.resolve import EnvRef, GymEnvSpec, resolve_env, spec_problems
from snnkart.envs.spaces import ActionAdapter, ObsAdapter, space_words
from snnkart.errors import EnvError

SPEC_KIND = "gymnasium"
"""The ``kind`` of a gymnasium env's spec (a kart env's spec has none: it came first)."""


def make_gym_env(
    ref: EnvRef, kwargs: Mapping[str, object] | None = None, render_mode: str | None = None
) -> gym.Env:
    """``ref``'s env with ``kwargs``, wrapped as the module docstring says."""
    env = ref.make(dict(kwargs or {}), render_mode=render_mode)
    try:
        ObsAdapter.of(env.observation_space)  # refuses images and unsupported spaces
        actions = ActionAdapter.of(env.action_space)
        _check_actions(ref.name, env.action_space, actions)
    except EnvError:
        env.close()
        raise
    obs = env.observation_space
    flat = isinstance(obs, spaces.Box) and len(obs.shape) == 1
    if not flat:
        env = FlattenObservation(env)
    if env.observation_space.dtype != np.float32:
        env = DtypeObservation(env, np.float32)
    act = env.action_space
    if isinstance(act, spaces.MultiDiscrete) or (
        isinstance(act, spaces.Discrete) and int(act.start) != 0
    ):
        env = JointDiscrete(env)
    if isinstance(act, spaces.Box) and _needs_rescale(act):
        env = RescaleAction(env, np.float32(-1.0), np.float32(1.0))
    return env


MAX_JOINT_ACTIONS = 256
"""The most joint actions a MultiDiscrete space may have: the policy's one categorical head has
one output per joint action (its readout layer's width)."""


class JointDiscrete(gym.ActionWrapper):  # type: ignore[type-arg]
    """A ``MultiDiscrete`` (or a ``Discrete`` not starting at 0) as one ``Discrete`` space from
    0: joint action ``a`` is the components' index in C order (``numpy.unravel_index`` over
    ``nvec``), each component offset by its ``start``. The policy's categorical head is then
    over the joint actions (not factorised per component, as Stable-Baselines3's
    ``MultiCategorical`` is): exact, and every backend runs it as a Discrete policy."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        space = env.action_space
        assert isinstance(space, (spaces.Discrete, spaces.MultiDiscrete))
        self.multi = isinstance(space, spaces.MultiDiscrete)
        nvec = space.nvec if isinstance(space, spaces.MultiDiscrete) else space.n
        self.nvec = np.atleast_1d(nvec).ravel()
        self.start = np.atleast_1d(space.start).ravel()
        self.shape, self.dtype = space.shape, space.dtype
        self.action_space = spaces.Discrete(int(np.prod(self.nvec)))

    def action(self, action: Any) -> Any:
        parts = np.array(np.unravel_index(int(action), tuple(self.nvec))) + self.start
        if not self.multi:
            return np.int64(parts[0])
        return parts.reshape(self.shape).astype(self.dtype)


def _check_actions(name: str, space: spaces.Space[Any], actions: ActionAdapter) -> None:
    """The action spaces the policies' heads cannot take, refused in words."""
    words = space_words(actions.describe())
    if isinstance(space, spaces.MultiDiscrete) and int(np.prod(space.nvec)) > MAX_JOINT_ACTIONS:
        raise EnvError(
            f"env {name!r} has MultiDiscrete actions ({words}): {int(np.prod(space.nvec))} "
            f"joint actions, more than the {MAX_JOINT_ACTIONS} snnkart's categorical head takes; "
            "wrap the env to fewer actions"
        )
    if isinstance(space, spaces.Box) and len(space.shape) != 1:
        raise EnvError(
            f"env {name!r} has Box actions of shape {space.shape}; snnkart's policies take a "
            "flat Box: wrap the env to flatten its actions"
        )


def _needs_rescale(space: spaces.Box) -> bool:
    """Whether a Box action space has finite bounds other than [-1, 1]."""
    low, high = space.low.astype(np.float64), space.high.astype(np.float64)
    if not (np.all(np.isfinite(low)) and np.all(np.isfinite(high))):
        return False
    return not (np.all(low == -1.0) and np.all(high == 1.0))


def gym_spec(ref: EnvRef, env: gym.Env, kwargs: Mapping[str, object] | None) -> dict[str, object]:
    """What a policy trained on ``env`` (:func:`make_gym_env`'s) depends on, as checkpoints
    and manifests store it: the env's :class:`~snnkart.envs.resolve.GymEnvSpec` (the spaces as
    the policy sees them, after the wrappers it names), its ``kind`` and ``obs_dim``."""
    record = ref.spec_record(env, dict(kwargs or {}))
    dim = int(np.prod(env.observation_space.shape or (0,)))
    return {"kind": SPEC_KIND, "env": ref.name, "obs_dim": dim, **record}


def is_gym_spec(spec: Mapping[str, object]) -> bool:
    """Whether a saved spec is a gymnasium env's (else a kart env's)."""
    return spec.get("kind") == SPEC_KIND


def gym_spec_problems(
    saved: Mapping[str, object], now: Mapping[str, object]
) -> tuple[list[str], list[str]]:
    """How a saved gymnasium spec differs from the env's now: (refusals, warnings)."""
    if not is_gym_spec(now):
        return [f"the policy was trained on {saved.get('env')!r}, not a kart env"], []
    return spec_problems(_record(saved), _record(now))


def check_trained_on(
    saved: Mapping[str, object], now: Mapping[str, object], fix: str, where: str = ""
) -> None:
    """Refuse (:class:`EnvError`, ending with ``fix``) a gymnasium env whose spec ``now`` has
    another id or other spaces than the ``saved`` one a policy was trained on; warn (prefixed
    with ``where``) of any other difference, such as another package version."""
    refusals, notes = gym_spec_problems(saved, now)
    if refusals:
        raise EnvError(
            f"the env is not the one the policy was trained on ({'; '.join(refusals)}); {fix}"
        )
    for note in notes:
        warnings.warn(f"{where}not the env version the policy was trained on: {note}", stacklevel=4)


def _record(spec: Mapping[str, object]) -> GymEnvSpec:
    keys = GymEnvSpec.__annotations__
    return {k: spec.get(k) for k in keys}  # type: ignore[return-value]


def rebuild(spec: Mapping[str, object], render_mode: str | None = None) -> gym.Env:
    """The env a gymnasium spec was recorded of, made again with its kwargs."""
    ref = resolve_env(str(spec["name"]))
    kwargs = spec.get("kwargs")
    return make_gym_env(ref, kwargs if isinstance(kwargs, dict) else {}, render_mode)
