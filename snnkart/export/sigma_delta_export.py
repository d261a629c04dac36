"""Export a sigma-delta policy: a trained ``sdnn`` run, or a ReLU ANN run converted with no
retraining, as NIR's affine chain plus a v3 manifest with a calibrated sigma-delta block.

The NIR graph is ``input -> fc1 -> ... -> fcL -> readout -> output``, every node an Affine with
the weights and biases **as trained** (float32, not fake-quantised): the block's units make the
integer weights (``round(W s_{l-1} / s_l)``, :func:`snnkart.backends.sigma_delta.spec_from_block`),
and rounding the raw weights gives exactly the integers the sdnn actor trained with, which
rounding already-quantised float32 values would not always do. The units follow
:func:`snnkart.rl.sigma_delta.layer_units` for both origins (for an ANN, from its trained weights);
the thresholds come from :func:`snnkart.export.calibrate.calibrate`.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np

from snnkart.contract.encoding import normalise, obs_std
from snnkart.contract.manifest import MANIFEST_SCHEMA, Manifest, manifest_path
from snnkart.contract.obs_node import OBS_NODE, with_obs_node
from snnkart.contract.sigma_delta import SigmaDeltaBlock, SigmaDeltaLayer
from snnkart.errors import ExportError
from snnkart.export.calibrate import AffineLayers, calibrate
from snnkart.export.run_fields import action_mode, run_fields
from snnkart.io import atomic_path
from snnkart.rl.sigma_delta import input_scale, layer_units
from snnkart.rl.trained import LoadedRun

NIR_DT = 1e-4
"""Recorded as the manifest's ``nir_dt`` (snntorch's convention); a sigma-delta graph has no
time constants, so nothing depends on it."""


@dataclass(frozen=True)
class Calibration:
    """Overrides of the run's ``sdnn`` calibration keys (None: the run's own)."""

    target: float | None = None
    episodes: int | None = None

    def __post_init__(self) -> None:
        if self.target is not None and not 0.0 < self.target <= 1.0:
            raise ExportError(f"--sigma-delta-target must be in (0, 1], not {self.target}")
        if self.episodes is not None and self.episodes < 1:
            raise ExportError(f"--calibration-episodes must be >= 1, not {self.episodes}")


def affine_layers(run: LoadedRun) -> tuple[AffineLayers, str]:
    """The run's actor as float32 affine layers, and the block's ``origin``; refuses what is
    not a ReLU network."""
    try:
        linears, origin = run.policy.relu_layers()
    except ExportError as exc:
        raise ExportError(f"{run.run_dir}: {exc}") from None
    weights = [m.weight.detach().numpy().astype(np.float32) for m in linears]
    biases = [m.bias.detach().numpy().astype(np.float32) for m in linears]
    for w in weights:
        if not np.isfinite(w).all():
            raise ExportError(f"{run.run_dir}: the actor's weights contain NaN or infinite values")
    return AffineLayers(weights, biases), origin


def zero_block(net: AffineLayers, clip_obs: float, input_bits: int, origin: str) -> SigmaDeltaBlock:
    """The block of ``net`` with every threshold at zero, units from its weights."""
    units = layer_units(
        input_scale(clip_obs, input_bits), [float(np.abs(w).max()) for w in net.weights]
    )
    layers = tuple(
        SigmaDeltaLayer(f"fc{i + 1}", int(w.shape[0]), units[i + 1], 0)
        for i, w in enumerate(net.weights[:-1])
    )
    return SigmaDeltaBlock(
        layers=layers,
        readout_node="readout",
        input_scale=units[0],
        out_scale=units[-1],
        input_bits=input_bits,
        origin=origin,
    )


def export_sigma_delta(
    run: LoadedRun, out: str | Path, options: Calibration = Calibration()
) -> tuple[Path, Path]:
    """Write ``out`` (.nir) and its v3 manifest for a sdnn or ReLU ANN run; return both paths."""
    net, origin = affine_layers(run)
    cfg = run.config
    block = zero_block(net, cfg.ppo.clip_obs, cfg.sdnn.input_bits, origin)
    mean, std = run.obs_rms.mean, obs_std(run.obs_rms.var)
    env = cfg.make_env(track=run.track)
    try:
        block = calibrate(
            block,
            net,
            env,
            lambda obs: normalise(obs, mean, std, cfg.ppo.clip_obs),
            action_mode(cfg.action_mode, run.meta["env_spec"]),
            options.target if options.target is not None else cfg.sdnn.calibration_target,
            options.episodes if options.episodes is not None else cfg.sdnn.calibration_episodes,
            cfg.sdnn.calibration_seed,
        )
        space = env.observation_space
        assert isinstance(space, gym.spaces.Box)
        low, high = space.low, space.high
    finally:
        env.close()
    out = Path(out)
    manifest = Manifest(
        schema=MANIFEST_SCHEMA,
        **run_fields(run, low, high),
        nir_file=out.name,
        nir_dt=NIR_DT,
        num_steps=1,
        layers=(),
        encoding="delta",
        obs_mean=tuple(float(x) for x in mean),
        obs_std=tuple(float(x) for x in std),
        readout_node=block.readout_node,
        state_persists=True,
        sigma_delta=block,
        obs_node=OBS_NODE,
    )
    _write(out, net, manifest)
    mpath = manifest_path(out)
    manifest.write(mpath)
    return out, mpath


def _write(out: Path, net: AffineLayers, manifest: Manifest) -> None:
    """The NIR graph ``input -> fc1 .. fcL -> readout -> output`` (Affine nodes)."""
    import nir

    names = [la.node for la in manifest.sigma_delta.layers] if manifest.sigma_delta else []
    names.append(manifest.readout_node)
    nodes: dict[str, nir.NIRNode] = {
        "input": nir.Input({"input": np.array([net.weights[0].shape[1]])}),
        "output": nir.Output({"output": np.array([net.weights[-1].shape[0]])}),
    }
    for name, w, b in zip(names, net.weights, net.biases, strict=True):
        nodes[name] = nir.Affine(weight=w, bias=b)
    chain = ["input", *names, "output"]
    graph = nir.NIRGraph(nodes=nodes, edges=list(itertools.pairwise(chain)))
    # the graph takes the raw observation (contract/obs_node.py)
    graph = with_obs_node(graph, np.asarray(manifest.obs_mean), np.asarray(manifest.obs_std))
    graph.metadata = {"snnkart_manifest": manifest.to_json()}
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp:
        nir.write(tmp, graph)
