"""A sigma-delta policy on disk for the tests (reusable): a NIR graph ``Input -> fc1 -> fc2 ->
readout -> Output`` of ``nir.Affine`` nodes and a v3 manifest with a ``sigma_delta`` block,
for the grid env of the committed ANN test policy (``tests/data/policies/grid-ann``: its
observation normaliser, env spec and track).

Weights: the ANN's actor (21 -> 64 -> 64 -> 5, trained with tanh; here run as ReLU, which is
what a conversion would do) or, with ``hidden`` given, a small random net. Units are chosen so
the largest integer weight of each Dense is about 120 (8-bit Lava weights)."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from snnkart.contract.encoding import obs_std
from snnkart.contract.manifest import MANIFEST_SCHEMA, Manifest, manifest_path
from snnkart.contract.sigma_delta import SigmaDeltaBlock, SigmaDeltaLayer
from snnkart.envs.spec import spec_hash

ROOT = Path(__file__).resolve().parents[1]
ANN_RUN = ROOT / "tests/data/policies/grid-ann"
INPUT_SCALE = 1 / 12
"""Input unit: z in [-10, 10] (the manifest's clip) becomes an integer in [-120, 120]."""


@cache
def _ann() -> dict[str, Any]:
    """What the policy borrows from the committed grid ANN run (loaded once)."""
    from snnkart.rl.trained import load_run

    run = load_run(ANN_RUN)
    linears = [m for m in run.policy.actor if hasattr(m, "weight")]
    return {
        "weights": [m.weight.detach().numpy().astype(np.float32) for m in linears],
        "biases": [m.bias.detach().numpy().astype(np.float32) for m in linears],
        "mean": tuple(float(x) for x in run.obs_rms.mean),
        "std": tuple(float(x) for x in obs_std(run.obs_rms.var)),
        "clip": float(run.config.ppo.clip_obs),
        "spec": run.meta["env_spec"],
        "track": run.track_record(),
        "versions": dict(run.meta.get("versions", {})),
    }


def _random_net(sizes: Sequence[int], seed: int) -> tuple[list[np.ndarray], list[np.ndarray]]:
    rng = np.random.default_rng(seed)
    ws = [
        rng.normal(0, 1 / np.sqrt(a), (b, a)).astype(np.float32)
        for a, b in itertools.pairwise(sizes)
    ]
    bs = [rng.normal(0, 0.1, b).astype(np.float32) for b in sizes[1:]]
    return ws, bs


def write_sigma_delta_policy(
    out_dir: Path,
    *,
    hidden: Sequence[int] | None = None,
    vth: Sequence[int] | int = 0,
    vth_in: int = 0,
    seed: int = 0,
    divisor: float = 120,
) -> Path:
    """Write ``policy.nir`` and its manifest into ``out_dir``; return the ``.nir`` path.
    ``hidden`` None: the ANN's weights; else a random net with these hidden sizes.
    ``vth``: each hidden layer's threshold (integer units), or one for all. ``divisor``: each
    unit is ``max|W| x`` the previous unit ``/ divisor`` (the trained kind's is 254: finer
    units, wider integers)."""
    import nir

    ann = _ann()
    if hidden is None:
        weights, biases = ann["weights"], ann["biases"]
    else:
        n_in, n_out = ann["weights"][0].shape[1], ann["weights"][-1].shape[0]
        weights, biases = _random_net([n_in, *hidden, n_out], seed)
    units = [INPUT_SCALE]
    for w in weights:
        units.append(float(np.abs(w).max()) * units[-1] / divisor)
    names = [f"fc{i + 1}" for i in range(len(weights) - 1)] + ["readout"]
    vths = [vth] * (len(weights) - 1) if isinstance(vth, int) else list(vth)
    block = SigmaDeltaBlock(
        layers=tuple(
            SigmaDeltaLayer(node=name, size=int(w.shape[0]), act_scale=unit, vth=int(v))
            for name, w, unit, v in zip(names[:-1], weights[:-1], units[1:-1], vths, strict=True)
        ),
        readout_node="readout", input_scale=INPUT_SCALE, out_scale=units[-1], vth_in=vth_in,
        input_bits=8, origin="ann-relu",
    )  # fmt: skip
    nodes: dict[str, Any] = {"input": nir.Input(input_type=np.array([weights[0].shape[1]]))}
    for name, w, b in zip(names, weights, biases, strict=True):
        nodes[name] = nir.Affine(weight=w, bias=b)
    nodes["output"] = nir.Output(output_type=np.array([weights[-1].shape[0]]))
    order = list(nodes)
    graph = nir.NIRGraph(nodes=nodes, edges=list(itertools.pairwise(order)))
    spec = ann["spec"]
    lows = [lo for _, n, lo, _ in spec["observation_layout"] for _ in range(n)]
    highs = [hi for _, n, _, hi in spec["observation_layout"] for _ in range(n)]
    manifest = Manifest(
        schema=MANIFEST_SCHEMA, nir_file="policy.nir", nir_dt=1e-3, num_steps=1, layers=(),
        encoding="delta", obs_mean=ann["mean"], obs_std=ann["std"], obs_clip=ann["clip"],
        obs_low=tuple(float(x) for x in lows), obs_high=tuple(float(x) for x in highs),
        readout_node="readout", action_mode=spec["action_mode"],
        env={**spec, "env_spec_hash": spec_hash(spec)}, versions=ann["versions"],
        track=ann["track"], state_persists=True, sigma_delta=block,
        training={"source": "tests/sigma_delta_policy.py"},
    )  # fmt: skip
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "policy.nir"
    nir.write(path, graph)
    manifest.write(manifest_path(path))
    return path
