"""Training configuration: one frozen, validated record, from defaults, a TOML file and the CLI.

The resolved config is written into every run directory (``config.toml``) and is what
``--resume``, ``eval`` and ``replay`` read back. Unknown keys are errors that name the key.
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, get_args

import gymnasium as gym
import tomli_w
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    create_model,
    field_validator,
    model_validator,
)

from snnkart.envs import resolve_env_name
from snnkart.envs.resolve import resolve_env
from snnkart.envs.spec import make_env
from snnkart.envs.task_env import make_gym_env
from snnkart.errors import ConfigError, did_you_mean
from snnkart.rl import kinds
from snnkart.rl.bc_config import BCConfig
from snnkart.rl.config_names import renamed_keys
from snnkart.rl.sections import (
    ANNConfig,
    EvalConfig,
    PPOConfig,
    RunConfig,
    SNNConfig,
    StopConfig,
)
from snnkart.rl.sigma_delta_config import SDNNConfig

if TYPE_CHECKING:
    from snnkart.envs.tracks import Track

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

CONFIG_SCHEMA = "snnkart/train-config/v1"


def _merge_defaults(data: dict[str, Any], defaults: dict[str, dict[str, Any]]) -> dict[str, Any]:
    for section, values in defaults.items():
        given = data.get(section)
        if not isinstance(given, BaseModel):
            data = {**data, section: {**values, **(given or {})}}
    return data


class _TrainConfig(BaseModel):
    """Everything that defines a training run (and every kind's own section: :data:`TrainConfig`)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    schema_: str = Field(CONFIG_SCHEMA, alias="schema")
    env: str = Field(
        "steer",
        description="a kart env (grid, gazebo, steer), a gymnasium id (CartPole-v1), "
        "'module:EnvId-v0' or 'package.module:ClassName'",
    )
    env_kwargs: dict[str, object] = Field(
        default_factory=dict, description="keyword arguments of a gymnasium env's make"
    )
    track: str = "small_S"
    action_mode: Literal["discrete", "continuous"] = "discrete"
    policy: str = Field("snn", description="the policy kind (snnkart.rl.kinds)")
    total_steps: int = Field(300_000, ge=1)
    seed: int = 1
    env_config: dict[str, object] = Field(default_factory=dict)
    ppo: PPOConfig = PPOConfig()
    ann: ANNConfig = ANNConfig()
    snn: SNNConfig = SNNConfig()
    sdnn: SDNNConfig = SDNNConfig()
    run: RunConfig = RunConfig()
    stop: StopConfig = StopConfig()
    eval: EvalConfig = EvalConfig()
    bc: BCConfig | None = Field(None, description="behaviour-cloning warm start (off: none)")

    @model_validator(mode="before")
    @classmethod
    def _policy_defaults(cls, data: Any, info: ValidationInfo) -> Any:
        """Defaults that differ by policy kind (and env), applied only where the user set nothing.

        Not to a run's saved config: it is resolved already, and a key it lacks was added after
        it was saved, so the run trained with that key's plain default, not with a per-env one.
        """
        if not isinstance(data, dict):
            return data
        resolved = bool((info.context or {}).get("resolved"))
        data = renamed_keys(data, warn=not resolved)
        if resolved:
            return data
        policy = str(data.get("policy", "snn"))
        try:
            env = resolve_env_name(str(data.get("env", "steer")))
        except ValueError:
            env = ""  # reported by the field validation below
        if policy in kinds.REGISTRY:  # an unknown kind is reported by the field validation
            declared = kinds.kind(policy)
            for defaults in (declared.defaults, declared.env_defaults.get(env, {})):
                data = _merge_defaults(data, defaults)
        snn_cfg = data.get("snn")
        if isinstance(snn_cfg, dict) and snn_cfg.get("neuron") == "cuba":
            data = {**data, "snn": {"hidden_bias": False, **snn_cfg}}
        return data

    @field_validator("policy")
    @classmethod
    def _known_kind(cls, policy: str) -> str:
        kinds.entry(policy)
        return policy

    @model_validator(mode="after")
    def _check(self) -> _TrainConfig:
        ref = resolve_env(self.env)
        object.__setattr__(self, "env", resolve_env_name(self.env) if ref.kart else ref.name)
        if not ref.kart:
            for what, on in (("stop.finishes", self.stop.finishes), ("bc", self.bc)):
                if on is not None:
                    raise ValueError(
                        f"{what} needs a kart env (finished laps, a recorded driver); "
                        f"{self.env!r} is a gymnasium env: leave {what} unset"
                    )
            if self.eval.every_steps:
                raise ValueError(
                    f"eval.every_steps needs a kart env for now; {self.env!r} is a gymnasium "
                    "env: set eval.every_steps = 0 and run snnkart eval on the checkpoints"
                )
        batch = self.ppo.num_envs * self.ppo.rollout_steps
        if batch < self.ppo.num_minibatches:
            raise ValueError(
                f"ppo.num_envs * ppo.rollout_steps = {batch} is smaller than "
                f"ppo.num_minibatches = {self.ppo.num_minibatches}"
            )
        kinds.kind(self.policy).check(self)
        return self

    @property
    def kart(self) -> bool:
        """Whether the env is one of snnkart's kart envs (tracks, laps), not any gymnasium env."""
        return resolve_env(self.env).kart

    @property
    def batch_size(self) -> int:
        return self.ppo.num_envs * self.ppo.rollout_steps

    def make_env(
        self, render_mode: str | None = None, track: str | Path | Track | None = None
    ) -> gym.Env:
        """The env of this config; ``track`` (e.g. the one embedded in a checkpoint) instead
        of ``self.track``. A gymnasium env takes ``env_kwargs`` and no track."""
        ref = resolve_env(self.env)
        if not ref.kart:
            return make_gym_env(ref, self.env_kwargs, render_mode)
        return make_env(
            self.env,
            self.track if track is None else track,
            action_mode=self.action_mode,
            config=self.env_config or None,
            render_mode=render_mode,
        )

    def to_toml(self) -> str:
        data = self.model_dump(by_alias=True, exclude_none=True)
        return tomli_w.dumps(_lists(data))


def _with_kind_sections(base: type[_TrainConfig]) -> type[_TrainConfig]:
    """``base`` with a section for every kind that declares one of its own (``[rsnn]``)."""
    sections: dict[str, tuple[type, object]] = {
        k.name: (k.section, k.section())
        for k in kinds.all_kinds()
        if k.section is not None and k.name not in base.model_fields
    }
    if not sections:
        return base
    return create_model(  # type: ignore[no-any-return,call-overload]
        "TrainConfig", __base__=base, __module__=__name__, __doc__=base.__doc__, **sections
    )


if TYPE_CHECKING:
    TrainConfig = _TrainConfig
else:
    TrainConfig = _with_kind_sections(_TrainConfig)


def _lists(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _lists(v) for k, v in obj.items()}
    if isinstance(obj, tuple):
        return [_lists(v) for v in obj]
    return obj


def _set_dotted(data: dict[str, object], key: str, value: object) -> None:
    parts = key.split(".")
    node = data
    for p in parts[:-1]:
        child = node.setdefault(p, {})
        if not isinstance(child, dict):
            raise ConfigError(f"--set {key}: {p!r} is not a section")
        node = child
    node[parts[-1]] = value


def parse_override(text: str) -> tuple[str, Any]:
    """Parse ``key=value`` with a TOML value (``ppo.learning_rate=3e-4``, ``snn.hidden=[64,64]``)."""
    if "=" not in text:
        raise ConfigError(f"--set {text!r}: expected KEY=VALUE, e.g. ppo.learning_rate=3e-4")
    key, raw = (s.strip() for s in text.split("=", 1))
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw  # bare words are strings: policy=snn
    return key, value


def load_config(
    path: str | Path | None = None,
    overrides: Mapping[str, object] | None = None,
    sets: list[str] | None = None,
) -> TrainConfig:
    """Defaults <- TOML file <- ``overrides`` (CLI flags) <- ``sets`` (``--set key=value``)."""
    data: dict[str, object] = {}
    if path is not None:
        p = Path(path)
        if not p.is_file():
            raise ConfigError(f"config file {p} does not exist")
        try:
            data = tomllib.loads(p.read_text("utf-8"))
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"{p}: not valid TOML: {exc}") from exc
    for key, value in (overrides or {}).items():
        if value is not None:
            _set_dotted(data, key, value)
    for text in sets or []:
        _set_dotted(data, *parse_override(text))
    return validate_config(data, source=str(path) if path else "command line")


def config_keys() -> list[str]:
    """Every key a config takes, dotted (``ppo.learning_rate``, ``seed``)."""
    keys = []
    for name, info in TrainConfig.model_fields.items():
        section = next(
            (a for a in get_args(info.annotation) if a is not type(None)), info.annotation
        )
        if isinstance(section, type) and issubclass(section, BaseModel):
            keys += [f"{name}.{key}" for key in section.model_fields]
        else:
            keys.append(info.alias or name)
    return keys


def read_run_config(run_dir: str | Path) -> TrainConfig:
    """The resolved training config saved in a run directory."""
    path = Path(run_dir) / "config.toml"
    if not Path(run_dir).exists():
        raise ConfigError(f"{run_dir} does not exist; pass the --out of a training run")
    if not path.is_file():
        raise ConfigError(
            f"{run_dir} is not a run directory (no config.toml); pass the --out of a training run"
        )
    return validate_config(tomllib.loads(path.read_text()), str(path), resolved=True)


def validate_config(
    data: Mapping[str, object], source: str = "config", *, resolved: bool = False
) -> TrainConfig:
    """`data` as a TrainConfig; `resolved`: a run's saved config, given every key it had."""
    try:
        return TrainConfig.model_validate(data, context={"resolved": resolved})
    except ValidationError as exc:
        lines = []
        for err in exc.errors():
            loc = ".".join(str(x) for x in err["loc"])
            if err["type"] == "extra_forbidden":
                near = did_you_mean(loc, config_keys()).strip(" ()")
                lines.append(f"unknown key {loc!r} (misspelled?{' ' + near if near else ''})")
            else:
                msg = err["msg"].removeprefix("Value error, ")
                if err["type"] == "literal_error":
                    msg += f", not {err['input']!r}"
                lines.append(f"{loc}: {msg}" if loc else msg)
        raise ConfigError(f"{source}: invalid training config: " + "; ".join(lines)) from None
    except ValueError as exc:
        raise ConfigError(f"{source}: {exc}") from None
