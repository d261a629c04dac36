"""The ``sdnn`` section of a training config: a sigma-delta actor (``policy = "sdnn"``) and the
calibration of its message thresholds at export (also used to convert a ReLU ANN run).

docs/sigma-delta.md, "Training and conversion", says what each key does on the chip.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, field_validator


class SDNNConfig(BaseModel):
    """Sigma-delta actor: a ReLU MLP trained with the chip's integer arithmetic faked in (straight-
    through estimators), an optional penalty on its expected messages, and how export calibrates
    the message thresholds."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    hidden: tuple[int, ...] = Field(
        (64, 64), description="hidden ReLU layers (SigmaDelta populations), e.g. [64, 64]"
    )
    input_bits: int = Field(
        8, ge=2, le=24, description="signed bits of the integer observation the host sends"
    )
    weight_bits: int = Field(
        8, ge=8, le=8, description="bits of a Dense weight: Lava's fixed-point Dense has 8"
    )
    message_penalty: float = Field(
        0.0,
        ge=0.0,
        description="weight of the message proxy in the loss (0: off): the normalised L1 change "
        "of each hidden activation from the previous env step",
    )
    message_penalty_warmup: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        description="fraction of training over which the message penalty ramps up linearly "
        "from 0 (0: the full penalty from the start)",
    )
    calibration_target: float = Field(
        0.95,
        gt=0.0,
        le=1.0,
        description="export: the share of recorded env steps whose action the calibrated "
        "thresholds must leave unchanged",
    )
    calibration_episodes: int = Field(
        3, ge=1, description="export: seeded episodes recorded to calibrate the thresholds"
    )
    calibration_seed: int = Field(
        70_000, description="export: the recorded episodes use seeds seed, seed+1, ..."
    )

    @field_validator("hidden")
    @classmethod
    def _some_layers(cls, hidden: tuple[int, ...]) -> tuple[int, ...]:
        if not hidden or min(hidden) < 1:
            raise ValueError(f"sdnn.hidden must list layer sizes >= 1, got {list(hidden)}")
        return hidden
