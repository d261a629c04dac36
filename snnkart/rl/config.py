"""Training configuration: one frozen, validated record, from defaults, a TOML file and the CLI.

The resolved config is written into every run directory (``config.toml``) and is what
``--resume``, ``eval`` and ``replay`` read back. Unknown keys are errors that name the key.
"""

from __future__ import annotations

import sys
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
    field_validator,
    model_validator,
)

from snnkart.envs import resolve_env_name
from snnkart.envs.spec import make_env
from snnkart.errors import ConfigError, did_you_mean
from snnkart.rl.bc_config import BCConfig
from snnkart.rl.config_defaults import ENV_POLICY_DEFAULTS, POLICY_DEFAULTS
from snnkart.rl.config_names import renamed_keys
from snnkart.rl.sdnn_config import SDNNConfig
from snnkart.rl.stateful_config import stateful_problem

if TYPE_CHECKING:
    from snnkart.envs.tracks import Track

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

CONFIG_SCHEMA = "snnkart/train-config/v1"


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class PPOConfig(_Section):
    """PPO hyperparameters (CleanRL / Stable-Baselines3 names)."""

    num_envs: int = Field(8, ge=1, description="parallel envs (gymnasium SyncVectorEnv)")
    rollout_steps: int = Field(
        256,
        ge=1,
        description="rollout steps per env per iteration (was ppo.num_steps, a name it shared "
        "with snn.num_steps, the SNN's T)",
    )
    learning_rate: float = Field(3e-4, ge=0.0, description="0 trains nothing (a control)")
    anneal_lr: bool = True
    gamma: float = Field(0.995, gt=0.0, le=1.0, description="0.995: a ~3 s horizon at 60 Hz")
    gae_lambda: float = Field(0.95, ge=0.0, le=1.0)
    update_epochs: int = Field(10, ge=1)
    num_minibatches: int = Field(8, ge=1)
    clip_coef: float = Field(0.2, gt=0.0)
    clip_vloss: bool = False
    ent_coef: float = Field(0.01, ge=0.0)
    anneal_ent: bool = Field(
        True,
        description="entropy coefficient to 0 with the learning rate: explore early, end sharp, "
        "so the deterministic (argmax) policy drives like the sampled one",
    )
    vf_coef: float = Field(0.5, ge=0.0)
    max_grad_norm: float = Field(0.5, gt=0.0)
    target_kl: float | None = Field(None, gt=0.0, description="stop the epochs early above this")
    norm_adv: bool = True
    norm_obs: bool = Field(True, description="running mean/std observation normalisation")
    clip_obs: float = Field(10.0, gt=0.0)
    init_log_std: float = Field(-0.5, description="continuous actions: initial log std")
    start_spread: float = Field(
        0.0,
        ge=0.0,
        lt=1.0,
        description="share of training episodes that start just past a random checkpoint "
        "instead of at the spawn (not laps; see snnkart.envs.starts)",
    )


class ANNConfig(_Section):
    """The MLPs: the ANN policy's actor and critic, and the SNN policy's critic (width only)."""

    hidden: tuple[int, ...] = (128, 128)
    activation: Literal["tanh", "relu"] = Field(
        "tanh", description="the ANN policy's hidden activation, actor and critic (the SNN's "
        "critic stays tanh); relu: what a sigma-delta or int8 chip computes exactly"
    )  # fmt: skip


MAX_SPIKING_LAYERS = 3
"""The spiking layers an actor may have (the export and both backends map 1 to 3)."""


class SNNConfig(_Section):
    """Spiking actor: encoding, one to three LIF layers, linear readout of mean spike counts."""

    num_steps: int = Field(8, ge=1, description="T: SNN time steps per env step")
    hidden: tuple[int, ...] = Field(
        (64, 64), description="sizes of the spiking layers: 1 to 3 layers, e.g. [64, 64]"
    )
    neuron: Literal["lif", "cuba"] = Field(
        "lif",
        description="lif: snntorch Leaky; cuba: current-based LIF (snntorch Synaptic: a "
        "synaptic current decaying by alpha feeds the membrane; Lava's and Loihi's LIF)",
    )
    alpha: float = Field(0.5, ge=0.0, lt=1.0, description="cuba: synaptic current decay")
    learn_alpha: bool = False
    hidden_bias: bool = Field(
        True,
        description="biases on the synapses between spiking layers (default: off for cuba, "
        "whose NIR bias feeds the decaying current, which Lava's LIF cannot: it adds its bias "
        "to the voltage)",
    )
    beta: float = Field(0.9, ge=0.0, lt=1.0, description="membrane decay per SNN step")
    threshold: float = Field(1.0, gt=0.0)
    learn_beta: bool = False
    learn_threshold: bool = False
    surrogate_slope: float = Field(25.0, gt=0.0, description="fast-sigmoid slope k")
    encoding: Literal["current", "rate", "population"] = "current"
    population: int = Field(
        8, ge=2, description="population encoding: Gaussian receptive fields per observation"
    )
    rate_reg: float = Field(0.0, ge=0.0, description="penalty weight on the mean firing rate")
    rate_reg_warmup: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="fraction of training over which the firing-rate penalty ramps up linearly "
        "from 0 to rate_reg (0: the full penalty from the start), so the policy learns to "
        "drive before it is made sparse",
    )
    init_gain: float = Field(
        2.0, gt=0.0, description="scale of the spiking layers' initial weights"
    )
    fused: bool = Field(
        True, description="use the fused LIF kernel in training and evaluation (tested equal)"
    )
    stateful: bool = Field(
        False, description="membranes carry across env steps (docs/stateful.md; recurrent PPO)"
    )

    @field_validator("hidden")
    @classmethod
    def _one_to_three_layers(cls, hidden: tuple[int, ...]) -> tuple[int, ...]:
        if not 1 <= len(hidden) <= MAX_SPIKING_LAYERS or min(hidden) < 1:
            raise ValueError(
                f"snn.hidden must list 1 to {MAX_SPIKING_LAYERS} layer sizes >= 1, got "
                f"{list(hidden)}"
            )
        return hidden


class StopConfig(_Section):
    """Stopping a run before ``total_steps`` once it has learned (off unless ``finishes`` is
    set): after ``finishes`` finished training episodes, every ``every`` env steps the
    deterministic policy drives ``episodes`` seeded evaluation episodes, and the run stops
    once ``checks`` checks in a row reach ``success``. The learning-rate schedule still
    spans ``total_steps``, so a stopped run trained exactly as the uncapped run did."""

    finishes: int | None = Field(None, ge=1, description="finished episodes before checking")
    success: float = Field(0.8, gt=0.0, le=1.0, description="eval success rate to reach")
    every: int = Field(50_000, ge=1, description="env steps between checks")
    checks: int = Field(2, ge=1, description="consecutive checks at or above success")
    episodes: int = Field(20, ge=1, description="evaluation episodes per check")
    seed: int = Field(90_000, description="the checks' episodes use seeds seed, seed+1, ...")


class EvalConfig(_Section):
    """Periodic evaluation during training (off unless ``every_steps`` > 0): every
    ``every_steps`` env steps the deterministic policy drives ``episodes`` seeded episodes
    (as the ``stop`` checks do: nothing is drawn from training's generators) and the run keeps
    the best policy so far in ``best.pt``: the highest success rate, ties by mean return."""

    every_steps: int = Field(0, ge=0, description="env steps between evaluations (0: none)")
    episodes: int = Field(10, ge=1, description="evaluation episodes per evaluation")
    seed: int = Field(80_000, description="the episodes use seeds seed, seed+1, ...")


class RunConfig(_Section):
    checkpoint_every: int = Field(10, ge=1, description="iterations between checkpoints")
    trajectories: bool = Field(True, description="record kart positions for replay")
    torch_threads: int = Field(1, ge=1)
    tensorboard: bool = True


def _merge_defaults(data: dict[str, Any], defaults: dict[str, dict[str, Any]]) -> dict[str, Any]:
    for section, values in defaults.items():
        given = data.get(section)
        if not isinstance(given, BaseModel):
            data = {**data, section: {**values, **(given or {})}}
    return data


class TrainConfig(BaseModel):
    """Everything that defines a training run."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    schema_: str = Field(CONFIG_SCHEMA, alias="schema")
    env: str = "steer"
    track: str = "small_S"
    action_mode: Literal["discrete", "continuous"] = "discrete"
    policy: Literal["ann", "snn", "sdnn"] = "snn"
    total_steps: int = Field(300_000, ge=1)
    seed: int = 1
    env_config: dict[str, Any] = Field(default_factory=dict)
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
        for defaults in (
            POLICY_DEFAULTS.get(policy, {}),
            ENV_POLICY_DEFAULTS.get((env, policy), {}),
        ):
            data = _merge_defaults(data, defaults)
        snn_cfg = data.get("snn")
        if isinstance(snn_cfg, dict) and snn_cfg.get("neuron") == "cuba":
            data = {**data, "snn": {"hidden_bias": False, **snn_cfg}}
        return data

    @model_validator(mode="after")
    def _check(self) -> TrainConfig:
        object.__setattr__(self, "env", resolve_env_name(self.env))
        batch = self.ppo.num_envs * self.ppo.rollout_steps
        if batch < self.ppo.num_minibatches:
            raise ValueError(
                f"ppo.num_envs * ppo.rollout_steps = {batch} is smaller than "
                f"ppo.num_minibatches = {self.ppo.num_minibatches}"
            )
        if self.snn.stateful and self.policy == "snn":
            stateful_problem(self)
        return self

    @property
    def batch_size(self) -> int:
        return self.ppo.num_envs * self.ppo.rollout_steps

    def make_env(
        self, render_mode: str | None = None, track: str | Path | Track | None = None
    ) -> gym.Env:
        """The env of this config; ``track`` (e.g. the one embedded in a checkpoint) instead
        of ``self.track``."""
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


def _lists(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _lists(v) for k, v in obj.items()}
    if isinstance(obj, tuple):
        return [_lists(v) for v in obj]
    return obj


def _set_dotted(data: dict[str, Any], key: str, value: Any) -> None:
    parts = key.split(".")
    node = data
    for p in parts[:-1]:
        node = node.setdefault(p, {})
        if not isinstance(node, dict):
            raise ConfigError(f"--set {key}: {p!r} is not a section")
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
    overrides: dict[str, Any] | None = None,
    sets: list[str] | None = None,
) -> TrainConfig:
    """Defaults <- TOML file <- ``overrides`` (CLI flags) <- ``sets`` (``--set key=value``)."""
    data: dict[str, Any] = {}
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
    data: dict[str, Any], source: str = "config", *, resolved: bool = False
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
