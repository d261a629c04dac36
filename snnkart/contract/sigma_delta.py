"""The sigma-delta part of a v3 manifest: what a NIR graph of affine layers cannot say.

NIR has no sigma-delta (nor ReLU) node. A sigma-delta policy is exported as NIR's affine layers
(``Input -> fc1 -> fc2 -> ... -> readout -> Output``, weights and biases as trained, in float32)
and this block, which turns them into the network the chip runs (docs/sigma-delta.md):

- between consecutive affine layers sits a ReLU (a reader of the NIR file alone sees a linear
  network);
- every value travels as an integer in its layer's unit: the host sends ``round(z / input_scale)``
  (``z`` the normalised observation), clipped to ``input_bits`` signed bits; hidden layer ``l``'s
  activation is an integer in units of ``act_scale[l]``; the readout Sigma is in units of
  ``out_scale`` and the host computes ``sigma * out_scale + b_readout``;
- Dense ``l``'s integer weights are ``round(W_l * s_{l-1} / s_l)`` (``s_0 = input_scale``,
  ``s_{L+1} = out_scale``), then Lava's 8-bit clip and truncation; hidden biases are
  ``round(b_l / s_l)``; ``weight_exp``, ``spike_exp`` and ``state_exp`` are 0 so the chain is
  exact (docs/sigma-delta.md, "When it is exact");
- a neuron sends a graded message when its activation has changed by at least its layer's
  threshold (``vth``, integer units; ``vth_in`` for the input Delta) since its last message;
  state persists across env steps and episodes (never reset);
- schedule ``"held"``: every env step holds the observation for ``L + 2`` Lava steps, so the
  change crosses all ``L + 1`` Dense delays and the action belongs to this env step's observation.

This module imports neither torch nor Lava.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

from snnkart.errors import ManifestError

SCHEDULES = ("held",)
"""How env steps map to Lava steps: ``held`` = ``L + 2`` Lava steps per env step, input held."""
ORIGINS = ("sdnn", "ann-relu")
"""Where the network came from: trained as sigma-delta (``--policy sdnn``), or converted from a
ReLU ANN run with no retraining."""


@dataclass(frozen=True)
class SigmaDeltaLayer:
    """One hidden SigmaDelta population: the NIR Affine node feeding it, its size, its
    activation unit (real value per integer) and its message threshold (integer units)."""

    node: str
    size: int
    act_scale: float
    vth: int


@dataclass(frozen=True)
class SigmaDeltaBlock:
    """The sigma-delta semantics of a policy (module docstring)."""

    layers: tuple[SigmaDeltaLayer, ...]
    readout_node: str
    input_scale: float
    out_scale: float
    vth_in: int = 0
    input_bits: int = 8
    weight_bits: int = 8
    num_message_bits: int = 24
    weight_exp: int = 0
    spike_exp: int = 0
    state_exp: int = 0
    schedule: str = "held"
    origin: str = "sdnn"
    calibration: dict[str, Any] = field(default_factory=dict)
    """How the thresholds were chosen: target and measured fraction of steps whose action is
    unchanged, steps and episodes recorded, seed, tolerance (continuous actions)."""

    def __post_init__(self) -> None:
        if not self.layers:
            raise ManifestError("a sigma-delta block needs at least one hidden layer")
        if self.schedule not in SCHEDULES:
            raise ManifestError(f"unknown sigma-delta schedule {self.schedule!r}; use {SCHEDULES}")
        if self.origin not in ORIGINS:
            raise ManifestError(f"unknown sigma-delta origin {self.origin!r}; use {ORIGINS}")
        scales = [self.input_scale, self.out_scale, *(la.act_scale for la in self.layers)]
        if any(not s > 0 for s in scales):
            raise ManifestError("sigma-delta scales (input, activations, readout) must be > 0")
        if any(la.vth < 0 for la in self.layers) or self.vth_in < 0:
            raise ManifestError("sigma-delta thresholds must be >= 0 (integer units)")
        if (self.weight_exp, self.spike_exp, self.state_exp) != (0, 0, 0):
            raise ManifestError(
                "sigma-delta exponents other than 0 make Lava's chain drift from the network "
                "(docs/sigma-delta.md); put the scale into act_scale instead"
            )

    @property
    def depth(self) -> int:
        """Dense delays from the input Delta to the readout Sigma: hidden layers + 1."""
        return len(self.layers) + 1

    @property
    def rows(self) -> int:
        """Lava steps per env step under the ``held`` schedule."""
        return self.depth + 1

    def as_dict(self) -> dict[str, object]:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SigmaDeltaBlock:
        data = dict(data)
        data["layers"] = tuple(SigmaDeltaLayer(**layer) for layer in data["layers"])
        return cls(**data)
