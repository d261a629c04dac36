"""Actor-critic policies for PPO: an MLP (ANN) and a spiking actor (SNN, snntorch); the
sigma-delta actor (SDNN) is :mod:`snnkart.rl.sdnn`'s, its policy here.

All share one interface, :class:`ActorCritic`, so the PPO loop does not know which it trains.
The critic is always an MLP: it never leaves the host. The spiking actor is built for
deployment on Lava (docs/deployment.md): reset-to-zero LIF neurons, one
beta and one threshold per layer, membranes reset at every env step, no recurrence; or, with
``snn.stateful``, membranes that carry across env steps (:class:`StatefulSNNPolicy`).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
import torch
from torch import nn
from torch.distributions import Categorical, Normal

from snnkart.contract.encoding import population_centres
from snnkart.envs.base import KartEnv
from snnkart.rl.config import ANNConfig, SNNConfig, TrainConfig
from snnkart.rl.sdnn import SigmaDeltaActor, changed_share, message_proxy
from snnkart.rl.sdnn_config import SDNNConfig
from snnkart.rl.spiking import SpikingActor, layer_init
from snnkart.rl.stateful import state_size, stream_sequence, stream_step
from snnkart.rl.stateful_lif import fused_stream_sequence

BETA_MAX = 0.999
"""Upper clamp of a learnable beta: beta = 1 would export an infinite NIR time constant."""
THRESHOLD_MIN = 1e-3


ACTIVATIONS: dict[str, type[nn.Module]] = {"tanh": nn.Tanh, "relu": nn.ReLU}
"""The hidden activations an MLP may have, by their ``ann.activation`` name."""


def mlp(sizes: list[int], out_std: float, activation: str = "tanh") -> nn.Sequential:
    """Linear -> activation -> ... -> Linear, the last layer initialised with ``out_std``."""
    layers: list[nn.Module] = []
    for a, b in itertools.pairwise(sizes[:-1]):
        layers += [layer_init(nn.Linear(a, b)), ACTIVATIONS[activation]()]
    layers.append(layer_init(nn.Linear(sizes[-2], sizes[-1]), std=out_std))
    return nn.Sequential(*layers)


@dataclass
class PolicyOutput:
    action: torch.Tensor
    log_prob: torch.Tensor
    entropy: torch.Tensor
    value: torch.Tensor
    input_spikes: torch.Tensor | None  # rate encoding: the sampled input trains [B, T, n_in]
    rates: torch.Tensor | None  # SNN: mean firing rate per layer [n_layers]
    state: torch.Tensor | None = None  # stateful SNN: the actor's state after this step


class ActorCritic(nn.Module):
    """Common part: action distribution, critic, observation scaling for the actor."""

    kind = "base"
    critic: nn.Module

    def __init__(
        self, obs_dim: int, action_dim: int, discrete: bool, init_log_std: float = -0.5
    ) -> None:
        super().__init__()
        self.obs_dim = obs_dim
        self.action_dim = action_dim
        self.discrete = discrete
        if not discrete:
            self.log_std = nn.Parameter(torch.full((action_dim,), float(init_log_std)))

    def actor_output(
        self, obs: torch.Tensor, raw_obs: torch.Tensor, input_spikes: torch.Tensor | None
    ) -> tuple[torch.Tensor, torch.Tensor | None, torch.Tensor | None]:
        """Logits (discrete) or action means (continuous), plus SNN extras."""
        raise NotImplementedError

    def value(self, obs: torch.Tensor) -> torch.Tensor:
        return self.critic(obs).squeeze(-1)

    def distribution(self, out: torch.Tensor) -> Categorical | Normal:
        if self.discrete:
            return Categorical(logits=out, validate_args=False)
        return Normal(out, self.log_std.exp().expand_as(out), validate_args=False)

    def forward(
        self,
        obs: torch.Tensor,
        raw_obs: torch.Tensor,
        action: torch.Tensor | None = None,
        input_spikes: torch.Tensor | None = None,
    ) -> PolicyOutput:
        """``obs`` is normalised (critic, ANN actor); ``raw_obs`` is the env's observation."""
        out, spikes, rates = self.actor_output(obs, raw_obs, input_spikes)
        return self.output(out, obs, action, spikes, rates)

    def output(
        self,
        out: torch.Tensor,
        obs: torch.Tensor,
        action: torch.Tensor | None,
        spikes: torch.Tensor | None,
        rates: torch.Tensor | None,
        state: torch.Tensor | None = None,
    ) -> PolicyOutput:
        """The action distribution of the actor's ``out``, a sample of it unless ``action`` is
        given, its log-probability, entropy and the critic's value of ``obs``."""
        dist = self.distribution(out)
        if action is None:
            action = dist.sample()
        log_prob = dist.log_prob(action)
        entropy = dist.entropy()
        if not self.discrete:
            log_prob, entropy = log_prob.sum(-1), entropy.sum(-1)
        return PolicyOutput(action, log_prob, entropy, self.value(obs), spikes, rates, state)

    @torch.no_grad()
    def act_deterministic(
        self, obs: torch.Tensor, raw_obs: torch.Tensor, input_spikes: torch.Tensor | None = None
    ) -> torch.Tensor:
        out, _, rates = self.actor_output(obs, raw_obs, input_spikes)
        self.last_rates = None if rates is None else rates.detach()  # the side panel's
        return out.argmax(-1) if self.discrete else out

    def clamp_parameters(self) -> None:
        """Keep learnable neuron parameters in their valid range (after an optimiser step)."""


class ANNPolicy(ActorCritic):
    """MLP actor and critic (the original used 128-128 ReLU; here tanh as in CleanRL, or ReLU
    with ``ann.activation = "relu"``, for both)."""

    kind = "ann"

    def __init__(
        self, obs_dim: int, action_dim: int, discrete: bool, cfg: ANNConfig, init_log_std: float
    ) -> None:
        super().__init__(obs_dim, action_dim, discrete, init_log_std)
        sizes = [obs_dim, *cfg.hidden]
        self.actor = mlp([*sizes, action_dim], out_std=0.01, activation=cfg.activation)
        self.critic = mlp([*sizes, 1], out_std=1.0, activation=cfg.activation)

    def actor_output(self, obs, raw_obs, input_spikes):  # type: ignore[no-untyped-def]
        return self.actor(obs), None, None


class SNNPolicy(ActorCritic):
    """Spiking actor (:class:`SpikingActor`) with an MLP critic on normalised observations."""

    kind = "snn"
    obs_low: torch.Tensor
    obs_span: torch.Tensor
    centres: torch.Tensor

    def __init__(
        self,
        obs_dim: int,
        action_dim: int,
        discrete: bool,
        cfg: SNNConfig,
        critic_hidden: tuple[int, ...],
        obs_low: np.ndarray,
        obs_high: np.ndarray,
        init_log_std: float,
    ) -> None:
        super().__init__(obs_dim, action_dim, discrete, init_log_std)
        self.cfg = cfg
        n_in = obs_dim * cfg.population if cfg.encoding == "population" else obs_dim
        self.snn = SpikingActor(n_in, action_dim, cfg)
        self.critic = mlp([obs_dim, *critic_hidden, 1], out_std=1.0)
        self.register_buffer("obs_low", torch.as_tensor(obs_low, dtype=torch.float32))
        self.register_buffer("obs_span", torch.as_tensor(obs_high - obs_low, dtype=torch.float32))
        # the receptive fields' centres (population encoding): fixed, so not in the state dict
        centres = (
            population_centres(cfg.population)
            if cfg.encoding == "population"
            else np.zeros(0, dtype=np.float32)
        )
        self.register_buffer("centres", torch.as_tensor(centres), persistent=False)

    def scale01(self, raw_obs: torch.Tensor) -> torch.Tensor:
        return (raw_obs - self.obs_low) / self.obs_span

    def actor_input(self, obs: torch.Tensor, raw_obs: torch.Tensor) -> torch.Tensor:
        """What the spiking actor takes: the normalised observation (current encoding), the
        observation scaled to [0, 1] by its true bounds (rate: spike probabilities), or the
        population code of that (:func:`snnkart.contract.encoding.population`)."""
        if self.cfg.encoding == "current":
            return obs
        x01 = self.scale01(raw_obs)
        if self.cfg.encoding == "rate":
            return x01
        d = (x01.clamp(0.0, 1.0).unsqueeze(-1) - self.centres) * float(self.cfg.population - 1)
        return torch.exp(-0.5 * d * d).flatten(-2)  # exp: equal to numpy's up to the last bit

    def actor_output(self, obs, raw_obs, input_spikes):  # type: ignore[no-untyped-def]
        x = self.actor_input(obs, raw_obs)
        if self.cfg.encoding == "rate" and input_spikes is None:
            input_spikes = self.snn.encode(x)
        out, rates, _ = self.snn(x, input_spikes, fused=self.cfg.fused)
        return out, input_spikes, rates

    @torch.no_grad()
    def act_deterministic(
        self, obs: torch.Tensor, raw_obs: torch.Tensor, input_spikes: torch.Tensor | None = None
    ) -> torch.Tensor:
        was = self.training
        self.eval()
        try:
            return super().act_deterministic(obs, raw_obs, input_spikes)
        finally:
            self.train(was)

    def clamp_parameters(self) -> None:
        with torch.no_grad():
            for lif in self.snn.lifs:
                lif.beta.clamp_(0.0, BETA_MAX)
                lif.threshold.clamp_(min=THRESHOLD_MIN)
                if self.snn.cuba:
                    lif.alpha.clamp_(0.0, BETA_MAX)


class SDNNPolicy(ActorCritic):
    """Sigma-delta actor (:class:`SigmaDeltaActor`) with an MLP critic (tanh, ``ann.hidden``)
    on normalised observations; ``previous`` observations feed the message penalty."""

    kind = "sdnn"

    def __init__(
        self,
        obs_dim: int,
        action_dim: int,
        discrete: bool,
        cfg: SDNNConfig,
        critic_hidden: tuple[int, ...],
        clip_obs: float,
        init_log_std: float,
    ) -> None:
        super().__init__(obs_dim, action_dim, discrete, init_log_std)
        self.cfg = cfg
        self.sdnn = SigmaDeltaActor(obs_dim, action_dim, cfg, clip_obs)
        self.critic = mlp([obs_dim, *critic_hidden, 1], out_std=1.0)

    def actor_output(self, obs, raw_obs, input_spikes):  # type: ignore[no-untyped-def]
        return self.sdnn(obs)[0], None, None

    def message_proxy(self, obs: torch.Tensor, previous: torch.Tensor) -> torch.Tensor:
        """:func:`message_proxy` of the hidden layers between ``previous`` and ``obs``."""
        return message_proxy(self.sdnn(obs)[1], self.sdnn(previous)[1])

    @torch.no_grad()
    def message_rates(self, obs: torch.Tensor, previous: torch.Tensor) -> torch.Tensor:
        """:func:`changed_share` for the input, then each hidden layer ``[L + 1]``."""
        now = [self.sdnn.input_integers(obs), *self.sdnn(obs)[1]]
        before = [self.sdnn.input_integers(previous), *self.sdnn(previous)[1]]
        return changed_share(now, before)


class StatefulSNNPolicy(SNNPolicy):
    """A spiking actor whose membranes carry across env steps (``snn.stateful``): each env step
    is the Lava row stream of :mod:`snnkart.rl.stateful` from the state the last one left.

    ``forward`` takes the state ``[B, D]`` before this step (``state``), or with ``starts``
    ``[S, E]`` whole env sequences (``obs`` time-major ``[S * E, ...]``, ``state`` ``[E, D]``
    before step 0, zeroed where an episode starts), and returns the new state in
    :attr:`PolicyOutput.state`."""

    stateful = True

    def state_size(self) -> int:
        return state_size(tuple(self.cfg.hidden))

    def initial_state(self, batch: int) -> torch.Tensor:
        """The state at an episode's start: zero membranes, no spikes in flight."""
        return torch.zeros(batch, self.state_size())

    def actor_output(self, obs, raw_obs, input_spikes):  # type: ignore[no-untyped-def]
        raise TypeError("a stateful policy acts from a state: call it with state=")

    def forward(  # type: ignore[override]
        self,
        obs: torch.Tensor,
        raw_obs: torch.Tensor,
        action: torch.Tensor | None = None,
        input_spikes: torch.Tensor | None = None,
        state: torch.Tensor | None = None,
        starts: torch.Tensor | None = None,
    ) -> PolicyOutput:
        if state is None:
            raise TypeError("a stateful policy acts from a state: call it with state=")
        x = self.actor_input(obs, raw_obs)
        new: torch.Tensor | None
        if starts is None:
            out, rates, new = stream_step(self.snn, x, state)
        else:
            run = fused_stream_sequence if self.cfg.fused else stream_sequence
            out, rates, new = run(self.snn, x, state, starts)
        return self.output(out, obs, action, None, rates, new)

    @torch.no_grad()
    def act_from(
        self, obs: torch.Tensor, raw_obs: torch.Tensor, state: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The deterministic action (argmax or mean) from ``state``, and the new state."""
        was = self.training
        self.eval()
        try:
            out, rates, new = stream_step(self.snn, self.actor_input(obs, raw_obs), state)
        finally:
            self.train(was)
        self.last_rates = rates.detach()
        return (out.argmax(-1) if self.discrete else out), new


def build_policy(
    kind: str,
    obs_dim: int,
    action_dim: int,
    discrete: bool,
    ann: ANNConfig,
    snn_cfg: SNNConfig,
    obs_low: np.ndarray,
    obs_high: np.ndarray,
    init_log_std: float = -0.5,
    sdnn_cfg: SDNNConfig | None = None,
    clip_obs: float = 10.0,
) -> ActorCritic:
    if kind == "ann":
        return ANNPolicy(obs_dim, action_dim, discrete, ann, init_log_std)
    if kind == "snn":
        return (StatefulSNNPolicy if snn_cfg.stateful else SNNPolicy)(
            obs_dim, action_dim, discrete, snn_cfg, ann.hidden, obs_low, obs_high, init_log_std
        )
    if kind == "sdnn":
        cfg = sdnn_cfg or SDNNConfig()
        return SDNNPolicy(obs_dim, action_dim, discrete, cfg, ann.hidden, clip_obs, init_log_std)
    raise ValueError(f"unknown policy kind {kind!r}; choose ann, snn or sdnn")


def policy_for(cfg: TrainConfig, env: KartEnv) -> ActorCritic:
    space = env.action_space
    if isinstance(space, gym.spaces.Discrete):
        discrete, action_dim = True, int(space.n)
    elif isinstance(space, gym.spaces.Box):
        discrete, action_dim = False, int(space.low.shape[0])
    else:
        raise TypeError(f"unsupported action space {space}")
    obs_space = env.observation_space
    return build_policy(
        cfg.policy,
        int(obs_space.low.shape[0]),
        action_dim,
        discrete,
        cfg.ann,
        cfg.snn,
        obs_space.low.astype(np.float64),
        obs_space.high.astype(np.float64),
        cfg.ppo.init_log_std,
        cfg.sdnn,
        cfg.ppo.clip_obs,
    )
