"""What a reader of a snnkart NIR file alone would miss: the lines ``snnkart nir info`` adds
from the manifest beside the graph (a sigma-delta policy's semantics, or LIF membranes that
persist across env steps)."""

from __future__ import annotations

from pathlib import Path

from snnkart.contract.manifest import Manifest, manifest_path
from snnkart.contract.sigma_delta import SigmaDeltaBlock


def policy_notes(path: Path) -> list[str]:
    """The notes for the NIR file at ``path`` (none without a manifest beside it)."""
    mpath = manifest_path(Path(path))
    if not mpath.is_file():
        return []
    manifest = Manifest.read(mpath)
    if manifest.sigma_delta is not None:
        return sigma_delta_notes(manifest.sigma_delta)
    if manifest.state_persists:
        return [
            "state persists: the LIF membranes carry across env steps (no reset per decision), "
            "so an action depends on the episode so far, not on this observation alone"
        ]
    return []


def sigma_delta_notes(block: SigmaDeltaBlock) -> list[str]:
    """A sigma-delta block in plain words (:mod:`snnkart.contract.sigma_delta`)."""
    names = [la.node for la in block.layers]
    units = ", ".join(f"{la.node} {la.act_scale:.6g}" for la in block.layers)
    vth = ", ".join([f"input {block.vth_in}", *(f"{la.node} {la.vth}" for la in block.layers)])
    return [
        f"sigma-delta policy ({block.origin}): the affine layers are not a linear network",
        f"  ReLU after {', '.join(names)} (between the affine layers; none after "
        f"{block.readout_node})",
        f"  integer units: the host sends round(z / {block.input_scale:.6g}) in "
        f"{block.input_bits} signed bits; activation units {units}; readout sigma * "
        f"{block.out_scale:.6g} + its bias; integer weights round(W s_in / s_out) with Lava's "
        f"{block.weight_bits}-bit clip and truncation",
        f"  thresholds (integer units): {vth}; a neuron sends a {block.num_message_bits}-bit "
        "graded message when its activation has changed by at least its threshold since its "
        "last message",
        f"  held schedule: every env step holds the observation for {block.rows} Lava steps "
        f"({block.depth} Dense delays + 1), so the action belongs to this env step",
        "  state persists across env steps and episodes (never reset); the observation enters "
        "as deltas",
        "  " + _calibration(block),
    ]


def _calibration(block: SigmaDeltaBlock) -> str:
    c = block.calibration
    if not c:
        return "thresholds not calibrated (no calibration record)"
    tolerance = "" if c.get("tolerance") is None else f", tolerance {c['tolerance']}"
    line = (
        f"calibration: the action is unchanged on {c['fraction']:.1%} of {c['steps']} recorded "
        f"steps (target {c['target']:.0%}, {c['episodes']} episode{'s' * (c['episodes'] != 1)} "
        f"from seed {c['seed']}"
        f"{tolerance}, f {c['f']:.4g})"
    )
    if c.get("state_bits"):
        bits = ", ".join(
            f"{n} {b}" for n, b in zip(c["state_bits_layers"], c["state_bits"], strict=True)
        )
        over = " (over Loihi 2's 24)" if max(c["state_bits"]) > 24 else ""
        line += f"; state bits needed: {bits}{over}"
    return line
