"""SANA-FE, a second and independent chip model: where it runs, and its figures term by term
against snnkart's own Loihi 1 estimate.

SANA-FE (Boyle, Plagge, Cardwell, Chance, Gerstlauer, "SANA-FE: Simulating Advanced
Neuromorphic Architectures for Fast Exploration", IEEE TCAD 44(8):3165-3178, 2025,
doi:10.1109/TCAD.2025.3537971) simulates a mapped spiking network core by core and reports
energy and latency; its Loihi description (``sanafe/examples/loihi.yaml``) is calibrated against
Loihi's measured dynamic energy (within 12 % on three applications, the paper's abstract).

How it runs: SANA-FE is GPL-3.0 and snnkart Apache-2.0, so it is an optional extra
(``pip install 'snnkart[sanafe]'``) and never imported into snnkart's process:
:mod:`snnkart.energy.sanafe_worker` runs as a script under a Python that has it (``$SNNKART_
SANAFE_PYTHON``, else this interpreter when it can import sanafe), fed a job directory, and a
C++ abort in SANA-FE ends that process only.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from snnkart.contract.report_record import TermRecord
from snnkart.contract.sanafe_record import SanafeEstimate, SanafeVersus
from snnkart.errors import SnnkartError

PYTHON_ENV = "SNNKART_SANAFE_PYTHON"
INSTALL_HINT = (
    "pip install 'snnkart[sanafe]' (SANA-FE 2.2.9, GPL-3.0), or point "
    f"${PYTHON_ENV} at a Python 3.10 that has it"
)
WORKER = Path(__file__).with_name("sanafe_worker.py")
TIMEOUT_S = 1800.0

LOIHI_YAML = "sanafe 2.2.9, sanafe/examples/loihi.yaml (= arch/loihi.yaml of SLAM-Lab/SANA-FE)"
SANAFE_PJ = {
    "access_neuron": 51.2,  # l. 43: every mapped LIF neuron, every time step
    "update_neuron": 21.6,  # l. 45: when it has input, a non-zero potential or a bias
    "spike_out": 69.3,  # l. 47: per spike fired
    "dense_synapse": 35.5,  # l. 73: per synaptic event (spike x fan-out)
    "message_out": 111.0,  # l. 88: per packet, one per spike and destination core
}
"""SANA-FE's Loihi prices (pJ), calibrated against measured Loihi dynamic energy (TCAD 2025);
hops cost 3.0 pJ east-west and 4.2 pJ north-south (l. 20-27); dendrites and message input 0."""


class SanafeError(SnnkartError, RuntimeError):
    """SANA-FE failed, died or timed out; the message says what it reported."""


def sanafe_python() -> str | None:
    """The Python that runs SANA-FE: ``$SNNKART_SANAFE_PYTHON``, else this one when it can
    import sanafe (looked up, not imported), else None."""
    given = os.environ.get(PYTHON_ENV)
    if given:
        return given
    return sys.executable if importlib.util.find_spec("sanafe") is not None else None


def run_sanafe(
    job: dict[str, Any],
    arrays: dict[str, np.ndarray],
    python: str,
    worker: Path = WORKER,
    timeout: float = TIMEOUT_S,
) -> dict[str, Any]:
    """Run ``worker`` (:mod:`snnkart.energy.sanafe_worker`: a LIF job, or a sigma-delta
    replay) on ``job`` under ``python``; its result."""
    with tempfile.TemporaryDirectory(prefix="snnkart-sanafe-") as tmp:
        job_dir = Path(tmp)
        (job_dir / "job.json").write_text(json.dumps(job))
        np.savez(job_dir / "job.npz", **arrays)
        try:
            proc = subprocess.run(
                [python, "-I", str(worker), str(job_dir)],
                capture_output=True,
                text=True,
                timeout=timeout,
                check=False,
            )
        except (OSError, subprocess.TimeoutExpired) as exc:
            raise SanafeError(f"SANA-FE could not run under {python}: {exc}") from exc
        result = job_dir / "result.json"
        if proc.returncode != 0 or not result.is_file():
            text = (proc.stderr or proc.stdout).strip()
            missing = "No module named 'sanafe'" in text
            raise SanafeError(
                f"SANA-FE ended with status {proc.returncode} under {python}: "
                + (
                    f"sanafe is not installed there; {INSTALL_HINT}"
                    if missing
                    else " | ".join(text.splitlines()[-2:]) or "no message"
                )
            )
        return dict(json.loads(result.read_text()))


def per_inference(run: dict[str, Any]) -> SanafeEstimate:
    """SANA-FE's replay per env step: energy by component and term (pJ), counts, latency."""
    n = max(run["env_steps"], 1)
    e = {k: v * 1e12 / n for k, v in run["energy_j"].items()}
    c = {k: v / n for k, v in run["counts"].items()}
    replayed = sum(run["replayed_spikes"]) / n  # input neurons: counted, not priced, by SANA-FE
    lif_updated = c["neurons_updated"] - replayed
    lif_fired = c["neurons_fired"] - replayed
    access = run["lif_neuron_rows"] / n
    terms = {
        "synapse: synaptic events x 35.5": c["synaptic_events"] * SANAFE_PJ["dense_synapse"],
        "soma: neuron accesses x 51.2": access * SANAFE_PJ["access_neuron"],
        "soma: neuron updates x 21.6": lif_updated * SANAFE_PJ["update_neuron"],
        "soma: spikes fired x 69.3": lif_fired * SANAFE_PJ["spike_out"],
        "network: packets x 111": c["packets"] * SANAFE_PJ["message_out"],
    }
    terms["network: hops"] = e["network"] - terms["network: packets x 111"]
    explained = sum(terms.values()) - terms["network: hops"]
    return {
        "energy_pj": {**e, "total": sum(e.values())},
        "terms_pj": terms,
        "unexplained_pj": e["synapse"]
        + e["soma"]
        + e["dendrite"]
        + e["network"]
        - explained
        - terms["network: hops"],
        "counts": {
            **c,
            "neuron_accesses": access,
            "lif_neurons_updated": lif_updated,
            "lif_spikes_fired": lif_fired,
        },
        "latency_s": run["latency_s"],
    }


def _prices(chip_terms: Sequence[TermRecord], part: str) -> str:
    """snnkart's price(s) for ``part``, as the terms name them: "81 pJ (loihi1)"."""
    terms = [t for t in chip_terms if t["part"] == part]
    prices = sorted({f"{t['price_pj']:g}" for t in terms})
    return f"{' / '.join(prices) or '-'} pJ ({terms[0]['profile'] if terms else 'no term'})"


def versus_snnkart(sanafe: SanafeEstimate, chip_terms: Sequence[TermRecord]) -> list[SanafeVersus]:
    """SANA-FE's components against snnkart's chip terms (``snn_terms`` on ``loihi1``, as
    dicts), each pair's ratio, and the pairs more than 2x apart flagged."""
    ours = {
        part: sum(t["energy_pj"] for t in chip_terms if t["part"] == part)
        for part in ("synaptic ops", "neuron updates", "spikes")
    }
    t = sanafe["terms_pj"]
    pairs = [
        (
            "synaptic ops",
            "SANA-FE 35.5 pJ per dense synaptic event; snnkart "
            f"{_prices(chip_terms, 'synaptic ops')} per synaptic op",
            t["synapse: synaptic events x 35.5"],
        ),
        (
            "neuron updates",
            "SANA-FE 51.2 pJ access for every neuron and step + 21.6 pJ per "
            f"update; snnkart {_prices(chip_terms, 'neuron updates')} per neuron and step",
            t["soma: neuron accesses x 51.2"] + t["soma: neuron updates x 21.6"],
        ),
        (
            "spikes",
            "SANA-FE 69.3 pJ per spike fired + 111 pJ per packet to another core + "
            f"hops; snnkart {_prices(chip_terms, 'spikes')} per spike",
            t["soma: spikes fired x 69.3"] + t["network: packets x 111"] + t["network: hops"],
        ),
    ]
    rows = [(part, why, ours[part], theirs) for part, why, theirs in pairs]
    rows.append(("chip total", "the three above", sum(ours.values()), sanafe["energy_pj"]["total"]))
    return [_versus(*row) for row in rows]


def _versus(term: str, why: str, ours: float, theirs: float) -> SanafeVersus:
    """One pair of figures, their ratio, and whether they are more than 2x apart."""
    apart = ours != theirs and (min(ours, theirs) <= 0 or max(ours, theirs) > 2 * min(ours, theirs))
    return SanafeVersus(
        term=term,
        why=why,
        snnkart_pj=ours,
        sanafe_pj=theirs,
        ratio_sanafe_to_snnkart=theirs / ours if ours > 0 else None,
        over_2x=apart,
    )
