"""Runs a deployed network on SANA-FE's Loihi model, in a process of its own.

SANA-FE (``pip install 'snnkart[sanafe]'``, GPL-3.0) is imported here only, and this file is
run as a script by :func:`snnkart.energy.sanafe_model.run_sanafe` (``python -I sanafe_worker.py
JOB_DIR``), so SANA-FE never loads into snnkart's process and a C++ abort in it cannot take
snnkart down. It imports numpy and sanafe, nothing of snnkart.

Input, in ``JOB_DIR``: ``job.json`` (per layer ``n``, ``threshold``, ``leak_decay``,
``input_decay``; ``rows`` W and ``steps`` T per window; ``modes``; ``neurons_per_core``) and
``job.npz`` (``bias{i}`` ``[n_i]``, ``weight{i}`` ``[n_i, n_{i-1}]`` for i >= 1, ``current``
``[E, T or 1, n_0]``, ``raster`` ``[E, W, N]`` bool: layer i's logical step t at row i + t); optionally
``env_steps``, per mode the number of env steps to run (default: all).
Output: ``result.json``, one entry per mode.

The network, per layer i: a LIF group ``N{i}`` (``loihi_lif``, dense synapses), reset (its
potential set to 0) at row i of every window as Lava's ``LIFReset`` does; layer 0 is driven by
the host's current as a per-row bias. Modes:

- ``replay``: layer by layer; an input group ``R{i}`` on layer i's core replays layer i's
  recorded spikes into ``N{i+1}``, so every synaptic event and message is the deployment's
  own, whatever SANA-FE's LIF computes;
- ``chain``: ``N{i}`` feeds ``N{i+1}`` directly: does SANA-FE's LIF reproduce the spikes?

A spike sent at row r is integrated at row r + 1 (one step per layer, as Lava's Dense).

A sigma-delta job (``job.json`` ``family: "sigma_delta"``, written by
:mod:`snnkart.energy.sanafe_sigma_delta`) replays a deployment's messages instead. SANA-FE 2.2.9
has no sigma-delta neuron and no graded message, so each message is mapped to a spike event:
the sending layer is an input group replaying which of its neurons sent at each Lava row, and
the receiving layer a LIF group that integrates without ever firing (threshold out of reach,
no leak, no reset), so SANA-FE charges what it charges a Loihi neuron for every mapped neuron
at every row (access) and for every one with input, potential or bias (update), and for every
event its synapse, packet and hops. What the payload leaves out: the spike carries no value, so
a message costs one binary event whatever its bits, and a synaptic event is an accumulate, not
the multiply a graded one is. Its ``job.json``: ``sizes`` (the input Delta's ``n_in``, each
SigmaDelta layer's size, the readout Sigma's ``n_out``), ``rows`` (Lava steps per env step),
``neurons_per_core``; its ``job.npz``: ``weight{i}`` ``[sizes[i+1], sizes[i]]`` for the Dense
from sending layer i, ``bias{i}`` ``[sizes[i]]`` for i >= 1, ``sent{i}`` for the sending layers
i = 0..L: ``[E, rows, sizes[i]]`` bool, which neurons sent at each row of env step e, or
``[E, sizes[i]]``, which sent in env step e, placed at row i as the held schedule has it.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
import time
from importlib import metadata
from itertools import pairwise
from pathlib import Path
from typing import Any

import numpy as np

COMPONENTS = ("synapse", "dendrite", "soma", "network")
NEVER = 1e30
"""A sigma-delta job's receiving groups' threshold: they integrate and never fire."""


def _cores(arch: Any, sizes: list[int], per_core: int) -> list[list[Any]]:
    """Each layer's cores, a layer starting a fresh core (tile k // 4, core k % 4)."""
    out, k = [], 0
    for n in sizes:
        chunks = -(-n // per_core)
        out.append([arch.tiles[(k + c) // 4].cores[(k + c) % 4] for c in range(chunks)])
        k += chunks
    return out


def build(sanafe: Any, job: dict[str, Any], arrays: Any, mode: str) -> Any:
    """The chip with the job's network loaded (module docstring)."""
    arch = sanafe.load_loihi()
    layers, per_core = job["layers"], job["neurons_per_core"]
    sizes = [layer["n"] for layer in layers]
    cores = _cores(arch, sizes, per_core)
    net = sanafe.Network()
    lif = []
    for i, layer in enumerate(layers):
        attrs = {k: layer[k] for k in ("threshold", "leak_decay", "input_decay")}
        group = net.create_neuron_group(
            f"N{i}",
            layer["n"],
            log_spikes=True,
            soma_hw_name="loihi_lif",
            default_synapse_hw_name="loihi_dense_synapse",
            model_attributes={**attrs, "reset": 0.0, "reset_mode": "hard"},
        )
        for j, neuron in enumerate(group):
            neuron.set_attributes(model_attributes={"bias": float(arrays[f"bias{i}"][j])})
            neuron.map_to_core(cores[i][j // per_core])
        lif.append(group)
    for i in range(1, len(layers)):
        src = lif[i - 1]
        if mode == "replay":
            src = net.create_neuron_group(f"R{i - 1}", sizes[i - 1], log_spikes=True)
            for j, neuron in enumerate(src):
                neuron.set_attributes(soma_hw_name=f"loihi_inputs[{j % per_core}]")
                neuron.map_to_core(cores[i - 1][j // per_core])
        weight = np.asarray(arrays[f"weight{i}"], dtype=np.float64)  # [n_i, n_{i-1}]
        src.connect_neurons_dense(lif[i], {"weight": weight.T.ravel().tolist()})  # (pre, post)
    chip = sanafe.SpikingChip(arch)
    chip.load(net)
    return chip


class Tally:
    """What SANA-FE reported, summed over windows, and its spikes per group and row."""

    def __init__(self, sizes: list[int], rows: int) -> None:
        self.energy = dict.fromkeys(COMPONENTS, 0.0)
        self.counts = dict.fromkeys(
            ("synaptic_events", "packets", "neurons_updated", "neurons_fired", "hops"), 0
        )
        self.latency: list[float] = []
        self.sizes, self.rows = sizes, rows
        self.offsets = np.cumsum((0, *sizes))
        self.window = np.zeros((rows, int(self.offsets[-1])), dtype=bool)
        self.replayed = np.zeros(len(sizes), dtype=np.int64)

    def latency_s(self) -> dict[str, float]:
        """Simulated latency per env step: mean and max (s)."""
        lat = self.latency
        return {
            "mean": float(np.mean(lat)) if lat else 0.0,
            "max": float(np.max(lat)) if lat else 0.0,
        }

    def add(self, res: dict[str, Any], row: int) -> None:
        for k in COMPONENTS:
            self.energy[k] += res["energy"][k]
        perf = res["perf_trace"]
        self.latency[-1] += float(sum(perf["sim_time"]))
        self.counts["hops"] += int(sum(perf["hops"]))
        for key, name in (
            ("synaptic_events", "spikes"),
            ("packets", "packets_sent"),
            ("neurons_updated", "neurons_updated"),
            ("neurons_fired", "neurons_fired"),
        ):
            self.counts[key] += int(res[name])
        for dt, step in enumerate(res.get("spike_trace") or ()):
            for address in step:
                kind, layer = address.group_name[0], int(address.group_name[1:])
                if kind == "N":
                    self.window[row + dt, self.offsets[layer] + address.neuron_offset] = True
                else:
                    self.replayed[layer] += 1


def _events(job: dict[str, Any], held: bool) -> list[int]:
    """The rows of a window at which something is set: each layer's reset (row i), and layer
    0's current (each row it changes, and row T where the host stops sending)."""
    rows, steps = job["rows"], job["steps"]
    marks = set(range(len(job["layers"]))) | ({steps} if steps < rows else set())
    if not held:
        marks |= set(range(steps))
    return sorted(marks | {rows})


def _set_row(groups: Any, row: int, steps: int, current: np.ndarray, bias0: np.ndarray) -> None:
    """Before ``row``: layer ``row``'s reset (potential 0), and layer 0's bias, its own plus
    the host's current of this row (none from row T on)."""
    reset = {"potential": 0.0}
    if 0 < row < len(groups):
        for neuron in groups[f"N{row}"]:
            neuron.set_attributes(model_attributes=reset)
    if row <= steps:
        drive = current[min(row, len(current) - 1)] if row < steps else np.zeros_like(bias0)
        for j, neuron in enumerate(groups["N0"]):
            attrs = {**(reset if row == 0 else {}), "bias": float(bias0[j] + drive[j])}
            neuron.set_attributes(model_attributes=attrs)


def run_window(chip: Any, job: dict[str, Any], arrays: Any, e: int, tally: Tally) -> None:
    """One env step's W rows: replay spikes set, then the rows simulated between events."""
    groups, offsets = chip.mapped_neuron_groups, tally.offsets
    raster, current = arrays["raster"][e], arrays["current"][e]
    lif = {name: group for name, group in groups.items() if name.startswith("N")}
    for i in range(len(tally.sizes) - 1):
        for j, neuron in enumerate(groups.get(f"R{i}", [])):
            spikes = raster[:, offsets[i] + j].tolist()
            neuron.set_attributes(model_attributes={"spikes": spikes})
    tally.window[:] = False
    tally.latency.append(0.0)
    for start, stop in pairwise(_events(job, len(current) == 1)):
        _set_row(lif, start, job["steps"], current, arrays["bias0"])
        with contextlib.redirect_stdout(io.StringIO()):
            res = chip.sim(stop - start, spike_trace=True, perf_trace=True, processing_threads=1)
        tally.add(res, start)


def run(sanafe: Any, job: dict[str, Any], arrays: Any, mode: str) -> dict[str, Any]:
    """The job's env steps in ``mode`` (the first ``job["env_steps"][mode]`` of them, or all):
    energies (J), counts, latency per env step (s), and per layer the spikes SANA-FE saw
    against the recorded ones."""
    t0 = time.perf_counter()
    chip = build(sanafe, job, arrays, mode)
    sizes, rows, steps = [x["n"] for x in job["layers"]], job["rows"], job["steps"]
    tally = Tally(sizes, rows)
    limit = job.get("env_steps", {}).get(mode)
    raster = arrays["raster"][:limit]
    fired = np.zeros(len(sizes), dtype=np.int64)
    mismatched = np.zeros(len(sizes), dtype=np.int64)
    for e in range(raster.shape[0]):
        run_window(chip, job, arrays, e, tally)
        for i in range(len(sizes)):
            cols = slice(tally.offsets[i], tally.offsets[i + 1])
            fired[i] += int(tally.window[:, cols].sum())
            logical = slice(i, i + steps)
            mismatched[i] += int((tally.window[logical, cols] != raster[e][logical, cols]).sum())
    offsets = tally.offsets
    recorded = [int(raster[:, :, a:b].sum()) for a, b in pairwise(offsets)]
    return {
        "mode": mode,
        "env_steps": int(raster.shape[0]),
        "rows": rows,
        "energy_j": tally.energy,
        "counts": tally.counts,
        "lif_neuron_rows": int(sum(sizes) * rows * raster.shape[0]),
        "latency_s": tally.latency_s(),
        "recorded_spikes": recorded,
        "lif_spikes": fired.tolist(),
        "replayed_spikes": tally.replayed.tolist(),
        "lif_mismatched_logical_neuron_steps": mismatched.tolist(),
        "wall_s": time.perf_counter() - t0,
    }


def build_sigma_delta(sanafe: Any, job: dict[str, Any], arrays: Any) -> Any:
    """The chip with the replay network loaded (module docstring): ``R{i}`` replays sending
    layer i (i = 0: the host's Delta, on a core of its own; else on ``N{i}``'s cores),
    ``N{i}`` (i >= 1) integrates; each group starts a fresh core (tile k // 4, core k % 4)."""
    arch = sanafe.load_loihi()
    sizes, per_core = job["sizes"], job["neurons_per_core"]
    cores = _cores(arch, sizes, per_core)
    net = sanafe.Network()
    attrs = {"threshold": NEVER, "leak_decay": 1.0, "input_decay": 0.0, "reset_mode": "none"}
    lif = {}
    for i in range(1, len(sizes)):
        group = net.create_neuron_group(
            f"N{i}",
            sizes[i],
            soma_hw_name="loihi_lif",
            default_synapse_hw_name="loihi_dense_synapse",
            model_attributes=attrs,
        )
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


def run_sigma_delta(sanafe: Any, job: dict[str, Any], arrays: Any) -> dict[str, Any]:
    """Every env step: each sending layer's messages set at its row, then ``rows`` rows run."""
    t0 = time.perf_counter()
    chip = build_sigma_delta(sanafe, job, arrays)
    sizes, rows = job["sizes"], job["rows"]
    senders = range(len(sizes) - 1)
    sent = [np.asarray(arrays[f"sent{i}"], dtype=bool) for i in senders]
    tally = Tally(sizes, rows)
    groups = chip.mapped_neuron_groups
    for e in range(sent[0].shape[0]):
        for i in senders:
            for j, neuron in enumerate(groups[f"R{i}"]):
                train = _train(sent[i][e], j, i, rows)
                neuron.set_attributes(model_attributes={"spikes": train})
        tally.latency.append(0.0)
        with contextlib.redirect_stdout(io.StringIO()):
            tally.add(chip.sim(rows, perf_trace=True, processing_threads=1), 0)
    return {
        "env_steps": int(sent[0].shape[0]),
        "rows": rows,
        "energy_j": tally.energy,
        "counts": tally.counts,
        "messages": [int(s.sum()) for s in sent],  # per sending layer, all env steps
        "lif_neuron_rows": int(sum(sizes[1:]) * rows * sent[0].shape[0]),
        "latency_s": tally.latency_s(),
        "wall_s": time.perf_counter() - t0,
    }


def main(job_dir: Path) -> None:
    job = json.loads((job_dir / "job.json").read_text())
    import sanafe  # GPL-3.0: only ever in this process

    with np.load(job_dir / "job.npz", allow_pickle=False) as f:
        arrays = {k: f[k] for k in f.files}
    result: dict[str, Any]
    if job.get("family") == "sigma_delta":
        result = run_sigma_delta(sanafe, job, arrays)
    else:
        result = {mode: run(sanafe, job, arrays, mode) for mode in job["modes"]}
    result["sanafe_version"] = metadata.version("sanafe")
    (job_dir / "result.json").write_text(json.dumps(result))


if __name__ == "__main__":
    main(Path(sys.argv[1]))
