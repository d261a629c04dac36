"""A sigma-delta policy loaded once: the NIR graph's affine layers, in order, checked against
the manifest's ``sigma_delta`` block (:mod:`snnkart.contract.sigma_delta`), and the chain it
makes in each arithmetic (:func:`snnkart.backends.sigma_delta.spec_from_block`).

The graph is ``Input -> fc1 -> ... -> fcL -> readout -> Output``, every inner node a
``nir.Affine`` (a ``nir.Linear`` counts as one with zero bias); the ReLU between them, the units,
thresholds and message bits are the block's. Every mismatch is one
:class:`~snnkart.errors.NIRFileError` line naming the file, the node and what to do.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from snnkart.backends.base import Arithmetic
from snnkart.backends.graph_walk import chain_order as _chain_order
from snnkart.backends.sigma_delta import SigmaDeltaSpec, spec_from_block
from snnkart.contract.deploy_record import NetworkShape
from snnkart.contract.manifest import Manifest
from snnkart.contract.sigma_delta import SigmaDeltaBlock
from snnkart.errors import NIRFileError, UnsupportedGraphError

REEXPORT = "; export the policy again"


@dataclass(frozen=True)
class SigmaDeltaPolicy:
    """An exported sigma-delta policy: ``weights[i]`` ``[n_out, n_in]`` and ``biases[i]`` of
    the graph's affine layers in order (hidden layers, then the readout), as stored (float32),
    with the manifest and its block."""

    path: Path
    graph: Any  # nir.NIRGraph
    manifest: Manifest
    block: SigmaDeltaBlock
    weights: tuple[np.ndarray, ...]
    biases: tuple[np.ndarray, ...]
    family: ClassVar[str] = "sigma_delta"

    @property
    def readout_bias(self) -> np.ndarray:
        """The readout's bias, added on the host (:func:`readout_value`)."""
        return self.biases[-1]

    @property
    def sizes(self) -> tuple[int, ...]:
        """Neurons of every sending layer, in order: the input Delta, each SigmaDelta, the
        readout Sigma."""
        return (int(self.weights[0].shape[1]), *(int(w.shape[0]) for w in self.weights))

    @property
    def num_steps(self) -> int:
        """Policy steps per env step: 1 (the block's ``rows`` Lava steps compute it)."""
        return self.manifest.num_steps

    def shape(self) -> NetworkShape:
        """The chain's shape, as the deploy record keeps it: the input, the SigmaDelta layers
        and the readout."""
        n_in, *hidden, n_out = self.sizes
        return NetworkShape(n_in=n_in, sizes=tuple(hidden), n_out=n_out)

    def spec(self, arithmetic: Arithmetic) -> SigmaDeltaSpec:
        """The chain in ``arithmetic`` (``fixed`` or ``float64``)."""
        return spec_from_block(self.block, list(self.weights), list(self.biases), arithmetic)


def affine_layers(graph: Any) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """``(node, weight, bias)`` of every node between the graph's Input and Output, in order;
    anything but an Affine or Linear there raises :class:`UnsupportedGraphError`."""
    import nir

    order = _chain_order(graph)
    layers = []
    for name in order[1:-1]:
        node = graph.nodes[name]
        if not isinstance(node, nir.Affine | nir.Linear):
            raise UnsupportedGraphError(
                f"node {name!r} is a {type(node).__name__}; a sigma-delta graph holds only "
                "Affine (or Linear) nodes between its Input and Output"
            )
        weight = np.asarray(node.weight, dtype=np.float32)
        bias = getattr(node, "bias", None)
        bias = np.zeros(weight.shape[0], np.float32) if bias is None else np.asarray(bias)
        if not (np.isfinite(weight).all() and np.isfinite(bias).all()):
            raise UnsupportedGraphError(f"node {name!r}: NaN or infinite weights or bias")
        layers.append((name, weight, bias.astype(np.float32)))
    return layers


def sigma_delta_policy(path: Path, graph: Any, manifest: Manifest) -> SigmaDeltaPolicy:
    """``graph`` checked against ``manifest``'s sigma-delta block (which it must have)."""
    block = manifest.sigma_delta
    if block is None:
        raise NIRFileError(f"{path}: the manifest has no sigma_delta block")
    try:
        layers = affine_layers(graph)
    except UnsupportedGraphError as exc:
        raise NIRFileError(f"{path}: {exc}") from exc
    names = [*(la.node for la in block.layers), block.readout_node]
    if [name for name, _, _ in layers] != names:
        raise NIRFileError(
            f"{path}: the graph's affine nodes {[n for n, _, _ in layers]} are not the "
            f"sigma_delta block's {names} (hidden layers, then the readout){REEXPORT}"
        )
    n_in = manifest.obs_dim
    for (name, w, _), want in zip(layers, (*(la.size for la in block.layers), None), strict=True):
        if w.shape[1] != n_in:
            raise NIRFileError(
                f"{path}: node {name!r} takes {w.shape[1]} inputs but gets {n_in}{REEXPORT}"
            )
        if want is not None and w.shape[0] != want:
            raise NIRFileError(
                f"{path}: node {name!r} has {w.shape[0]} neurons, the sigma_delta block says "
                f"{want}{REEXPORT}"
            )
        n_in = w.shape[0]
    return SigmaDeltaPolicy(
        path=path,
        graph=graph,
        manifest=manifest,
        block=block,
        weights=tuple(w for _, w, _ in layers),
        biases=tuple(b for _, _, b in layers),
    )
