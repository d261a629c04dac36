"""A sigma-delta deployment on SANA-FE's Loihi model: each message mapped to a spike event
(the sigma-delta job of :mod:`snnkart.energy.sanafe_worker`), and SANA-FE's energy per inference term by term.

SANA-FE 2.2.9 ships no sigma-delta neuron and no graded message, and adding one through its
plugin interface (a C++ soma model built against its headers) is not done here. The mapping
keeps every count SANA-FE prices: each recorded message is one spike of its sender at the row
it was sent, entering the Dense it entered (so SANA-FE's synaptic events, packets and hops are
the deployment's), and every chip neuron is a mapped neuron that SANA-FE accesses at every row.
What the payload leaves out:

- **the payload's bits**: a spike carries no value, so a 24-bit graded message costs SANA-FE
  one packet (111 pJ) and each synaptic event one accumulate (35.5 pJ), whatever the bits;
- **the multiply**: a graded synaptic event multiplies the payload by the weight;
- **the sender's spike-out**: the replayed senders are SANA-FE input neurons, which it does not
  charge for firing; :func:`per_inference` adds 69.3 pJ per message of a chip layer (what a
  Loihi neuron firing costs in the same model), not for the host's input Delta;
- **the sigma-delta soma**: SANA-FE's LIF update (21.6 pJ, whenever a neuron has input, a
  non-zero potential or a bias) stands for the SigmaDelta's ReLU, compare and residue;
- **the host and the link**: not on the chip; add snnkart's host and link terms to compare
  with an ANN (:func:`snnkart.energy.goal.decide` takes the sum).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from snnkart.energy.sanafe_model import SANAFE_PJ, TIMEOUT_S, run_sanafe

NEURONS_PER_CORE = 1024
"""SANA-FE's Loihi: 1,024 neurons per core (loihi.yaml), each group on cores of its own."""


def sent_from_counts(messages: np.ndarray, sizes: list[int]) -> list[np.ndarray]:
    """Per sending layer, ``[E, n_i]`` bool masks from ``messages`` ``[E, L + 1]`` counts alone
    (the first ``k`` neurons of a layer sent ``k`` messages): for a record that keeps no
    per-neuron messages. Counts, packets and synaptic events are the same; the hops can differ
    only for a layer spread over several cores."""
    m = np.asarray(messages, dtype=np.int64)
    return [np.arange(n)[None, :] < m[:, i : i + 1] for i, n in enumerate(sizes[:-1])]


def job_of(
    sizes: list[int],
    rows: int,
    weights: list[np.ndarray],
    biases: list[np.ndarray],
    sent: list[np.ndarray],
) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """The worker's job: ``sizes`` = ``[n_in, *hidden, n_out]``, ``weights[i]``
    ``[sizes[i+1], sizes[i]]`` (the integer Dense weights), ``biases[i]`` for ``sizes[i+1]``,
    ``sent[i]`` for the sending layers (the input Delta first): ``[E, rows, sizes[i]]`` per
    row, or ``[E, sizes[i]]`` per env step, placed at row i (under the held schedule a layer
    sends only there, except while the biases first propagate in a deployment's first env step:
    the same counts, a row or two apart)."""
    if not (len(weights) == len(biases) == len(sent) == len(sizes) - 1):
        raise ValueError(
            f"{len(sizes)} groups need {len(sizes) - 1} weights, biases and sent masks; got "
            f"{len(weights)}, {len(biases)}, {len(sent)}"
        )
    arrays: dict[str, np.ndarray] = {}
    for i, (w, b, s) in enumerate(zip(weights, biases, sent, strict=True)):
        if (
            np.shape(w) != (sizes[i + 1], sizes[i])
            or np.shape(s)[-1] != sizes[i]
            or (np.ndim(s) == 3 and np.shape(s)[1] != rows)
        ):
            raise ValueError(
                f"layer {i}: weight {np.shape(w)} or sent {np.shape(s)} does not fit sizes {sizes}"
            )
        arrays[f"weight{i}"] = np.asarray(w, np.float64)
        arrays[f"bias{i + 1}"] = np.asarray(b, np.float64)
        arrays[f"sent{i}"] = np.asarray(s, bool)
    job = {
        "family": "sigma_delta",
        "sizes": list(sizes),
        "rows": rows,
        "neurons_per_core": NEURONS_PER_CORE,
    }
    return job, arrays


def run_sd(
    job: dict[str, Any], arrays: dict[str, np.ndarray], python: str, timeout: float = TIMEOUT_S
) -> dict[str, Any]:
    """Run the sigma-delta replay under ``python`` (the Python that has SANA-FE)."""
    return run_sanafe(job, arrays, python, timeout=timeout)


def per_inference(run: dict[str, Any]) -> dict[str, Any]:
    """SANA-FE's replay per env step: its energy by component and term (pJ), the spike-out it
    does not charge the replayed chip senders, and the chip total with it."""
    n = max(run["env_steps"], 1)
    e = {k: v * 1e12 / n for k, v in run["energy_j"].items()}
    c = {k: v / n for k, v in run["counts"].items()}
    chip_messages = sum(run["messages"][1:]) / n  # the input Delta's are the host's
    replayed = sum(run["messages"]) / n  # input neurons: counted as updated, not priced
    access = run["lif_neuron_rows"] / n
    terms = {
        "synapse: synaptic events x 35.5": c["synaptic_events"] * SANAFE_PJ["dense_synapse"],
        "soma: neuron accesses x 51.2": access * SANAFE_PJ["access_neuron"],
        "soma: neuron updates x 21.6": (c["neurons_updated"] - replayed)
        * SANAFE_PJ["update_neuron"],
        "network: packets x 111": c["packets"] * SANAFE_PJ["message_out"],
    }
    terms["network: hops"] = e["network"] - terms["network: packets x 111"]
    spike_out = chip_messages * SANAFE_PJ["spike_out"]
    sanafe_total = sum(e.values())
    return {
        "energy_pj": {**e, "total": sanafe_total},
        "terms_pj": terms,
        "unexplained_pj": sanafe_total - sum(terms.values()),
        "added_spike_out_pj": spike_out,
        "chip_pj": sanafe_total + spike_out,
        "counts": {**c, "neuron_accesses": access, "chip_messages": chip_messages},
        "latency_s": run["latency_s"],
    }
