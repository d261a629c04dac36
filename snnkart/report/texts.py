"""The report's fixed texts: what the estimate includes, what it leaves out, its references."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

INCLUDES = (
    "Chip: synaptic operations (spikes x fan-out between spiking layers), neuron updates (every "
    "neuron at every SNN step, as Loihi clocks them), spikes; the Lava pipeline's fill and drain "
    "steps (L per action) are priced too; routing: spikes x the tile hops of the layers' "
    "placement (each layer on cores of its own) where the chip prices a hop.",
    "Host link: the bits the deployment sends per action (T x n1 input currents in, the last "
    "layer's T x n spike flags out), priced per bit where a figure or bound exists.",
    "Host, priced as digital operations on the host profile: observation normalisation, the "
    "first layer's input current W1 z + b1 (once per action), the readout from spike counts, "
    "the decoding, and reading those weights from the memory array that holds the host's own "
    "weights (Horowitz's 8 KB / 32 KB / 1 MB SRAM rows, DRAM beyond).",
    "ANN: the same normalisation and decoding, every layer's multiply-accumulates and biases, "
    "and one read per weight from the array that holds the ANN's own weights. The ANN runs on "
    "the host, so it has no link.",
    "Static power x the control period (one action per env step, 60 Hz), a term of its own on "
    "each side, where a figure is published; report.json gives the verdict with and without it "
    "and the average power at the control rate.",
)
LEAVES_OUT = (
    "No power was measured: Lava's CPU simulator has no power model; every number is a count "
    "from the deployment times a published, derived or assumed per-operation price.",
    "Loihi 1's per-operation energies are pre-silicon simulations, the synaptic one a minimum "
    "(Davies et al. 2018; SANA-FE's silicon-calibrated figures are the high ends); Loihi 2 has "
    "no published per-operation figures: its ranges are derived from Hala Point's totals.",
    "Technology nodes differ (Loihi 14 nm and Intel 4, Horowitz's digital figures 45 nm): the "
    "ratios compare published figures, not equal processes.",
    "Static power is not published for the digital targets (the host's static power would add "
    "alike to both sides), nor for SpiNNaker; TrueNorth's figure is all-in and includes it. "
    "The ANN's activation functions (tanh or ReLU: ann.activation) are not priced.",
    "Weight reuse across inferences and caches are not modelled; memory-inclusive profiles "
    "read every weight once per inference.",
)
REFERENCES = (
    "Davies et al., Loihi: a neuromorphic manycore processor with on-chip learning, IEEE Micro "
    "38(1):82-99, 2018 (Table 2, pre-silicon).",
    "Horowitz, Computing's energy problem (and what we can do about it), ISSCC 2014.",
    "Merolla et al., Science 2014 (TrueNorth: 26 pJ per synaptic event, measured, all-in).",
    "Höppner et al., arXiv 1903.08941, 2019 (SpiNNaker 2 prototype), as encoded by "
    "KerasSpiking's ModelEnergy.",
    "Yik et al., The NeuroBench framework ..., Nat. Commun. 16:1545, 2025.",
    "Dampfhoffer et al., Are SNNs really more energy-efficient than ANNs?, IEEE TETCI 7(3), 2023.",
    "Yan et al., Reconsidering the energy efficiency of SNN inference, arXiv 2409.08290.",
    "Intel/Sandia, Hala Point (1,152 Loihi 2), press release, April 2024.",
    "Boyle et al., SANA-FE, IEEE TCAD 44(8):3165-3178, 2025 (Loihi figures calibrated on silicon).",
    "Degnan et al. 2015 (ARM-class processor, 0.9 nJ per operation), as encoded by "
    "KerasSpiking's ModelEnergy.",
    "Paredes-Vallés et al., Science Robotics 2024 (Loihi idle power); lava-dl's PilotNet "
    "benchmarks on Loihi 2 (static power).",
)


def not_driving(policy: str, success: str, report: Mapping[str, Any]) -> dict[str, str]:
    """The first screen's warning when ``policy`` (a phrase: "the spiking policy") fails its
    task: success ``success`` (a percentage) below 80 %; or, where the env has no pass mark
    (``drives`` None), the note that nothing judged the task."""
    control = report.get("control") or {}
    mark = control.get("pass_mark", "finished laps")
    if report["drives"] is None:
        return {
            "kind": "warn",
            "text": (
                f"NOTE: nothing judges whether {policy} does its task (pass mark: {mark}); "
                "read the energy numbers beside its mean return."
            ),
        }
    kart = mark == "finished laps"
    what = "does not drive" if kart else "does not do its task"
    bound = "< 80 %" if kart else f"< 80 %; {mark}"
    return {
        "kind": "warn",
        "text": (
            f"WARNING: {policy} {what}: success {success} ({bound}). The energy numbers "
            "below describe a policy that fails its task; they are not a result."
        ),
    }


def deployment(report: Mapping[str, Any], network: str, schedule: str) -> str:
    """The deployment paragraph's first sentences, from a report's ``deploy`` and ``network``
    sections: the file, backend and run; ``network`` (what the family calls its network), its
    shape and ``schedule`` (how its steps run); the host profile."""
    d, net = report["deploy"], report["network"]
    return (
        f"Deployment: {d['file']} ({d['backend']}, {d['precision']}), {d['env']}/{d['track']}, "
        f"{d['episodes']} episodes, {d['env_steps']} env steps (inferences). {network} "
        f"{net['n_in']} -> {net['sizes']} -> {net['n_out']}, {schedule}. Host work priced on "
        f"{report['host_profile']}."
    )
