"""``policy = "ann"``: an MLP actor and critic (:class:`~snnkart.rl.policies.ANNPolicy`)."""

from __future__ import annotations

from typing import Any

from snnkart.rl.kinds.base import Kind, PolicySpace
from snnkart.rl.policies import ActorCritic, ANNPolicy


def build(cfg: Any, space: PolicySpace) -> ActorCritic:
    return ANNPolicy(space.obs_dim, space.action_dim, space.discrete, cfg.ann, cfg.ppo.init_log_std)


KIND = Kind(
    name="ann",
    build=build,
    # The ANN actor and critic are as wide as the SNN actor; the SNN's critic keeps
    # ann.hidden = 128-128. why: docs/decisions.md#ann-width
    defaults={"ann": {"hidden": (64, 64)}},
    env_defaults={
        # why: docs/decisions.md#gazebo-ann-entropy
        "gazebo": {"ppo": {"learning_rate": 1e-3, "ent_coef": 0.02}},
        # why: docs/decisions.md#steer-ann-entropy
        "steer": {"ppo": {"ent_coef": 0.02}},
        # Grid: a small entropy floor, half of the training episodes start just past a random
        # checkpoint (snnkart.envs.starts; why: docs/decisions.md#grid-entropy and
        # docs/decisions.md#grid-spread-starts).
        "grid": {"ppo": {"ent_coef": 0.005, "start_spread": 0.5}},
    },
    sections_used=("ann",),
    label=lambda cfg: "ANN",
)
