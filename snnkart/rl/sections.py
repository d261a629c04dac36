"""The sections of a training config that policies and kinds read: PPO, the MLPs, the spiking
actor, stopping, periodic evaluation and the run's own settings. :mod:`snnkart.rl.config` puts
them (and every kind's own section) together into :class:`~snnkart.rl.config.TrainConfig`; the
kinds (:mod:`snnkart.rl.kinds`) read only these, so they do not depend on the whole config.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator


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
    norm_reward: bool = Field(
        False,
        description="reward scaling as Stable-Baselines3's VecNormalize: each reward divided by "
        "the running std of the discounted return (ppo.gamma), clipped to +-clip_reward",
    )
    clip_reward: float = Field(10.0, gt=0.0)
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
        "tanh",
        description="the ANN policy's hidden activation, actor and critic (the SNN's "
        "critic stays tanh); relu: what a sigma-delta or int8 chip computes exactly",
    )


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
