"""The energy report's cost terms beyond the operations: each side's memory array from its own
footprint, routing from a placement, the host<->chip link's bits, static power over the control
period; a shared price moved on one side only; a profile that prices the ANN at nothing."""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from snnkart.backends.reference import NIRReference
from snnkart.contract.deploy_record import DeployRecord
from snnkart.energy.counts import AnnCounts, SnnCounts
from snnkart.energy.placement import Placement
from snnkart.energy.pricing import Comparison, ann_terms, terms, total, with_price
from snnkart.energy.profiles import load_profile, memory_row
from snnkart.errors import ProfileError

ROOT = Path(__file__).resolve().parents[1]
RECORD = ROOT / "tests/data/records/deploy-nir-ref-fixed.json"  # 21 -> 64 -> 64 -> 5, T = 8
COMMITTED_NIR = ROOT / "tests/data/policies/grid-snn-nir-8ddd6dd/policy.nir"


@pytest.fixture(scope="module")
def snn() -> SnnCounts:
    return SnnCounts.of_deploy(DeployRecord.read(RECORD))


def test_each_side_reads_its_weights_from_the_array_that_holds_them(snn: SnnCounts) -> None:
    kb = 1024
    sizes = (1, 8 * kb, 8 * kb + 1, 32 * kb, 32 * kb + 1, kb * kb, kb * kb + 1)
    rows = ("8kb", "8kb", "32kb", "32kb", "1mb", "1mb")
    assert [memory_row(n) for n in sizes] == [*(f"sram_read_{r}" for r in rows), "dram_read"]
    ann = AnnCounts((21, 64, 64, 5))
    # host: W1 21 x 64 + 64, readout 64 x 5 + 5 = 1,733 weights; the ANN: 5,893
    assert snn.net.host_parameters == 1733 and ann.parameters == 5893
    fp32, int8 = load_profile("horowitz45_fp32_sram"), load_profile("horowitz45_int8")

    def reads(terms: list, op: str) -> float:
        assert {t.op for t in terms if t.part == "memory"} == {op}
        return sum(t.count for t in terms if t.part == "memory")

    # fp32: the host's 6,932 bytes fit 8 KB, the ANN's 23,572 bytes need 32 KB
    assert reads(terms(snn, load_profile("loihi1"), fp32), "sram_read_8kb") == 1733 / 2
    assert reads(ann_terms(ann, fp32), "sram_read_32kb") == 5893 / 2
    # int8: the ANN's 5,893 bytes fit 8 KB; an 8-bit weight is an eighth of a 64-bit read
    assert reads(ann_terms(ann, int8), "sram_read_8kb") == 5893 / 8
    assert total(ann_terms(ann, fp32)) - total(ann_terms(ann, load_profile("horowitz45_fp32"))) \
        == pytest.approx(5893 / 2 * 20.0)  # fmt: skip


def test_placement_and_routing_by_hand(snn: SnnCounts) -> None:
    # 2,048 + 1,024 + 512 neurons, 1,024 per core, one core per tile: cores 0-1 | 2 | 3;
    # a spike of layer 1 goes to core 2: from core 0 two hops, from core 1 one (half each)
    p = Placement.of((2048, 1024, 512), 1024, 1)
    assert p.cores == (2, 1, 1) and p.hops_per_spike == (1.5, 1.0, 0.0) and p.tiles == 4
    assert Placement.of((2048, 1024, 512), 1024, 4).hops_per_spike == (0.0, 0.0, 0.0)
    # a partly filled core weighs by its neurons: 1,024 neurons 2 hops, 476 neurons 1 hop
    assert Placement.of((1500, 10), 1024, 1).hops_per_spike[0] == pytest.approx(
        (1024 * 2 + 476) / 1500
    )
    # a layer of two cores receives each spike on both: from core 0 to cores 1 and 2
    assert Placement.of((10, 20), 10, 1).hops_per_spike == (1 + 2, 0.0)
    # priced: the deployment's layer-1 spikes (with fill/drain) x the hops x the hop price
    loihi = load_profile("loihi1")
    apart = dataclasses.replace(loihi, neurons_per_core=64, cores_per_tile=1)  # one tile a layer
    drained = dataclasses.replace(snn, overhead_spikes=(5.0, 1.0))  # fill/drain spikes travel too
    routing = [t for t in terms(drained, apart, load_profile("horowitz45_fp32")) if
               t.part == "routing"]  # fmt: skip
    assert len(routing) == 1 and routing[0].price_pj == 3.5
    assert routing[0].count == pytest.approx(snn.spikes[0] + 5.0)  # 1 hop from core 0 to 1
    kept = [t for t in terms(snn, loihi, load_profile("horowitz45_fp32"))
            if t.part == "routing"]  # fmt: skip
    assert [t.count for t in kept] == [0.0]  # both layers in one tile of four cores


@pytest.mark.parametrize(("arithmetic", "word"), [("fixed", 24), ("float32", 32)])
def test_the_backend_counts_the_link_bits_the_energy_model_prices(
    arithmetic: str, word: int, snn: SnnCounts
) -> None:
    """The reference backend counts the bits it sends and receives per env step; the energy
    model prices the same count from the deployment's shape: T x 64 currents in, T x 64
    spike flags out."""
    backend = NIRReference(COMMITTED_NIR, arithmetic)  # type: ignore[arg-type]
    rng = np.random.default_rng(0)
    for _ in range(3):
        backend.step(rng.normal(size=21).astype(np.float32))
    assert backend.counts.host_to_chip_bits == 3 * 8 * 64 * word
    assert backend.counts.chip_to_host_bits == 3 * 8 * 64
    if arithmetic == "fixed":  # the committed record is a fixed-point deployment
        assert snn.link_bits == (8 * 64 * 24, 8 * 64)
    link = [t for t in terms(snn, load_profile("loihi1"), load_profile("horowitz45_fp32"))
            if t.part == "host link"]  # fmt: skip
    assert [t.count for t in link] == [8 * 64 * 24, 8 * 64]
    assert {t.price_pj for t in link} == {20.3}


def test_static_power_over_the_control_period_by_hand(snn: SnnCounts) -> None:
    ann = AnnCounts((21, 64, 64, 5))
    sram = load_profile("horowitz45_fp32_sram")
    cmp = Comparison(snn, ann, load_profile("loihi1"), sram, sram)
    e_snn, e_ann = cmp.energies()
    static = cmp.with_static()
    # Loihi 1's 0.94 W idle over one 60 Hz env step: 0.94 / 60 J = 15.67 mJ; no digital figure
    assert static["control_period_s"] == pytest.approx(1 / 60)
    assert static["snn_static_pj"] == pytest.approx(0.94 / 60 * 1e12)
    assert static["ann_static_pj"] == 0.0
    assert static["ratio"] == pytest.approx((e_snn + 0.94e12 / 60) / e_ann)
    assert static["average_power_w"]["snn_with_static"] == pytest.approx(0.94 + e_snn * 60e-12)
    assert static["average_power_w"]["ann_dynamic"] == pytest.approx(e_ann * 60e-12)
    assert [n["profile"] for n in static["not_published"]] == ["horowitz45_fp32_sram"]
    # TrueNorth's all-in figure has no static term of its own
    assert Comparison(snn, ann, load_profile("truenorth"), sram, sram).with_static()[
        "snn_static_pj"] == 0.0  # fmt: skip


def test_a_shared_price_moved_on_one_side_only_is_caught(snn: SnnCounts) -> None:
    """The ANN and the SNN's host work share the digital profile: moving its SRAM read for one
    side only is refused, and the sensitivity analysis moves it on both."""
    ann = AnnCounts((21, 64, 64, 5))
    sram, loihi = load_profile("horowitz45_fp32_sram"), load_profile("loihi1")
    moved = with_price(sram, "sram_read_8kb", 20.0)
    with pytest.raises(ProfileError, match=r"sram_read_8kb: 20 pJ for the ANN but 10 pJ"):
        Comparison(snn, ann, loihi, sram, moved)
    with pytest.raises(ProfileError, match="move a shared price on both sides together"):
        Comparison(snn, ann, loihi, moved, sram)
    both = Comparison(snn, ann, loihi, moved, moved)  # moved together: fine
    rows = Comparison(snn, ann, loihi, sram, sram).sensitivity()
    row = next(r for r in rows if r["op"] == "sram_read_8kb")
    assert row["side"] == "host+digital" and row["ratio_high"] == pytest.approx(both.ratio())
    assert not any(r["side"] == "host" for r in rows)
    # with a host profile of its own, each side moves alone
    own = Comparison(snn, ann, loihi, load_profile("arm_degnan2015"), sram).sensitivity()
    assert {r["side"] for r in own} == {"chip", "host", "digital"}


def test_a_zero_priced_digital_profile_is_a_one_line_error(tmp_path: Path) -> None:
    text = (ROOT / "snnkart/energy/builtin/horowitz45_fp32_sram.toml").read_text()
    zero = tmp_path / "free.toml"
    zero.write_text(re.sub(r"^(value|low|high) = .*$", r"\1 = 0.0", text, flags=re.M))
    assert all(p.value == 0 for p in load_profile(zero).prices.values())
    result = subprocess.run(
        [sys.executable, "-m", "snnkart.cli", "report", str(RECORD), "--profile", "loihi1",
         "--profile", str(zero), "--out", str(tmp_path / "r")],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    assert "prices the ANN at 0 pJ" in result.stderr and "undefined" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
