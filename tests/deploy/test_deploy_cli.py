"""``snnkart deploy`` and ``snnkart eval --backend`` on the command line: bad input refused in
one line, a Lava fixed-point run writing its record, a run directory on the reference."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

import json
import time
from pathlib import Path
from typing import Any

import nir
import numpy as np
import pytest
from deploy_helpers import (
    copy_export,
)
from typer.testing import CliRunner

from snnkart.backends.reference import NIRReference
from snnkart.cli import app
from snnkart.contract.manifest import manifest_path
from snnkart.contract.records import to_data
from snnkart.eval.closed_loop import DEPLOY_SCHEMA, DeployRequest, run_deploy
from snnkart.rl.trained import TorchPredictor, load_run

pytestmark = pytest.mark.xdist_group("deploy_cli")  # one worker builds the module's fixtures once

# -- bad input on the command line -------------------------------------------------------------


def _edit_manifest(path: Path, edit: Any) -> None:
    mpath = manifest_path(path)
    data = json.loads(mpath.read_text())
    edit(data)
    mpath.write_text(json.dumps(data))


def _bad_input(case: str, plain: Path, tmp: Path) -> tuple[Path, list[str], list[str]]:
    """(nir file, extra CLI options, fragments the error message must contain)."""
    target = tmp / "bad" / "policy.nir"
    if case == "missing":
        return target, [], ["no NIR file", str(target)]
    copy_export(plain, target)
    if case == "truncated":
        data = plain.read_bytes()
        target.write_bytes(data[: len(data) // 2])
        return target, [], ["not a readable NIR file", str(target)]
    if case == "text":
        target.write_text("this is not an HDF5 file\n")
        return target, [], ["not a readable NIR file"]
    if case == "env-obs-size":
        return target, ["--env", "grid"], ["23 observation values", "observes 21"]
    if case == "env-action-space":
        return target, ["--env", "gazebo"], ["acts in Discrete(9)", "'gazebo' expects Discrete(5)"]
    if case == "manifest-obs-size":

        def drop_one(data: dict[str, Any]) -> None:
            for key in ("obs_mean", "obs_std", "obs_low", "obs_high"):
                data[key] = data[key][:-1]

        _edit_manifest(target, drop_one)
        return target, [], ["23 inputs", "has 22"]
    if case == "nan":
        graph = nir.read(plain)
        graph.nodes["2"].weight[1, 2] = np.nan
        nir.write(target, graph)
        return target, [], ["NaN", "'2'"]
    if case == "moon":
        _edit_manifest(target, lambda data: data["env"].update(env="moon"))
        return target, [], ["unknown env 'moon'"]
    if case == "old-revision":
        _edit_manifest(target, lambda data: data["env"].pop("revision"))
        return target, [], ["env revision 1 or 2", "retrain the run and export it again"]
    if case == "backend":
        return target, ["--backend", "loihi3"], ["unknown backend 'loihi3'"]
    if case == "precision-lava":
        return target, ["--precision", "float32"], ["--precision", "'float32'", "float or fixed"]
    if case == "precision-ref":
        return target, ["--backend", "nir-ref", "--precision", "half"], ["--precision", "'half'"]
    raise AssertionError(case)


BAD_CASES = [
    "missing", "truncated", "text", "env-obs-size", "env-action-space", "manifest-obs-size", "nan", "moon",
    "old-revision", "backend", "precision-lava", "precision-ref",
]  # fmt: skip


@pytest.mark.timeout(60)
@pytest.mark.parametrize("case", BAD_CASES)
def test_cli_deploy_rejects_bad_input(case: str, exported: Path, tmp_path: Path) -> None:
    target, options, fragments = _bad_input(case, exported, tmp_path)
    out = tmp_path / "out"
    t0 = time.perf_counter()
    result = CliRunner().invoke(
        app, ["deploy", str(target), *options, "--episodes", "1", "--out", str(out)]
    )
    elapsed = time.perf_counter() - t0
    assert result.exit_code not in (0, None), result.output
    assert isinstance(result.exception, SystemExit), result.exception  # no traceback
    assert "error:" in result.output
    flat = " ".join(result.output.split())  # rich/typer may wrap long lines
    for fragment in fragments:
        assert fragment in flat, (fragment, result.output)
    assert not (out / "deploy.json").exists()
    assert elapsed < 20, f"{case}: took {elapsed:.1f} s to refuse"


# -- the command line, successful runs ---------------------------------------------------------


@pytest.mark.lava
@pytest.mark.timeout(120)
def test_cli_deploy_lava_fixed_writes_the_record(exported: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    result = CliRunner().invoke(
        app,
        ["deploy", str(exported), "--backend", "lava-sim", "--precision", "fixed",
         "--episodes", "1", "--out", str(out)],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    record = json.loads((out / "deploy.json").read_text())
    assert record["schema"] == DEPLOY_SCHEMA == "snnkart/deploy/v4"
    for key in ("summary", "counts", "parity", "timing", "quantization", "episodes"):
        assert key in record, key
    assert record["backend"] == "lava-sim" and record["precision"] == "fixed"
    parity, counts = record["parity"], record["counts"]
    (episode,) = record["episodes"]
    assert parity["same_arithmetic_reference"] == "fixed"
    assert parity["same_arithmetic_mismatched_windows"] == 0
    assert parity["same_arithmetic_mismatched_actions"] == 0
    assert parity["env_steps"] == counts["env_steps"] == episode["length"] > 0
    # (fixed-vs-float agreement is a claim about a policy that drives: tests/test_fixed_point.py;
    # this tiny policy picks one action, so its fraction here could not fail)
    assert "float32_identical_action_fraction" in parity
    assert episode["counts"] == counts
    assert record["summary"]["episodes"] == 1
    assert len(record["quantization"]) == 2 and record["quantization"][1]["weight_bits"] == 8
    assert record["timing"]["startup_s"] > 0 and record["timing"]["ms_per_env_step"] > 0
    assert f"0 of {counts['env_steps']} env steps differ" in " ".join(result.output.split())
    # the same arithmetic in numpy drives the same episode with the same counts
    ref = to_data(run_deploy(DeployRequest(exported, "nir-ref", "fixed", episodes=1)))
    assert ref["counts"] == counts
    assert ref["episodes"][0]["length"] == episode["length"]
    assert ref["summary"] == record["summary"]


def test_cli_eval_run_dir_on_the_reference(
    runs: dict[str, Path], exported: Path, tmp_path: Path
) -> None:
    out = tmp_path / "eval"
    result = CliRunner().invoke(
        app,
        ["eval", str(runs["steer"]), "--backend", "nir-ref", "--precision", "float32",
         "--episodes", "2", "--out", str(out)],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    record = json.loads((out / "deploy.json").read_text())
    assert record["schema"] == DEPLOY_SCHEMA
    assert record["backend"] == "nir-ref" and record["precision"] == "float32"
    assert record["summary"]["episodes"] == 2 and len(record["episodes"]) == 2
    assert record["parity"]["same_arithmetic_reference"] is None
    assert record["counts"]["env_steps"] == sum(e["length"] for e in record["episodes"])
    assert record["counts"]["pipeline_overhead"]["neuron_updates"] == [0, 0]
    # the run directory was exported on the fly: the same policy as the exported file
    direct = to_data(run_deploy(DeployRequest(exported, "nir-ref", "float32", episodes=2)))
    assert direct["episodes"] == record["episodes"]
    assert direct["counts"] == record["counts"]
    assert not any(runs["steer"].glob("eval-*"))  # --out was honoured
    # the torch policy takes the same actions in the same episodes (rare float32 order flips aside)
    run = load_run(runs["steer"])
    predictor = TorchPredictor(run)
    reference = NIRReference(exported, "float32")
    env = run.config.make_env()
    agree = total = 0
    try:
        obs, _ = env.reset(seed=10_000)
        for _ in range(record["episodes"][0]["length"]):
            action = predictor.predict(obs)
            agree += action == reference.predict(obs)
            total += 1
            obs, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
    finally:
        env.close()
    assert total == record["episodes"][0]["length"]
    assert agree >= 0.99 * total


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["deploy", "{nir}", "--episodes", "0"], "--episodes must be >= 1, got 0"),
        (["eval", "{nir}", "--backend", "nir-ref", "--episodes", "0"], "--episodes must be >= 1"),
        (["eval", "{nir}", "--backend", "loihi"], "unknown backend 'loihi'; choose torch, nir-ref"),
        (["eval", "{nir}", "--backend", "lava-sim", "--precision", "half"], "is float or fixed"),
    ],
    ids=["deploy-episodes", "eval-episodes", "eval-backend", "eval-precision"],
)
def test_the_deploy_request_is_refused_in_one_line(
    args: list[str], message: str, exported: Path, tmp_path: Path
) -> None:
    """The CLI builds one DeployRequest, checked once where it is made: nothing is written."""
    out = tmp_path / "out"
    argv = [a.format(nir=exported) for a in args] + ["--out", str(out)]
    result = CliRunner().invoke(app, argv)
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and message in lines[0], lines
    assert not out.exists()
