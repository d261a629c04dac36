"""The ``bc`` section of a training config: a behaviour-cloning warm start before PPO
(``snnkart train --pretrain-bc DATA.npz``; docs/training.md, "Behaviour cloning")."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class BCConfig(BaseModel):
    """Behaviour cloning of a recording (:mod:`snnkart.envs.recording`) into the actor, and
    into the critic from the recorded returns, before the first PPO iteration."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    data: str = Field(description="the recording (.npz) to clone")
    epochs: int = Field(20, ge=1, description="passes over the recording")
    batch_size: int = Field(256, ge=1, description="steps per minibatch")
    learning_rate: float = Field(1e-3, gt=0.0, description="Adam's learning rate")
    value: bool = Field(
        True, description="also fit the critic to the recorded returns-to-go (with ppo.gamma)"
    )
    value_coef: float = Field(0.5, ge=0.0, description="weight of the critic's loss")
