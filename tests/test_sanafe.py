"""SANA-FE, the second chip model: the recorded inputs (``inputs.npz``) replay the deployment,
SANA-FE's events on a hand-built network are the ones counted by hand, and on a real deployment
it sees the very spikes ``deploy.json`` counted, so only the prices differ.

The SANA-FE tests need the ``sanafe`` extra (``pip install 'snnkart[sanafe]'``, or
``$SNNKART_SANAFE_PYTHON``); without it they skip as optional."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from snnkart.app.report import build_report
from snnkart.app.sanafe_report import sanafe_section
from snnkart.backends.loading import load_policy
from snnkart.backends.reference import LavaFixedChain, NIRReference
from snnkart.contract.deploy_inputs import DeployInputs
from snnkart.contract.deploy_record import DeployRecord
from snnkart.energy.counts import SnnCounts
from snnkart.energy.profiles import load_profile
from snnkart.energy.sanafe_model import (
    SANAFE_PJ,
    SanafeError,
    per_inference,
    run_sanafe,
    sanafe_python,
)
from snnkart.eval.closed_loop import run_deploy
from snnkart.eval.recorded import record_inputs, recorded_inputs
from snnkart.eval.request import DeployRequest
from snnkart.report.sanafe_page import sanafe_lines, sanafe_rows

ROOT = Path(__file__).resolve().parents[1]
NIR = ROOT / "tests/data/policies/grid-snn-nir-8ddd6dd/policy.nir"


@pytest.fixture(scope="module")
def deployed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One seeded episode of the committed 64-64 policy on the fixed-point reference."""
    out = tmp_path_factory.mktemp("deploy")
    run_deploy(DeployRequest(nir_file=NIR, backend="nir-ref", precision="fixed", episodes=1,
                             seed=700, out=out))  # fmt: skip
    return out


@pytest.fixture
def sanafe_py() -> str:
    python = sanafe_python()
    if python is None:
        pytest.skip("optional: SANA-FE is not installed (pip install 'snnkart[sanafe]')")
    return python


def test_inputs_npz_replays_the_deployment(deployed: Path) -> None:
    """The recorded currents, run again through the fixed-point pipeline, give the recorded
    rasters; the rasters' spikes per layer are deploy.json's (policy + fill/drain)."""
    inputs = DeployInputs.load(deployed)
    record = DeployRecord.read(deployed / "deploy.json")
    c = record.counts
    assert inputs.env_steps == c.env_steps and inputs.arithmetic == "fixed"
    assert c.pipeline_overhead is not None
    assert inputs.layer_spikes() == [
        a + b for a, b in zip(c.spikes, c.pipeline_overhead.spikes, strict=True)
    ]
    policy = load_policy(NIR)
    engine = LavaFixedChain(policy.chain, policy.num_steps, policy.fixed)
    for step in range(inputs.env_steps):
        assert np.array_equal(engine.window(inputs.currents(step)), inputs.raster[step]), step


def test_a_current_that_changes_within_a_window_is_kept_row_by_row(tmp_path: Path) -> None:
    """Rate encoding sends a new current at every SNN step: inputs.npz keeps all T rows (and
    one row per env step only while every env step holds its current)."""
    backend = NIRReference(NIR, "float32")
    recorder = record_inputs(backend)
    T, n1 = backend.T, backend.chain.sizes[0]
    rng = np.random.default_rng(0)
    held = np.broadcast_to(rng.normal(size=n1).astype(np.float32), (T, n1))
    changing = rng.normal(size=(T, n1)).astype(np.float32)
    rasters = [backend.engine.window(c) for c in (held, changing)]
    recorded_inputs(backend, recorder, first_seed=0).save(tmp_path / "inputs.npz")
    inputs = DeployInputs.load(tmp_path)
    assert inputs.current.shape == (2, T, n1)
    assert np.array_equal(inputs.currents(0), held) and np.array_equal(inputs.currents(1), changing)
    assert np.array_equal(inputs.raster, np.stack(rasters))


def _hand_job() -> tuple[dict, dict[str, np.ndarray]]:
    """Layer 0 (2 neurons, driven by the host current [1.5, 0]) -> layer 1 (2 neurons), T = 3,
    one Dense delay: W = 4 rows; two identical env steps."""
    layers = [
        {"n": 2, "threshold": 1.0, "leak_decay": 1.0, "input_decay": 0.0},
        {"n": 2, "threshold": 1.0, "leak_decay": 0.5, "input_decay": 0.0},
    ]
    raster = np.zeros((4, 4), dtype=bool)  # rows x (layer 0: 0, 1 | layer 1: 2, 3)
    raster[0:3, 0] = True  # layer 0 neuron 0: v = 1.5 > 1 at each of the T rows
    raster[3, 2] = True  # layer 1 neuron 0 (w 0.6): 0.6, 0.3 -> 19/64 + 0.6, 28/64 + 0.6 > 1
    raster[1:4, 3] = True  # layer 1 neuron 1 (w 1.5): every row it gets a spike
    arrays = {
        "bias0": np.zeros(2), "bias1": np.zeros(2),
        "weight1": np.array([[0.6, 0.0], [1.5, 0.0]]),  # [post, pre]
        "current": np.array([[[1.5, 0.0]]] * 2),
        "raster": np.stack([raster, raster]),
    }  # fmt: skip
    job = {"layers": layers, "rows": 4, "steps": 3, "modes": ["replay", "chain"],
           "neurons_per_core": 512}  # fmt: skip
    return job, arrays


def test_sanafe_counts_a_hand_built_network_as_by_hand(sanafe_py: str) -> None:
    job, arrays = _hand_job()
    result = run_sanafe(job, arrays, sanafe_py)
    # per env step, by hand: layer 0 fires 3 spikes, each to both layer-1 neurons on one core
    synaptic_events, packets = 3 * 2, 3
    accesses = 4 * 4  # every LIF neuron at every row
    updates = 3 + 3 + 3  # layer 0 neuron 0 (bias, rows 0-2); layer 1 both (input, rows 1-3)
    fired = 3 + 1 + 3
    for mode in ("replay", "chain"):
        run = result[mode]
        assert run["lif_spikes"] == [6, 8] and run["lif_mismatched_logical_neuron_steps"] == [0, 0]
        est = per_inference(run)
        counts, energy = est["counts"], est["energy_pj"]
        assert (counts["synaptic_events"], counts["packets"]) == (synaptic_events, packets)
        assert (counts["lif_neurons_updated"], counts["lif_spikes_fired"]) == (updates, fired)
        assert energy["synapse"] == pytest.approx(synaptic_events * SANAFE_PJ["dense_synapse"])
        assert energy["network"] == pytest.approx(packets * SANAFE_PJ["message_out"])
        assert energy["soma"] == pytest.approx(
            accesses * SANAFE_PJ["access_neuron"] + updates * SANAFE_PJ["update_neuron"]
            + fired * SANAFE_PJ["spike_out"]
        )  # fmt: skip
        assert 0 < est["latency_s"]["mean"] < 1e-3
    assert result["replay"]["replayed_spikes"] == [6, 0]


def test_sanafe_sees_the_spikes_deploy_json_counted(deployed: Path, sanafe_py: str) -> None:
    record = DeployRecord.read(deployed / "deploy.json")
    snn = SnnCounts.of_deploy(record)
    section = sanafe_section(record, deployed, snn)
    assert section["available"], section.get("reason")
    spikes = section["spikes_per_layer"]
    assert spikes["inputs_npz"] == spikes["deploy_json"] == spikes["sanafe_lif_replay"]
    assert spikes["replayed_by_sanafe"][:-1] == spikes["deploy_json"][:-1]
    assert section["lif_check"]["reproduces"], section["lif_check"]
    est = section["per_inference"]
    assert est["counts"]["synaptic_events"] == pytest.approx(snn.synops[0] + snn.overhead_synops[0])
    assert abs(est["unexplained_pj"]) < 1e-6 * est["energy_pj"]["total"]
    pairs = {row["term"]: row for row in section["versus_snnkart_loihi1"]}
    # the same synaptic events on both sides: only the price differs (35.5 vs 23.6 pJ)
    price = load_profile("loihi1").prices["synaptic_op"].value
    ratio = SANAFE_PJ["dense_synapse"] / price
    assert pairs["synaptic ops"]["ratio_sanafe_to_snnkart"] == pytest.approx(ratio)
    assert pairs["spikes"]["over_2x"] and not pairs["synaptic ops"]["over_2x"]
    latency = section["latency"]
    assert 0 < latency["on_chip_s_per_inference"] < latency["control_period_s"]
    json.dumps(section)  # JSON-ready, as report.json needs it
    page = "\n".join(sanafe_lines({"sanafe": section}))
    assert "Spikes per layer: SANA-FE's equal deploy.json's." in page
    assert "reproduces every recorded spike" in page
    assert [row["term"] for row in sanafe_rows({"sanafe": section})] == list(pairs)


def test_without_sanafe_the_report_says_how_to_add_it(deployed: Path) -> None:
    record = DeployRecord.read(deployed / "deploy.json")
    section = sanafe_section(record, deployed, SnnCounts.of_deploy(record), find=lambda: None)
    assert section == {
        "available": False,
        "reason": "SANA-FE is not installed: pip install 'snnkart[sanafe]' (SANA-FE 2.2.9, "
        "GPL-3.0), or point $SNNKART_SANAFE_PYTHON at a Python 3.10 that has it",
    }
    assert sanafe_lines({"sanafe": section}) == [f"SANA-FE did not run: {section['reason']}."]
    assert sanafe_rows({"sanafe": section}) == []


def test_a_sanafe_failure_is_one_clear_error(sanafe_py: str) -> None:
    """SANA-FE refusing a network (here more neurons than a Loihi core holds) ends its own
    process only; snnkart gets SANA-FE's message as a SanafeError."""
    n = 1100
    job = {"layers": [{"n": n, "threshold": 1.0, "leak_decay": 1.0, "input_decay": 0.0}],
           "rows": 1, "steps": 1, "modes": ["chain"], "neurons_per_core": 2048}  # fmt: skip
    arrays = {"bias0": np.zeros(n), "current": np.zeros((1, 1, n)),
              "raster": np.zeros((1, 1, n), dtype=bool)}  # fmt: skip
    with pytest.raises(SanafeError, match=r"status 1 .*Exceeded maximum neurons per core"):
        run_sanafe(job, arrays, sanafe_py)


def test_a_missing_or_broken_inputs_npz_is_named_in_the_report(
    deployed: Path, tmp_path: Path
) -> None:
    """A deployment from before inputs.npz, or a damaged one: the section says which file and
    to deploy again (SANA-FE is not started)."""
    shutil.copyfile(deployed / "deploy.json", tmp_path / "deploy.json")
    record = DeployRecord.read(tmp_path / "deploy.json")
    snn = SnnCounts.of_deploy(record)
    section = sanafe_section(record, tmp_path, snn, find=lambda: "/nonexistent/python")
    assert section["available"] is False
    assert section["reason"] == (
        f"no {tmp_path / 'inputs.npz'}: the deployment was run before snnkart recorded its "
        "inputs; run snnkart deploy --out DIR again"
    )
    (tmp_path / "inputs.npz").write_bytes(b"not a zip file")
    section = sanafe_section(record, tmp_path, snn, find=lambda: "/nonexistent/python")
    assert section["reason"].startswith(f"{tmp_path / 'inputs.npz'}: not a readable inputs.npz")


def test_report_json_carries_the_sanafe_entry(deployed: Path, sanafe_py: str) -> None:
    """``snnkart report``'s record holds SANA-FE's figures beside its own, and validates."""
    import jsonschema

    report = build_report(deployed, None, ["loihi1", "horowitz45_fp32_sram"])
    section = report["sanafe"]
    assert section["available"] and section["lif_check"]["reproduces"]
    schema = json.loads((ROOT / "snnkart/report/report.schema.json").read_text())
    jsonschema.validate({**report, "figures": []}, schema)
