"""What a trained policy depends on in an env, and the one way snnkart builds an env.

:func:`env_spec` describes an env (revision, env, track and its hash, action and observation
layout, env config); checkpoints and manifests record it with :func:`spec_hash`, and
:func:`spec_differences` says in words how a saved spec differs from an env, so a policy is
never run on an env whose observations mean something else.
"""

from __future__ import annotations

import copy
import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict

import gymnasium as gym
import numpy as np

from snnkart.envs import make

if TYPE_CHECKING:
    from snnkart.envs.base import KartEnv
    from snnkart.envs.tracks import Track

ENV_REVISION = 3
"""Revision of what the observations and rewards mean, recorded with every checkpoint and
NIR export, so a policy is never run on observations whose meaning changed under it (the
layout and bounds alone do not show that):

1. progress and the checkpoint observation measured straight at the next checkpoint line;
2. both along the shortest drivable path (geodesic); heading reward term;
3. steer's path keeps the car's turning radius from the walls.
"""


def revision_mismatch(saved: object) -> str | None:
    """What to tell a user whose policy was made on env revision ``saved`` (None when it is
    the current one); the caller adds what to do."""
    if saved == ENV_REVISION:
        return None
    return (
        f"env revision {saved if saved is not None else '1 or 2'}, and this snnkart's envs "
        f"are revision {ENV_REVISION}: what the observations and rewards mean has changed "
        "since (snnkart.envs.spec.ENV_REVISION)"
    )


_ADDED_UNSET = ("route_clearance_m", "sim2real", "observation")
"""Env config fields added after revision 3 began; left out of the spec while unset (None),
so runs made before they existed still match."""

SPEC_KEYS = (
    "env",
    "track",
    "track_sha256",
    "action_mode",
    "action_space",
    "observation_layout",
    "env_config",
)


def make_env(
    env: str,
    track: str | Path | Track,
    action_mode: str = "discrete",
    config: dict[str, object] | None = None,
    render_mode: str | None = None,
) -> gym.Env:
    """The env ``env`` (any accepted spelling) on ``track``: :func:`snnkart.envs.make` with
    every argument that defines it named."""
    return make(
        env,
        track=track,
        action_mode=action_mode,
        config=config or None,
        render_mode=render_mode,
    )


class EnvSpec(TypedDict):
    """What a trained policy depends on in an env (:func:`env_spec`), as checkpoints,
    recordings and manifests store it."""

    revision: int
    env: str
    track: str
    track_sha256: str
    action_mode: str
    action_space: str
    observation_layout: list[list[str | int | float]]  # per component: name, size, low, high
    obs_dim: int
    env_config: dict[str, object]  # the env config as JSON, terms added while off left out


def env_spec(env: KartEnv) -> dict[str, object]:
    """Everything about an env that a trained policy depends on (an :class:`EnvSpec`), as
    the JSON data the records store, hash and compare key by key."""
    track = env.track_given  # random tracks: their stand-in, not the current one
    track_text = track.to_toml()
    spec: EnvSpec = {
        "revision": ENV_REVISION,
        "env": env.env_name,
        "track": track.name,
        "track_sha256": hashlib.sha256(track_text.encode()).hexdigest(),
        "action_mode": env.action_mode,
        "action_space": str(env.action_space),
        "observation_layout": [[f.name, f.size, f.low, f.high] for f in env.observation_layout],
        "obs_dim": int(env.observation_space.low.shape[0]),
        "env_config": _env_config(env),
    }
    return dict(spec)


_ADDED_OFF = {
    "reward": (("stall", ("stall", "stall_grace_steps")), ("wall_per_m_s", ("wall_per_m_s",))),
}
"""Env config terms added after revision 3 began, by section: (the switch, the fields it
governs) pairs. While a switch is off (0), its fields change nothing and are left out of the
spec."""


def _env_config(env: KartEnv) -> dict[str, object]:
    data = env.config.model_dump(mode="json")
    for key in _ADDED_UNSET:
        if data.get(key) is None:
            data.pop(key, None)
    for section, added in _ADDED_OFF.items():
        values = data.get(section)
        for switch, fields in added:
            if isinstance(values, dict) and not values.get(switch):
                for field in fields:
                    values.pop(field, None)
    return data


def trained_env_config(saved: Mapping[str, object]) -> dict[str, object] | None:
    """The env config a policy was trained with, from its saved spec (None if it has none):
    the full resolved config, with the terms left out while off written back as off, so a
    later change of a default does not change the env an existing run evaluates or resumes
    in."""
    data = saved.get("env_config")
    if not isinstance(data, dict):
        return None
    data = {k: copy.deepcopy(v) for k, v in data.items() if v is not None}  # None: unset
    for section, added in _ADDED_OFF.items():
        values = data.get(section)
        for switch, _ in added:
            if isinstance(values, dict) and switch not in values:
                values[switch] = 0.0
    return data


def layout_of(spec: Mapping[str, object]) -> list[list[object]]:
    """A spec's observation layout, ``[name, size, low, high]`` per component (none: ``[]``)."""
    layout = spec.get("observation_layout")
    return layout if isinstance(layout, list) else []


def spec_hash(spec: Mapping[str, object]) -> str:
    return hashlib.sha256(json.dumps(spec, sort_keys=True).encode()).hexdigest()[:16]


def spec_differences(saved: Mapping[str, object], spec: Mapping[str, object]) -> list[str]:
    """How the saved spec differs from ``spec`` (an env's :func:`env_spec`), one phrase per
    difference; a revision mismatch comes alone, first (what the observations mean has
    changed)."""
    mismatch = revision_mismatch(saved.get("revision"))
    if mismatch:
        return [mismatch]
    diffs = []
    if saved.get("obs_dim") != spec["obs_dim"]:
        diffs.append(f"observation size {saved.get('obs_dim')} vs {spec['obs_dim']}")
    for key in SPEC_KEYS:
        if saved.get(key) != spec[key]:
            diffs.append(
                "track geometry differs"
                if key == "track_sha256"
                else f"{key}: {saved.get(key)!r} vs {spec[key]!r}"
            )
    return diffs


def fit_problem(saved: Mapping[str, object], env: gym.Env) -> str | None:
    """Why a policy made for the saved spec cannot act in ``env`` at all (observation size,
    action space), or None. Weaker than :func:`spec_differences`: a deployed policy may be
    run on another track or env when it fits, a resumed run may not."""
    name = getattr(env.unwrapped, "env_name", "?")
    obs_dim = int(np.prod(env.observation_space.shape or (0,)))
    layout = layout_problem(saved, env)  # first: it names the difference
    if layout:
        return layout
    if saved.get("obs_dim") != obs_dim:
        return (
            f"the policy takes {saved.get('obs_dim')} observation values but env {name!r} "
            f"observes {obs_dim}; deploy it on the env it was trained on ({saved.get('env')})"
        )
    if saved.get("action_space") and str(env.action_space) != saved["action_space"]:
        return (
            f"the policy acts in {saved['action_space']} but env {name!r} expects "
            f"{env.action_space}"
        )
    return None


def layout_problem(saved: Mapping[str, object], env: gym.Env) -> str | None:
    """How the observation components of the saved spec differ from ``env``'s, or None.
    Checked when either names its components (``env_config.observation``); a spec without
    them means the env's own layout, so two default layouts (of different envs) still fit."""
    saved_config = saved.get("env_config")
    wanted = saved_config.get("observation") if isinstance(saved_config, dict) else None
    mine = getattr(getattr(env.unwrapped, "config", None), "observation", None)
    if wanted is None and mine is None:
        return None
    theirs = [str(f[0]) for f in layout_of(saved)]
    ours = [f.name for f in getattr(env.unwrapped, "observation_layout", ())]
    if theirs == ours:
        return None
    fix = f"env_config.observation = {list(wanted)}" if wanted else "no env_config.observation"
    return (
        f"the policy observes [{', '.join(theirs)}] but env "
        f"{getattr(env.unwrapped, 'env_name', '?')!r} observes [{', '.join(ours)}]; "
        f"deploy it on an env with {fix}"
    )
