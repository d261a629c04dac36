"""Actor-critic policies for PPO: an MLP (ANN) and a spiking actor (SNN, snntorch); the
sigma-delta actor (SDNN) is :mod:`snnkart.rl.sigma_delta`'s, its policy here.

All share one interface, :class:`ActorCritic`, so the PPO loop does not know which it trains.
The critic is always an MLP: it never leaves the host. The spiking actor is built for
deployment on Lava (docs/deployment.md): reset-to-zero LIF neurons, one
beta and one threshold per layer, membranes reset at every env step, no recurrence; or, with
``snn.stateful``, membranes that carry across env steps (:class:`StatefulSNNPolicy`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import nn

from snnkart.contract.encoding import population_centres, rate_probabilities, rate_spikes
from snnkart.errors import ExportError
from snnkart.rl.actor_critic import ActorCritic, BufferNeeds, PolicyOutput, mlp
from snnkart.rl.lif_nir import NIRGraph, lif_graph
from snnkart.rl.sections import ANNConfig, SNNConfig
from snnkart.rl.sigma_delta import SigmaDeltaActor, changed_share, message_proxy
from snnkart.rl.sigma_delta_config import SDNNConfig
from snnkart.rl.spiking import SpikingActor
from snnkart.rl.stateful import state_size, stream_sequence, stream_step
from snnkart.rl.stateful_lif import fused_stream_sequence

BETA_MAX = 0.999
"""Upper clamp of a learnable beta: beta = 1 would export an infinite NIR time constant."""
THRESHOLD_MIN = 1e-3


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
        self.activation = cfg.activation

    def relu_layers(self) -> tuple[list[nn.Linear], str]:
        if self.activation != "relu":
            raise ExportError(
                f"a {self.activation} ANN; only a ReLU ANN converts to sigma-delta: train with "
                "--set ann.activation=relu"
            )
        return [m for m in self.actor.modules() if isinstance(m, nn.Linear)], "ann-relu"

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

    def buffer_needs(self) -> BufferNeeds:
        return BufferNeeds(input_spikes=self.cfg.encoding == "rate")

    def penalty_weights(self, progress: float) -> dict[str, float]:
        """``rate_reg``: the firing-rate penalty, ramped up over ``snn.rate_reg_warmup``."""
        weight = self.cfg.rate_reg
        if self.cfg.rate_reg_warmup > 0.0:
            weight *= min(1.0, progress / self.cfg.rate_reg_warmup)
        return {"rate_reg": weight} if weight > 0.0 or self.cfg.rate_reg_warmup else {}

    def penalties(
        self, out: PolicyOutput, obs: torch.Tensor, previous: torch.Tensor | None
    ) -> dict[str, torch.Tensor]:
        return {} if out.rates is None else {"rate_reg": out.rates.sum()}

    def metrics(
        self, stats: dict[str, list[np.ndarray]], weights: dict[str, float]
    ) -> dict[str, float]:
        record = {f"charts/{k}": w for k, w in weights.items() if self.cfg.rate_reg_warmup}
        if stats.get("rates"):
            for k, r in enumerate(np.mean(stats["rates"], axis=0)):
                record[f"snn/firing_rate_layer{k + 1}"] = float(r)
        return record

    def input_spikes(self, raw: np.ndarray, rng: np.random.Generator) -> torch.Tensor | None:
        """The deployment contract (:mod:`snnkart.contract.encoding`): numpy PCG64 seeded once
        per predictor, one ``[T, n_in]`` draw per env step, so every backend sees these spikes."""
        if self.cfg.encoding != "rate":
            return None
        low = self.obs_low.numpy()
        p = rate_probabilities(raw, low, low + self.obs_span.numpy())
        return torch.from_numpy(rate_spikes(rng, p, self.cfg.num_steps))[None]

    def layer_sizes(self) -> tuple[int, ...]:
        return tuple(self.cfg.hidden)

    def nir_graph(self) -> NIRGraph:
        return lif_graph(self.snn)


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

    def relu_layers(self) -> tuple[list[nn.Linear], str]:
        return self.sdnn.affine_layers(), "sdnn"

    def message_proxy(self, obs: torch.Tensor, previous: torch.Tensor) -> torch.Tensor:
        """:func:`message_proxy` of the hidden layers between ``previous`` and ``obs``."""
        return message_proxy(self.sdnn(obs)[1], self.sdnn(previous)[1])

    @torch.no_grad()
    def message_rates(self, obs: torch.Tensor, previous: torch.Tensor) -> torch.Tensor:
        """:func:`changed_share` for the input, then each hidden layer ``[L + 1]``."""
        now = [self.sdnn.input_integers(obs), *self.sdnn(obs)[1]]
        before = [self.sdnn.input_integers(previous), *self.sdnn(previous)[1]]
        return changed_share(now, before)

    def buffer_needs(self) -> BufferNeeds:
        return BufferNeeds(previous=True)

    def penalty_weights(self, progress: float) -> dict[str, float]:
        """``messages``: the message penalty, ramped up over ``sdnn.message_penalty_warmup``."""
        weight = self.cfg.message_penalty
        if self.cfg.message_penalty_warmup > 0.0:
            weight *= min(1.0, progress / self.cfg.message_penalty_warmup)
        return {"messages": weight}

    def penalties(
        self, out: PolicyOutput, obs: torch.Tensor, previous: torch.Tensor | None
    ) -> dict[str, torch.Tensor]:
        return {} if previous is None else {"messages": self.message_proxy(obs, previous)}

    def rollout_stats(
        self, out: PolicyOutput, obs: torch.Tensor, previous: torch.Tensor | None
    ) -> dict[str, np.ndarray]:
        assert previous is not None
        return {"messages": self.message_rates(obs, previous).numpy()}

    def metrics(
        self, stats: dict[str, list[np.ndarray]], weights: dict[str, float]
    ) -> dict[str, float]:
        if not stats.get("messages"):
            return {}
        shares = np.mean(stats["messages"], axis=0)
        record = {
            "sdnn/message_penalty": weights["messages"],
            "sdnn/message_rate_input": float(shares[0]),
        }
        for k, r in enumerate(shares[1:]):
            record[f"sdnn/message_rate_layer{k + 1}"] = float(r)
        return record


class StatefulSNNPolicy(SNNPolicy):
    """A spiking actor whose membranes carry across env steps (``snn.stateful``): each env step
    is the Lava row stream of :mod:`snnkart.rl.stateful` from the state the last one left.

    ``forward`` takes the state ``[B, D]`` before this step (``state``), or with ``starts``
    ``[S, E]`` whole env sequences (``obs`` time-major ``[S * E, ...]``, ``state`` ``[E, D]``
    before step 0, zeroed where an episode starts), and returns the new state in
    :attr:`PolicyOutput.state`."""

    carries_state = True
    loops: Sequence[nn.Linear] = ()
    """Each layer i >= 1's recurrent synapse (``loops[i - 1]``), or none (the recurrent kind,
    :mod:`snnkart.rl.kinds.rsnn`, has them)."""

    def state_size(self) -> int:
        return state_size(tuple(self.cfg.hidden), bool(self.loops))

    def initial_state(self, batch: int) -> torch.Tensor:
        """The state at an episode's start: zero membranes, no spikes in flight."""
        return torch.zeros(batch, self.state_size())

    def actor_output(self, obs, raw_obs, input_spikes):  # type: ignore[no-untyped-def]
        """The readout of one env step from an episode's start (a zero state)."""
        out, rates, _ = stream_step(
            self.snn, self.actor_input(obs, raw_obs), self.initial_state(obs.shape[0]), self.loops
        )
        return out, None, rates

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
            out, rates, new = stream_step(self.snn, x, state, self.loops)
        else:  # env sequences; the update's layer by layer (snn.fused)
            run = fused_stream_sequence if self.cfg.fused else stream_sequence
            out, rates, new = run(self.snn, x, state, starts, self.loops)
        return self.output(out, obs, action, None, rates, new)

    @torch.no_grad()
    def act_from(
        self, obs: torch.Tensor, raw_obs: torch.Tensor, state: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The deterministic action (argmax or mean) from ``state``, and the new state."""
        was = self.training
        self.eval()
        try:
            out, rates, new = stream_step(
                self.snn, self.actor_input(obs, raw_obs), state, self.loops
            )
        finally:
            self.train(was)
        self.last_rates = rates.detach()
        return (out.argmax(-1) if self.discrete else out), new


__all__ = [
    "ANNPolicy",
    "ActorCritic",
    "BufferNeeds",
    "PolicyOutput",
    "SDNNPolicy",
    "SNNPolicy",
    "SpikingActor",
    "StatefulSNNPolicy",
    "mlp",
]
