"""The RL Zoo's tuned PPO settings for the standard gymnasium tasks, in snnkart's config terms.

:func:`zoo_settings` gives rl-baselines3-zoo's ``hyperparams/ppo.yml`` entry for an env id (an
installed ``rl_zoo3``'s, else the transcription shipped here, ``zoo_ppo.toml``, which names the
commit it was read at); :func:`to_snnkart` maps it onto snnkart's config keys and lists what does
not carry over; :func:`as_overrides` gives those keys as ``snnkart train --set`` arguments::

    >>> t = to_snnkart(zoo_settings("CartPole-v1"))
    >>> t.config["ppo.num_minibatches"]  # 8 envs * 32 steps / batch_size 256
    1

Sharp edges: the zoo has no v5 keys (HalfCheetah-, Hopper-, Walker2d-v5 take the v4 settings, and
``key`` and ``note`` say so). gSDE, clip-range schedules, reward normalisation, ``ortho_init=False``
... do not carry over (:attr:`ZooTranslation.unexpressible`). ``ppo.vf_coef`` is twice the zoo's
(SB3's value loss is the MSE, snnkart's half of it). An installed rl_zoo3's YAML needs PyYAML.
"""

from __future__ import annotations

import ast
import contextlib
import functools
import importlib.metadata
import importlib.util
import json
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Any, get_args

from snnkart.errors import ConfigError, did_you_mean
from snnkart.rl.sections import ANNConfig

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

TABLE = "zoo_ppo.toml"
"""The transcription of the zoo's ``hyperparams/ppo.yml`` shipped with snnkart (package data)."""

# fmt: off
SB3_PPO_DEFAULTS: Mapping[str, object] = MappingProxyType({
    "learning_rate": 3e-4, "n_steps": 2048, "batch_size": 64, "n_epochs": 10, "gamma": 0.99,
    "gae_lambda": 0.95, "clip_range": 0.2, "clip_range_vf": None, "normalize_advantage": True,
    "ent_coef": 0.0, "vf_coef": 0.5, "max_grad_norm": 0.5, "use_sde": False,
    "sde_sample_freq": -1, "target_kl": None,
})
"""What a zoo entry leaves unset is: ``PPO.__init__``'s defaults (stable_baselines3 2.9.2,
``stable_baselines3/ppo/ppo.py``)."""

SB3_POLICY_DEFAULTS: Mapping[str, object] = MappingProxyType({
    "net_arch": {"pi": [64, 64], "vf": [64, 64]}, "activation_fn": "nn.Tanh", "ortho_init": True,
    "log_std_init": 0.0,
})
"""``ActorCriticPolicy.__init__``'s defaults for ``MlpPolicy`` (``common/policies.py``: a
``net_arch`` of None becomes ``dict(pi=[64, 64], vf=[64, 64])``)."""
# fmt: on

VEC_NORMALIZE_DEFAULTS: Mapping[str, object] = MappingProxyType(
    {"norm_obs": True, "norm_reward": True, "clip_obs": 10.0, "clip_reward": 10.0}
)
"""``VecNormalize.__init__``'s defaults (``common/vec_env/vec_normalize.py``), what the zoo's
``normalize: true`` wraps the envs in (its ``gamma`` set to the entry's)."""

ZOO_DEFAULTS: Mapping[str, object] = MappingProxyType({"n_envs": 1, "normalize": False})
"""The zoo's own defaults (``rl_zoo3/exp_manager.py``: ``hyperparams.get("n_envs", 1)``; no
``VecNormalize`` unless ``normalize`` is set)."""

_DEFAULTS: dict[str, tuple[object, str]] = {
    **{k: (v, "SB3's default") for k, v in SB3_PPO_DEFAULTS.items()},
    **{k: (v, "SB3's policy default") for k, v in SB3_POLICY_DEFAULTS.items()},
    **{k: (v, "the zoo's default") for k, v in ZOO_DEFAULTS.items()},
}
"""What stands in for a key a zoo entry leaves unset, and whose default it is."""

COMMON_NOTES = (
    "ppo.anneal_ent=false: SB3's ent_coef is constant (snnkart's default anneals it)",
    "ppo.norm_adv: as SB3's normalize_advantage (per minibatch, mean 0, sample std + 1e-8)",
    "ppo.target_kl must stay unset (SB3's and snnkart's default None; --set cannot unset a key)",
    "the same in both without a key: Adam eps 1e-5, time-limit truncations bootstrapped with "
    "gamma * V(final obs), continuous actions clipped to the env's bounds",
    "continuous actions: snnkart acts in [-1, 1], rescaled to the env's bounds, so where they are "
    "not [-1, 1] (Pendulum-v1: [-2, 2]) SB3's log_std_init s is snnkart's init_log_std "
    "s + log(2 / (high - low))",
    "ann.hidden and ann.activation shape an ANN policy's actor and critic (policy=ann: SB3's "
    "MlpPolicy); a spiking policy takes only its critic's widths from them",
)
"""What every translation says: SB3's behaviour and how the translated keys match it."""

_NOT_TASKS = ("default", "atari")

_SB3_ONLY = {
    "clip_range_vf": "a value clip range of its own; snnkart's clip_vloss clips with clip_coef",
    "target_kl": "SB3 stops an update mid-epoch once approx_kl > 1.5 * target_kl; snnkart's "
    "ppo.target_kl checks after each epoch, against target_kl itself",
}
"""SB3 settings snnkart has no equal for, and why (when an entry sets them)."""

_PLAIN: dict[str, tuple[str, type]] = {
    "ppo.update_epochs": ("n_epochs", int),
    "ppo.gamma": ("gamma", float),
    "ppo.gae_lambda": ("gae_lambda", float),
    "ppo.ent_coef": ("ent_coef", float),
    "ppo.max_grad_norm": ("max_grad_norm", float),
    "ppo.norm_adv": ("normalize_advantage", bool),
}
"""snnkart's keys that are a zoo key's value as it is: ``{snnkart key: (zoo key, type)}``."""


@dataclass(frozen=True)
class ZooSettings:
    """One entry of the zoo's ``hyperparams/ppo.yml``: ``values`` as the zoo writes them.

    ``env_id`` is the id asked for, ``key`` the zoo key whose entry this is (a v4 key for a v5
    id, with ``note`` saying so), ``source`` where the entry was read."""

    env_id: str
    key: str
    values: Mapping[str, object]
    source: str
    note: str | None = None


@dataclass(frozen=True)
class ZooTranslation:
    """A zoo entry in snnkart's terms: ``config`` maps snnkart's dotted keys (``ppo.gamma``) to
    values; ``unexpressible`` names every zoo setting (or SB3 behaviour) snnkart cannot reproduce;
    ``notes`` say how translated keys match SB3's; ``defaulted`` names the keys the entry leaves
    unset and the default that stood in."""

    settings: ZooSettings
    config: Mapping[str, object]
    unexpressible: tuple[str, ...]
    notes: tuple[str, ...]
    defaulted: tuple[str, ...]


@functools.lru_cache(maxsize=1)
def _shipped() -> dict[str, Any]:
    return tomllib.loads(resources.files("snnkart.rl").joinpath(TABLE).read_text("utf-8"))


def installed_zoo_file() -> Path | None:
    """The ``hyperparams/ppo.yml`` of an installed ``rl_zoo3`` (found, not imported), else None."""
    spec = importlib.util.find_spec("rl_zoo3")
    if spec is None or spec.origin is None:
        return None
    package = Path(spec.origin).parent
    for path in (package / "hyperparams" / "ppo.yml", package.parent / "hyperparams" / "ppo.yml"):
        if path.is_file():  # the wheel's copy, or a source checkout's (as exp_manager looks)
            return path
    return None


def _entries(yml: Path | None) -> tuple[dict[str, Mapping[str, object]], str]:
    """The task entries of ``yml`` (the shipped table when None) and a line naming the source."""
    if yml is None:
        table = _shipped()
        src = table["source"]
        where = f"{src['repository']} at {src['commit'][:7]}, {src['file']}, read {src['read']}"
        return dict(table["ppo"]), f"snnkart/rl/{TABLE} ({where})"
    import yaml  # only here: rl_zoo3 depends on PyYAML, snnkart does not

    try:
        data = yaml.safe_load(yml.read_text("utf-8"))
    except yaml.YAMLError as exc:
        raise ConfigError(f"{yml}: not valid YAML: {exc}") from None
    tasks: dict[str, Mapping[str, object]] = {
        k: v for k, v in data.items() if k not in _NOT_TASKS and isinstance(v, dict)
    }
    dist = importlib.metadata.distributions(name="rl_zoo3")
    return tasks, f"rl_zoo3 {next((x.version for x in dist), '(no version)')} installed: {yml}"


def zoo_settings(env_id: str) -> ZooSettings:
    """The zoo's PPO entry for ``env_id``: from an installed ``rl_zoo3``'s ``ppo.yml`` when
    ``rl_zoo3`` is importable, else from the shipped table; a v5 id without a key of its own
    takes its v4 key's entry (``key`` and ``note`` say so).

    Raises:
        ConfigError: the zoo has no entry for ``env_id``; the message lists the ids that have.
    """
    entries, source = _entries(installed_zoo_file())
    fallback: dict[str, str] = _shipped()["fallback"]
    key = env_id if env_id in entries else fallback.get(env_id, env_id)
    if key not in entries:
        known = sorted([*entries, *(k for k, v in fallback.items() if v in entries)])
        raise ConfigError(
            f"the RL Zoo's PPO hyperparameters ({source}) have no entry for {env_id!r}"
            f"{did_you_mean(env_id, known)}; entries: {', '.join(known)}. The zoo itself would "
            "train it with its 'default' entry: SB3's untuned PPO defaults "
            "(snnkart.rl.zoo.SB3_PPO_DEFAULTS), not tuned settings to compare against"
        )
    note = None
    if key != env_id:
        note = (
            f"the zoo has no {env_id} key: these are its {key} settings (snnkart's choice; "
            f"the zoo would use its untuned 'default' entry), tuned on {key}, not on {env_id}"
        )
    return ZooSettings(env_id, key, MappingProxyType(dict(entries[key])), source, note)


@dataclass
class _Draft:
    """A translation being built: every zoo key read is marked used; the rest are reported."""

    values: Mapping[str, object]
    config: dict[str, object] = field(default_factory=dict)
    unexpressible: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    defaulted: list[str] = field(default_factory=list)
    used: set[str] = field(default_factory=set)

    def get(self, key: str, given: Mapping[str, object] | None = None) -> Any:
        """The entry's ``key`` (of ``given``: policy_kwargs), else its default, recorded."""
        self.used.add(key)
        given = self.values if given is None else given
        if key in given:
            return given[key]
        value, origin = _DEFAULTS[key]
        self.defaulted.append(f"{key} = {value!r} ({origin})")
        return value


def _schedule(key: str, value: object) -> tuple[float, bool]:
    """A zoo value that may be a schedule: (initial value, linear to 0?); ``lin_0.001`` is
    ``SimpleLinearSchedule(0.001)``: ``progress_remaining * 0.001`` (rl_zoo3/utils.py)."""
    kind, _, initial = value.partition("_") if isinstance(value, str) else ("", "", "")
    with contextlib.suppress(ValueError):
        if kind == "lin":
            return float(initial), True
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value), False
    raise ConfigError(f"zoo {key} {value!r}: expected a number or lin_<number>")


def _minibatches(d: _Draft, n_envs: int, n_steps: int) -> None:
    """SB3 cuts the rollout into minibatches of ``batch_size``, snnkart into equal ones."""
    batch, rollout = int(d.get("batch_size")), n_envs * n_steps
    d.config["ppo.num_minibatches"] = max(1, rollout // batch)
    if batch > rollout:
        d.notes.append(
            f"batch_size {batch} > n_envs * n_steps = {rollout}: SB3 takes the whole rollout as "
            "its one minibatch (it warns), as ppo.num_minibatches=1 does"
        )
    elif rollout % batch:
        d.unexpressible.append(
            f"batch_size {batch} does not divide n_envs * n_steps = {rollout}: SB3 adds a "
            f"minibatch of {rollout % batch}; snnkart's minibatches are equal (here "
            f"{rollout // batch} of {rollout // (rollout // batch)})"
        )


def _run_keys(d: _Draft, env_id: str) -> None:
    """The env, the budget and the rollout's shape."""
    d.used.add("n_timesteps")
    steps = d.values.get("n_timesteps")
    if not isinstance(steps, (int, float)) or steps < 1 or not float(steps).is_integer():
        raise ConfigError(f"zoo n_timesteps {steps!r}: expected a whole number of env steps")
    n_envs, n_steps = int(d.get("n_envs")), int(d.get("n_steps"))
    d.config |= {"env": env_id, "total_steps": int(steps)}
    d.config |= {"ppo.num_envs": n_envs, "ppo.rollout_steps": n_steps}
    _minibatches(d, n_envs, n_steps)


def _loss_keys(d: _Draft) -> None:
    """Epochs, discounting, learning rate, the clipped surrogate, the entropy and value terms."""
    for key, (zoo_key, kind) in _PLAIN.items():
        d.config[key] = kind(d.get(zoo_key))
    lr, linear = _schedule("learning_rate", d.get("learning_rate"))
    d.config |= {"ppo.learning_rate": lr, "ppo.anneal_lr": linear}
    if linear:
        d.unexpressible.append(
            "learning_rate lin_: SB3 sets it after each rollout from the progress left, so its "
            "update i of N uses lr*(1 - i/N) (the last ~0); snnkart's anneal_lr uses "
            "lr*(1 - (i-1)/N): the same line, one iteration earlier"
        )
    clip, clip_linear = _schedule("clip_range", d.get("clip_range"))
    d.config["ppo.clip_coef"] = clip
    if clip_linear:
        d.unexpressible.append(
            f"clip_range lin_{clip:g}: a clip range annealed linearly to 0; snnkart's "
            f"ppo.clip_coef is constant (set to the initial {clip:g})"
        )
    d.config["ppo.anneal_ent"] = False
    vf = float(d.get("vf_coef"))
    d.config["ppo.vf_coef"] = 2.0 * vf
    d.notes.append(
        f"ppo.vf_coef={2.0 * vf!r} is the zoo's vf_coef {vf!r} doubled: SB3's value loss is "
        "F.mse_loss, snnkart's 0.5 * the mean squared error"
    )
    d.config["ppo.clip_vloss"] = False
    for key, why in _SB3_ONLY.items():
        if (value := d.get(key)) is not None:
            d.unexpressible.append(f"{key} {value!r}: {why}")


def _normalize_keys(d: _Draft) -> None:
    """The zoo's ``normalize`` (``true``, or VecNormalize's keyword arguments)."""
    normalize = d.get("normalize")
    given = isinstance(normalize, (str, Mapping))  # VecNormalize's keyword arguments
    kwargs = _policy_kwargs("normalize", normalize) if given else {}
    if not (given or normalize):
        d.config["ppo.norm_obs"] = False
        return
    opts = {**VEC_NORMALIZE_DEFAULTS, **kwargs}
    d.config["ppo.norm_obs"] = bool(opts["norm_obs"])
    if opts["norm_obs"]:
        d.config["ppo.clip_obs"] = float(opts["clip_obs"])  # type: ignore[arg-type]
    d.config["ppo.norm_reward"] = bool(opts["norm_reward"])
    if opts["norm_reward"]:
        d.config["ppo.clip_reward"] = float(opts["clip_reward"])  # type: ignore[arg-type]
    for key in sorted(set(kwargs) - {"norm_obs", "norm_reward", "clip_obs", "clip_reward"}):
        d.unexpressible.append(f"normalize {key}={kwargs[key]!r}: no snnkart equivalent")


def _policy_kwargs(key: str, value: object) -> dict[str, object]:
    """A zoo keyword-argument string (``dict(log_std_init=-2, activation_fn=nn.ReLU)``) read with
    :mod:`ast`, which executes nothing (the zoo ``eval``s it): ``nn.ReLU`` becomes ``"nn.ReLU"``."""
    if isinstance(value, Mapping):
        return dict(value)
    try:
        parsed = _literal(ast.parse(str(value).strip(), mode="eval").body)
    except (SyntaxError, ValueError) as exc:
        raise ConfigError(f"zoo {key} {value!r}: not a dict(...) to read ({exc})") from None
    if not isinstance(parsed, dict):
        raise ConfigError(f"zoo {key} {value!r}: expected dict(...)")
    return parsed


def _literal(node: ast.expr) -> object:
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "dict":
        if node.args or any(kw.arg is None for kw in node.keywords):
            raise ValueError("dict(...) with positional or ** arguments")
        return {str(kw.arg): _literal(kw.value) for kw in node.keywords}
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
        return f"{node.value.id}.{node.attr}"
    if isinstance(node, (ast.List, ast.Tuple)):
        return [_literal(e) for e in node.elts]
    return ast.literal_eval(node)


def _arch_keys(d: _Draft, kw: Mapping[str, object]) -> None:
    """The widths and activation of the actor and critic."""
    arch = d.get("net_arch", kw)
    if isinstance(arch, list) and arch and isinstance(arch[0], Mapping):
        arch = arch[0]  # the old [dict(pi=..., vf=...)] form, as SB3 reads it
    pi, vf = (list(arch["pi"]), list(arch["vf"])) if isinstance(arch, Mapping) else (arch, arch)
    d.config["ann.hidden"] = [int(n) for n in pi]
    if pi != vf:
        d.unexpressible.append(
            f"net_arch pi={pi} vf={vf}: snnkart's actor and critic share ann.hidden (set to the "
            f"actor's {pi})"
        )
    activation = str(d.get("activation_fn", kw)).removeprefix("nn.").lower()
    if activation in get_args(ANNConfig.model_fields["activation"].annotation):
        d.config["ann.activation"] = activation
    else:
        d.unexpressible.append(f"activation_fn {activation!r}: ann.activation is tanh or relu")


def _net_keys(d: _Draft) -> None:
    """The policy network: its kind, widths, activation, init, gSDE and initial log std."""
    d.used |= {"policy", "policy_kwargs"}
    if d.values.get("policy", "MlpPolicy") != "MlpPolicy":
        d.unexpressible.append(f"policy {d.values['policy']!r}: snnkart's MLPs are an MlpPolicy")
    kw = _policy_kwargs("policy_kwargs", d.values.get("policy_kwargs") or {})
    _arch_keys(d, kw)
    if not d.get("ortho_init", kw):
        d.unexpressible.append(
            "ortho_init=False: SB3 keeps PyTorch's default Linear init; snnkart's MLPs are always "
            "orthogonal (gain sqrt(2), 0.01 on the policy head, 1 on the value head)"
        )
    log_std = float(d.get("log_std_init", kw))
    if d.get("use_sde"):
        freq = d.get("sde_sample_freq")
        sample = "drawn once per rollout" if freq <= 0 else f"drawn every {freq} steps"
        d.unexpressible.append(
            f"use_sde: gSDE, state-dependent noise {sample}, log_std_init {log_std:g} the log "
            "std of its noise matrix; snnkart's Gaussian has a state-independent log std, and "
            "ppo.init_log_std is left unset (no value of it is the same)"
        )
    else:
        d.config["ppo.init_log_std"] = log_std
    for key in sorted(set(kw) - set(SB3_POLICY_DEFAULTS)):
        d.unexpressible.append(f"policy_kwargs {key}={kw[key]!r}: no snnkart equivalent")


def to_snnkart(settings: ZooSettings) -> ZooTranslation:
    """``settings`` as snnkart's training-config keys, with what does not carry over.

    ``num_minibatches`` is ``n_envs * n_steps / batch_size``; a ``lin_`` learning rate is
    ``anneal_lr`` (linear to 0), a constant one ``anneal_lr=false``; ``normalize: true`` is
    ``norm_obs`` (its reward half is listed as unexpressible); ``net_arch``, ``activation_fn``
    and ``log_std_init`` are ``ann.hidden``, ``ann.activation`` and ``ppo.init_log_std``.
    """
    d = _Draft(settings.values)
    _run_keys(d, settings.env_id)
    _loss_keys(d)
    _normalize_keys(d)
    _net_keys(d)
    for key in sorted(set(d.values) - d.used):
        d.unexpressible.append(f"{key} = {d.values[key]!r}: no snnkart equivalent")
    notes = [*([settings.note] if settings.note else []), *d.notes, *COMMON_NOTES]
    config = MappingProxyType(dict(d.config))
    return ZooTranslation(settings, config, (*d.unexpressible,), (*notes,), (*d.defaulted,))


def as_overrides(translation: ZooTranslation) -> list[str]:
    """The translated keys as ``snnkart train --set`` arguments, ``key=<TOML value>``
    (``ppo.gamma=0.98``, ``ann.hidden=[256, 256]``, ``ann.activation="relu"``)."""
    # JSON's numbers, true/false, strings and lists of them are TOML values too
    return [f"{k}={json.dumps(v, allow_nan=False)}" for k, v in translation.config.items()]
