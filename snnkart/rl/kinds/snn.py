"""``policy = "snn"``: a LIF spiking actor (snntorch) with an MLP critic: membranes reset at
every env step (:class:`~snnkart.rl.policies.SNNPolicy`), or, with ``snn.stateful = true``,
carried across env steps (:class:`~snnkart.rl.policies.StatefulSNNPolicy`, docs/stateful.md)."""

from __future__ import annotations

from typing import Any

from snnkart.rl.kinds.base import Kind, PolicySpace
from snnkart.rl.policies import ActorCritic, SNNPolicy, StatefulSNNPolicy
from snnkart.rl.stateful_config import stateful_problem


def spiking(cls: type[SNNPolicy], cfg: Any, space: PolicySpace, **extra: Any) -> ActorCritic:
    """A LIF actor of class ``cls`` for ``space``, from the config's snn, ann (the critic's
    widths) and ppo sections; ``extra``: the class's own arguments."""
    return cls(
        space.obs_dim,
        space.action_dim,
        space.discrete,
        cfg.snn,
        cfg.ann.hidden,
        space.obs_low,
        space.obs_high,
        cfg.ppo.init_log_std,
        **extra,
    )


def build(cfg: Any, space: PolicySpace) -> ActorCritic:
    return spiking(StatefulSNNPolicy if cfg.snn.stateful else SNNPolicy, cfg, space)


def label(cfg: Any) -> str:
    """Stateful when membranes carry across env steps, sparse with a firing-rate penalty."""
    if cfg.snn.stateful:
        return "stateful LIF"
    return "sparse LIF" if cfg.snn.rate_reg > 0 else "dense LIF"


def check(cfg: Any) -> None:
    if cfg.snn.stateful:
        stateful_problem(cfg)


KIND = Kind(
    name="snn",
    build=build,
    defaults={"ppo": {"learning_rate": 1e-3}},  # why: docs/decisions.md#snn-learning-rate
    env_defaults={
        # why: docs/decisions.md#gazebo-snn-rollout
        "gazebo": {"ppo": {"ent_coef": 0.02, "num_envs": 16, "rollout_steps": 128}},
        # no entropy floor, spread starts (why: docs/decisions.md#grid-entropy)
        "grid": {"ppo": {"ent_coef": 0.0, "start_spread": 0.5}},
    },
    check=check,
    label=label,
    sections_used=("snn",),
)
