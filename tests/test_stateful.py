"""Stateful LIF policies (``snn.stateful``, docs/stateful.md): the torch actor runs Lava's row
stream without reset, recurrent PPO recomputes the rollout's log-probabilities from the stored
states, the export says the state persists, and the numpy references and Lava run the same
stream (zeroed at each episode's start) bit for bit."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

from pathlib import Path
from typing import Any

import nir
import numpy as np
import pytest
import torch
from tiny_runs import TINY, train_tiny
from typer.testing import CliRunner

from snnkart.app.nir_tools import run_nir_info
from snnkart.backends.reference import Float32Chain, Float32Stream, NIRReference
from snnkart.backends.registry import open_backend
from snnkart.cli import app
from snnkart.contract.manifest import Manifest, manifest_path
from snnkart.eval.closed_loop import DeployRequest, make_policy_env, run_deploy
from snnkart.export.nir_export import export_nir
from snnkart.rl.buffer import RolloutBuffer, minibatches
from snnkart.rl.config import ConfigError, load_config
from snnkart.rl.policies import StatefulSNNPolicy
from snnkart.rl.ppo import Trainer
from snnkart.rl.rollout import IterationStats
from snnkart.rl.stateful import stream_sequence
from snnkart.rl.stateful_lif import fused_stream_sequence
from snnkart.rl.trained import TorchPredictor, load_run

STATEFUL = ["snn.stateful=true", "snn.num_steps=2", "snn.hidden=[32, 24]"]
COMMITTED = Path(__file__).parent / "data" / "policies" / "grid-snn-nir-8ddd6dd" / "policy.nir"


def _readout_seed(run: Any) -> None:
    """A readout that depends on the spikes, so that actions vary (as test_snn_depth does)."""
    with torch.no_grad():
        weight = run.policy.snn.readout.weight
        weight.copy_(torch.randn(weight.shape, generator=torch.Generator().manual_seed(1)))


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A tiny stateful grid run (2 layers, T = 2) and its export."""
    base = tmp_path_factory.mktemp("stateful")
    run_dir = train_tiny(base / "run", "grid", "snn", extra_sets=STATEFUL)
    run = load_run(run_dir)
    _readout_seed(run)
    nir_path, _ = export_nir(run, base / "policy.nir")
    return run_dir, nir_path


@pytest.mark.parametrize(
    ("sets", "message"),
    [
        (["snn.encoding=rate"], "snn.encoding"),
        (["snn.neuron=cuba"], "snn.neuron"),
        (["ppo.num_envs=3", "ppo.num_minibatches=2"], "multiple of ppo.num_minibatches"),
    ],
)
def test_config_refuses_what_the_stream_cannot_train(sets: list[str], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        load_config(overrides={"policy": "snn"}, sets=["snn.stateful=true", *sets])


def _torch_rows(policy: StatefulSNNPolicy, predictor: TorchPredictor, obs: Any) -> tuple:
    """The torch policy's action and its spikes of every row of this env step ``[W, N]``."""
    rows: list[list[np.ndarray]] = [[] for _ in policy.snn.lifs]
    hooks = [
        lif.register_forward_hook(lambda _m, _i, out, k=k: rows[k].append(out[0][0].numpy()))
        for k, lif in enumerate(policy.snn.lifs)
    ]
    try:
        action = predictor.predict(obs)
    finally:
        for hook in hooks:
            hook.remove()
    return action, np.concatenate([np.stack(r) for r in rows], axis=1) != 0


def test_an_episode_of_the_torch_policy_equals_the_float32_reference(
    exported: tuple[Path, Path],
) -> None:
    """Every env step of a whole episode: the same action and the same spikes in every row of
    the W = T + L row stream (the membranes carried from the steps before)."""
    run_dir, nir_path = exported
    run = load_run(run_dir)
    _readout_seed(run)
    assert isinstance(run.policy, StatefulSNNPolicy)
    predictor, reference = TorchPredictor(run), NIRReference(nir_path, "float32")
    assert isinstance(reference.engine, Float32Stream)
    env = make_policy_env(reference.manifest, None, None)
    actions, overhead = set(), 0
    try:
        for episode in range(2):  # the second starts from zero state again
            obs, _ = env.reset(seed=3 + episode)
            predictor.reset()
            reference.reset()
            for step in range(500):
                window, out = reference.step(obs)
                action, rows = _torch_rows(run.policy, predictor, obs)
                assert rows.shape == window.raster.shape == (3, 56)
                np.testing.assert_array_equal(rows, window.raster, f"{episode}/{step}")
                assert action == reference.codec.decode(out), (episode, step)
                actions.add(action)
                overhead += int(window.overhead_spikes.sum())
                obs, _, terminated, truncated, _ = env.step(action)
                if terminated or truncated:
                    break
            assert terminated or truncated
    finally:
        env.close()
    assert len(actions) >= 2, actions
    assert reference.counts.spikes.min() > 0


@pytest.mark.parametrize("precision", ["fixed", "float64"])
def test_the_numpy_references_carry_the_state_across_env_steps(
    precision: str, exported: tuple[Path, Path]
) -> None:
    """Without Lava: the fixed-point and float64 references of a stateful policy are not the
    same reference restarted at every env step (the membranes and the spikes in flight carry),
    and an episode's start (``reset``) forgets all of it."""
    _, nir_path = exported
    carried, restarted = NIRReference(nir_path, precision), NIRReference(nir_path, precision)
    env = make_policy_env(carried.manifest, None, None)
    differ = steps = 0
    try:
        obs, _ = env.reset(seed=3)
        carried.reset()
        first = None
        for step in range(1, 200):
            steps = step
            window, out = carried.step(obs)
            restarted.reset()
            alone, _ = restarted.step(obs)
            first = window.raster.copy() if first is None else first
            differ += int(not np.array_equal(window.raster, alone.raster))
            obs, _, terminated, truncated, _ = env.step(carried.codec.decode(out))
            if terminated or truncated:
                break
        obs, _ = env.reset(seed=3)
        carried.reset()
        np.testing.assert_array_equal(carried.step(obs)[0].raster, first)
    finally:
        env.close()
    assert differ >= steps // 4, (differ, steps)


def _rollout_twice(tmp_path: Path, *extra: str) -> tuple[Trainer, RolloutBuffer]:
    """A stateful trainer after two rollouts (the second starts from the state the first
    left), episodes of at most 20 steps so that several start inside each rollout; three
    layers, so that spikes are in flight between steps (a first layer never spikes on its drain
    rows: its input is 0 there)."""
    cfg = load_config(
        overrides={"env": "grid", "policy": "snn", "total_steps": 512, "track": "small_S"},
        sets=[*TINY, *STATEFUL, "ppo.num_envs=4", "ppo.rollout_steps=64",
              "env_config.max_episode_steps=20", "snn.hidden=[24, 20, 16]", *extra],
    )  # fmt: skip
    trainer = Trainer(cfg, tmp_path / "run")
    buf = trainer._allocate()
    trainer.rollout.reset(seed=5)
    for _ in range(2):
        trainer.rollout.collect(
            trainer.policy, trainer.obs_rms, buf, trainer.progress, IterationStats(), lambda: False
        )
    return trainer, buf


def test_the_recurrent_update_recomputes_the_rollouts_log_probs(tmp_path: Path) -> None:
    """Before any optimiser step, every minibatch of whole env sequences, rerun from the stored
    initial state with the episode starts zeroing the state, gives the log-probabilities the
    rollout stored (ratio 1): the sequence and state bookkeeping is right."""
    trainer, buf = _rollout_twice(tmp_path)
    try:
        seq = trainer.rollout.sequences(buf)
        assert seq is not None
        assert seq.state0.abs().sum() > 0  # the second rollout starts mid-episode
        assert 0 < seq.starts.sum() < seq.starts.numel()
        zeros = torch.zeros_like(buf.rewards)
        seen = 0
        with torch.no_grad():
            for mb, extra in minibatches(buf.flat(zeros, zeros), 2, np.random.default_rng(0), seq):
                out = trainer.policy(mb.obs, mb.raw, action=mb.actions, **extra)
                np.testing.assert_allclose(out.log_prob, mb.logprobs, rtol=0, atol=1e-6)
                seen += mb.obs.shape[0]
        assert seen == buf.obs.shape[0] * buf.obs.shape[1]
    finally:
        trainer.close()


def test_the_fused_sequence_equals_the_stepped_snntorch_modules(tmp_path: Path) -> None:
    """The update's layer-by-layer fused kernel: the same readouts as snntorch's modules
    stepped row by row, and the same gradients (weights, learnable beta and threshold) up to
    float32 rounding, across episode starts and from a non-zero stored state."""
    trainer, buf = _rollout_twice(tmp_path, "snn.learn_beta=true", "snn.learn_threshold=true")
    try:
        policy = trainer.policy
        assert isinstance(policy, StatefulSNNPolicy)
        seq = trainer.rollout.sequences(buf)
        assert seq is not None
        x = policy.actor_input(
            buf.obs.reshape(-1, buf.obs.shape[-1]), buf.raw.reshape(-1, buf.raw.shape[-1])
        )
        results = []
        for run in (fused_stream_sequence, stream_sequence):
            policy.zero_grad()
            out, rates, _ = run(policy.snn, x, seq.state0, seq.starts)
            (out.square().sum() + rates.sum()).backward()
            grads = {k: p.grad.clone() for k, p in policy.snn.named_parameters()}
            results.append((out.detach(), grads))
        (fused, fused_grads), (stepped, stepped_grads) = results
        torch.testing.assert_close(fused, stepped, rtol=0, atol=0)
        assert fused_grads.keys() == stepped_grads.keys() >= {"lif1.beta", "lif2.threshold"}
        for name, grad in stepped_grads.items():
            assert grad.abs().max() > 0, name
            torch.testing.assert_close(fused_grads[name], grad, rtol=1e-4, atol=1e-5, msg=name)
    finally:
        trainer.close()


def test_a_stateful_run_trains_and_resumes(tmp_path: Path) -> None:
    run_dir = train_tiny(tmp_path / "run", "grid", "snn", total_steps=256, extra_sets=STATEFUL)
    trainer = Trainer(load_config(), run_dir, resume=True, total_steps=512)
    try:
        progress = trainer.train()
    finally:
        trainer.close()
    assert progress.global_step == 512
    assert isinstance(load_run(run_dir).policy, StatefulSNNPolicy)
    lines = (run_dir / "metrics.jsonl").read_text().splitlines()
    assert len(lines) == 2
    assert '"losses/first_minibatch_max_ratio_deviation": 0.0' in lines[0]


def test_the_export_says_the_state_persists(exported: tuple[Path, Path]) -> None:
    _, nir_path = exported
    manifest = Manifest.read(manifest_path(nir_path))
    assert manifest.state_persists and manifest.num_steps == 2
    graph = nir.read(nir_path)
    assert all(isinstance(graph.nodes[s.node], nir.LIF) for s in manifest.layers)
    assert "carry across env steps" in (run_nir_info(nir_path, None, None).state or "")
    shown = CliRunner().invoke(app, ["nir", "info", str(nir_path)], terminal_width=400)
    assert shown.exit_code == 0
    assert "state: membranes carry across env steps" in shown.output
    committed = NIRReference(COMMITTED, "float32")  # a v2 manifest: reset every env step
    assert not committed.manifest.state_persists
    assert isinstance(committed.engine, Float32Chain)
    assert run_nir_info(COMMITTED, None, None).state is None


@pytest.mark.lava
@pytest.mark.timeout(240)
@pytest.mark.parametrize("precision", ["fixed", "float"])
def test_lava_runs_the_stream_bit_for_bit_over_episodes(
    precision: str, exported: tuple[Path, Path]
) -> None:
    """200 closed-loop env steps over several episodes (Lava's network built again from zero
    state at each start): every window's raster and readout equal the reference's."""
    _, nir_path = exported
    reference = NIRReference(nir_path, "fixed" if precision == "fixed" else "float64")
    env = make_policy_env(reference.manifest, None, None)
    episodes = 1
    try:
        with open_backend(nir_path, "lava-sim", precision) as lava:
            obs, _ = env.reset(seed=11)
            for step in range(200):
                ref_window, ref_out = reference.step(obs)
                lava_window, lava_out = lava.step(obs)
                np.testing.assert_array_equal(lava_window.raster, ref_window.raster, str(step))
                np.testing.assert_array_equal(lava_out, ref_out)
                obs, _, terminated, truncated, _ = env.step(reference.codec.decode(ref_out))
                if terminated or truncated:
                    lava.reset()
                    reference.reset()
                    episodes += 1
                    obs, _ = env.reset(seed=12 + step)
            assert lava.counts.as_dict() == reference.counts.as_dict()
    finally:
        env.close()
    assert episodes >= 2
    assert reference.counts.spikes.min() > 0


@pytest.mark.lava
@pytest.mark.timeout(240)
def test_a_lava_deploy_resets_the_backend_and_its_references_together(
    exported: tuple[Path, Path], tmp_path: Path
) -> None:
    """``snnkart deploy``'s loop: several episodes, every env step checked against the fixed
    reference, which must be zeroed at each episode's start along with Lava."""
    _, nir_path = exported
    record = run_deploy(
        DeployRequest(nir_path, "lava-sim", "fixed", episodes=4, seed=3, out=tmp_path / "d")
    )
    assert record.parity.env_steps > 100
    assert record.parity.same_arithmetic_mismatched_windows == 0
    assert record.parity.float32_identical_action_fraction > 0.9
