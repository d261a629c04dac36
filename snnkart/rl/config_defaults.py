"""Training defaults that differ by policy kind, and by env and policy kind: applied by
:class:`snnkart.rl.config.TrainConfig` only where the user set nothing. Why each is what it is,
with the result that showed it: docs/decisions.md.
"""

from __future__ import annotations

from typing import Any

POLICY_DEFAULTS: dict[str, dict[str, dict[str, Any]]] = {
    "snn": {"ppo": {"learning_rate": 1e-3}},  # why: docs/decisions.md#snn-learning-rate
    # The ANN actor and critic are as wide as the SNN actor; the SNN's critic keeps
    # ann.hidden = 128-128. why: docs/decisions.md#ann-width
    "ann": {"ann": {"hidden": (64, 64)}},
    # The sigma-delta actor is the ANN's ReLU MLP with the chip's integers faked in: the ANN's
    # critic width. why: docs/decisions.md#sigma-delta-width
    "sdnn": {"ann": {"hidden": (64, 64)}},
}


ENV_POLICY_DEFAULTS: dict[tuple[str, str], dict[str, dict[str, Any]]] = {
    # why: docs/decisions.md#gazebo-ann-entropy
    ("gazebo", "ann"): {"ppo": {"learning_rate": 1e-3, "ent_coef": 0.02}},
    # why: docs/decisions.md#gazebo-snn-rollout
    ("gazebo", "snn"): {"ppo": {"ent_coef": 0.02, "num_envs": 16, "rollout_steps": 128}},
    # why: docs/decisions.md#steer-ann-entropy
    ("steer", "ann"): {"ppo": {"ent_coef": 0.02}},
    # Grid: a small entropy floor for the ANN, none for the SNN (why:
    # docs/decisions.md#grid-entropy); half of the training episodes start just past a random
    # checkpoint (snnkart.envs.starts; why: docs/decisions.md#grid-spread-starts).
    ("grid", "ann"): {"ppo": {"ent_coef": 0.005, "start_spread": 0.5}},
    ("grid", "snn"): {"ppo": {"ent_coef": 0.0, "start_spread": 0.5}},
}
# The sdnn actor is the ANN's network quantised: it starts from the ANN's per-env settings
# (not tuned for sdnn separately yet; why: docs/decisions.md#sigma-delta-width).
ENV_POLICY_DEFAULTS.update(
    {
        (env, "sdnn"): values
        for (env, kind), values in list(ENV_POLICY_DEFAULTS.items())
        if kind == "ann"
    }
)
