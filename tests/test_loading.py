"""A deployed policy is read once: one deploy parses its NIR file once and quantises it at most
once, however many backends (the primary and its parity references) run it."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

from pathlib import Path
from typing import Any

import nir
import pytest

import snnkart.backends.loading
from snnkart.eval.closed_loop import DeployRequest, run_deploy

POLICY = Path(__file__).parent / "data" / "policies" / "grid-snn-nir-8ddd6dd" / "policy.nir"


def _count_loads(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """Count ``nir.read`` and ``quantize`` calls from now on."""
    calls = {"nir.read": 0, "quantize": 0}
    real_read, real_quantize = nir.read, snnkart.backends.loading.quantize

    def read(*args: Any, **kwargs: Any) -> Any:
        calls["nir.read"] += 1
        return real_read(*args, **kwargs)

    def quantize(*args: Any, **kwargs: Any) -> Any:
        calls["quantize"] += 1
        return real_quantize(*args, **kwargs)

    monkeypatch.setattr(nir, "read", read)
    monkeypatch.setattr(snnkart.backends.loading, "quantize", quantize)
    return calls


@pytest.mark.timeout(120)
@pytest.mark.parametrize(("precision", "quantised"), [("fixed", 1), ("float64", 0)])
def test_a_reference_deploy_reads_the_policy_once(
    precision: str, quantised: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """nir-ref fixed runs beside its float32 reference: one read, one quantisation."""
    calls = _count_loads(monkeypatch)
    record = run_deploy(DeployRequest(POLICY, "nir-ref", precision, episodes=1, seed=3))
    assert record.parity.env_steps > 0
    assert calls == {"nir.read": 1, "quantize": quantised}


@pytest.mark.lava
@pytest.mark.timeout(180)
def test_a_lava_deploy_reads_the_policy_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """lava-sim fixed runs beside its fixed and float32 references: one read, one
    quantisation (before: four reads and two)."""
    calls = _count_loads(monkeypatch)
    record = run_deploy(DeployRequest(POLICY, "lava-sim", "fixed", episodes=1, seed=3))
    assert record.parity.same_arithmetic_mismatched_windows == 0
    assert record.parity.env_steps > 0
    assert calls == {"nir.read": 1, "quantize": 1}
