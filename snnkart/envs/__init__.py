"""The snnkart racing environments, registered with gymnasium when ``snnkart`` is imported.

Registration uses string entry points, so importing the package does not import pymunk.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from snnkart.errors import EnvError, did_you_mean

ENV_IDS: dict[str, str] = {
    "grid": "snnkart/Grid-v0",
    "gazebo": "snnkart/Gazebo-v0",
    "steer": "snnkart/Steer-v0",
}
"""Short env names (as used by the CLI) -> gymnasium ids."""

ENV_ALIASES: dict[str, str] = {
    **{name: name for name in ENV_IDS},
    **{f"{name}_env": name for name in ENV_IDS},  # the original project's names
    **{env_id: name for name, env_id in ENV_IDS.items()},
    "latenv": "grid",
}

_ENTRY_POINTS = {
    "grid": "snnkart.envs.grid:GridEnv",
    "gazebo": "snnkart.envs.gazebo:GazeboEnv",
    "steer": "snnkart.envs.steer:SteerEnv",
}


def resolve_env_name(name: str) -> str:
    """Map any accepted spelling (``steer``, ``steer_env``, ``snnkart/Steer-v0``) to ``steer``."""
    key = name if name in ENV_ALIASES else name.lower()
    if key not in ENV_ALIASES:
        raise EnvError(
            f"unknown env {name!r}{did_you_mean(key, ENV_IDS)}; choose one of {', '.join(ENV_IDS)} "
            f"(also accepted: {', '.join(f'{n}_env' for n in ENV_IDS)}, {', '.join(ENV_IDS.values())})"
        )
    return ENV_ALIASES[key]


def make(name: str, **kwargs: Any) -> gym.Env:
    """``gymnasium.make`` by any accepted env name."""
    return gym.make(ENV_IDS[resolve_env_name(name)], **kwargs)


def register_envs() -> None:
    for name, env_id in ENV_IDS.items():
        if env_id not in gym.registry:
            gym.register(id=env_id, entry_point=_ENTRY_POINTS[name])
