"""``snnkart report --sanafe`` on a sigma-delta deployment: its messages replayed on SANA-FE's
Loihi model (:mod:`snnkart.energy.sanafe_sigma_delta`: each message one spike event), SANA-FE's chip
energy per inference plus snnkart's host and link terms, the figure the goal checks SANA-FE with
(:func:`snnkart.energy.goal.decide`).

The deploy record keeps each layer's messages summed over the env steps, not per env step, so the
replay spreads each layer's total evenly over the env steps (:func:`spread`: the totals exactly,
every env step within one message of the mean) and sends them from each layer's first neurons
(:func:`snnkart.energy.sanafe_sigma_delta.sent_from_counts`). SANA-FE's synaptic events and packets are
then the deployment's; its per-neuron update counts and hops can differ from a replay of the
recorded per-neuron messages.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from snnkart.contract.deploy_record import DeployRecord
from snnkart.energy.pricing import terms, total
from snnkart.energy.profiles import load_profile
from snnkart.energy.sanafe_model import INSTALL_HINT, sanafe_python
from snnkart.energy.sanafe_sigma_delta import job_of, per_inference, run_sd, sent_from_counts
from snnkart.energy.sigma_delta_counts import SigmaDeltaCounts
from snnkart.errors import SnnkartError

OFF_CHIP = ("host link", "host compute", "memory")
"""The parts of :func:`~snnkart.energy.pricing.terms` SANA-FE does not model (added to its chip energy)."""
LINK_CHIP = "loihi1"
"""The profile whose host-link price (io_bit) is added: SANA-FE's model is Loihi 1's."""


def spread(totals: list[int], env_steps: int) -> np.ndarray:
    """``[env_steps, len(totals)]`` messages per env step: each total spread evenly (the first
    ``total mod env_steps`` env steps one more), so every column sums to its total."""
    e = np.arange(env_steps)[:, None]
    t = np.asarray(totals, np.int64)[None, :]
    return t // env_steps + (e < t % env_steps)


def sanafe_sd(
    record: DeployRecord, counts: SigmaDeltaCounts, baselines: list[str]
) -> tuple[dict[str, Any], dict[str, float] | None]:
    """The report's SANA-FE section and the energy per inference (chip + host and link, per
    baseline that prices the host) the goal takes; ``available: False`` with the reason, and
    None, when SANA-FE or the NIR file is missing."""
    from snnkart.backends.loading import open_policy
    from snnkart.backends.sigma_delta_policy import SigmaDeltaPolicy

    python = sanafe_python()
    sd = record.counts.sigma_delta
    if python is None or sd is None:
        return {"available": False, "reason": f"SANA-FE is not installed ({INSTALL_HINT})"}, None
    try:
        policy = open_policy(record.nir_file)
    except SnnkartError as exc:
        return {"available": False, "reason": f"the NIR file is not readable: {exc}"}, None
    assert isinstance(policy, SigmaDeltaPolicy)
    spec = policy.spec("fixed")
    sizes = [counts.n_in, *counts.sizes, counts.n_out]
    sent = sent_from_counts(spread(sd.messages[:-1], max(record.counts.env_steps, 1)), sizes)
    biases = [*(np.asarray(b, np.float64) for b in spec.biases), np.zeros(counts.n_out)]
    run = run_sd(
        *job_of(sizes, counts.rows, [np.asarray(w) for w in spec.weights], biases, sent), python
    )
    per = per_inference(run)
    link = load_profile(LINK_CHIP)
    off_chip = {
        b: total(t for t in terms(counts, link, load_profile(b)) if t.part in OFF_CHIP)
        for b in baselines
    }
    energy = {b: per["chip_pj"] + e for b, e in off_chip.items()}
    return {
        "available": True,
        "model": "SANA-FE 2.2.9 Loihi (sigma-delta replay, each message a spike event)",
        "per_inference": per,
        "off_chip_pj": off_chip,
        "energy_pj": energy,
        "messages": "each layer's total spread evenly over the env "
        "steps, sent from its first neurons (snnkart.app.sanafe_sigma_delta_report)",
    }, energy
