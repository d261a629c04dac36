"""``policy = "sdnn"``: a sigma-delta actor, the ReLU MLP whose forward pass is Lava's integer
chain (:mod:`snnkart.rl.sigma_delta`, :class:`~snnkart.rl.policies.SDNNPolicy`, docs/sigma-delta.md)."""

from __future__ import annotations

from typing import Any

from snnkart.rl.kinds import ann
from snnkart.rl.kinds.base import Kind, PolicySpace
from snnkart.rl.policies import ActorCritic, SDNNPolicy
from snnkart.rl.sigma_delta_config import SDNNConfig


def build(cfg: Any, space: PolicySpace) -> ActorCritic:
    return SDNNPolicy(
        space.obs_dim,
        space.action_dim,
        space.discrete,
        cfg.sdnn,
        cfg.ann.hidden,
        cfg.ppo.clip_obs,
        cfg.ppo.init_log_std,
    )


KIND = Kind(
    name="sdnn",
    build=build,
    section=SDNNConfig,
    # The ANN's network quantised: the ANN's critic width and its per-env settings (not tuned
    # for sdnn separately yet; why: docs/decisions.md#sigma-delta-width).
    defaults={"ann": {"hidden": (64, 64)}},
    env_defaults=ann.KIND.env_defaults,
    sections_used=("sdnn",),
    label=lambda cfg: "sigma-delta trained",
)
