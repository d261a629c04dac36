"""Replays a sigma-delta deployment's messages on SANA-FE's Loihi model, in a process of its own.

SANA-FE 2.2.9 has no sigma-delta neuron and no graded message, so each message is mapped to a
spike event: the sending layer is an input group replaying which of its neurons sent at each
Lava row, and the receiving layer a LIF group that integrates without ever firing (threshold
out of reach, no leak, no reset), so SANA-FE charges what it charges a Loihi neuron for every
mapped neuron at every row (access) and for every one with input, potential or bias (update),
and for every event its synapse, packet and hops. What the payload leaves out: the spike
carries no value, so a message costs one binary event whatever its bits, and a synaptic event
is an accumulate, not the multiply a graded one is. Like :mod:`snnkart.energy.sanafe_worker`,
this file imports numpy and sanafe, nothing of snnkart, and is run as a script
(``python -I sanafe_sd_worker.py JOB_DIR``).

Input, in ``JOB_DIR``: ``job.json`` (``sizes``: the input Delta's ``n_in``, each SigmaDelta
layer's size, the readout Sigma's ``n_out``; ``rows``: Lava steps per env step;
``neurons_per_core``) and ``job.npz`` (``weight{i}`` ``[sizes[i+1], sizes[i]]`` for the Dense
from sending layer i; ``bias{i}`` ``[sizes[i]]`` for i >= 1; ``sent{i}`` for the sending
layers i = 0..L: ``[E, rows, sizes[i]]`` bool, which neurons sent at each row of env step e, or
``[E, sizes[i]]``, which sent in env step e, placed at row i as the held schedule has it).
Output: ``result.json``.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
import time
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

COMPONENTS = ("synapse", "dendrite", "soma", "network")
NEVER = 1e30
"""The receiving groups' threshold: they integrate and never fire (the messages are replayed)."""


def build(sanafe: Any, job: dict[str, Any], arrays: Any) -> Any:
    """The chip with the replay network loaded (module docstring): ``R{i}`` replays sending
    layer i (i = 0: the host's Delta, on a core of its own; else on ``N{i}``'s cores),
    ``N{i}`` (i >= 1) integrates; each group starts a fresh core (tile k // 4, core k % 4)."""
    arch = sanafe.load_loihi()
    sizes, per_core = job["sizes"], job["neurons_per_core"]
    cores, k = [], 0
    for n in sizes:
        chunks = -(-n // per_core)
        cores.append([arch.tiles[(k + c) // 4].cores[(k + c) % 4] for c in range(chunks)])
        k += chunks
    net = sanafe.Network()
    attrs = {"threshold": NEVER, "leak_decay": 1.0, "input_decay": 0.0, "reset_mode": "none"}
    lif = {}
    for i in range(1, len(sizes)):
        group = net.create_neuron_group(
            f"N{i}", sizes[i], soma_hw_name="loihi_lif",
            default_synapse_hw_name="loihi_dense_synapse", model_attributes=attrs,
        )  # fmt: skip
        for j, neuron in enumerate(group):
            neuron.set_attributes(model_attributes={"bias": float(arrays[f"bias{i}"][j])})
            neuron.map_to_core(cores[i][j // per_core])
        lif[i] = group
    for i in range(len(sizes) - 1):
        src = net.create_neuron_group(f"R{i}", sizes[i])
        for j, neuron in enumerate(src):
            neuron.set_attributes(soma_hw_name=f"loihi_inputs[{j % per_core}]")
            neuron.map_to_core(cores[i][j // per_core])
        weight = np.asarray(arrays[f"weight{i}"], dtype=np.float64)  # [post, pre]
        src.connect_neurons_dense(lif[i + 1], {"weight": weight.T.ravel().tolist()})
    chip = sanafe.SpikingChip(arch)
    chip.load(net)
    return chip


def _train(sent: np.ndarray, j: int, layer: int, rows: int) -> list[bool]:
    """Neuron ``j``'s spikes over the rows of one env step: as recorded per row, or, from a
    per-env-step mask, at row ``layer`` (the held schedule)."""
    if sent.ndim == 2:
        return [bool(x) for x in sent[:, j]]
    return [bool(sent[j]) and r == layer for r in range(rows)]


def run(sanafe: Any, job: dict[str, Any], arrays: Any) -> dict[str, Any]:
    """Every env step: each sending layer's messages set at its row, then ``rows`` rows run."""
    t0 = time.perf_counter()
    chip = build(sanafe, job, arrays)
    sizes, rows = job["sizes"], job["rows"]
    senders = range(len(sizes) - 1)
    sent = [np.asarray(arrays[f"sent{i}"], dtype=bool) for i in senders]
    energy = dict.fromkeys(COMPONENTS, 0.0)
    counts = dict.fromkeys(("synaptic_events", "packets", "neurons_updated", "neurons_fired",
                            "hops"), 0)  # fmt: skip
    latency: list[float] = []
    groups = chip.mapped_neuron_groups
    for e in range(sent[0].shape[0]):
        for i in senders:
            for j, neuron in enumerate(groups[f"R{i}"]):
                train = _train(sent[i][e], j, i, rows)
                neuron.set_attributes(model_attributes={"spikes": train})
        with contextlib.redirect_stdout(io.StringIO()):
            res = chip.sim(rows, perf_trace=True, processing_threads=1)
        for k in COMPONENTS:
            energy[k] += res["energy"][k]
        latency.append(float(sum(res["perf_trace"]["sim_time"])))
        counts["hops"] += int(sum(res["perf_trace"]["hops"]))
        for key, name in (("synaptic_events", "spikes"), ("packets", "packets_sent"),
                          ("neurons_updated", "neurons_updated"),
                          ("neurons_fired", "neurons_fired")):  # fmt: skip
            counts[key] += int(res[name])
    return {
        "env_steps": int(sent[0].shape[0]), "rows": rows, "energy_j": energy, "counts": counts,
        "messages": [int(s.sum()) for s in sent],  # per sending layer, all env steps
        "lif_neuron_rows": int(sum(sizes[1:]) * rows * sent[0].shape[0]),
        "latency_s": {"mean": float(np.mean(latency)) if latency else 0.0,
                      "max": float(np.max(latency)) if latency else 0.0},
        "wall_s": time.perf_counter() - t0,
    }  # fmt: skip


def main(job_dir: Path) -> None:
    job = json.loads((job_dir / "job.json").read_text())
    import sanafe  # GPL-3.0: only ever in this process

    with np.load(job_dir / "job.npz", allow_pickle=False) as f:
        arrays = {k: f[k] for k in f.files}
    result = run(sanafe, job, arrays)
    result["sanafe_version"] = metadata.version("sanafe")
    (job_dir / "result.json").write_text(json.dumps(result))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
