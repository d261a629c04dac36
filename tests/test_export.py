"""NIR export of trained spiking policies: graph and manifest contents, parity of the numpy NIR
reference with the torch policy in closed loop, refusals, broken NIR input and the CLI."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

import dataclasses
import json
import math
import shutil
from pathlib import Path
from typing import Any

import jsonschema
import nir
import numpy as np
import pytest
import torch
from tiny_runs import train_tiny
from typer.testing import CliRunner

from snnkart.app.report import build_report
from snnkart.backends.reference import NIRFileError, NIRReference
from snnkart.cli import app
from snnkart.contract.encoding import population
from snnkart.contract.manifest import (
    MANIFEST_SCHEMA,
    SCHEMA_FILE,
    Manifest,
    ManifestError,
    manifest_path,
)
from snnkart.envs.spec import spec_hash
from snnkart.export.nir_export import NIR_DT, ExportError, check_exportable, export_nir
from snnkart.rl.config import load_config
from snnkart.rl.kinds import policy_for
from snnkart.rl.policies import SNNPolicy
from snnkart.rl.trained import LoadedRun, TorchPredictor, load_run

RUNS = {
    "grid": ("grid", "snn", "discrete"),
    "steer": ("steer", "snn", "discrete"),
    "steer-continuous": ("steer", "snn", "continuous"),
    "ann": ("grid", "ann", "discrete"),
}
SNN_RUNS = ["grid", "steer", "steer-continuous"]
CHAIN = {
    "input": nir.Input,
    "normalise": nir.Affine,  # the raw observation's normalisation (contract/obs_node.py)
    "0": nir.Affine,
    "1": nir.LIF,
    "2": nir.Affine,
    "3": nir.LIF,
    "4": nir.Affine,
    "output": nir.Output,
}
CHAIN_EDGES = {
    ("input", "normalise"),
    ("normalise", "0"),
    ("0", "1"),
    ("1", "2"),
    ("2", "3"),
    ("3", "4"),
    ("4", "output"),
}
PARITY_STEPS = 1000


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Tiny trained runs (512 env steps each), trained once for the module."""
    base = tmp_path_factory.mktemp("runs")
    return {name: train_tiny(base / name, *spec) for name, spec in RUNS.items()}


@pytest.fixture(scope="module")
def exported(runs: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The exported ``policy.nir`` of each SNN run (read-only for the tests)."""
    base = tmp_path_factory.mktemp("exported")
    out = {}
    for name in SNN_RUNS:
        nir_path, mpath = export_nir(load_run(runs[name]), base / name / "policy.nir")
        assert nir_path == base / name / "policy.nir"
        assert mpath == base / name / "policy.manifest.json"
        out[name] = nir_path
    return out


def _copy_export(src: Path, dst: Path) -> Path:
    """Copy a .nir file and its manifest to ``dst`` (a .nir path)."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(src, dst)
    shutil.copyfile(manifest_path(src), manifest_path(dst))
    return dst


# -- the exported graph and manifest ------------------------------------------------------------


@pytest.mark.parametrize("name", SNN_RUNS)
def test_export_writes_the_expected_nir_chain(
    name: str, runs: dict[str, Path], tmp_path: Path
) -> None:
    run = load_run(runs[name])
    nir_path, mpath = export_nir(run, tmp_path / "sub" / "policy.nir")
    assert nir_path == tmp_path / "sub" / "policy.nir" and nir_path.is_file()
    assert mpath == tmp_path / "sub" / "policy.manifest.json" and mpath.is_file()

    graph = nir.read(nir_path)
    assert set(graph.nodes) == set(CHAIN)
    for node_name, kind in CHAIN.items():
        assert type(graph.nodes[node_name]) is kind, (node_name, graph.nodes[node_name])
    assert {tuple(e) for e in graph.edges} == CHAIN_EDGES
    assert len(graph.edges) == len(CHAIN_EDGES)

    policy = run.policy
    assert isinstance(policy, SNNPolicy)
    actor = policy.snn
    for node_name, fc in (("0", actor.fc1), ("2", actor.fc2), ("4", actor.readout)):
        node = graph.nodes[node_name]
        np.testing.assert_array_equal(node.weight, fc.weight.detach().numpy())
        np.testing.assert_array_equal(node.bias, fc.bias.detach().numpy())
    assert graph.nodes["0"].weight.shape[1] == run.meta["env_spec"]["obs_dim"]
    std = np.sqrt(run.obs_rms.var + 1e-8)  # the normaliser's frozen statistics, as a node
    np.testing.assert_allclose(graph.nodes["normalise"].weight, np.diag(1.0 / std), rtol=1e-15)
    np.testing.assert_allclose(graph.nodes["normalise"].bias, -run.obs_rms.mean / std, rtol=1e-15)
    assert graph.nodes["4"].weight.shape[0] == policy.action_dim

    layers = (("1", actor.lif1, actor.fc1.out_features), ("3", actor.lif2, actor.fc2.out_features))
    for node_name, lif, size in layers:
        node = graph.nodes[node_name]
        beta = float(lif.beta.detach().reshape(-1)[0])
        threshold = float(lif.threshold.detach().reshape(-1)[0])
        for attr in ("tau", "v_threshold", "v_reset"):
            values = np.asarray(getattr(node, attr))
            assert values.shape == (size,), (node_name, attr, values.shape)
            assert np.all(values == values[0]), (node_name, attr)
        assert np.all(np.asarray(node.v_reset) == 0.0)
        assert np.all(np.asarray(node.v_threshold) == np.float32(threshold))
        beta_back = 1.0 - NIR_DT / np.asarray(node.tau, dtype=np.float64)
        np.testing.assert_allclose(beta_back, beta, rtol=0, atol=1e-6)


@pytest.mark.parametrize("name", SNN_RUNS)
def test_manifest_round_trips_and_describes_the_run(
    name: str, runs: dict[str, Path], exported: dict[str, Path], tmp_path: Path
) -> None:
    run = load_run(runs[name])
    mpath = manifest_path(exported[name])
    manifest = Manifest.read(mpath)

    # every field survives JSON, and a second write/read gives the same record
    raw = json.loads(mpath.read_text())
    # every field, but the default discretisation (euler) is not written, as before it existed
    assert set(raw) == {f.name for f in dataclasses.fields(Manifest)} - {"discretisation"}

    schema = json.loads(SCHEMA_FILE.read_text())
    jsonschema.validate(raw, schema)  # the versioned JSON Schema other tools can read
    for broken in ({**raw, "num_steps": 0}, {k: v for k, v in raw.items() if k != "layers"}):
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate(broken, schema)
    assert manifest.discretisation == "euler"
    for f in dataclasses.fields(Manifest):
        value = getattr(manifest, f.name)
        if f.name == "discretisation":
            continue
        if f.name == "layers":
            # a LIF layer is written without a current decay (alpha), as before CubaLIF
            assert all(layer.alpha is None for layer in value)
            as_written = [{k: v for k, v in dataclasses.asdict(la).items() if k != "alpha"}
                          for la in value]  # fmt: skip
            assert as_written == raw["layers"]
        elif isinstance(value, tuple):
            assert list(value) == raw[f.name], f.name
        else:
            assert value == raw[f.name], f.name
    copy = tmp_path / "copy.manifest.json"
    manifest.write(copy)
    again = Manifest.read(copy)
    for f in dataclasses.fields(Manifest):
        assert getattr(again, f.name) == getattr(manifest, f.name), f.name
    assert again == manifest
    assert Manifest.from_json(manifest.to_json()) == manifest

    cfg = run.config
    assert manifest.schema == MANIFEST_SCHEMA == "snnkart/manifest/v4"
    assert manifest.nir_file == "policy.nir"
    assert manifest.nir_dt == NIR_DT
    assert manifest.num_steps == cfg.snn.num_steps == 8
    assert manifest.encoding == cfg.snn.encoding == "current"
    assert manifest.action_mode == cfg.action_mode == RUNS[name][2]
    assert manifest.obs_clip == cfg.ppo.clip_obs
    assert manifest.obs_dim == run.meta["env_spec"]["obs_dim"]
    np.testing.assert_array_equal(manifest.obs_mean, run.obs_rms.mean)
    np.testing.assert_array_equal(manifest.obs_std, np.sqrt(run.obs_rms.var + 1e-8))
    assert not np.allclose(manifest.obs_mean, 0.0)  # trained statistics, not the initial ones
    assert isinstance(run.policy, SNNPolicy)
    np.testing.assert_allclose(manifest.obs_low, run.policy.obs_low.numpy(), rtol=1e-6)
    assert [layer.node for layer in manifest.layers] == ["1", "3"]
    assert [layer.size for layer in manifest.layers] == list(cfg.snn.hidden)
    for layer in manifest.layers:
        assert layer.beta == pytest.approx(cfg.snn.beta, abs=1e-6)
        assert layer.threshold == cfg.snn.threshold
    assert manifest.readout_node == "4"
    env_hash = manifest.env["env_spec_hash"]
    assert env_hash == run.meta["env_spec_hash"]
    assert env_hash == spec_hash({k: v for k, v in manifest.env.items() if k != "env_spec_hash"})
    assert manifest.env["env"] == RUNS[name][0]
    assert manifest.versions["nir"] and manifest.versions["snntorch"]
    assert manifest.training["global_step"] == run.meta["global_step"]


# -- parity: numpy NIR reference vs the torch policy --------------------------------------------


def _torch_readout(run: LoadedRun, obs: np.ndarray) -> np.ndarray:
    """The torch actor's readout (logits or action means) with the frozen normalisation."""
    raw = np.asarray(obs, dtype=np.float32)[None]
    norm = run.obs_rms.normalize(raw, run.config.ppo.clip_obs)
    assert isinstance(run.policy, SNNPolicy)
    with torch.no_grad():
        out, _, _ = run.policy.snn(torch.from_numpy(norm), None, fused=False)
    return out[0].numpy()


def _closed_loop(
    run: LoadedRun, reference: NIRReference, min_steps: int
) -> tuple[int, int, int, float]:
    """Drive the env with the torch action for at least ``min_steps`` steps; return
    (steps, action mismatches, readout mismatches, largest readout difference)."""
    assert isinstance(run.policy, SNNPolicy)
    captured: list[torch.Tensor] = []
    # the readout of the very forward pass TorchPredictor.predict makes (no second torch call)
    hook = run.policy.snn.readout.register_forward_hook(
        lambda module, args, out: captured.append(out.detach().clone())
    )
    torch_pred = TorchPredictor(run)
    env = run.config.make_env()
    steps = mismatches = readout_mismatches = 0
    max_diff = 0.0
    try:
        for episode in range(100):
            if steps >= min_steps:
                break
            obs, _ = env.reset(seed=1000 + episode)
            torch_pred.reset()
            reference.reset()
            done = False
            while not done:
                captured.clear()
                action = torch_pred.predict(obs)
                assert len(captured) == 1
                torch_out = captured[0][0].numpy()
                ref_out = reference.readout(obs)
                ref_action = reference.predict(obs)
                if run.policy.discrete:
                    assert isinstance(action, int) and isinstance(ref_action, int)
                    same = action == ref_action
                else:
                    np.testing.assert_array_equal(action, np.clip(torch_out, -1.0, 1.0))
                    same = ref_action.shape == action.shape and np.allclose(
                        ref_action, action, rtol=0, atol=1e-5
                    )
                diff = float(np.max(np.abs(ref_out - torch_out)))
                max_diff = max(max_diff, diff)
                readout_mismatches += diff > 1e-5
                mismatches += not same
                obs, _, terminated, truncated, _ = env.step(action)
                done = terminated or truncated
                steps += 1
    finally:
        hook.remove()
        env.close()
    return steps, mismatches, readout_mismatches, max_diff


@pytest.mark.parametrize("name", SNN_RUNS)
def test_reference_matches_torch_in_closed_loop(
    name: str, runs: dict[str, Path], exported: dict[str, Path]
) -> None:
    run = load_run(runs[name])
    reference = NIRReference(exported[name])
    steps, mismatches, readout_mismatches, max_diff = _closed_loop(run, reference, PARITY_STEPS)
    assert steps >= PARITY_STEPS
    assert mismatches <= 0.001 * steps, (
        f"{name}: {mismatches} of {steps} actions differ between NIRReference and torch"
    )
    assert readout_mismatches <= 0.001 * steps, (
        f"{name}: readout differs by more than 1e-5 on {readout_mismatches} of {steps} "
        f"steps (largest difference {max_diff:.3g})"
    )
    # the reference counts its work: T updates per neuron and env step, and some spikes
    counts = reference.counts
    assert counts.env_steps == 2 * steps  # readout() and predict() each ran once per step
    assert np.all(counts.neuron_updates == counts.env_steps * 8 * 64)
    assert counts.spikes.sum() > 0


def test_reference_readout_matches_torch_on_single_observations(
    runs: dict[str, Path], exported: dict[str, Path]
) -> None:
    run = load_run(runs["steer-continuous"])
    reference = NIRReference(exported["steer-continuous"])
    env = run.config.make_env()
    try:
        obs, _ = env.reset(seed=3)
    finally:
        env.close()
    out = reference.readout(obs)
    assert out.shape == (run.policy.action_dim,)
    np.testing.assert_allclose(out, _torch_readout(run, obs), rtol=0, atol=1e-5)
    action = reference.predict(obs)
    assert action.dtype == np.float32 and np.all(np.abs(action) <= 1.0)


# -- refusals -----------------------------------------------------------------------------------


@pytest.fixture
def grid_run(runs: dict[str, Path]) -> LoadedRun:
    """A freshly loaded grid SNN run that a test may modify."""
    return load_run(runs["grid"])


def test_export_refuses_an_ann_run(runs: dict[str, Path], tmp_path: Path) -> None:
    run = load_run(runs["ann"])
    with pytest.raises(ExportError, match="only spiking policies") as info:
        export_nir(run, tmp_path / "ann.nir")
    assert "ANN" in str(info.value)
    assert not (tmp_path / "ann.nir").exists()
    assert not manifest_path(tmp_path / "ann.nir").exists()


def test_export_refuses_subtractive_reset(grid_run: LoadedRun, tmp_path: Path) -> None:
    policy = grid_run.policy
    assert isinstance(policy, SNNPolicy)
    lif = policy.snn.lif1
    lif.reset_mechanism = "subtract"  # the property setter also updates reset_mechanism_val
    assert lif.reset_mechanism == "subtract" and int(lif.reset_mechanism_val) == 0
    with pytest.raises(ExportError, match="reset") as info:
        export_nir(grid_run, tmp_path / "p.nir")
    assert "lif1" in str(info.value) and "subtract" in str(info.value)
    assert not (tmp_path / "p.nir").exists()


def test_export_refuses_per_neuron_betas(grid_run: LoadedRun, tmp_path: Path) -> None:
    policy = grid_run.policy
    assert isinstance(policy, SNNPolicy)
    size = policy.snn.fc1.out_features
    policy.snn.lif1.beta = torch.linspace(0.5, 0.95, size)
    with pytest.raises(ExportError, match="one decay") as info:
        export_nir(grid_run, tmp_path / "p.nir")
    assert "lif1" in str(info.value)
    assert not (tmp_path / "p.nir").exists()


def test_export_refuses_nan_weights(grid_run: LoadedRun, tmp_path: Path) -> None:
    policy = grid_run.policy
    assert isinstance(policy, SNNPolicy)
    with torch.no_grad():
        policy.snn.fc1.weight[0, 0] = math.nan
    with pytest.raises(ExportError, match="NaN") as info:
        export_nir(grid_run, tmp_path / "p.nir")
    assert "fc1.weight" in str(info.value)
    assert not (tmp_path / "p.nir").exists()


def test_unmodified_run_is_exportable(grid_run: LoadedRun) -> None:
    check_exportable(grid_run.policy.snn)  # the refusals above come from the modifications


# -- broken NIR input for the reference ---------------------------------------------------------


def test_reference_missing_nir_file(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere" / "policy.nir"
    with pytest.raises(NIRFileError) as info:
        NIRReference(missing)
    assert str(missing) in str(info.value)


def test_reference_truncated_nir_file(exported: dict[str, Path], tmp_path: Path) -> None:
    target = _copy_export(exported["grid"], tmp_path / "trunc.nir")
    data = exported["grid"].read_bytes()
    target.write_bytes(data[: len(data) // 2])
    with pytest.raises(NIRFileError, match="not a readable NIR file"):
        NIRReference(target)


def test_reference_text_file_named_nir(exported: dict[str, Path], tmp_path: Path) -> None:
    target = _copy_export(exported["grid"], tmp_path / "x.nir")
    target.write_text("this is not an HDF5 file\n")
    with pytest.raises(NIRFileError, match="not a readable NIR file"):
        NIRReference(target)


def test_reference_input_size_mismatch(exported: dict[str, Path], tmp_path: Path) -> None:
    target = _copy_export(exported["grid"], tmp_path / "short.nir")
    mpath = manifest_path(target)
    data = json.loads(mpath.read_text())
    for key in ("obs_mean", "obs_std", "obs_low", "obs_high"):
        data[key] = data[key][:-1]
    mpath.write_text(json.dumps(data))
    n = len(data["obs_mean"])
    with pytest.raises(NIRFileError, match="inputs") as info:
        NIRReference(target)
    assert f"{n + 1} inputs" in str(info.value) and f"has {n}" in str(info.value)


def test_reference_nan_weights(exported: dict[str, Path], tmp_path: Path) -> None:
    graph = nir.read(exported["grid"])
    graph.nodes["2"].weight[1, 2] = np.nan
    target = tmp_path / "nan.nir"
    nir.write(target, graph)
    shutil.copyfile(manifest_path(exported["grid"]), manifest_path(target))
    assert np.isnan(nir.read(target).nodes["2"].weight[1, 2])
    with pytest.raises(NIRFileError, match="NaN"):
        NIRReference(target)


def test_reference_missing_manifest(exported: dict[str, Path], tmp_path: Path) -> None:
    target = tmp_path / "alone.nir"
    shutil.copyfile(exported["grid"], target)
    with pytest.raises(ManifestError, match="no manifest") as info:
        NIRReference(target)
    assert str(manifest_path(target)) in str(info.value)


def test_reference_wrong_manifest_schema(exported: dict[str, Path], tmp_path: Path) -> None:
    target = _copy_export(exported["grid"], tmp_path / "schema.nir")
    mpath = manifest_path(target)
    data: dict[str, Any] = json.loads(mpath.read_text())
    data["schema"] = "snnkart/manifest/v0"
    mpath.write_text(json.dumps(data))
    with pytest.raises(ManifestError, match="schema") as info:
        NIRReference(target)
    assert "snnkart/manifest/v0" in str(info.value)


def test_reference_copied_export_still_loads(exported: dict[str, Path], tmp_path: Path) -> None:
    target = _copy_export(exported["grid"], tmp_path / "ok.nir")
    reference = NIRReference(target)
    assert reference.manifest == Manifest.read(manifest_path(exported["grid"]))


# -- the command line ---------------------------------------------------------------------------


def test_cli_export_nir(runs: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "cli" / "x.nir"
    result = CliRunner().invoke(app, ["export", str(runs["grid"]), "--nir", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert str(out) in result.output
    assert str(manifest_path(out)) in result.output
    assert out.is_file() and manifest_path(out).is_file()
    assert Manifest.read(manifest_path(out)).nir_file == "x.nir"
    assert set(nir.read(out).nodes) == set(CHAIN)


def test_cli_export_needs_a_format(runs: dict[str, Path], tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["export", str(runs["grid"])])
    assert result.exit_code != 0
    assert "--nir" in result.output
    assert not (runs["grid"] / "policy.nir").exists()


def test_cli_export_refuses_an_ann_run(runs: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "ann.nir"
    result = CliRunner().invoke(app, ["export", str(runs["ann"]), "--nir", "-o", str(out)])
    assert result.exit_code != 0
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    assert "error:" in result.output and "only spiking policies" in result.output
    assert not out.exists()


# -- rate encoding: one random-number contract for every backend ---------------------------------


def test_rate_encoding_draws_the_same_spikes_in_torch_and_the_reference(tmp_path: Path) -> None:
    train_tiny(tmp_path / "rate", "steer", "snn", total_steps=256, extra_sets=["snn.encoding=rate"])
    run = load_run(tmp_path / "rate")
    nir_path, mpath = export_nir(run, tmp_path / "rate.nir")
    manifest = Manifest.read(mpath)
    assert manifest.encoding == "rate" and "PCG64" in (manifest.encoding_rng or "")
    torch_pred = TorchPredictor(run, seed=5)
    reference = NIRReference(nir_path, "float32", seed=5)
    other_seed = NIRReference(nir_path, "float32", seed=6)
    env = run.config.make_env()
    same = differs_with_other_seed = 0
    try:
        obs, _ = env.reset(seed=0)
        for _ in range(300):
            action = torch_pred.predict(obs)
            same += action == reference.predict(obs)
            drawn = reference.codec.last_input_spikes
            other_seed.predict(obs)
            assert drawn is not None and other_seed.codec.last_input_spikes is not None
            differs_with_other_seed += not np.array_equal(drawn, other_seed.codec.last_input_spikes)
            obs, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                obs, _ = env.reset()
    finally:
        env.close()
    assert same >= 0.999 * 300, f"{same} of 300 actions agree"
    assert differs_with_other_seed > 250  # the seed matters: the spikes are really random


def test_population_code_by_hand_and_in_torch() -> None:
    low, high = np.array([0.0, -2.0]), np.array([1.0, 2.0])
    a = population(np.array([0.5, 2.0]), low, high, 5)  # fields at 0, .25, .5, .75, 1
    g = np.exp(-0.5 * np.array([4.0, 1.0, 0.0, 1.0, 4.0]))  # distances 2, 1, 0, 1, 2 widths
    np.testing.assert_allclose(a[:5], g, rtol=1e-6)  # 0.5 is the middle field's centre
    last = np.exp(-0.5 * np.array([16.0, 9.0, 4.0, 1.0, 0.0]))  # 2.0 = high: the last centre
    np.testing.assert_allclose(a[5:], last, rtol=1e-6)
    assert a.dtype == np.float32 and a.shape == (10,)
    cfg = load_config(overrides={"env": "steer", "policy": "snn"},
                      sets=["snn.encoding=population", "snn.population=8"])  # fmt: skip
    env = cfg.make_env()
    try:
        policy = policy_for(cfg, env.unwrapped)
        space = env.observation_space
    finally:
        env.close()
    assert isinstance(policy, SNNPolicy)
    assert policy.snn.fcs[0].in_features == 8 * space.shape[0]
    obs = np.random.default_rng(0).uniform(space.low, space.high, (64, space.shape[0]))
    raw = torch.from_numpy(obs.astype(np.float32))
    ours = policy.actor_input(raw, raw).numpy()
    contract = population(obs.astype(np.float32), space.low, space.high, 8)
    np.testing.assert_allclose(ours, contract, rtol=0, atol=1e-6)  # exp: the last bit may differ


def test_population_encoding_exports_and_runs_like_torch(tmp_path: Path) -> None:
    train_tiny(tmp_path / "pop", "steer", "snn", total_steps=256,
               extra_sets=["snn.encoding=population", "snn.population=6"])  # fmt: skip
    run = load_run(tmp_path / "pop")
    nir_path, mpath = export_nir(run, tmp_path / "pop.nir")
    manifest = Manifest.read(mpath)
    assert manifest.encoding == "population" and manifest.population == 6
    assert manifest.input_size == 6 * manifest.obs_dim
    assert nir.read(nir_path).nodes["0"].weight.shape[1] == manifest.input_size
    steps, mismatches, readout_mismatches, max_diff = _closed_loop(run, NIRReference(nir_path), 300)
    assert mismatches <= 0.001 * steps and readout_mismatches <= 0.001 * steps, max_diff
    data = json.loads(mpath.read_text())
    data["population"] = None
    with pytest.raises(ManifestError, match="population"):
        Manifest.from_json(json.dumps(data))

    # deployed and priced: the host's work is the population code's, and the ANN baseline
    # takes the observation, not its receptive fields
    deployed = tmp_path / "deploy"
    result = CliRunner().invoke(app, ["deploy", str(nir_path), "--backend", "nir-ref",
                                      "--episodes", "1", "--out", str(deployed)])  # fmt: skip
    assert result.exit_code == 0, result.output
    report = build_report(deployed, None, None)
    assert report["network"]["obs_dim"] == manifest.obs_dim
    assert report["ann"]["same_width"]["widths"][0] == manifest.obs_dim
    host = {op["what"] for op in report["snn"]["per_inference"]["host_ops"]}
    assert "population encoding: x01 - centre" in host
    assert not any(what.startswith("normalisation") for what in host)


def test_manifest_is_mirrored_into_the_nir_metadata(exported: dict[str, Path]) -> None:
    graph = nir.read(exported["grid"])
    mirrored = Manifest.from_json(str(graph.metadata["snnkart_manifest"]), "metadata")
    assert mirrored == Manifest.read(manifest_path(exported["grid"]))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"encoding": "burst"}, "unknown encoding"),
        ({"action_mode": "joystick"}, "unknown action_mode"),
        ({"num_steps": 0}, "num_steps"),
        ({"obs_std": (1.0,)}, "differ in length"),
        ({"schema": "snnkart/manifest/v9"}, "schema"),
        ({"track": None}, "embeds its track"),
    ],
)
def test_manifest_is_validated_on_construction(
    exported: dict[str, Path], change: dict, message: str
) -> None:
    """However a manifest is made (read, exported, or built in code), it is valid or refused."""
    import dataclasses

    manifest = Manifest.read(manifest_path(exported["steer"]))
    with pytest.raises(ManifestError, match=message):
        dataclasses.replace(manifest, **change)
