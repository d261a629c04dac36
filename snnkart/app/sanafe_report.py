"""The report's SANA-FE section: the deployed network built in SANA-FE's Loihi model, driven with
the deployment's recorded inputs (``inputs.npz``), its energy and on-chip latency per inference
next to snnkart's own Loihi 1 estimate (:mod:`snnkart.energy.sanafe_model` says how it runs).

The network in SANA-FE: each spiking layer a LIF group on cores of its own (512 neurons per
core), reset at its row of every window as Lava's ``LIFReset``; layer 0 driven by the host's
recorded current. Two runs:

- **replay** (the estimate): each layer's recorded spikes replayed by an input group on that
  layer's cores into the next layer's LIF group, so SANA-FE's synaptic events and messages are
  the deployment's own and the two estimators differ only in their prices;
- **chain** (the check): the LIF groups feed each other, driven by layer 0's current only;
  where they reproduce the recorded spikes, SANA-FE's LIF computes what Lava computed.

Units: the fixed-point network in Lava's integer units (v / 64, as SANA-FE truncates v to
1/64 toward zero, and fires on v > threshold as Lava does: bit-exact but for Lava's 24-bit
wrap-around); float64 and float32 scaled by 2**12 (:data:`FLOAT_SCALE`), where SANA-FE's
truncation of v and its double precision still differ from Lava's float64 and torch's float32.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from snnkart.backends.lava_params import lava_layers
from snnkart.backends.loading import load_policy
from snnkart.backends.network import ChainNetwork
from snnkart.backends.quantize import FixedPointNetwork
from snnkart.contract.deploy_inputs import DeployInputs, InputsError
from snnkart.contract.deploy_record import DeployRecord
from snnkart.contract.sanafe_record import SanafeSection
from snnkart.energy.counts import SnnCounts
from snnkart.energy.pricing import terms
from snnkart.energy.profiles import load_profile
from snnkart.energy.sanafe_model import (
    INSTALL_HINT,
    LOIHI_YAML,
    per_inference,
    run_sanafe,
    sanafe_python,
    versus_snnkart,
)
from snnkart.errors import SnnkartError

NEURONS_PER_CORE = 512
"""A layer's LIF neurons per core; its replay inputs share the core (Loihi: 1,024 per core)."""
FLOAT_SCALE = 2.0**12
"""The float arithmetics' values (weights, biases, thresholds, currents) times this power of
two, exactly, so SANA-FE's truncation of v to 1/64 is 2**-18 of a unit, not 1/64 of the
threshold."""
CHECK_ENV_STEPS = 500
"""The chain check (and the latency, when it reproduces the spikes) runs the first env steps
only: SANA-FE takes about 5 ms per env step, and the replay already runs them all."""


def network_job(
    chain: ChainNetwork, fixed: FixedPointNetwork | None, inputs: DeployInputs
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The job for :mod:`snnkart.energy.sanafe_worker`: per layer its LIF parameters and the
    arrays (biases, weights, the current and the raster aligned to Lava's pipeline) in the
    deployment's arithmetic (``fixed`` needs the quantised network)."""
    if inputs.arithmetic == "float32":
        layers, arrays = _float32_layers(chain)
    else:
        layers, arrays = _lava_layers(chain, fixed if inputs.arithmetic == "fixed" else None)
    scale = 1.0 if inputs.arithmetic == "fixed" else FLOAT_SCALE
    for layer in layers:
        layer["threshold"] *= scale
    arrays = {k: v * scale for k, v in arrays.items()}
    depth = len(chain.sizes) - 1
    arrays["current"] = inputs.current.astype(np.float64) * scale
    arrays["raster"] = _aligned(inputs, depth)
    job = {
        "layers": layers,
        "rows": inputs.num_steps + depth,
        "steps": inputs.num_steps,
        "modes": ["replay", "chain"],
        "neurons_per_core": NEURONS_PER_CORE,
        "env_steps": {"chain": CHECK_ENV_STEPS},
    }
    return job, arrays


def _float32_layers(chain: ChainNetwork) -> tuple[list[dict[str, Any]], dict[str, np.ndarray]]:
    """torch's neuron: ``v = beta v + W s + b`` (layer 0's bias is in the host's current)."""
    layers, arrays = [], {}
    for i, layer in enumerate(chain.layers):
        alpha = 0.0 if layer.alpha is None else float(layer.alpha[0])
        layers.append(
            {
                "n": layer.size,
                "threshold": float(layer.threshold[0]),
                "leak_decay": float(layer.beta[0]),
                "input_decay": alpha,
            }
        )
        arrays[f"bias{i}"] = np.zeros(layer.size) if i == 0 else layer.bias.astype(np.float64)
        if i:
            arrays[f"weight{i}"] = layer.weight.astype(np.float64)
    return layers, arrays


def _lava_layers(
    chain: ChainNetwork, fixed: FixedPointNetwork | None
) -> tuple[list[dict[str, Any]], dict[str, np.ndarray]]:
    """Lava's parameters (:func:`snnkart.backends.lava_params.lava_layers`): fixed point in
    integer weight units (Lava's v / 64; decays over 4096, u's with Lava's offset of 1), or
    float64 as they are."""
    unit, one, offset = (64.0, 4096.0, 1) if fixed is not None else (1.0, 1.0, 0)
    layers, arrays = [], {}
    params = lava_layers(chain, "fixed" if fixed is not None else "float64", fixed)
    for i, p in enumerate(params):
        layers.append(
            {
                "n": chain.sizes[i],
                "threshold": float(p.vth),
                "leak_decay": (one - p.dv) / one,
                "input_decay": (one - p.du - offset) / one,
            }
        )
        bias = np.asarray(p.bias_mant, dtype=np.float64) * 2.0**p.bias_exp
        arrays[f"bias{i}"] = bias / unit
        if p.weight is not None:
            arrays[f"weight{i}"] = np.asarray(p.weight, dtype=np.float64)
    return layers, arrays


def _aligned(inputs: DeployInputs, depth: int) -> np.ndarray:
    """The raster with layer i's logical step t at row i + t (Lava's pipeline): as recorded
    for the Lava arithmetics; built from the logical steps for float32 (no pipeline)."""
    if inputs.depth == depth:
        return inputs.raster
    e, t = inputs.env_steps, inputs.num_steps
    out = np.zeros((e, t + depth, inputs.raster.shape[2]), dtype=bool)
    offsets = np.cumsum((0, *inputs.sizes))
    for i in range(len(inputs.sizes)):
        cols = slice(offsets[i], offsets[i + 1])
        out[:, i : i + t, cols] = inputs.raster[:, :t, cols]
    return out


def _find_nir(record: DeployRecord, deploy_dir: Path) -> Path | None:
    recorded = Path(record.nir_file or "policy.nir")
    base = deploy_dir if deploy_dir.is_dir() else deploy_dir.parent
    return next(
        (p for p in (recorded, base.parent / recorded.name, base / recorded.name) if p.is_file()),
        None,
    )


def sanafe_section(
    record: DeployRecord,
    deploy_dir: Path,
    snn: SnnCounts,
    find: Callable[[], str | None] = sanafe_python,
) -> SanafeSection:
    """The report's ``sanafe`` entry; ``available`` false with the reason and how to add it
    when SANA-FE (looked for by ``find``), the recorded inputs or the NIR file is missing."""
    python = find()
    if python is None:
        return {"available": False, "reason": f"SANA-FE is not installed: {INSTALL_HINT}"}
    nir_path = _find_nir(record, deploy_dir)
    if nir_path is None:
        return {"available": False, "reason": f"the NIR file {record.nir_file} is not there"}
    try:
        inputs = DeployInputs.load(deploy_dir if deploy_dir.is_dir() else deploy_dir.parent)
        policy = load_policy(nir_path)
        fixed = policy.fixed if inputs.arithmetic == "fixed" else None
        job, arrays = network_job(policy.chain, fixed, inputs)
        result = run_sanafe(job, arrays, python)
    except (InputsError, SnnkartError) as exc:
        return {"available": False, "reason": str(exc)}
    return compare(result, inputs, snn, record)


def compare(
    result: dict[str, Any], inputs: DeployInputs, snn: SnnCounts, record: DeployRecord
) -> SanafeSection:
    """SANA-FE's replay per inference against snnkart's Loihi 1 chip terms, the spike counts
    each side saw, the chain check, and the on-chip latency against the control period."""
    replay, chain = result["replay"], result["chain"]
    est = per_inference(replay)
    loihi1 = load_profile("loihi1")
    chip = [t.as_dict() for t in terms(replace(snn, host=()), loihi1, loihi1)]
    c = record.counts
    o = c.pipeline_overhead
    deployed = [s + (o.spikes[i] if o else 0) for i, s in enumerate(c.spikes)]
    reproduces = not any(chain["lif_mismatched_logical_neuron_steps"])
    # the chain is the network itself (no replay inputs in its pipelines): its latency, when
    # its spikes are the deployment's; else the replay's
    timed = chain if reproduces else replay
    latency = timed["latency_s"]["mean"]
    return {
        "available": True,
        "model": LOIHI_YAML,
        "sanafe_version": result.get("sanafe_version"),
        "run": {
            "env_steps": replay["env_steps"],
            "rows_per_env_step": replay["rows"],
            "mapping": f"a layer per core ({NEURONS_PER_CORE} neurons per core), "
            "replay inputs on their layer's cores",
            "wall_s": replay["wall_s"] + chain["wall_s"],
        },
        "per_inference": est,
        "versus_snnkart_loihi1": versus_snnkart(est, chip),
        "spikes_per_layer": {
            "deploy_json": deployed,
            "inputs_npz": inputs.layer_spikes(),
            "replayed_by_sanafe": replay["replayed_spikes"],
            "sanafe_lif_replay": replay["lif_spikes"],
        },
        "lif_check": {
            "what": "SANA-FE's LIF groups chained, driven only by layer 0's recorded current",
            "env_steps": chain["env_steps"],
            "recorded_spikes": chain["recorded_spikes"],
            "sanafe_spikes": chain["lif_spikes"],
            "mismatched_logical_neuron_steps": chain["lif_mismatched_logical_neuron_steps"],
            "reproduces": reproduces,
            "arithmetic": inputs.arithmetic,
        },
        "latency": {
            "on_chip_s_per_inference": latency,
            "max_s": timed["latency_s"]["max"],
            "from": f"the {timed['mode']} run",
            "replay_s_per_inference": replay["latency_s"]["mean"],
            "control_period_s": snn.period_s,
            "fraction_of_control_period": latency / snn.period_s,
            "steps_per_inference": replay["rows"],
        },
    }
