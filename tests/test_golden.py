"""Behaviour does not change under refactoring: the commands' outputs on explicit configs equal
the recorded golden values (``tests/golden/``; integers, rasters and actions exactly, floats
within a relative 1e-6). Re-record with ``scripts/record_golden.py`` only in a commit of its
own that says why the values had to move."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from golden.harness import DEPLOYS, EXPECTED, deploy, describe_export, differences, produce

OLD_EXPORT = Path(__file__).parent / "data/policies/grid-snn-nir-8ddd6dd/policy.nir"


@pytest.mark.lava
@pytest.mark.timeout(300)
def test_outputs_equal_the_golden_values(tmp_path: Path) -> None:
    expected = json.loads(EXPECTED.read_text())
    actual = json.loads(json.dumps(produce(tmp_path)))  # the same JSON round trip as recorded
    diff = differences(expected, actual)
    assert not diff, f"{len(diff)} golden values differ, the first:\n" + "\n".join(diff[:30])
    # not vacuous: every part was produced and is non-trivial
    assert expected["train"]["snn"]["progress"]["global_step"] == 1024
    assert len(expected["deploy"]["rasters"]) == 5
    assert len(set(expected["train"]["ann"]["actions"])) > 1


@pytest.mark.lava
@pytest.mark.timeout(300)
def test_a_nir_export_written_before_the_refactor_loads_and_deploys_the_same(
    tmp_path: Path,
) -> None:
    """``OLD_EXPORT`` was written by ``snnkart export`` at commit 8ddd6dd, before the layout
    refactor moved anything, from the committed grid SNN: today's code reads the same graph
    and manifest from it, and deploys it with the golden results on every backend."""
    expected = json.loads(EXPECTED.read_text())
    described = describe_export(OLD_EXPORT)
    assert described["manifest"]["schema"] == "snnkart/manifest/v2"  # as it was written
    described["manifest"]["schema"] = expected["export"]["manifest"]["schema"]
    diff = differences(_before_v4(expected["export"]), described)
    assert not diff, diff[:10]
    actual = json.loads(json.dumps(deploy(tmp_path, OLD_EXPORT, DEPLOYS)))
    diff = differences(expected["deploy"], actual)  # also the rasters of every backend
    assert not diff, diff[:10]


def _before_v4(export: dict) -> dict:
    """A golden export as written before manifest v4 put the normalisation in the graph: no
    ``normalise`` node (the input feeds the first synapse) and no ``obs_node``."""
    node = export["manifest"]["obs_node"]
    assert node == "normalise"  # today's export has it
    (into,) = [a for a, b in export["edges"] if b == node]
    edges = [[into if a == node else a, b] for a, b in export["edges"] if b != node]
    return {
        "nodes": [n for n in export["nodes"] if n != node],
        "edges": sorted(edges),
        "arrays": {k: v for k, v in export["arrays"].items() if not k.startswith(node + ".")},
        "manifest": {**export["manifest"], "obs_node": None},
    }


def test_differences_are_found() -> None:
    base = {"a": [1, 2.0, "x"], "b": {"c": True}}
    assert differences(base, json.loads(json.dumps(base))) == []
    assert differences(base, {"a": [1, 2.0 * (1 + 1e-7), "x"], "b": {"c": True}}) == []
    assert differences(base, {"a": [1, 2.0 * (1 + 1e-5), "x"], "b": {"c": True}})
    assert differences(base, {"a": [2, 2.0, "x"], "b": {"c": True}})
    assert differences(base, {"a": [1, 2.0], "b": {"c": True}})
    assert differences(base, {"a": [1, 2.0, "x"], "b": {"c": False}})
    assert differences(base, {"a": [1, 2.0, "x"], "b": {}})


def test_an_old_export_deploys_in_the_env_it_was_trained_in() -> None:
    """``OLD_EXPORT``'s grid was trained before grid's reward defaults took the stall term, a
    stand-still ending of 2 and the speed-scaled crash: deployed, its env has none of them
    (else its returns would differ from the same run's ``snnkart eval``)."""
    from snnkart.contract.manifest import Manifest
    from snnkart.eval.closed_loop import make_policy_env

    env = make_policy_env(Manifest.read(OLD_EXPORT.with_suffix(".manifest.json")), None, None)
    try:
        reward = env.unwrapped.config.reward
        assert (reward.stall, reward.stand_still, reward.wall_per_m_s) == (0.0, 1.0, 0.0)
    finally:
        env.close()
