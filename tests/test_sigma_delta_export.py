"""Export of sigma-delta policies: a sdnn run and a converted ReLU ANN as NIR affine chains and
v3 manifests with calibrated thresholds; ``nir info``'s notes; what already loaded still does."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import nir
import numpy as np
import pytest
import torch
from tiny_runs import train_tiny
from typer.testing import CliRunner

import snnkart
from snnkart.app.nir_notes import policy_notes
from snnkart.backends.sigma_delta import (
    input_integers,
    readout_value,
    relu_network,
    spec_from_block,
)
from snnkart.cli import app
from snnkart.contract.encoding import normalise, obs_std
from snnkart.contract.manifest import MANIFEST_SCHEMA, Manifest
from snnkart.export.calibrate import (
    BISECTIONS,
    CONTINUOUS_TOLERANCE,
    F_START,
    agreement,
    record,
    same_actions,
    search,
    thresholds,
)
from snnkart.export.nir_export import export_nir
from snnkart.export.sigma_delta_export import affine_layers, zero_block
from snnkart.rl.trained import load_run

ROOT = Path(__file__).resolve().parents[1]
POLICIES = ROOT / "tests/data/policies"
TARGET = 0.99


@pytest.fixture(scope="module")
def sdnn_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny sdnn run on grid, exported by the command with a strict calibration target."""
    run = train_tiny(tmp_path_factory.mktemp("sdnn") / "run", "grid", "sdnn",
                     extra_sets=["sdnn.hidden=[16, 16]"])  # fmt: skip
    result = CliRunner().invoke(
        app, ["export", str(run), "--nir", "--sigma-delta-target", str(TARGET),
              "--calibration-episodes", "2"],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    return run


def test_export_writes_a_manifest_whose_block_rebuilds_the_integer_network(
    sdnn_run: Path,
) -> None:
    m = Manifest.read(sdnn_run / "policy.manifest.json")
    block = m.sigma_delta
    assert block is not None and m.schema == MANIFEST_SCHEMA
    assert (m.encoding, m.num_steps, m.layers, m.state_persists) == ("delta", 1, (), True)
    assert block.origin == "sdnn" and [la.node for la in block.layers] == ["fc1", "fc2"]
    run = load_run(sdnn_run)
    graph = nir.read(sdnn_run / "policy.nir")
    assert list(graph.edges) == [("input", "normalise"), ("normalise", "fc1"), ("fc1", "fc2"),
                                 ("fc2", "readout"), ("readout", "output")]  # fmt: skip
    fcs = run.policy.sdnn.affine_layers()  # type: ignore[union-attr]
    for name, fc in zip(["fc1", "fc2", "readout"], fcs, strict=True):  # the raw weights
        np.testing.assert_array_equal(graph.nodes[name].weight, fc.weight.detach().numpy())
        np.testing.assert_array_equal(graph.nodes[name].bias, fc.bias.detach().numpy())
    weights = [graph.nodes[n].weight for n in ("fc1", "fc2", "readout")]
    biases = [graph.nodes[n].bias for n in ("fc1", "fc2", "readout")]
    zero = thresholds(block, 0.0, [0.0, 0.0, 0.0])
    spec = spec_from_block(zero, weights, biases, "fixed")
    z = np.clip(np.random.default_rng(4).normal(0, 2, (30, m.obs_dim)), -m.obs_clip, m.obs_clip)
    z = z.astype(np.float32)
    chip = readout_value(zero, relu_network(spec, input_integers(zero, z)), biases[-1], "fixed")
    with torch.no_grad():
        torch_out = run.policy.actor_output(torch.from_numpy(z), torch.from_numpy(z), None)[0]
    np.testing.assert_allclose(torch_out.numpy(), chip, rtol=1e-6, atol=1e-7)


def test_calibration_reaches_its_target_and_a_higher_factor_does_not(sdnn_run: Path) -> None:
    """Replaying the recording: the exported thresholds keep the recorded action on the
    recorded share (>= target) of steps, and the smallest rejected factor falls short."""
    run = load_run(sdnn_run)
    block = Manifest.read(sdnn_run / "policy.manifest.json").sigma_delta
    assert block is not None
    c = block.calibration
    assert (c["target"], c["episodes"], c["seed"]) == (TARGET, 2, run.config.sdnn.calibration_seed)
    net, _ = affine_layers(run)
    zero = zero_block(net, run.config.ppo.clip_obs, 8, "sdnn")
    mean, std = run.obs_rms.mean, obs_std(run.obs_rms.var)
    env = run.config.make_env(track=run.track)
    try:
        rec = record(zero, net, env, lambda o: normalise(o, mean, std, 10.0), "discrete", 2,
                     c["seed"])  # fmt: skip
    finally:
        env.close()
    assert rec.steps == c["steps"] and rec.activation_mean == pytest.approx(c["activation_mean"])
    assert block.layers == thresholds(zero, c["f"], rec.activation_mean).layers
    assert any(la.vth > 0 for la in block.layers) and c["f"] > 0
    share = agreement(block, net, rec, "discrete")
    assert share == c["fraction"] >= TARGET
    assert c["f_rejected"] is not None and c["f_rejected"] > c["f"]
    higher = thresholds(zero, c["f_rejected"], rec.activation_mean)
    assert agreement(higher, net, rec, "discrete") < TARGET
    assert len(c["state_bits"]) == 4 and c["over_24_bits"] == (max(c["state_bits"]) > 24)


def test_search_finds_the_largest_passing_factor() -> None:
    tried: list[float] = []

    def share(f: float) -> float:
        tried.append(f)
        return 1.0 - f

    f, got, rejected = search(share, 0.9)
    assert f <= 0.1 < rejected  # type: ignore[operator]
    assert rejected - f <= 0.125 / 2**BISECTIONS  # type: ignore[operator]
    assert got == 1.0 - f and tried[0] == F_START
    assert search(lambda f: 1.0, 0.9)[2] is None  # nothing fails: no rejected factor


def test_export_nir_dispatches_a_sdnn_run(sdnn_run: Path, tmp_path: Path) -> None:
    """The API's and eval's path (export_nir) writes the sigma-delta export too."""
    _, mpath = export_nir(load_run(sdnn_run), tmp_path / "p.nir")
    block = Manifest.read(mpath).sigma_delta
    assert block is not None and block.calibration["target"] == 0.95  # the run's own


def test_torch_eval_and_load_policy_work_on_a_sdnn_run(sdnn_run: Path, tmp_path: Path) -> None:
    result = CliRunner().invoke(
        app, ["eval", str(sdnn_run), "--episodes", "1", "--out", str(tmp_path / "e.json")]
    )
    assert result.exit_code == 0, result.output
    assert "SDNN" in result.output
    env = snnkart.make("grid", track="small_S")
    obs, _ = env.reset(seed=0)
    with snnkart.load_policy(sdnn_run) as policy:
        assert 0 <= policy.predict(obs) < 5


def test_nir_info_says_what_the_nir_file_alone_misses(sdnn_run: Path) -> None:
    result = CliRunner().invoke(app, ["nir", "info", str(sdnn_run / "policy.nir")])
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    for phrase in ("ReLU after fc1, fc2", "integer units", "thresholds (integer units): input",
                   "24-bit graded message", "holds the observation for 4 Lava steps",
                   "state persists across env steps", "recorded steps (target 99%"):  # fmt: skip
        assert phrase in text, phrase
    as_json = CliRunner().invoke(app, ["nir", "info", str(sdnn_run / "policy.nir"), "--json"])
    assert any("ReLU" in line for line in json.loads(as_json.output)["notes"])


def test_nir_info_notes_persisting_lif_membranes_and_nothing_for_v2(tmp_path: Path) -> None:
    old = POLICIES / "grid-snn-nir-8ddd6dd"
    assert policy_notes(old / "policy.nir") == []
    m = Manifest.read(old / "policy.manifest.json")
    (tmp_path / "policy.nir").write_bytes((old / "policy.nir").read_bytes())
    replace(m, schema=MANIFEST_SCHEMA, state_persists=True).write(tmp_path / "policy.manifest.json")
    [note] = policy_notes(tmp_path / "policy.nir")
    assert "membranes carry across env steps" in note


def test_committed_policies_and_v2_manifests_still_load() -> None:
    m = Manifest.read(POLICIES / "grid-snn-nir-8ddd6dd/policy.manifest.json")
    assert m.schema == "snnkart/manifest/v2" and m.sigma_delta is None and not m.state_persists
    for name in ("grid-ann", "grid-snn", "gazebo-snn"):
        assert load_run(POLICIES / name).policy.kind == name.split("-")[1]


def test_conversion_refuses_a_tanh_ann_with_the_fix() -> None:
    result = CliRunner().invoke(app, ["export", str(POLICIES / "grid-ann"), "--nir", "--sigma-delta",
                                      "--out", "/nonexistent/x.nir"])  # fmt: skip
    assert result.exit_code != 0
    assert "train with --set ann.activation=relu" in result.output
    assert len(result.output.strip().splitlines()) == 1


def test_a_relu_ann_converts_with_no_retraining(tmp_path: Path) -> None:
    run_dir = train_tiny(tmp_path / "ann", "grid", "ann", extra_sets=["ann.activation=relu"])
    result = CliRunner().invoke(app, ["export", str(run_dir), "--nir", "--sigma-delta",
                                      "--calibration-episodes", "1"])  # fmt: skip
    assert result.exit_code == 0, result.output
    m = Manifest.read(run_dir / "policy.manifest.json")
    assert m.sigma_delta is not None and m.sigma_delta.origin == "ann-relu"
    c = m.sigma_delta.calibration
    assert c["fraction"] >= c["target"] == 0.95 and c["episodes"] == 1
    run = load_run(run_dir)
    linears = [x for x in run.policy.actor.modules() if isinstance(x, torch.nn.Linear)]  # type: ignore[union-attr]
    graph = nir.read(run_dir / "policy.nir")
    for name, fc in zip(["fc1", "fc2", "readout"], linears, strict=True):
        np.testing.assert_array_equal(graph.nodes[name].weight, fc.weight.detach().numpy())


def test_same_actions_by_argmax_or_within_the_tolerance() -> None:
    a = np.array([[0.1, 0.9], [0.5, 0.4], [2.0, -0.3], [0.0, 0.0]])
    b = np.array([[0.2, 0.8], [0.4, 0.5], [1.0, -0.26], [0.06, 0.0]])
    assert same_actions(a, b, "discrete").tolist() == [True, False, True, True]
    # continuous: clipped to [-1, 1], then every component within 0.05
    assert same_actions(a, b, "continuous").tolist() == [False, False, True, False]
    assert CONTINUOUS_TOLERANCE == 0.05
