"""Any gymnasium env by name, made and recorded as data.

:func:`resolve_env` accepts

- snnkart's kart envs by any accepted spelling (``steer``, ``steer_env``, ``snnkart/Steer-v0``);
- any id in gymnasium's registry (``CartPole-v1``, ``Pendulum-v1``, ``Hopper-v5``);
- gymnasium's ``module:EnvId-v0``: the module is imported, which registers the id;
- an entry point ``package.module:ClassName`` (a :class:`gymnasium.Env` subclass).

The part after ``:`` is an id if the imported module registered it, else a class of the module.
An :class:`EnvRef` makes the env (:meth:`EnvRef.make`) and records what a policy trained on it
depends on (:meth:`EnvRef.spec_record`, a :class:`GymEnvSpec`); :func:`spec_problems` says in
words how a saved record differs from an env now.

Sharp edges: an entry point is made directly even if some id registers the same class (an id
may add kwargs and wrappers: name the id to get them). Envs whose optional dependency is
missing (Box2D, MuJoCo) are refused at :func:`resolve_env` with the extra that installs it.
"""

from __future__ import annotations

import difflib
import functools
import importlib
import importlib.metadata
import inspect
import json
import os
import re
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypedDict

import gymnasium as gym
from gymnasium.envs.registration import EnvSpec, load_env_creator
from gymnasium.error import DependencyNotInstalled

from snnkart.envs import ENV_IDS, register_envs, resolve_env_name
from snnkart.envs.spaces import SpaceRecord, describe_space, space_words
from snnkart.errors import EnvError

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

ENV_FORMS = (
    f"a snnkart env ({', '.join(ENV_IDS)}), a registered gymnasium id (e.g. CartPole-v1), "
    "'module:EnvId-v0' (the module registers the id) or 'package.module:ClassName'"
)
"""What :func:`resolve_env` accepts, as its errors say."""

EXTRAS: dict[str, tuple[str, str]] = {
    "gymnasium.envs.box2d": ("Box2D", "box2d"),
    "gymnasium.envs.mujoco": ("mujoco", "mujoco"),
}
"""Package of an env's entry point -> (the module its envs need, the snnkart extra that
installs it)."""


class GymEnvSpec(TypedDict):
    """What a policy trained on a gymnasium env depends on (:meth:`EnvRef.spec_record`), as
    checkpoints and manifests store it; spaces as :func:`~snnkart.envs.spaces.describe_space`
    writes them. ``name`` is what the user wrote, so ``resolve_env(record["name"])`` rebuilds it."""

    name: str
    id: str | None
    entry_point: str
    kwargs: dict[str, object]
    wrappers: list[str]  # wrapper classes around the base env, outermost first
    observation_space: SpaceRecord
    action_space: SpaceRecord
    max_episode_steps: int | None
    reward_threshold: float | None
    render_fps: float | None
    package: str | None  # the distribution providing the env's module
    package_version: str | None
    gymnasium_version: str


@dataclass(frozen=True)
class EnvRef:
    """A resolved env: ``name`` as the user wrote it, its registered ``id`` (None for an
    entry point made directly), its ``entry_point`` (``module:Class``) and whether it is one of
    snnkart's kart envs."""

    name: str
    id: str | None
    entry_point: str
    kart: bool = False

    def make(
        self, kwargs: dict[str, object] | None = None, render_mode: str | None = None
    ) -> gym.Env:
        """The env, by ``gymnasium.make``: a registered id gets its registered wrappers
        (TimeLimit, OrderEnforcing, PassiveEnvChecker); an entry point is made from a spec of
        its own, so it gets the same checks, and a TimeLimit only when ``max_episode_steps`` is
        in ``kwargs`` (for an id, that key overrides the registered limit)."""
        given: dict[str, Any] = dict(kwargs or {})
        if render_mode is not None:
            given["render_mode"] = render_mode
        target = self.id if self.id is not None else EnvSpec(self.entry_point, self.entry_point)
        try:
            return gym.make(target, **given)
        except DependencyNotInstalled as exc:
            raise EnvError(_dependency_message(self.name, self.entry_point, exc)) from exc
        except TypeError as exc:
            unexpected = re.search(r"unexpected keyword argument '(\w+)'", str(exc))
            if unexpected is None:
                raise
            raise EnvError(
                f"env {self.name!r} takes no argument {unexpected[1]!r} (check --env-kwargs); "
                f"it takes: {_parameters(self.entry_point)}"
            ) from exc

    def spec_record(self, env: gym.Env, kwargs: dict[str, object] | None = None) -> GymEnvSpec:
        """What a policy trained on ``env`` (made by :meth:`make` with ``kwargs``) depends on."""
        spec = env.spec
        package, package_version = _distribution(type(env.unwrapped).__module__)
        threshold = spec.reward_threshold if spec is not None else None
        return {
            "name": self.name,
            "id": self.id,
            "entry_point": self.entry_point,
            "kwargs": dict(kwargs or {}),
            "wrappers": wrapper_names(env),
            "observation_space": describe_space(env.observation_space),
            "action_space": describe_space(env.action_space),
            "max_episode_steps": spec.max_episode_steps if spec is not None else None,
            "reward_threshold": float(threshold) if threshold is not None else None,
            "render_fps": env.metadata.get("render_fps"),
            "package": package,
            "package_version": package_version,
            "gymnasium_version": gym.__version__,
        }


def resolve_env(name: str) -> EnvRef:
    """The env ``name`` stands for (see the module docstring); :class:`EnvError` naming the
    problem and the fix when there is none."""
    try:
        short = resolve_env_name(name)
    except EnvError:
        pass
    else:
        register_envs()
        env_id = ENV_IDS[short]
        return EnvRef(name, env_id, _entry_point_text(env_id), kart=True)
    if ":" in name:
        return _from_module(name)
    if name in gym.registry:
        return _registered(name, name)
    raise EnvError(_unknown(name, gym.registry))


def _registered(name: str, env_id: str) -> EnvRef:
    entry_point = _entry_point_text(env_id)
    for package, (module, extra) in EXTRAS.items():
        if entry_point.startswith(f"{package}."):
            try:
                importlib.import_module(module)
            except ImportError:
                raise EnvError(_needs(name, module, extra)) from None
    return EnvRef(name, env_id, entry_point)


def _entry_point_text(env_id: str) -> str:
    entry_point = gym.registry[env_id].entry_point
    if entry_point is None:
        raise EnvError(
            f"env {env_id!r} is registered without an entry point; snnkart cannot make it"
        )
    if isinstance(entry_point, str):
        return entry_point
    return f"{entry_point.__module__}:{getattr(entry_point, '__qualname__', entry_point)}"


def _import_here(module_name: str) -> Any:
    """Import ``module_name`` as ``python -m`` would: the current directory first on the path
    (a console script's path lacks it, and a user's env module usually lives there)."""
    here = os.getcwd()
    if here not in sys.path and "" not in sys.path:
        sys.path.insert(0, here)
    return importlib.import_module(module_name)


def _from_module(name: str) -> EnvRef:
    module_name, _, attr = name.partition(":")
    if not module_name or not attr or ":" in attr:
        raise EnvError(f"env {name!r} is neither 'module:EnvId-v0' nor 'package.module:ClassName'")
    try:
        module = _import_here(module_name)
    except DependencyNotInstalled as exc:
        raise EnvError(_dependency_message(name, module_name, exc)) from None
    except ImportError as exc:
        raise EnvError(_import_failure(name, module_name, exc)) from None
    if attr in gym.registry:
        return _registered(name, attr)
    target = getattr(module, attr, None)
    if target is None:
        classes = [
            k for k, v in vars(module).items() if isinstance(v, type) and issubclass(v, gym.Env)
        ]
        raise EnvError(
            f"module {module_name!r} registers no env {attr!r} and has no class {attr!r}"
            f"{_close(attr, [*gym.registry, *classes], 'ids and classes')}; give an id the module registers or an "
            "env class in it"
        )
    if not (isinstance(target, type) and issubclass(target, gym.Env)):
        raise EnvError(
            f"env {name!r}: {module_name}.{attr} is a {type(target).__name__}, not a "
            "gymnasium.Env subclass; give an env class or an id the module registers"
        )
    return EnvRef(name, None, f"{module_name}:{attr}")


def _import_failure(name: str, module_name: str, exc: ImportError) -> str:
    where = ""
    missing = getattr(exc, "name", None) or ""
    parent = missing.rpartition(".")[0]
    if parent and getattr(sys.modules.get(parent), "__file__", None):
        where = f"; {parent!r} here is {sys.modules[parent].__file__}"
    return (
        f"env {name!r}: cannot import module {module_name!r} ({type(exc).__name__}: {exc}{where}); "
        "it must be importable from the current directory or an installed package, with its "
        "dependencies installed"
    )


def _close(word: str, choices: Iterable[str], what: str = "registered ids") -> str:
    close = difflib.get_close_matches(word, list(choices), n=3, cutoff=0.6)
    return f" (close {what}: {', '.join(close)})" if close else ""


def _unknown(name: str, registry: Iterable[str]) -> str:
    return f"unknown env {name!r}{_close(name, [*ENV_IDS, *registry])}; give {ENV_FORMS}"


def _needs(name: str, module: str, extra: str) -> str:
    return f"env {name!r} needs {module}, which is not installed: pip install 'snnkart[{extra}]'"


def _dependency_message(name: str, where: str, exc: DependencyNotInstalled) -> str:
    for package, (module, extra) in EXTRAS.items():
        if where.startswith(f"{package}.") or module.lower() in str(exc).lower():
            return _needs(name, module, extra)
    return f"env {name!r} needs a package that is not installed: {exc}"


def _parameters(entry_point: str) -> str:
    try:
        names = list(inspect.signature(load_env_creator(entry_point)).parameters)
    except (TypeError, ValueError):
        return "(its signature cannot be read)"
    return ", ".join(names) or "no arguments"


def wrapper_names(env: gym.Env) -> list[str]:
    """The classes of the wrappers around ``env``'s base env, outermost first."""
    names = []
    while isinstance(env, gym.Wrapper):
        names.append(type(env).__name__)
        env = env.env
    return names


@functools.lru_cache(maxsize=1)
def _top_level_distributions() -> dict[str, list[str]]:
    return {
        top: sorted(set(names))
        for top, names in importlib.metadata.packages_distributions().items()
    }


def _distribution(module_name: str) -> tuple[str | None, str | None]:
    """(name, version) of the installed distribution that provides ``module_name``, else
    (None, None). A distribution that ships the same top-level name elsewhere (lava-nc ships a
    ``tests`` package) is not taken for it."""
    top = module_name.partition(".")[0]
    file = getattr(sys.modules.get(module_name), "__file__", None)
    for dist_name in _top_level_distributions().get(top, []):
        dist = importlib.metadata.distribution(dist_name)
        shipped = [f.parts[0] for f in dist.files or () if f.parts[0] in (top, f"{top}.py")]
        if shipped and file is not None:
            root = Path(str(dist.locate_file(shipped[0]))).resolve()
            if not Path(file).resolve().is_relative_to(root):
                continue
        return dist.metadata["Name"], dist.version
    return None, None


def parse_env_kwargs(items: Iterable[str]) -> dict[str, object]:
    """``--env-kwargs key=value ...`` as keyword arguments: each value as a TOML or JSON
    literal where it parses as one (``9.8``, ``true``, ``[1, 2]``, ``"text"``, ``null``), else
    the plain string; :class:`EnvError` for an item that is not ``key=value``."""
    kwargs: dict[str, object] = {}
    for item in items:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key.isidentifier():
            raise EnvError(
                f"env kwarg {item!r} is not key=value with key a Python name "
                "(e.g. --env-kwargs gravity=9.8 continuous=true)"
            )
        if key in kwargs:
            raise EnvError(f"env kwarg {key!r} is given twice (--env-kwargs); give it once")
        kwargs[key] = _literal(text)
    return kwargs


def _literal(text: str) -> object:
    parsers = (lambda t: tomllib.loads(f"v = {t}")["v"], json.loads)
    for parse in parsers:
        try:
            value = parse(text)
        except ValueError:  # TOMLDecodeError and JSONDecodeError are ValueErrors
            continue
        if _plain(value):
            return value
    return text


def _plain(value: object) -> bool:
    """JSON data (TOML dates and times are not)."""
    if value is None or isinstance(value, bool | int | float | str):
        return True
    if isinstance(value, list):
        return all(_plain(v) for v in value)
    return isinstance(value, dict) and all(_plain(v) for v in value.values())


_WARNED = {
    "entry_point": "entry point",
    "kwargs": "env kwargs",
    "wrappers": "wrappers",
    "max_episode_steps": "max episode steps",
    "package": "package",
    "package_version": "package version",
    "gymnasium_version": "gymnasium version",
}
"""Record fields that may differ with a warning: the policy still fits the env."""


def spec_problems(saved: GymEnvSpec, now: GymEnvSpec) -> tuple[list[str], list[str]]:
    """(refusals, warnings) in words, for a policy recorded with ``saved`` run on an env
    recorded as ``now``: another id (or, for entry points, class) or other observation or
    action spaces refuse; other versions, kwargs, wrappers or limits warn."""
    refusals = []
    if saved["id"] != now["id"]:
        refusals.append(f"env id {saved['id']!r} vs {now['id']!r}")
    elif saved["id"] is None and saved["entry_point"] != now["entry_point"]:
        refusals.append(f"env class {saved['entry_point']!r} vs {now['entry_point']!r}")
    was_, is_ = _as_data(saved), _as_data(now)
    for role in ("observation_space", "action_space"):
        if was_[role] != is_[role]:
            role_words = role.replace("_", " ")
            refusals.append(f"{role_words} {_space_difference(was_[role], is_[role])}")
    warnings = []
    for key, words in _WARNED.items():
        if key == "package_version" and was_["package"] == "gymnasium":
            continue  # the gymnasium version says it
        if was_.get(key) != is_.get(key):
            warnings.append(f"{words} {was_.get(key)!r} vs {is_.get(key)!r}")
    return refusals, warnings


def _as_data(record: GymEnvSpec) -> Mapping[str, Any]:
    """The record as a mapping, its fields looked up by names held in variables."""
    return record


def _space_difference(was: SpaceRecord, is_: SpaceRecord) -> str:
    words_was, words_is = space_words(was), space_words(is_)
    if words_was != words_is:
        return f"{words_was} vs {words_is}"
    path, a, b = _first_difference(was, is_, "")
    return f"{words_was}: {path} {a!r} vs {b!r}"


def _first_difference(a: Any, b: Any, path: str) -> tuple[str, Any, Any]:
    if isinstance(a, dict) and isinstance(b, dict):
        for key in [*a, *(k for k in b if k not in a)]:
            if a.get(key) != b.get(key):
                inner = path if key == "spaces" else f"{path}.{key}".lstrip(".")
                return _first_difference(a.get(key), b.get(key), inner)
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            if x != y:
                return _first_difference(x, y, f"{path}[{i}]")
    return path, a, b
