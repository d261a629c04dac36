"""Behaviour does not change under refactoring: the commands' outputs on explicit configs equal
the recorded golden values (``tests/golden/``; integers, rasters and actions exactly, floats
within a relative 1e-6). Re-record with ``scripts/record_golden.py`` only in a commit of its
own that says why the values had to move."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from golden.harness import EXPECTED, differences, produce


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


def test_differences_are_found() -> None:
    base = {"a": [1, 2.0, "x"], "b": {"c": True}}
    assert differences(base, json.loads(json.dumps(base))) == []
    assert differences(base, {"a": [1, 2.0 * (1 + 1e-7), "x"], "b": {"c": True}}) == []
    assert differences(base, {"a": [1, 2.0 * (1 + 1e-5), "x"], "b": {"c": True}})
    assert differences(base, {"a": [2, 2.0, "x"], "b": {"c": True}})
    assert differences(base, {"a": [1, 2.0], "b": {"c": True}})
    assert differences(base, {"a": [1, 2.0, "x"], "b": {"c": False}})
    assert differences(base, {"a": [1, 2.0, "x"], "b": {}})
