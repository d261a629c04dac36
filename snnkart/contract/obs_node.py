"""The observation normalisation as a node of the graph (manifest v4's ``obs_node``).

An exported graph takes the env's raw observation: its first node after the input is an
``nir.Affine`` of weight ``diag(1 / std)`` and bias ``-mean / std``, the frozen statistics of
training's normaliser, so any NIR reader (snnTorch, Norse, another chip's toolchain) gets the
policy as trained from raw observations. NIR has no clip: the clip to ``+-obs_clip`` stays in
the manifest, and a reader that runs the graph clips the raw observation to
``obs_mean +- obs_clip * obs_std`` first (:func:`raw_clip`; a policy trained briefly, whose
variances are small, sees observations beyond that often). snnkart's backends do not run the
node's float arithmetic: they check that it holds the manifest's statistics and apply the
manifest's normalisation (the contract's :func:`~snnkart.contract.encoding.normalise`, clip
included), so a v4 export deploys exactly as a v3 one did.

Sharp edge: the node's weight and bias are float64 (``1 / std`` is not exactly representable);
the check allows a relative 1e-12.
"""

from __future__ import annotations

import copy
from typing import Any

import numpy as np

OBS_NODE = "normalise"
"""The node's name in snnkart's exports."""


def node_arrays(mean: np.ndarray, std: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The node's weight ``diag(1 / std)`` and bias ``-mean / std`` (float64)."""
    mean, std = np.asarray(mean, dtype=np.float64), np.asarray(std, dtype=np.float64)
    return np.diag(1.0 / std), -mean / std


def raw_clip(obs: np.ndarray, mean: np.ndarray, std: np.ndarray, clip: float) -> np.ndarray:
    """The normaliser's clip in the raw observation's units: ``clip((obs - mean) / std, +-c)
    = (clip(obs, mean - c std, mean + c std) - mean) / std``."""
    mean, std = np.asarray(mean, dtype=np.float64), np.asarray(std, dtype=np.float64)
    return np.clip(np.asarray(obs, dtype=np.float64), mean - clip * std, mean + clip * std)


def with_obs_node(graph: Any, mean: np.ndarray, std: np.ndarray, name: str = OBS_NODE) -> Any:
    """``graph`` with the normalisation node between its input and what the input fed."""
    import nir

    inputs = [n for n, node in graph.nodes.items() if isinstance(node, nir.Input)]
    if len(inputs) != 1 or name in graph.nodes:
        raise ValueError(f"cannot insert {name!r}: the graph needs one input and no such node")
    (src,) = inputs
    weight, bias = node_arrays(mean, std)
    nodes = {**graph.nodes, name: nir.Affine(weight=weight, bias=bias)}
    edges = [(src, name)] + [(name if a == src else a, b) for a, b in graph.edges]
    out = nir.NIRGraph(nodes=nodes, edges=edges)
    out.metadata = copy.deepcopy(getattr(graph, "metadata", {}) or {})
    return out


def without_obs_node(graph: Any, name: str, mean: np.ndarray, std: np.ndarray) -> Any:
    """``graph`` with its normalisation node ``name`` removed (the input feeding what the node
    fed), after checking that the node normalises with ``mean`` and ``std``; ``ValueError``
    saying what does not match."""
    import nir

    node = graph.nodes.get(name)
    if not isinstance(node, nir.Affine):
        raise ValueError(f"the manifest's obs_node {name!r} is not an Affine node of the graph")
    into = [a for a, b in graph.edges if b == name]
    if len(into) != 1 or not isinstance(graph.nodes[into[0]], nir.Input):
        raise ValueError(f"obs_node {name!r} is not fed by the graph's input alone")
    weight, bias = node_arrays(mean, std)
    got_w = np.asarray(node.weight, dtype=np.float64)
    got_b = np.asarray(node.bias, dtype=np.float64)
    if got_w.shape != weight.shape:
        raise ValueError(
            f"the graph's obs_node {name!r} takes {got_w.shape[-1]} inputs but the manifest's "
            f"observation has {weight.shape[0]}"
        )
    if not (
        np.allclose(got_w, weight, rtol=1e-12, atol=0) and np.allclose(got_b, bias, rtol=1e-12)
    ):
        raise ValueError(
            f"obs_node {name!r} does not normalise with the manifest's obs_mean and obs_std"
        )
    src = into[0]
    nodes = {k: v for k, v in graph.nodes.items() if k != name}
    edges = [(src if a == name else a, b) for a, b in graph.edges if b != name]
    out = nir.NIRGraph(nodes=nodes, edges=edges)
    out.metadata = getattr(graph, "metadata", {})
    return out
