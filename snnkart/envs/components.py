"""Selectable observation components: which named blocks an env observes, in which order.

``env_config.observation`` lists component names (``None``, the default: the env's own
layout, unchanged). Each component is a block of :class:`~snnkart.envs.observation.ObsField`
with true bounds:

- ``lidar`` (one per ray, [0, 1]): ray distance / range, with sim2real's noise and dropout
  when those are configured (the noisy variant; there is no other);
- ``position`` (2, [0, 1]): x, y / world size (1000 px);
- ``heading`` (2, [-1, 1]): cos, sin of the heading;
- ``velocity`` (1, [-1, 1]): forward speed / max speed (grid: 2, x and y velocity);
- ``angular_velocity`` (1, [-1, 1]): yaw rate / max yaw rate (not in grid);
- ``steering`` (1, [-1, 1]): steering angle / lock (steer only);
- ``checkpoint`` (3): the route to the next checkpoint: cos, sin ([-1, 1]), distance ([0, 1]);
- ``previous_action``: the last action, one-hot ([0, 1], discrete) or the vector ([-1, 1]).

The default layouts are ``lidar velocity steering heading checkpoint`` (steer), ``lidar
velocity angular_velocity heading checkpoint`` (gazebo) and ``lidar velocity checkpoint``
(grid): the same values as before this option existed, named as before.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from snnkart.envs.constants import WORLD_SIZE_PX
from snnkart.envs.observation import ObsField

COMPONENTS = (
    "lidar",
    "position",
    "heading",
    "velocity",
    "angular_velocity",
    "steering",
    "checkpoint",
    "previous_action",
)
"""Every component name, in the table's order."""

_DEFAULT_FIELDS = {
    "lidar": ("lidar",),
    "heading": ("heading_cos", "heading_sin"),
    "velocity": ("speed", "linear_velocity", "velocity_x", "velocity_y"),  # the env's
    "angular_velocity": ("angular_velocity",),
    "steering": ("steering",),
    "checkpoint": ("checkpoint_cos", "checkpoint_sin", "checkpoint_distance"),
}
"""The fields of the env's own layout that each component is made of."""


def default_components(layout: Sequence[ObsField]) -> tuple[str, ...]:
    """The component names of an env's own (default) ``layout``, in order."""
    names: list[str] = []
    for f in layout:
        for component, fields in _DEFAULT_FIELDS.items():
            if f.name in fields and component not in names:
                names.append(component)
    return tuple(names)


def check_components(names: Sequence[str]) -> tuple[str, ...]:
    """``names`` validated: known, none twice, at least one."""
    unknown = [n for n in names if n not in COMPONENTS]
    if unknown:
        raise ValueError(
            f"unknown observation component(s) {unknown}; choose from {', '.join(COMPONENTS)}"
        )
    if len(set(names)) != len(names) or not names:
        raise ValueError(f"observation components {list(names)}: list each once, at least one")
    return tuple(names)


def select_components(
    env: Any, own: Sequence[ObsField], names: Sequence[str] | None
) -> Selection | None:
    """The :class:`Selection` of ``names`` for ``env`` (a KartEnv, typed ``Any``: envs.base
    imports this module) whose own layout is ``own``; None for None (the env observes its own
    layout)."""
    return None if names is None else Selection(env, own, names)


class Selection:
    """Builds the observation of the components ``names`` from the env's own (default)
    observation and state; see the module docstring."""

    def __init__(self, env: Any, own: Sequence[ObsField], names: Sequence[str]) -> None:
        self.names = check_components(names)
        starts, at = {}, 0
        for f in own:
            starts[f.name] = (at, f)
            at += f.size
        fields: list[ObsField] = []
        self._parts: list[Callable[[np.ndarray], np.ndarray]] = []
        for name in self.names:
            found = [starts[n] for n in _DEFAULT_FIELDS.get(name, ()) if n in starts]
            if found:
                lo, hi = found[0][0], found[-1][0] + found[-1][1].size
                fields += [f for _, f in found]
                self._parts.append(_slice(lo, hi))
            else:
                field, part = _extra(env, own, name)
                fields.append(field)
                self._parts.append(part)
        self.layout = tuple(fields)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return np.concatenate([part(obs) for part in self._parts]).astype(np.float32)


def _slice(lo: int, hi: int) -> Callable[[np.ndarray], np.ndarray]:
    """The part ``[lo:hi]`` of the env's own observation."""
    return lambda obs: obs[lo:hi]


def _extra(
    env: Any, own: Sequence[ObsField], name: str
) -> tuple[ObsField, Callable[[np.ndarray], np.ndarray]]:
    """A component that the env's own layout lacks: its field and how to compute it."""
    if name == "position":

        def position(_: np.ndarray) -> np.ndarray:
            x, y = env.position
            return np.clip(np.array([x, y]) / WORLD_SIZE_PX, 0.0, 1.0)

        return ObsField("position", 2, 0.0, 1.0, "x, y / world size"), position
    steering = any(f.name == "steering" for f in own)
    if name == "angular_velocity" and steering:  # steer: the bicycle's yaw rate

        def yaw_rate(_: np.ndarray) -> np.ndarray:
            s: Any = env
            rate = s._v * math.tan(s._delta) / (s._vmax * math.tan(s._lock))
            return np.array([min(max(rate, -1.0), 1.0)])

        return ObsField("angular_velocity", 1, -1.0, 1.0, "yaw rate / max yaw rate"), yaw_rate
    if name == "previous_action":
        return _previous_action(env)
    if name == "heading":  # grid: its kart never turns

        def heading(_: np.ndarray) -> np.ndarray:
            return np.array([math.cos(env.heading), math.sin(env.heading)])

        return ObsField("heading", 2, -1.0, 1.0, "cos, sin of the heading"), heading
    raise ValueError(
        f"env {env.env_name!r} has no observation component {name!r}; "
        f"it has {', '.join(default_components(own))}, position, "
        "previous_action"
    )


def _previous_action(env: Any) -> tuple[ObsField, Callable[[np.ndarray], np.ndarray]]:
    if env.action_mode == "discrete":
        n = int(env.action_space.n)  # type: ignore[attr-defined]

        def one_hot(_: np.ndarray) -> np.ndarray:
            out = np.zeros(n)
            if env.last_action is not None:
                out[int(env.last_action)] = 1.0
            return out

        return ObsField("previous_action", n, 0.0, 1.0, "the last action, one-hot"), one_hot
    size = int(np.prod(env.action_space.shape or (1,)))

    def vector(_: np.ndarray) -> np.ndarray:
        if env.last_action is None:
            return np.zeros(size)
        return np.clip(np.asarray(env.last_action, dtype=np.float64).ravel(), -1.0, 1.0)

    return ObsField("previous_action", size, -1.0, 1.0, "the last action"), vector
