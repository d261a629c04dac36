"""``snnkart nir manifest``: the deployment manifest for a graph snnkart did not write.

A foreign graph (Norse, Sinabs, Rockpool, lava-dl, snntorch without snnkart) carries neither
its time step nor how the kart's observation reaches its input or how its output becomes an
action. This writes the manifest (``snnkart/manifest/v2``, ``snnkart/contract/
manifest.schema.json``) after checking the graph against the env: its input size is the env's
observation size (times the receptive fields of a population code), its readout gives one
value per discrete action or the two continuous commands, and every layer has the one decay
and threshold per population that the backends need. Then ``snnkart deploy GRAPH.nir`` drives
the kart with it. The observation reaches the graph unnormalised (mean 0, scale 1) unless the
graph was trained with another normalisation, which a manifest of snnkart's own records.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from snnkart.app.nir_tools import load_open_chain
from snnkart.backends.network import ChainNetwork
from snnkart.contract.encoding import RATE_RNG
from snnkart.contract.manifest import MANIFEST_SCHEMA, LayerSpec, Manifest, manifest_path
from snnkart.errors import DeployError

OBS_CLIP = 1e6
"""No clipping to speak of: a foreign graph sees the observation as the env gives it."""


def _layers(chain: ChainNetwork) -> tuple[LayerSpec, ...]:
    specs = []
    for layer in chain.layers:
        for what, values in (("decay", layer.beta), ("threshold", layer.threshold)):
            if np.ptp(values) > 1e-9:
                raise DeployError(
                    f"node {layer.neuron!r} has per-neuron {what} values; a manifest layer has "
                    "one per population (as Lava's LIF)"
                )
        if layer.alpha is not None and np.ptp(layer.alpha) > 1e-9:
            raise DeployError(f"node {layer.neuron!r} has per-neuron current decays")
        specs.append(
            LayerSpec(
                layer.neuron,
                layer.size,
                float(layer.beta[0]),
                float(layer.threshold[0]),
                None if layer.alpha is None else float(layer.alpha[0]),
            )
        )
    return tuple(specs)


def _versions() -> dict[str, str]:
    import platform
    from importlib import metadata

    out = {"python": platform.python_version()}
    for pkg in ("snnkart", "nir", "numpy"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def _env_facts(
    env: str, track: str, action_mode: str
) -> tuple[dict[str, object], np.ndarray, np.ndarray, int, dict[str, str]]:
    """The env's spec, observation bounds, action count (2 for continuous) and embedded track."""
    from snnkart.envs import make, resolve_env_name
    from snnkart.envs.spec import env_spec
    from snnkart.envs.tracks import TrackError, embed_track, load_track

    try:
        kart = make(resolve_env_name(env), track=load_track(track), action_mode=action_mode)
    except (TrackError, ValueError) as exc:
        raise DeployError(f"cannot make env {env!r} on {track!r}: {exc}") from exc
    try:
        unwrapped: Any = kart.unwrapped
        spec = env_spec(unwrapped)
        space: Any = kart.observation_space
        low, high = space.low, space.high
        n_actions = int(getattr(kart.action_space, "n", 2))
        track_record = embed_track(unwrapped.track_given, track)
    finally:
        kart.close()
    return spec, low, high, n_actions, track_record


def _check_fit(
    chain: ChainNetwork,
    env: str,
    action_mode: str,
    readout: str | None,
    obs_dim: int,
    fields: int | None,
    n_actions: int,
) -> None:
    """The graph's input, readout size and readout node against the env's (clear errors)."""
    if readout is not None and readout != chain.readout_node:
        raise DeployError(
            f"--readout {readout!r} is not the graph's readout: the chain ends with "
            f"{chain.readout_node or 'no readout node (its last layer is read out)'!r}"
        )
    if chain.n_in != obs_dim * (fields or 1):
        per = f" x {fields} receptive fields" if fields else ""
        raise DeployError(
            f"the graph takes {chain.n_in} inputs; env {env!r} observes {obs_dim} values{per}"
        )
    if chain.n_out != n_actions:
        raise DeployError(
            f"the graph's readout gives {chain.n_out} values; env {env!r} ({action_mode}) needs "
            f"{n_actions}"
        )


def write_manifest(
    graph_path: Path,
    env: str,
    track: str,
    encoding: str,
    readout: str | None,
    dt: float,
    discretisation: str,
    num_steps: int,
    action_mode: str,
    population: int | None,
    force: bool,
) -> Path:
    """Check ``graph_path`` against the env and write its manifest beside it."""
    from snnkart.envs.spec import spec_hash

    graph_path = Path(graph_path)
    out = manifest_path(graph_path)
    if out.exists() and not force:
        raise DeployError(f"{out} exists; pass --force to replace it")
    if num_steps < 1:
        raise DeployError(f"--num-steps must be at least 1, not {num_steps}")
    chain = load_open_chain(graph_path, dt, discretisation)
    spec, low, high, n_actions, track_record = _env_facts(env, track, action_mode)
    obs_dim = int(low.shape[0])  # the spec's obs_dim: the observation space's size
    fields = population if encoding == "population" else None
    _check_fit(chain, env, action_mode, readout, obs_dim, fields, n_actions)
    manifest = Manifest(
        schema=MANIFEST_SCHEMA,
        nir_file=graph_path.name,
        nir_dt=dt,
        num_steps=num_steps,
        layers=_layers(chain),
        encoding=encoding,
        obs_mean=(0.0,) * obs_dim,
        obs_std=(1.0,) * obs_dim,
        obs_clip=OBS_CLIP,
        obs_low=tuple(float(x) for x in low),
        obs_high=tuple(float(x) for x in high),
        readout_node=chain.readout_node or "",
        action_mode=action_mode,
        env={**spec, "env_spec_hash": spec_hash(spec)},
        versions=_versions(),
        training={"foreign": str(graph_path), "written_by": "snnkart nir manifest"},
        encoding_rng=RATE_RNG if encoding == "rate" else None,
        track=track_record,
        population=fields,
        discretisation=discretisation,
    )
    manifest.write(out)
    return out
