"""The energy report: counts against a hand-computed network, profiles that refuse bad input,
every number of report.json recomputed as count x price, and the report as a browser shows it."""

from __future__ import annotations

import base64
import html
import io
import json
import math
import re
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from snnkart.backends.reference import NIRReference
from snnkart.contract.deploy_record import DeployRecord
from snnkart.energy.counts import AnnCounts, Network, SnnCounts, host_ops
from snnkart.energy.pricing import Comparison, ann_terms, terms, total
from snnkart.energy.profiles import BUILTIN, load_profile, parse_profile
from snnkart.errors import ProfileError

pytestmark = pytest.mark.xdist_group("energy")  # one worker builds the module's fixtures once

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = ROOT / "tests" / "data" / "policies" / "grid-snn"
COMMITTED_NIR = ROOT / "tests" / "data" / "policies" / "grid-snn-nir-8ddd6dd" / "policy.nir"
SNNKART = [sys.executable, "-m", "snnkart.cli"]


def _tiny_record() -> dict[str, Any]:
    """3 inputs -> 4 -> 2 spiking -> 2 actions, T = 2, two env steps. Over the two steps layer 1
    fires 6 spikes, layer 2 fires 2; fan-out 2 (to layer 2) and 2 (the readout)."""
    return {
        "schema": "snnkart/deploy/v1", "backend": "nir-ref", "precision": "float64",
        "manifest": {"num_steps": 2, "encoding": "current", "action_mode": "discrete"},
        "network": {"n_in": 3, "sizes": [4, 2], "n_out": 2, "readout": True, "input_scale": False},
        "counts": {"env_steps": 2, "spikes": [6, 2], "synops": [12, 4], "neuron_updates": [16, 8],
                   "pipeline_overhead": {"spikes": [2, 0], "synops": [4, 0],
                                         "neuron_updates": [8, 4]}},
        "episodes": [],
    }  # fmt: skip


def _counts(parts: dict[str, Any]) -> SnnCounts:
    """The counts of a deploy record made of ``parts`` over a real record's other fields."""
    data = {**json.loads((ROOT / "tests/data/records/deploy-nir-ref-fixed.json").read_text()),
            **parts}  # fmt: skip
    return SnnCounts.of_deploy(DeployRecord.from_json(json.dumps(data)))


def test_counts_and_energy_of_a_hand_computed_network() -> None:
    snn = _counts(_tiny_record())
    assert snn.spikes == (3.0, 1.0)
    assert snn.synops == (6.0, 0.0)  # the last layer's fan-out is the host's readout
    assert snn.neuron_updates == (8.0, 4.0)
    assert snn.firing_rates() == [3 / 8, 1 / 4]
    host = {op: sum(h.count for h in snn.host if h.op == op) for op in ("mac", "add", "mult")}
    # normalise 3 sub + 6 clip compares, b1 4, br 2, argmax 1 | W1 12 + Wr 4 | /std 3, /T 2
    assert host == {"add": 9 + 4 + 2 + 1, "mac": 12 + 4, "mult": 3 + 2}
    loihi, fp32, sram = (
        load_profile(n) for n in ("loihi1", "horowitz45_fp32", "horowitz45_fp32_sram")
    )
    # the pipeline's fill/drain per env step: 1 spike of layer 1 (2 synops), 4 + 2 updates
    assert snn.overhead_synops == (2.0, 0.0) and snn.overhead_neuron_updates == (4.0, 2.0)
    # chip: (6 + 2) synops x 23.6 + (12 + 6) neuron updates x 81 + (4 + 1) spikes x 1.7
    #     = 188.8 + 1458 + 8.5 = 1655.3 pJ; both layers fit one core each in one tile: 0 hops
    # link (float64): T 2 x 4 currents x 64 bits in + 2 x 2 spike flags out = 516 bits x 20.3
    # host (fp32): 16 MACs x 4.6 + 16 adds x 0.9 + 5 mults x 3.7 = 106.5 pJ
    assert snn.link_bits == (512.0, 4.0)
    assert total(terms(snn, loihi, fp32)) == pytest.approx(1655.3 + 516 * 20.3 + 106.5)
    # + the host's 22 weights x 32 bits = 11 64-bit reads from the 8 KB array (88 bytes), 10 pJ
    assert total(terms(snn, loihi, sram)) == pytest.approx(1655.3 + 10474.8 + 106.5 + 110)
    ann = AnnCounts((3, 4, 2, 2))
    assert ann.macs == 24 and ann.parameters == 32
    # 24 MACs x 4.6 + (8 biases + 9 normalise + 1 argmax) x 0.9 + 3 x 3.7 = 137.7 pJ
    assert total(ann_terms(ann, fp32)) == pytest.approx(137.7)
    assert total(ann_terms(ann, sram)) == pytest.approx(137.7 + 16 * 10.0)  # 32 x 32 bits
    nb = snn.neurobench()  # the first layer fed at each of the T = 2 steps, as NeuroBench counts
    assert nb["effective_acs"] == 6 and nb["effective_macs"] == 2 * 12 + 4
    assert nb["dense_ops"] == 2 * 12 + 2 * 8 + 4
    assert nb["activation_sparsity"] == pytest.approx(1 - 4 / 12)
    assert snn.deployed() == {"host_macs": 16, "chip_synaptic_ops": 8, "chip_neuron_updates": 18,
                              "spikes": 5}  # fmt: skip


def test_counts_of_a_real_deployment_against_its_rasters_by_hand(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A real deployment record (the committed grid SNN, 21 inputs -> 64 -> 64 -> 5 actions,
    T = 8, on the reference in fixed point, pipelined like Lava: T + 1 rows per window, layer
    i's logical steps in rows i..i+7), its counts recomputed by hand from the raw spike rasters
    of every window, then the energy model's per-inference counts from the record."""
    from snnkart.contract.records import to_data
    from snnkart.eval.closed_loop import DeployRequest, run_deploy

    rasters: list[np.ndarray] = []
    real_step = NIRReference.step

    def step(self: NIRReference, obs: np.ndarray) -> tuple[Any, np.ndarray]:
        window, out = real_step(self, obs)
        if self.arithmetic == "fixed":  # the deployed backend, not its float32 reference
            rasters.append(window.raster.copy())
        return window, out

    monkeypatch.setattr(NIRReference, "step", step)
    typed = run_deploy(DeployRequest(COMMITTED_NIR, "nir-ref", "fixed", episodes=2, seed=10_000))
    record = to_data(typed)
    assert record["network"] == {"n_in": 21, "sizes": [64, 64], "n_out": 5, "readout": True,
                                 "input_scale": False}  # fmt: skip
    assert record["manifest"]["num_steps"] == 8
    n = len(rasters)
    assert n == record["counts"]["env_steps"] == sum(e["length"] for e in record["episodes"])
    assert {r.shape for r in rasters} == {(9, 128)}
    layer = [slice(0, 64), slice(64, 128)]
    spikes = [sum(int(r[i : i + 8, layer[i]].sum()) for r in rasters) for i in (0, 1)]
    fill_drain = [sum(int(r[:, layer[i]].sum()) for r in rasters) - spikes[i] for i in (0, 1)]
    assert min(spikes) > 0 and fill_drain[1] > 0  # every count below is tested, none is 0
    fan_out = [64, 5]  # layer 1 drives layer 2; layer 2 drives the 5 readout units
    assert record["counts"] == {
        "env_steps": n,
        "spikes": spikes,
        "synops": [spikes[0] * 64, spikes[1] * 5],
        "neuron_updates": [64 * 8 * n, 64 * 8 * n],
        "pipeline_overhead": {
            "spikes": fill_drain,
            "synops": [fill_drain[0] * fan_out[0], fill_drain[1] * fan_out[1]],
            "neuron_updates": [64 * 1 * n, 64 * 1 * n],  # 1 Dense delay: one extra row
        },
    }
    for key in ("spikes", "synops", "neuron_updates"):  # the episodes add up to the whole
        per_episode = [e["counts"][key] for e in record["episodes"]]
        assert [sum(col) for col in zip(*per_episode, strict=True)] == record["counts"][key]
    snn = SnnCounts.of_deploy(typed)
    assert snn.spikes == pytest.approx([spikes[0] / n, spikes[1] / n])
    assert snn.synops == pytest.approx([spikes[0] * 64 / n, 0.0])  # layer 2's: the readout
    assert snn.neuron_updates == (512.0, 512.0)
    assert snn.overhead_neuron_updates == (64.0, 64.0)
    assert snn.deployed() == pytest.approx({
        "host_macs": 21 * 64 + 64 * 5,
        "chip_synaptic_ops": (spikes[0] + fill_drain[0]) * 64 / n,
        "chip_neuron_updates": 128 * 9,
        "spikes": (sum(spikes) + sum(fill_drain)) / n,
    })  # fmt: skip
    assert snn.neurobench() == pytest.approx({
        "effective_macs": 8 * 21 * 64 + 64 * 5,
        "effective_acs": spikes[0] * 64 / n,
        "dense_ops": 8 * 21 * 64 + 8 * 64 * 64 + 64 * 5,
        "activation_sparsity": 1 - sum(spikes) / (n * 128 * 8),
    })  # fmt: skip


def test_counts_of_three_layers_rate_encoding_and_continuous_actions() -> None:
    record = _tiny_record()
    record["manifest"].update(encoding="rate", action_mode="continuous")
    record["network"].update(sizes=[4, 3, 2])
    record["counts"].update(spikes=[6, 4, 2], synops=[18, 8, 4], neuron_updates=[16, 12, 8],
                            pipeline_overhead={"spikes": [0, 0, 0], "synops": [0, 0, 0],
                                               "neuron_updates": [0, 0, 0]})  # fmt: skip
    snn = _counts(record)
    assert snn.synops == (9.0, 4.0, 0.0) and snn.net.chip_synapses == 4 * 3 + 3 * 2
    host = {op: sum(h.count for h in snn.host if h.op == op) for op in ("mac", "add", "mult")}
    # rate: 9 encode adds + 2x3 compares + 2x3x4 dense first-layer adds + 2x4 biases; readout
    # 2 adds; clip 2x2 compares | readout 2x2 MACs | encode 3 mults, /T 2 mults
    assert host == {"add": 9 + 6 + 24 + 8 + 2 + 4, "mac": 4, "mult": 3 + 2}
    nb = snn.neurobench()
    assert nb["effective_macs"] == 4 and nb["effective_acs"] == 2 * 3 * 4 + 13


def test_break_even_without_spikes_is_none_and_json_safe() -> None:
    record = _tiny_record()
    record["counts"].update(spikes=[0, 0], synops=[0, 0])
    record["counts"]["pipeline_overhead"].update(spikes=[0, 0], synops=[0, 0])
    snn = _counts(record)
    fp32 = load_profile("horowitz45_fp32")
    be = Comparison(
        snn, AnnCounts((3, 64, 64, 2)), load_profile("truenorth"), fp32, fp32
    ).break_even()
    assert be["density"] is None and "does not depend on its spikes" in be["reason"]
    json.dumps(be, allow_nan=False)


def test_break_even_solves_for_the_spike_density() -> None:
    snn = _counts(_tiny_record())
    fp32, truenorth = load_profile("horowitz45_fp32"), load_profile("truenorth")
    ann = AnnCounts((3, 64, 64, 2))  # 4,352 MACs: dear enough for the tiny SNN to win
    cmp = Comparison(snn, ann, truenorth, fp32, fp32)
    be = cmp.break_even()
    d = be["density"]
    # at the break-even density the SNN costs exactly what the ANN does
    assert total(terms(snn.scaled(d), truenorth, fp32)) == pytest.approx(cmp.energies()[1])
    assert d > 1.0 and cmp.ratio() < 1.0
    # Loihi's clocked neuron updates can cost more than a small ANN whatever the spikes
    small = Comparison(snn, AnnCounts((3, 2, 2)), load_profile("loihi1"), fp32, fp32)
    assert small.break_even()["density"] is None


# Every built-in price as snn-nir-lava.md §3 gives it (pJ, static power pJ/s: value, low, high,
# tag). A zero-width range is exact by the profile's definition ("included", compute only) or a
# single published figure whose source says no range is published.
W = 1e12  # pJ/s in a watt
_LINK = (20.3, 1.4, 40.6, "derived")  # §3.3 DRAM 1300-2600 pJ / 64 bits; a 1.4 pJ/bit link
_SRAM = {"sram_read_8kb": (10.0, 10.0, 20.0, "derived"), "sram_read_32kb": (20.0, 10.0, 100.0,
         "derived"), "sram_read_1mb": (100.0, 20.0, 100.0, "derived"),
         "dram_read": (1300.0, 1300.0, 2600.0, "derived")}  # fmt: skip
_NO_MEMORY = dict.fromkeys(_SRAM, (0.0, 0.0, 0.0, "assumed"))
_FP32 = {"mac": (4.6, 4.6, 4.6, "derived"), "add": (0.9, 0.9, 0.9, "derived"),
         "mult": (3.7, 3.7, 3.7, "derived")}  # fmt: skip
_ARM = (900.0, 300.0, 8600.0, "derived")  # §3.7 Degnan 0.9 nJ; GPU 0.3 / CPU 8.6 nJ
REFERENCE_PRICES = {
    ("loihi1", "synaptic_op"): (23.6, 23.6, 35.5, "pre-silicon"),  # §3.1; SANA-FE 35.5 (§3.8)
    ("loihi1", "neuron_update"): (81.0, 52.0, 81.0, "pre-silicon"),  # §3.1 active / inactive
    ("loihi1", "spike"): (1.7, 1.7, 180.3, "pre-silicon"),  # §3.1; SANA-FE 69.3 + 111
    ("loihi1", "hop"): (3.5, 3.0, 4.2, "pre-silicon"),  # §3.1 3.0 / 4.0; SANA-FE 4.2
    ("loihi1", "io_bit"): _LINK,
    ("loihi1", "static_power"): (0.94 * W, 0.232 * W, 0.94 * W, "measured"),  # §3.8
    ("loihi2", "synaptic_op"): (4.2, 0.067, 6.8, "derived"),  # §3.2/§3.8 Hala Point totals
    ("loihi2", "neuron_update"): (
        4.2,
        0.148,
        10.8,
        "derived",
    ),  # 0.067 x 52 / 23.6, no TOPS/W floor
    ("loihi2", "spike"): (0.0, 0.0, 1.7, "assumed"),
    ("loihi2", "io_bit"): _LINK,
    ("loihi2", "static_power"): (0.232 * W, 0.232 * W, 0.282 * W, "measured"),  # §3.8
    ("spinnaker2", "synaptic_op"): (450.0, 450.0, 450.0, "measured"),  # §3.7, single figure
    ("spinnaker2", "neuron_update"): (2190.0, 2190.0, 2190.0, "measured"),
    ("spinnaker2", "spike"): (0.0, 0.0, 0.0, "assumed"),
    ("spinnaker2", "io_bit"): _LINK,
    ("spinnaker1", "synaptic_op"): (13300.0, 13300.0, 13300.0, "derived"),  # §3.7
    ("spinnaker1", "neuron_update"): (26000.0, 26000.0, 26000.0, "derived"),
    ("spinnaker1", "spike"): (0.0, 0.0, 0.0, "assumed"),
    ("spinnaker1", "io_bit"): _LINK,
    ("truenorth", "synaptic_op"): (26.0, 26.0, 26.0 * 11, "measured"),  # §3.1, §3.7 all-in
    ("truenorth", "neuron_update"): (0.0, 0.0, 0.0, "assumed"),
    ("truenorth", "spike"): (0.0, 0.0, 0.0, "assumed"),
    ("truenorth", "io_bit"): _LINK,
    **{("horowitz45_fp32", op): v for op, v in {**_FP32, **_NO_MEMORY}.items()},  # §3.3
    **{("horowitz45_fp32_sram", op): v for op, v in {**_FP32, **_SRAM}.items()},
    ("horowitz45_int8", "mac"): (0.3, 0.3, 0.3, "derived"),  # §3.3: int8 mult + int32 add
    ("horowitz45_int8", "add"): (0.1, 0.1, 0.1, "derived"),
    ("horowitz45_int8", "mult"): (0.2, 0.2, 3.1, "derived"),
    **{("horowitz45_int8", op): v for op, v in _SRAM.items()},
    **{("arm_degnan2015", op): _ARM for op in ("mac", "add", "mult")},
    **{("arm_degnan2015", op): v for op, v in _NO_MEMORY.items()},
}
NOT_PUBLISHED = {("loihi2", "hop"), ("truenorth", "hop"), ("truenorth", "static_power"),
                 ("spinnaker1", "hop"), ("spinnaker1", "static_power"), ("spinnaker2", "hop"),
                 ("spinnaker2", "static_power"), *((d, "static_power") for d in (
                     "horowitz45_fp32", "horowitz45_fp32_sram", "horowitz45_int8",
                     "arm_degnan2015"))}  # fmt: skip


def test_builtin_profiles_carry_the_reference_prices() -> None:
    seen, unpublished = {}, set()
    for name in BUILTIN:
        profile = load_profile(name)
        assert (ROOT / "hardware" / f"{name}.toml").resolve() == (
            ROOT / "snnkart/energy/builtin" / f"{name}.toml").resolve()  # fmt: skip
        for op, price in profile.prices.items():
            seen[(name, op)] = (price.value, price.low, price.high, price.tag)
            if price.low == price.high and price.value > 0:  # a single figure says so
                assert "no range published" in price.source, (name, op)
        unpublished |= {(name, op) for op in profile.not_published}
    assert seen.keys() == REFERENCE_PRICES.keys()
    assert unpublished == NOT_PUBLISHED
    for key, expected in REFERENCE_PRICES.items():
        assert seen[key][:3] == pytest.approx(expected[:3]), key
        assert seen[key][3] == expected[3], key
    assert "28 nm" in load_profile("truenorth").technology


GOOD = (ROOT / "snnkart/energy/builtin/loihi1.toml").read_text()


@pytest.mark.parametrize(
    ("edit", "fragments"),
    [
        (lambda t: t.replace("[prices.spike]", "[prices.spiky]"),
         ["prices.spike", "missing"]),
        (lambda t: t.replace("value = 23.6", "value = -23.6"),
         ["prices.synaptic_op.value", "cannot be negative"]),
        (lambda t: t.replace('unit = "pJ"', 'unit = "kWh"', 1),
         ["prices.synaptic_op.unit", "'kWh'", "fJ, pJ, nJ, uJ"]),
        (lambda t: "colour = 'blue'\n" + t, ["unknown key 'colour'"]),
        (lambda t: t.replace('tag = "pre-silicon"', 'tag = "rumour"', 1),
         ["prices.synaptic_op.tag", "'rumour'", "measured"]),
        (lambda t: t.replace('source = "Davies', 'sauce = "Davies', 1),
         ["prices.synaptic_op.sauce", "unknown key"]),
        (lambda t: t + '[not_published]\nhop = "no figure"\n',
         ["hop: give [prices.hop] or", "exactly one of the two"]),
        (lambda t: t[: t.index("[prices.io_bit]")],  # the file's last table
         ["io_bit: give [prices.io_bit] or", "not_published.io_bit"]),
        (lambda t: t.replace('unit = "W"', 'unit = "pJ"'),
         ["prices.static_power.unit", "'pJ'", "uW, mW, W"]),
        (lambda t: t.replace("hardware/2", "hardware/1"),
         ["snnkart.hardware/1", "sram_read_8kb", "weight_bits"]),
        (lambda t: t.replace("neurons_per_core = 1024\n", ""),
         ["neurons_per_core: missing", "prices hop"]),
    ],
    ids=["missing", "negative", "unit", "unknown-key", "tag", "price-key", "hop-twice",
         "io-bit-neither", "power-unit", "schema-v1", "placement"],
)  # fmt: skip
def test_bad_profiles_are_refused_with_file_key_and_fix(edit: Any, fragments: list[str],
                                                        tmp_path: Path) -> None:  # fmt: skip
    path = tmp_path / "mine.toml"
    path.write_text(edit(GOOD))
    with pytest.raises(ProfileError) as info:
        load_profile(path)
    message = str(info.value)
    assert str(path) in message
    for fragment in fragments:
        assert fragment in message, message
    parse_profile(GOOD, "ok")  # the unedited file is fine


def _cli(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*SNNKART, *args], cwd=ROOT, capture_output=True, text=True,
                          timeout=timeout)  # fmt: skip


@pytest.fixture(scope="session")  # built once per worker, whatever runs between its tests
def deployed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The committed grid SNN, exported and deployed on the reference in fixed point."""
    tmp = tmp_path_factory.mktemp("deployed")
    assert _cli("export", "--nir", str(FIXTURE), "--out", str(tmp / "policy.nir")).returncode == 0
    result = _cli("deploy", str(tmp / "policy.nir"), "--backend", "nir-ref", "--precision",
                  "fixed", "--episodes", "3", "--out", str(tmp / "deploy"))  # fmt: skip
    assert result.returncode == 0, result.stderr
    return tmp / "deploy"


@pytest.fixture(scope="session")  # built once per worker, whatever runs between its tests
def ann_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short grid ANN run on small_S (the fixture's env and track)."""
    run = tmp_path_factory.mktemp("ann") / "run"
    result = _cli("train", "--env", "grid", "--policy", "ann", "--track", "small_S", "--steps",
                  "2048", "--seed", "3", "--out", str(run))  # fmt: skip
    assert result.returncode == 0, result.stderr
    return run


@pytest.fixture(scope="session")  # built once per worker, whatever runs between its tests
def report(deployed: Path, ann_run: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("report")
    sweep = tmp_path_factory.mktemp("sweep") / "sweep.json"  # not in --out: not the report's
    sweep.write_text(json.dumps(_sweep_from(deployed)))
    result = _cli("report", str(deployed), "--ann", str(ann_run), "--sweep", str(sweep),
                  "--step", "5", "--out", str(out))  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "energy per inference" in result.stdout and "loihi1" in result.stdout
    return out


def _sweep_from(deployed: Path) -> dict[str, Any]:
    """A two-variant study record (the committed tiny study's, its SNN runs replaced) made of
    the deployment's own counts (and half of them)."""
    import dataclasses

    from snnkart.contract.deploy_record import DeployRecord, StepCounts
    from snnkart.contract.records import to_data
    from snnkart.report.study_record import StudyRecord

    record = DeployRecord.read(deployed / "deploy.json")
    study = StudyRecord.read(ROOT / "tests/data/records/study.json")
    snn = next(r for r in study.runs if r.policy == "snn")
    runs = []
    for variant, k in (("measured", 1.0), ("half", 0.5)):
        counts = StepCounts.of(record)
        counts = dataclasses.replace(
            counts,
            spikes_per_step=[k * x for x in counts.spikes_per_step],
            synops_per_step=[k * x for x in counts.synops_per_step],
        )
        runs.append(dataclasses.replace(
            snn, variant=variant, seed=1, eval_success_rate=record.summary.success_rate,
            eval_counts_per_step=counts,
        ))  # fmt: skip
    data = to_data(dataclasses.replace(study, runs=runs))
    data["machine"]["commit"] = "test"
    return data


@pytest.mark.timeout(600)
def test_report_files_and_schema(report: Path) -> None:
    import jsonschema

    for name in ("report.json", "report.md", "report.html", "firing_rates.png", "breakdown.png",
                 "sensitivity.png", "tradeoff.png", "raster.png"):  # fmt: skip
        assert (report / name).is_file(), name
    data = json.loads((report / "report.json").read_text())
    schema = json.loads((ROOT / "snnkart/report/report.schema.json").read_text())
    jsonschema.validate(data, schema)
    bad = {**data, "comparisons": [{**data["comparisons"][0], "snn_pj": -1.0}]}
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(bad, schema)
    # the ANN run was scored on the deployment's own seeded episodes
    ann_task = data["ann"]["run"]["task"]
    assert (ann_task["episodes"], ann_task["first_seed"]) == (3, 10_000)
    assert 0 <= ann_task["success_rate"] <= 1
    # and quantised to int8, driven on the same episodes: an int8 row carries its task
    int8 = ann_task["int8"]
    assert (int8["episodes"], int8["first_seed"]) == (3, 10_000)
    assert int8["calibration"]["first_seed"] == 10_003
    row = next(c for c in data["comparisons"]
               if c["ann"] == "run" and c["ann_profile"] == "horowitz45_int8")  # fmt: skip
    assert row["ann_success_rate"] == int8["success_rate"] and "int8" in row["ann_success"]
    assert row["ann_per_episode_pj"] == pytest.approx(row["ann_pj"] * int8["steps_per_episode"])


@pytest.mark.timeout(600)
def test_nir_info_and_the_report_count_the_same_parameters(report: Path) -> None:
    data = json.loads((report / "report.json").read_text())
    graph = Path(data["deploy"]["file"]).parent / "policy.nir"
    info = json.loads(_cli("nir", "info", str(graph), "--json").stdout)
    assert info["weight_count"] == data["snn"]["footprint"]["parameters"]
    text = _cli("nir", "info", str(graph)).stdout
    assert f"{info['weight_count']:,} weights and biases" in text
    md = (report / "report.md").read_text()
    assert f"| footprint | weights and biases | {info['weight_count']:,} |" in md
    numbers = re.sub(r"doi:\S+", "", md)  # the price table's sources cite DOIs (10.1109/...)
    assert "{'" not in md and not re.search(r"\d\.\d{7,}", numbers)  # no dicts, 16-digit floats


@pytest.mark.timeout(600)
def test_every_energy_in_the_report_is_count_times_a_profile_price(report: Path) -> None:
    data = json.loads((report / "report.json").read_text())
    profiles = {name: load_profile(name) for name in data["profiles"]}
    checked = 0
    for c in data["comparisons"]:
        for side, key in (("snn_terms", "snn_pj"), ("ann_terms", "ann_pj")):
            for term in c[side]:  # the price read back from the profile file, not the report
                assert term["price_pj"] == profiles[term["profile"]][term["op"]]
                assert term["source"] == profiles[term["profile"]].prices[term["op"]].source
                checked += 1
            assert c[key] == pytest.approx(sum(t["count"] * t["price_pj"] for t in c[side]))
        for side in ("snn", "ann"):  # static power x the control period, a term of its own
            terms = c["static"][f"{side}_static_terms"]
            for term in terms:
                assert term["price_pj"] == profiles[term["profile"]]["static_power"]
                assert term["count"] == pytest.approx(1 / 60)
            assert c["static"][f"{side}_static_pj"] == pytest.approx(
                sum(t["count"] * t["price_pj"] for t in terms))  # fmt: skip
        snn_steps = data["snn"]["task"]["steps_per_episode"]
        assert c["snn_per_episode_pj"] == pytest.approx(c["snn_pj"] * snn_steps)
        assert c["ratio"] == pytest.approx(c["snn_pj"] / c["ann_pj"])
        snn_return = data["snn"]["task"]["mean_return"]
        if snn_return > 0:
            assert c["snn_per_return_pj"] == pytest.approx(c["snn_per_episode_pj"] / snn_return)
        # with no --host-profile the SNN's host work is priced like the ANN it is compared with
        assert {t["profile"] for t in c["snn_terms"] if t["part"] in ("host compute", "memory")} == {
            c["ann_profile"]}  # fmt: skip
    assert checked > 100
    # the counts are the deployment's, per env step
    deploy = json.loads((Path(data["deploy"]["file"]) / "deploy.json").read_text())
    n = deploy["counts"]["env_steps"]
    per = data["snn"]["per_inference"]
    assert per["spikes"] == [s / n for s in deploy["counts"]["spikes"]]
    assert per["synops_chip"][:-1] == [s / n for s in deploy["counts"]["synops"][:-1]]
    loihi = next(c for c in data["comparisons"] if c["snn_profile"] == "loihi1")
    synaptic = sum(t["count"] for t in loihi["snn_terms"] if t["op"] == "synaptic_op")
    assert synaptic == pytest.approx(
        sum(per["synops_chip"]) + sum(per["pipeline_overhead"]["synops_chip"])
    )


def test_report_refuses_bad_input(deployed: Path, tmp_path: Path) -> None:
    missing = _cli("report", str(tmp_path / "nowhere"))
    assert missing.returncode == 2 and "no deployment at" in missing.stderr
    assert "Traceback" not in missing.stderr
    bad = tmp_path / "bad.toml"
    bad.write_text(GOOD.replace("value = 81.0", "value = -81.0"))
    result = _cli("report", str(deployed), "--profile", str(bad), "--profile", "horowitz45_fp32",
                  "--out", str(tmp_path / "r"))  # fmt: skip
    assert result.returncode == 2 and "prices.neuron_update.value" in result.stderr
    other = tmp_path / "gazebo"
    trained = _cli("train", "--env", "gazebo", "--policy", "ann", "--steps", "1024",
                   "--out", str(other))  # fmt: skip
    assert trained.returncode == 0, trained.stderr
    wrong = _cli("report", str(deployed), "--ann", str(other), "--out", str(tmp_path / "r"))
    assert wrong.returncode == 2 and "gazebo run, the deployment drove grid" in wrong.stderr


def test_a_policy_that_does_not_drive_is_flagged(deployed: Path, tmp_path: Path) -> None:
    record = json.loads((deployed / "deploy.json").read_text())
    record["summary"]["success_rate"] = 0.4
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "deploy.json").write_text(json.dumps(record))
    result = _cli("report", str(tmp_path / "d"), "--profile", "loihi1", "--profile",
                  "horowitz45_fp32", "--step", "0")  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "does not drive" in result.stdout
    assert "does not drive" in (tmp_path / "d" / "report.html").read_text()


# The report as a person sees it: headless Chromium renders the page; the test reads the DOM
# after the page's own layout and checks the screenshot's pixels where each figure is.
_PROBE = """<script>window.addEventListener('load', () => {
  const out = {height: document.documentElement.scrollHeight, figures: {}, images: []};
  for (const f of document.querySelectorAll('figure')) {
    const r = f.querySelector('img').getBoundingClientRect();
    out.figures[f.id] = [r.left, r.top, r.width, r.height];
  }
  for (const img of document.images) out.images.push(img.complete && img.naturalWidth > 0);
  const box = (e) => { const r = e.getBoundingClientRect(); return [r.top, r.bottom]; };
  out.verdict = box(document.getElementById('verdict'));
  out.headings = [...document.querySelectorAll('h2, table')].map(box);
  document.body.setAttribute('data-probe', JSON.stringify(out));
});</script>"""


def _chromium(*args: str) -> subprocess.CompletedProcess[str]:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        pytest.skip("optional: Debian's chromium is not installed (apt-get install chromium)")
    return subprocess.run(
        [exe, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
         "--virtual-time-budget=5000", *args],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip


@pytest.mark.timeout(600)
def test_the_html_report_in_a_real_browser(report: Path, tmp_path: Path) -> None:
    import numpy as np
    from PIL import Image

    page = (report / "report.html").read_text()
    assert not re.search(r"https?://", page), "the page must not reference the network"
    probed = tmp_path / "probed.html"
    probed.write_text(page.replace("</body>", _PROBE + "</body>"))
    width, screen = 1280, 900  # the same layout width for the DOM probe and the screenshot
    dom = _chromium(f"--window-size={width},{screen}", "--dump-dom", probed.as_uri()).stdout
    probe = json.loads(re.search(r'data-probe="([^"]*)"', dom).group(1).replace("&quot;", '"'))
    for table in ("pairs", "headline", "counts", "prices", "ledger-0"):
        assert re.search(rf'<table id="{table}">.*?<td>', dom, re.S), table
    verdict = re.search(r'<p id="verdict">(.*?)</p>', dom).group(1)
    for said in ("Dynamic energy only", "P(SNN cheaper)", "with static power", "success"):
        assert said in verdict, verdict
    assert probe["images"] and all(probe["images"]), "an embedded image did not decode"
    for src in re.findall(r'src="data:image/png;base64,([^"]+)"', page):
        Image.open(io.BytesIO(base64.b64decode(src))).verify()
    height = math.ceil(probe["height"]) + 10
    shot = tmp_path / "shot.png"
    _chromium(f"--window-size={width},{height}", f"--screenshot={shot}", probed.as_uri())
    pixels = np.asarray(Image.open(shot).convert("L"), dtype=np.float64)
    assert set(probe["figures"]) >= {"fig-verdict", "fig-firing_rates", "fig-breakdown",
                                     "fig-sensitivity", "fig-tradeoff", "fig-raster"}  # fmt: skip
    # the first screen answers: the verdict sentence, then its whole chart, before any heading
    # or table, all within the first 900 px at 1280 wide, and the chart drawn there
    _, chart_top, _, chart_height = probe["figures"]["fig-verdict"]
    assert probe["verdict"][0] < chart_top < min(top for top, _ in probe["headings"])
    assert probe["verdict"][1] < screen and chart_top + chart_height <= screen, probe
    top = pixels[:screen]
    assert top.std() > 10 and (top < 128).mean() > 0.01, "the first screen looks blank"
    for name, (left, top, w, h) in probe["figures"].items():
        region = pixels[int(top) : int(top + h), int(left) : int(left + w)]
        assert region.size > 10_000, (name, region.shape)
        assert region.std() > 10 and (region < 128).mean() > 0.005, f"{name} looks blank"


def _words_and_numbers(text: str) -> tuple[list[str], list[str]]:
    """A page's section titles and every number it shows, in order."""
    numbers = re.findall(r"\d+(?:[.,]\d+)*(?:e[+-]\d+)?", text)
    return re.findall(r"^## (.+)$", text, re.M), numbers


@pytest.mark.timeout(600)
def test_markdown_and_html_carry_the_same_sections_and_numbers(report: Path) -> None:
    md = (report / "report.md").read_text()
    page = (report / "report.html").read_text()
    page = re.sub(r"<style>.*?</style>|<img [^>]*>", "", page, flags=re.S)
    page = re.sub(r"<h2>(.*?)</h2>", r"\n## \1\n", page)  # a section title, as in Markdown
    page = html.unescape(re.sub(r"<[^>]+>", " ", page))
    md = re.sub(r"!\[(.*?)\]\(\w+\.png\)", r"\1", md)  # a figure: its caption, as in the page
    md_titles, md_numbers = _words_and_numbers(md)
    html_titles, html_numbers = _words_and_numbers(page)
    assert md_titles == html_titles and "Prices" in md_titles and "Verdict per pair" in md_titles
    assert md_numbers == html_numbers and len(md_numbers) > 1000
    # no duplicate rows: the same-width ANN's rows equal the run's and are merged, and said so
    table = md.split("## Energy per inference and per episode")[1].split("\n## ")[0]
    cells = [line.split(" | ") for line in table.splitlines() if line.startswith("| ")][1:]
    energies = [(c[0], c[1], c[3], c[4]) for c in cells]  # SNN on, its nJ, ANN on, its nJ
    assert len(energies) == len(set(energies)) == 15 and "merged into them" in md


def test_plot_raster_shows_one_step_of_every_layer(deployed: Path, tmp_path: Path) -> None:
    """The membranes are recorded before the reset: a neuron spikes exactly where its membrane
    is above the threshold; the command writes a PNG and refuses a step past the episode."""
    import numpy as np
    from PIL import Image

    from snnkart.eval.trace import trace_step

    nir_file = deployed.parent / "policy.nir"
    trace = trace_step(nir_file, 10, seed=10_000)
    start = 0
    for n, theta in zip(trace.sizes, trace.thresholds, strict=True):
        layer = slice(start, start + n)
        np.testing.assert_array_equal(trace.raster[:, layer], trace.membranes[:, layer] > theta)
        start += n
    assert trace.raster.any() and not trace.raster.all()
    out = tmp_path / "raster.png"
    result = _cli("plot", "raster", str(nir_file), "--step", "10", "--out", str(out))
    assert result.returncode == 0, result.stderr
    assert Image.open(out).size[0] > 500
    past = _cli("plot", "raster", str(nir_file), "--step", "100000", "--out", str(out))
    assert past.returncode == 2 and "choose --step below" in past.stderr


def test_the_side_panel_shows_the_driving_policys_layer_activity(deployed: Path) -> None:
    """``eval --render/--video`` of a spiking run: the panel's per-layer firing rates are the
    torch policy's, equal to the float32 reference's spikes for the same observation, and the
    panel draws them."""
    import os

    import numpy as np

    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    from snnkart.app.evaluate import _ShowingActivity
    from snnkart.backends.reference import NIRReference
    from snnkart.rl.trained import TorchPredictor, load_run

    run = load_run(FIXTURE)
    env = run.config.make_env(render_mode="rgb_array", track=run.track)
    reference = NIRReference(deployed.parent / "policy.nir", "float32")
    driver = _ShowingActivity(TorchPredictor(run, seed=0), env.unwrapped)
    try:
        obs, _ = env.reset(seed=4)
        for _ in range(15):
            action = driver.predict(obs)
            window, _ = reference.step(obs)
            rates = [r for _, r in env.unwrapped.activity]
            expected = window.spikes / (np.asarray(reference.chain.sizes) * reference.T)
            np.testing.assert_allclose(rates, expected, rtol=1e-6)
            obs, *_ = env.step(action)
        shown = env.render()
        env.unwrapped.activity = []
        without = env.render()  # the same state without the activity
    finally:
        env.close()
    assert len(rates) == 2 and 0 < min(rates) < 1
    assert (shown != without).any(axis=2).sum() > 500  # the bars and their labels


def test_population_encoding_host_ops_count_every_receptive_field() -> None:
    """The host's work of a population-coded input: per observation value the scaling, per
    receptive field the distance, its square and the exp, then the first layer's MACs on all
    fields; not the normalisation the current encoding does instead."""
    n_obs, fields, n1 = 21, 8, 64
    net = Network(n_in=n_obs * fields, sizes=(n1, 64), n_out=5, num_steps=8,
                  encoding="population", population=fields)  # fmt: skip
    ops = {op.what: (op.op, op.count) for op in host_ops(net)}
    assert ops["population encoding: (obs - low) / (high - low)"] == ("mult", n_obs)
    assert ops["population encoding: x01 - centre"] == ("add", n_obs * fields)
    assert ops["population encoding: x (P - 1), square, x -1/2"] == ("mult", 3 * n_obs * fields)
    assert ops["first layer: W1 z, once per env step"] == ("mac", n_obs * fields * n1)
    assert not any(name.startswith("normalisation") for name in ops)
