"""What ``snn.stateful = true`` needs from the rest of a train config (checked when the config
is built; the stateful actor itself is :mod:`snnkart.rl.stateful`)."""

from __future__ import annotations

from typing import Any


def stateful_problem(cfg: Any) -> None:
    """Raise ValueError naming the setting that a stateful spiking actor cannot train with.

    The actor runs the Lava row stream of ``T + L`` steps per env step from the state the last
    env step left (docs/stateful.md): a deterministic input (current or population encoding),
    plain LIF neurons, and minibatches of whole env sequences (``ppo.num_envs`` split evenly
    into ``ppo.num_minibatches``)."""
    snn, ppo = cfg.snn, cfg.ppo
    if snn.encoding == "rate":
        raise ValueError(
            "snn.stateful needs a deterministic input: set snn.encoding to current or population"
        )
    if snn.neuron != "lif":
        raise ValueError("snn.stateful runs plain LIF neurons: set snn.neuron = lif")
    if ppo.num_envs % ppo.num_minibatches:
        raise ValueError(
            f"snn.stateful splits the rollout by env: ppo.num_envs = {ppo.num_envs} must be a "
            f"multiple of ppo.num_minibatches = {ppo.num_minibatches}"
        )
