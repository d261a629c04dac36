"""The protocol every policy kind implements (:class:`ActorCritic`), what a policy returns
(:class:`PolicyOutput`) and the MLP every kind's critic is. The kinds themselves:
:mod:`snnkart.rl.policies` (ANN, SNN, sigma-delta) and :mod:`snnkart.rl.kinds`."""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn
from torch.distributions import Categorical, Normal

from snnkart.errors import ExportError
from snnkart.rl.lif_nir import NIRGraph
from snnkart.rl.spiking import layer_init

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


@dataclass(frozen=True)
class BufferNeeds:
    """What a kind's rollout buffer holds beyond observations, actions and values."""

    input_spikes: bool = False  # the rate encoding's sampled input trains [steps, envs, T, n]
    previous: bool = False  # each step's previous observation (a message penalty's input)


class ActorCritic(nn.Module):
    """The protocol every policy kind implements (:mod:`snnkart.rl.kinds`): the action
    distribution, the critic, and what training, rollout, evaluation and export ask of a kind.

    Training and rollout never ask which kind a policy is: they call

    - :meth:`forward` (``state=`` and ``starts=`` when :attr:`carries_state`),
    - :meth:`buffer_needs` (extra rollout-buffer fields), :meth:`penalties` (extra loss terms
      and their weights), :meth:`rollout_stats` (what a rollout step records),
    - :meth:`initial_state`, :meth:`act` (a deterministic step for evaluation),
      :meth:`input_spikes` (the deployment contract's input draw), :meth:`layer_sizes`.
    """

    kind = "base"
    """The registry name of the kind that built it (:mod:`snnkart.rl.kinds`)."""
    carries_state = False
    """The actor's state runs across env steps (recurrent PPO: whole env sequences)."""
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

    # -- what training asks of a kind ------------------------------------------------------

    def buffer_needs(self) -> BufferNeeds:
        """The extra rollout-buffer fields this kind's loss or statistics need."""
        return BufferNeeds()

    def penalty_weights(self, progress: float) -> dict[str, float]:
        """The weight of each extra loss term at ``progress`` (0 at the start of training, 1
        at its end), by the term's name; empty: none."""
        return {}

    def penalties(
        self, out: PolicyOutput, obs: torch.Tensor, previous: torch.Tensor | None
    ) -> dict[str, torch.Tensor]:
        """Each extra loss term (unweighted) of a minibatch, by the names of
        :meth:`penalty_weights`."""
        return {}

    def rollout_stats(
        self, out: PolicyOutput, obs: torch.Tensor, previous: torch.Tensor | None
    ) -> dict[str, np.ndarray]:
        """What one rollout step records for the iteration's metrics (``rates``: mean firing
        rate per layer; ``messages``: a sigma-delta actor's message shares)."""
        return {} if out.rates is None else {"rates": out.rates.numpy()}

    def metrics(
        self, stats: dict[str, list[np.ndarray]], weights: dict[str, float]
    ) -> dict[str, float]:
        """An iteration's kind-specific metrics from its steps' :meth:`rollout_stats` and the
        penalty weights it trained with (names as in TensorBoard)."""
        return {}

    def initial_state(self, batch: int) -> torch.Tensor:
        """The actor's state at an episode's start (a kind that :attr:`carries_state`)."""
        raise NotImplementedError(f"a {self.kind} policy carries no state")

    # -- what evaluation asks of a kind ----------------------------------------------------

    def input_spikes(self, raw: np.ndarray, rng: np.random.Generator) -> torch.Tensor | None:
        """The input spike trains ``[1, T, n]`` of one env step under the deployment contract
        (a rate-encoded actor), or None: the input is not drawn."""
        return None

    @torch.no_grad()
    def act(
        self,
        obs: torch.Tensor,
        raw_obs: torch.Tensor,
        state: torch.Tensor | None,
        input_spikes: torch.Tensor | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """The deterministic action (argmax or mean) and the state after it (None for an actor
        that :attr:`carries_state` not; from its :meth:`initial_state` when ``state`` is None)."""
        if not self.carries_state:
            return self.act_deterministic(obs, raw_obs, input_spikes), None
        start = self.initial_state(obs.shape[0]) if state is None else state
        return self.act_from(obs, raw_obs, start)

    def act_from(
        self, obs: torch.Tensor, raw_obs: torch.Tensor, state: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The deterministic action from ``state`` and the new state (a kind that
        :attr:`carries_state`)."""
        raise NotImplementedError(f"a {self.kind} policy carries no state")

    def layer_sizes(self) -> tuple[int, ...]:
        """The spiking layers' sizes whose firing rates :attr:`last_rates` holds (empty: not a
        spiking actor)."""
        return ()

    # -- what export asks of a kind --------------------------------------------------------

    def relu_layers(self) -> tuple[list[nn.Linear], str]:
        """The actor as the affine layers of a ReLU network, and where they come from (a
        sigma-delta export's ``origin``); raise ExportError if it is not one."""
        raise ExportError(
            f"a {self.kind} policy is not a ReLU network; --sigma-delta converts a ReLU ANN run "
            "(train one with --policy ann --set ann.activation=relu) or exports a --policy sdnn run"
        )

    def nir_graph(self) -> NIRGraph:
        """The actor as a NIR graph with its layers' parameters (a kind of the LIF family)."""
        raise ExportError(f"a {self.kind} policy has no NIR graph of its own")
