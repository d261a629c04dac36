"""Export a trained spiking actor to NIR plus its manifest.

The policy builds its own graph (:meth:`snnkart.rl.policies.ActorCritic.nir_graph`: a LIF actor
through snntorch's exporter, :mod:`snnkart.rl.lif_nir`; a recurrent one with its recurrent
edges as cycles); this module writes it with the manifest of what NIR does not carry. Which
writer a run takes is its kind's family (:mod:`snnkart.rl.kinds`): a sigma-delta actor is
written by :mod:`snnkart.export.sigma_delta_export` (calibrated thresholds).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from snnkart.contract.encoding import RATE_RNG, obs_std
from snnkart.contract.manifest import MANIFEST_SCHEMA, Manifest, manifest_path
from snnkart.contract.obs_node import OBS_NODE, with_obs_node
from snnkart.errors import ExportError
from snnkart.export.run_fields import run_fields
from snnkart.io import atomic_path
from snnkart.rl import kinds
from snnkart.rl.lif_nir import NIR_DT, check_exportable
from snnkart.rl.trained import LoadedRun

__all__ = ["NIR_DT", "ExportError", "check_exportable", "export_nir"]


def export_nir(run: LoadedRun, out: str | Path) -> tuple[Path, Path]:
    """Write ``out`` (.nir) and its manifest; return both paths. A spiking run writes the graph
    its policy builds; a sigma-delta run goes through
    :func:`snnkart.export.sigma_delta_export.export_sigma_delta` (calibrated thresholds)."""
    family = kinds.family(run.config.policy)
    if not family.spiking:
        raise ExportError(
            f"only spiking policies can be exported to NIR for Lava; this run trained a "
            f"{run.config.policy.upper()} policy ({family.phrase}; a ReLU ANN converts to a "
            "sigma-delta network with --sigma-delta)"
        )
    if family.graded:
        from snnkart.export.sigma_delta_export import export_sigma_delta

        return export_sigma_delta(run, out)
    return _export_spiking(run, Path(out))


def obs_bounds(policy: object) -> tuple[np.ndarray, np.ndarray]:
    """The observation's bounds as the policy holds them (low and span), unbounded ones
    (a gymnasium env's velocities) as infinities."""
    low = np.asarray(policy.obs_low, dtype=np.float64)  # type: ignore[attr-defined]
    span = np.asarray(policy.obs_span, dtype=np.float64)  # type: ignore[attr-defined]
    with np.errstate(invalid="ignore"):
        return low, np.where(np.isinf(span), np.inf, low + span)


def _export_spiking(run: LoadedRun, out: Path) -> tuple[Path, Path]:
    import nir

    policy = run.policy
    exported = policy.nir_graph()
    graph, layers = exported.graph, exported.layers
    cfg = run.config
    rms = run.obs_rms
    low, high = obs_bounds(policy)
    mean, std = rms.mean, obs_std(rms.var)
    # the current encoding's graph takes the raw observation (contract/obs_node.py); the rate
    # and population encodings take it raw already, scaled by the bounds
    normalised = cfg.snn.encoding == "current"
    if normalised:
        graph = with_obs_node(graph, mean, std)
    manifest = Manifest(
        schema=MANIFEST_SCHEMA,
        **run_fields(run, low, high),
        nir_file=out.name,
        nir_dt=NIR_DT,
        num_steps=cfg.snn.num_steps,
        layers=layers,
        encoding=cfg.snn.encoding,
        obs_mean=tuple(float(x) for x in mean),
        obs_std=tuple(float(x) for x in std),
        readout_node=exported.readout_node,
        encoding_rng=RATE_RNG if cfg.snn.encoding == "rate" else None,
        population=cfg.snn.population if cfg.snn.encoding == "population" else None,
        state_persists=policy.carries_state,
        obs_node=OBS_NODE if normalised else None,
    )
    # Mirrored for information only: backends read the manifest file, never NIR metadata.
    graph.metadata = {"snnkart_manifest": manifest.to_json()}
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp:
        nir.write(tmp, graph)
    mpath = manifest_path(out)
    manifest.write(mpath)
    return out, mpath
