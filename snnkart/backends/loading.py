"""A policy loaded once: its NIR graph read and checked against its manifest, and its quantised
network computed at most once, then handed to every backend and reference that runs it.

Only the two exported files are read (the ``.nir`` graph and the manifest beside it), never the
training code; every problem with them is a :class:`~snnkart.errors.NIRFileError` or
:class:`~snnkart.contract.manifest.ManifestError` naming the file.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from snnkart.backends.network import (
    ChainNetwork,
    SpikingLayer,
    UnsupportedGraphError,
    chain_from_graph,
)
from snnkart.backends.quantize import FixedPointNetwork, quantize
from snnkart.backends.sigma_delta_policy import SigmaDeltaPolicy, sigma_delta_policy
from snnkart.contract.deploy_record import NetworkShape
from snnkart.contract.manifest import LayerSpec, Manifest, manifest_path
from snnkart.contract.obs_node import without_obs_node
from snnkart.errors import NIRFileError

MISSING_HINT = "; create one with `snnkart export --nir RUN`"


@dataclass(frozen=True)
class LoadedPolicy:
    """An exported policy, read and validated once: the NIR graph, its manifest and the chain
    checked against the manifest (whose decays, the float32 values torch used, replace the
    ones derived from tau). :attr:`fixed` quantises the chain on first use, once."""

    path: Path
    graph: Any  # nir.NIRGraph
    manifest: Manifest
    chain: ChainNetwork
    family: ClassVar[str] = "lif"

    @cached_property
    def fixed(self) -> FixedPointNetwork:
        """The quantised network (:mod:`snnkart.backends.quantize`), computed once."""
        return quantize(self.chain)

    @property
    def num_steps(self) -> int:
        """T: SNN steps per env step."""
        return self.manifest.num_steps

    def shape(self) -> NetworkShape:
        """The chain's shape, as the deploy record keeps it for the energy report."""
        chain = self.chain
        return NetworkShape(
            n_in=chain.n_in,
            sizes=tuple(chain.sizes),
            n_out=chain.n_out,
            readout=chain.readout_weight is not None,
            input_scale=chain.input_scale is not None,
        )


def load_policy(path: str | Path) -> LoadedPolicy:
    """Read and validate the LIF policy ``path`` (``.nir`` and the manifest beside it)."""
    policy = open_policy(path)
    if isinstance(policy, SigmaDeltaPolicy):
        raise NIRFileError(
            f"{path} is a sigma-delta policy (its manifest has a sigma_delta block), not a LIF "
            "chain; open it with snnkart.backends.loading.open_policy"
        )
    return policy


Opened = LoadedPolicy | SigmaDeltaPolicy
"""What :func:`open_policy` reads: a policy of one family (its ``family``)."""


def open_policy(path: str | Path) -> Opened:
    """Read and validate the policy ``path``: a LIF chain, or a sigma-delta policy when its
    manifest has a ``sigma_delta`` block (:mod:`snnkart.backends.sigma_delta_policy`)."""
    path = Path(path)
    graph, manifest = load_nir(path)
    graph = _host_normalised(path, graph, manifest)
    if manifest.sigma_delta is not None:
        return sigma_delta_policy(path, graph, manifest)
    return LoadedPolicy(path, graph, manifest, _checked_chain(path, graph, manifest))


def _host_normalised(path: Path, graph: Any, manifest: Manifest) -> Any:
    """The graph as the backends run it: a v4 manifest's ``obs_node`` checked against the
    manifest's statistics and removed, since the host applies the manifest's normalisation
    (:mod:`snnkart.contract.obs_node`)."""
    if manifest.obs_node is None:
        return graph
    try:
        return without_obs_node(
            graph, manifest.obs_node, np.asarray(manifest.obs_mean), np.asarray(manifest.obs_std)
        )
    except ValueError as exc:
        raise NIRFileError(f"{path}: {exc}; export the policy again") from None


def as_policy(source: str | Path | LoadedPolicy) -> LoadedPolicy:
    """``source`` itself if already loaded, else the policy read from that path."""
    return source if isinstance(source, LoadedPolicy) else load_policy(source)


def read_graph(path: str | Path, missing: str = "") -> Any:
    """A NIR graph, or a clear error for a missing or unreadable file (``missing``: what to
    do about a missing one)."""
    import nir

    path = Path(path)
    if not path.is_file():
        raise NIRFileError(f"no NIR file at {path}{missing}")
    try:
        return nir.read(path)
    except Exception as exc:  # h5py raises several types for truncated or foreign files
        raise NIRFileError(
            f"{path}: not a readable NIR file ({type(exc).__name__}: {exc})"
        ) from exc


def load_nir(path: str | Path) -> tuple[Any, Manifest]:
    """Read a NIR graph and its manifest, with clear errors for missing or broken files."""
    path = Path(path)
    if not path.is_file():
        raise NIRFileError(f"no NIR file at {path}{MISSING_HINT}")
    manifest = Manifest.read(manifest_path(path))
    return read_graph(path, MISSING_HINT), manifest


def load_chain(path: str | Path) -> tuple[ChainNetwork, Manifest]:
    """A policy's chain checked against its manifest, and the manifest (see
    :func:`load_policy`, which also keeps the graph)."""
    policy = load_policy(path)
    return policy.chain, policy.manifest


def _checked_chain(path: Path, graph: Any, manifest: Manifest) -> ChainNetwork:
    try:
        chain = chain_from_graph(graph, manifest.nir_dt, manifest.discretisation)
    except UnsupportedGraphError as exc:
        raise NIRFileError(f"{path}: {exc}") from exc
    if chain.n_in != manifest.input_size:
        fields = f" x {manifest.population} receptive fields" if manifest.population else ""
        raise NIRFileError(
            f"{path}: the graph takes {chain.n_in} inputs but the manifest's observation has "
            f"{manifest.obs_dim}{fields}"
        )
    if len(chain.layers) != len(manifest.layers):
        raise NIRFileError(
            f"{path}: the graph has {len(chain.layers)} spiking layers, the manifest "
            f"{len(manifest.layers)}"
        )
    layers = [
        _checked_layer(path, layer, spec)
        for layer, spec in zip(chain.layers, manifest.layers, strict=True)
    ]
    if manifest.readout_node and chain.readout_node != manifest.readout_node:
        raise NIRFileError(f"{path}: readout node {chain.readout_node!r} is not the manifest's")
    return dataclasses.replace(chain, layers=tuple(layers))


def _checked_layer(path: Path, layer: SpikingLayer, spec: LayerSpec) -> SpikingLayer:
    """``layer`` with the manifest's decays, or an error naming what does not match."""
    if layer.neuron != spec.node or layer.size != spec.size:
        raise NIRFileError(
            f"{path}: LIF node {layer.neuron!r} ({layer.size} neurons) does not match the "
            f"manifest's layer {spec.node!r} ({spec.size})"
        )
    if np.any(layer.v_reset != 0):
        raise NIRFileError(f"{path}: LIF node {spec.node} does not reset to 0")
    if np.ptp(layer.beta) > 1e-6 or np.ptp(layer.threshold) > 0:
        raise NIRFileError(f"{path}: LIF node {spec.node} has non-uniform decay or threshold")
    if abs(layer.beta[0] - spec.beta) > 1e-6 or layer.threshold[0] != spec.threshold:
        raise NIRFileError(
            f"{path}: LIF node {spec.node} (beta {layer.beta[0]:.6f}, threshold "
            f"{layer.threshold[0]}) does not match the manifest (beta {spec.beta:.6f}, "
            f"threshold {spec.threshold})"
        )
    if (layer.alpha is None) != (spec.alpha is None) or (
        layer.alpha is not None
        and spec.alpha is not None
        and (np.ptp(layer.alpha) > 1e-6 or abs(layer.alpha[0] - spec.alpha) > 1e-6)
    ):
        raise NIRFileError(
            f"{path}: node {spec.node}'s current decay ({_alpha(layer.alpha)}) does not "
            f"match the manifest's ({spec.alpha})"
        )
    alpha = None if spec.alpha is None else np.full(layer.size, spec.alpha)
    return dataclasses.replace(layer, beta=np.full(layer.size, spec.beta), alpha=alpha)


def _alpha(alpha: np.ndarray | None) -> str:
    return "none: a LIF" if alpha is None else f"alpha {alpha[0]:.6f}"
