"""Deploying a sigma-delta policy (NIR affine chain + manifest v3 ``sigma_delta`` block):
nir-ref and lava-sim closed loop, the held schedule, parity and the counts."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from sigma_delta_policy import write_sigma_delta_policy

from snnkart.backends import sigma_delta_lava
from snnkart.backends.loading import load_policy, open_policy
from snnkart.backends.sigma_delta import (
    SigmaDeltaChain,
    input_integers,
    readout_value,
    relu_network,
)
from snnkart.backends.sigma_delta_backend import SigmaDeltaReference
from snnkart.backends.sigma_delta_policy import SigmaDeltaPolicy
from snnkart.contract import encoding
from snnkart.contract.manifest import Manifest, manifest_path
from snnkart.contract.sigma_delta import SigmaDeltaBlock, SigmaDeltaLayer
from snnkart.errors import NIRFileError, ParityError
from snnkart.eval.closed_loop import run_deploy
from snnkart.eval.policy_env import make_policy_env
from snnkart.eval.request import DeployRequest


@pytest.fixture(scope="module")
def policies(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The grid ANN's weights as a sigma-delta policy, with thresholds and with none."""
    base = tmp_path_factory.mktemp("sdnn")
    return {
        "vth": write_sigma_delta_policy(base / "vth", vth=4, vth_in=2),
        "zero": write_sigma_delta_policy(base / "zero"),
    }


def _observations(policy: SigmaDeltaPolicy, steps: int, seed: int = 3) -> list[np.ndarray]:
    """Observations of ``steps`` env steps driven by the numpy reference (over episode ends)."""
    env = make_policy_env(policy.manifest, None, None)
    backend = SigmaDeltaReference(policy, "fixed")
    obs, _ = env.reset(seed=seed)
    out = []
    for _ in range(steps):
        out.append(obs)
        obs, _, terminated, truncated, _ = env.step(backend.predict(obs))
        if terminated or truncated:
            obs, _ = env.reset()
    env.close()
    return out


def test_a_sigma_delta_manifest_loads_and_the_lif_loader_names_the_way(
    policies: dict[str, Path],
) -> None:
    policy = open_policy(policies["vth"])
    assert isinstance(policy, SigmaDeltaPolicy)
    assert policy.sizes == (21, 64, 64, 5) and policy.block.rows == 4
    with pytest.raises(NIRFileError, match=r"is a sigma-delta policy.*open_policy"):
        load_policy(policies["vth"])


def test_graph_and_block_sizes_that_differ_are_one_clear_error(
    policies: dict[str, Path], tmp_path: Path
) -> None:
    source = policies["vth"]
    manifest = Manifest.read(manifest_path(source))
    assert manifest.sigma_delta is not None
    layers = list(manifest.sigma_delta.layers)
    layers[1] = dataclasses.replace(layers[1], size=32)
    block = dataclasses.replace(manifest.sigma_delta, layers=tuple(layers))
    target = tmp_path / "policy.nir"
    target.write_bytes(source.read_bytes())
    dataclasses.replace(manifest, sigma_delta=block).write(manifest_path(target))
    with pytest.raises(
        NIRFileError, match="node 'fc2' has 64 neurons, the sigma_delta block says 32"
    ):
        open_policy(target)


def test_nir_ref_closed_loop_equals_a_hand_loop_over_the_chain(policies: dict[str, Path]) -> None:
    policy = open_policy(policies["vth"])
    assert isinstance(policy, SigmaDeltaPolicy)
    observations = _observations(policy, 150)
    backend = SigmaDeltaReference(policy, "fixed")
    chain, block, m = SigmaDeltaChain(policy.spec("fixed")), policy.block, policy.manifest
    for obs in observations:
        backend.reset()  # an episode's start changes nothing: the state persists
        got = backend.readout(obs)
        z = encoding.normalise(obs, np.array(m.obs_mean), np.array(m.obs_std), m.obs_clip)
        x = input_integers(block, z)
        for _ in range(block.rows):  # the held schedule: L + 2 Lava steps on one input
            sigma = chain.step(x)
        np.testing.assert_array_equal(
            got, readout_value(block, sigma, policy.readout_bias, "fixed")
        )
    assert backend.counts.env_steps == 150 and 0 < sum(backend.counts.sums["messages"][1:3])


@pytest.mark.parametrize("arithmetic", ["fixed", "float64"])
def test_with_every_threshold_zero_the_deployed_actions_are_the_quantised_relu_networks(
    policies: dict[str, Path], arithmetic: str
) -> None:
    policy = open_policy(policies["zero"])
    assert isinstance(policy, SigmaDeltaPolicy)
    observations = _observations(policy, 200)
    backend = SigmaDeltaReference(policy, arithmetic)  # type: ignore[arg-type]
    spec, m = policy.spec(arithmetic), policy.manifest  # type: ignore[arg-type]
    z = np.stack([
        encoding.normalise(o, np.array(m.obs_mean), np.array(m.obs_std), m.obs_clip)
        for o in observations
    ])  # fmt: skip
    x = input_integers(policy.block, z) if arithmetic == "fixed" else z
    relu = readout_value(policy.block, relu_network(spec, x), policy.readout_bias, arithmetic)  # type: ignore[arg-type]
    actions = [backend.predict(obs) for obs in observations]
    assert actions == [int(np.argmax(r)) for r in relu]
    assert len(set(actions)) > 1  # the observations make the policy act differently


def _tiny_policy() -> SigmaDeltaPolicy:
    """1 -> 1 -> 1: ``W1 = 2``, bias 1, ``vth = 2``, ``W2 = 1``; all units 1, z = obs."""
    block = SigmaDeltaBlock(
        layers=(SigmaDeltaLayer(node="fc1", size=1, act_scale=1.0, vth=2),),
        readout_node="readout", input_scale=1.0, out_scale=1.0,
    )  # fmt: skip
    manifest = Manifest(
        schema="snnkart/manifest/v3", nir_file="p.nir", nir_dt=1e-3, num_steps=1, layers=(),
        encoding="delta", obs_mean=(0.0,), obs_std=(1.0,), obs_clip=10.0, obs_low=(-1.0,),
        obs_high=(1.0,), readout_node="readout", action_mode="continuous", env={},
        versions={}, track={}, state_persists=True, sigma_delta=block,
    )  # fmt: skip
    weights = (np.array([[2.0]], np.float32), np.array([[1.0]], np.float32))
    biases = (np.array([1.0], np.float32), np.array([0.0], np.float32))
    return SigmaDeltaPolicy(Path("p.nir"), None, manifest, block, weights, biases)


def test_counts_equal_hand_counts_on_a_three_step_input() -> None:
    # docs/sigma-delta.md's example, with the held schedule (3 Lava steps per env step), and a
    # fourth env step repeating the third (nothing changes: no message, nothing active)
    backend = SigmaDeltaReference(_tiny_policy(), "fixed")
    readouts, steps = [], []
    for obs in (1.0, 0.0, 2.0, 2.0):
        window, out = backend.step(np.array([obs]))
        readouts.append(float(out[0]))
        steps.append(window.counts)
    assert readouts == [3.0, 1.0, 5.0, 5.0]
    # per env step: [input Delta, SigmaDelta, readout Sigma]
    assert [s.messages.tolist() for s in steps] == [[1, 1, 1]] * 3 + [[0, 0, 1]]
    assert [s.synaptic_events.tolist() for s in steps] == [[1, 1, 0]] * 3 + [[0, 0, 0]]
    assert [s.payload_bits.tolist() for s in steps] == [[24, 24, 24]] * 3 + [[0, 0, 24]]
    assert all(s.updates_clocked.tolist() == [3, 3, 3] for s in steps)
    # active: the input changes at row 0, the SigmaDelta receives at row 1 and sends then,
    # the Sigma receives at row 2 (the bias moves the hidden act at the very first row, but
    # with no input and no message that row is idle by definition)
    assert [s.updates_active.tolist() for s in steps] == [[1, 1, 1]] * 3 + [[0, 0, 0]]
    assert [(s.host_to_chip_bits, s.chip_to_host_bits) for s in steps] == [(24, 24)] * 3 + [(0, 24)]
    totals = backend.counts.as_dict()["sigma_delta"]
    assert totals["messages"] == [3, 3, 4] and totals["updates_active"] == [3, 3, 3]


def _deploy(nir: Path, backend: str, precision: str, episodes: int, out: Path) -> object:
    return run_deploy(DeployRequest(nir, backend, precision, episodes, seed=11, out=out))


@pytest.mark.lava
@pytest.mark.timeout(300)
@pytest.mark.parametrize("precision", ["fixed", "float"])
def test_lava_closed_loop_is_bit_exact_with_the_reference_for_200_env_steps(
    policies: dict[str, Path], precision: str, tmp_path: Path
) -> None:
    record = _deploy(policies["vth"], "lava-sim", precision, 3, tmp_path / "lava")
    reference = _deploy(policies["vth"], "nir-ref", precision, 3, tmp_path / "ref")
    p = record.parity  # type: ignore[attr-defined]
    assert p.env_steps >= 200 and p.same_arithmetic_mismatched_windows == 0
    assert p.same_arithmetic_reference == ("fixed" if precision == "fixed" else "float64")
    assert record.bit_exact and p.float32_identical_action_fraction is None  # type: ignore[attr-defined]
    sd = record.counts.sigma_delta  # type: ignore[attr-defined]
    assert sd == reference.counts.sigma_delta  # type: ignore[attr-defined]
    assert sd.layers == ["input", "fc1", "fc2", "readout"] and sum(sd.messages) > 0
    assert (tmp_path / "lava" / "deploy.json").is_file()


@pytest.mark.lava
@pytest.mark.timeout(300)
def test_a_readout_wider_than_lavas_int32_stays_bit_exact(tmp_path: Path) -> None:
    """Units as fine as the trained kind's make the readout's integers exceed 2**31 (Lava's
    fixed-point models compute in int32 and would wrap): the readout runs beside the bridge in
    int64, and Lava still agrees with the reference on every env step."""
    nir_file = write_sigma_delta_policy(tmp_path / "wide", vth=4, vth_in=2, divisor=400)
    policy = open_policy(nir_file)
    backend = SigmaDeltaReference(policy, "fixed")
    widest = 0
    for obs in _observations(policy, 40):
        window, _ = backend.step(obs)
        widest = max(widest, int(np.abs(window.raster[:, -policy.sizes[-1] :]).max()))
    assert widest > 2**31  # the case Lava's own Sigma would wrap
    record = _deploy(nir_file, "lava-sim", "fixed", 1, tmp_path / "lava")
    p = record.parity  # type: ignore[attr-defined]
    assert p.env_steps > 0 and p.same_arithmetic_mismatched_windows == 0


@pytest.mark.lava
@pytest.mark.timeout(300)
def test_a_broken_lava_engine_is_caught_by_the_parity_check(
    policies: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    real = sigma_delta_lava.sigma_delta_lava_spec

    def broken(spec, rows):  # type: ignore[no-untyped-def]
        lava = real(spec, rows)
        readout = lava.weights[-1].copy()
        readout[0, 0] += 8  # Lava runs one synapse that is not the policy's
        return dataclasses.replace(lava, weights=(*lava.weights[:-1], readout))

    monkeypatch.setattr(sigma_delta_lava, "sigma_delta_lava_spec", broken)
    with pytest.raises(
        ParityError, match=r"lava-sim \(fixed\) differs from the numpy reference"
    ) as caught:
        _deploy(policies["vth"], "lava-sim", "fixed", 1, None)  # type: ignore[arg-type]
    first = caught.value.record.parity.first_same_arithmetic_mismatch
    assert first["layer"] == 3  # the readout Sigma: the first population after the broken synapse


@pytest.mark.parametrize("command", ["deploy", "eval"])
def test_the_cli_deploys_and_evaluates_a_sigma_delta_nir_file(
    policies: dict[str, Path], tmp_path: Path, command: str
) -> None:
    from typer.testing import CliRunner

    from snnkart.cli import app

    out = tmp_path / "out"
    result = CliRunner().invoke(
        app,
        [command, str(policies["vth"]), "--backend", "nir-ref", "--precision", "float",
         "--episodes", "1", "--out", str(out)],
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    record = json.loads((out / "deploy.json").read_text())
    assert record["schema"] == "snnkart/deploy/v4" and record["precision"] == "float64"
    assert record["counts"]["sigma_delta"]["layers"] == ["input", "fc1", "fc2", "readout"]
    assert "messages input" in " ".join(result.output.split())


def test_a_graph_with_other_nodes_and_float32_are_one_clear_error(
    policies: dict[str, Path], tmp_path: Path
) -> None:
    import nir

    from snnkart.backends.registry import open_backend
    from snnkart.errors import DeployError

    refused = "sigma-delta policy runs on nir-ref in fixed or float64, not float32: --precision"
    with pytest.raises(DeployError, match=refused):
        open_backend(policies["vth"], "nir-ref", "float32")
    graph = nir.read(policies["vth"])
    graph.nodes["fc2"] = nir.LIF(
        tau=np.ones(64), r=np.ones(64), v_leak=np.zeros(64), v_threshold=np.ones(64)
    )
    target = tmp_path / "policy.nir"
    nir.write(target, graph)
    manifest_path(target).write_text(manifest_path(policies["vth"]).read_text())
    with pytest.raises(NIRFileError, match="node 'fc2' is a LIF; a sigma-delta graph holds only"):
        open_policy(target)
