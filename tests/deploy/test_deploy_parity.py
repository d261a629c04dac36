"""``snnkart deploy``'s parity: Lava (float and fixed point) bit for bit with the numpy reference
of the same arithmetic in closed loop, Lava float against the torch policy, the reference's
counts against torch's, the split of a window into policy and pipeline, and a parity mismatch
failing the command."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from deploy_helpers import (
    PARITY_STEPS,
    TORCH_RUNS,
    TORCH_STEPS,
)
from tiny_runs import train_tiny
from typer.testing import CliRunner

from snnkart.backends.base import SpikeCounts, split_window
from snnkart.backends.lava_sim import LavaSimPredictor
from snnkart.backends.reference import NIRReference
from snnkart.cli import app
from snnkart.eval.closed_loop import make_policy_env
from snnkart.export.nir_export import export_nir
from snnkart.rl.policies import SNNPolicy
from snnkart.rl.ppo import normalize_obs
from snnkart.rl.trained import LoadedRun, TorchPredictor, load_run


def test_split_window_on_a_hand_built_raster() -> None:
    """Layer i's logical steps are raster rows i..i+T-1 (one Dense delay per layer); the other
    rows are fill/drain overhead. Expected values written out by hand."""
    T, sizes = 3, (2, 3)
    raster = np.array(
        [  # layer 0 | layer 1
            [1, 0, 1, 1, 0],  # row 0: layer 0 step 0; layer 1 fill (overhead)
            [0, 1, 0, 0, 1],  # row 1: layer 0 step 1; layer 1 step 0
            [1, 1, 1, 0, 0],  # row 2: layer 0 step 2; layer 1 step 1
            [1, 0, 0, 1, 1],  # row 3: layer 0 drain (overhead); layer 1 step 2
        ],
        dtype=bool,
    )
    w = split_window(raster, sizes, T)
    expected_logical = np.array(
        [[1, 0, 0, 0, 1], [0, 1, 1, 0, 0], [1, 1, 0, 1, 1]], dtype=bool
    )  # fmt: skip
    np.testing.assert_array_equal(w.logical, expected_logical)
    assert w.spikes.tolist() == [4, 4]
    assert w.overhead_spikes.tolist() == [1, 2]
    assert w.last_counts.tolist() == [1, 1, 2]
    assert w.neuron_updates.tolist() == [6, 9]
    assert w.overhead_neuron_updates.tolist() == [2, 3]
    # an unpipelined (float32) window of T rows: all of it is the policy's own steps
    flat = split_window(raster[:T], sizes, T)
    np.testing.assert_array_equal(flat.logical, raster[:T])
    assert flat.spikes.tolist() == [4, 4] and flat.overhead_spikes.tolist() == [0, 0]
    assert flat.last_counts.tolist() == [2, 1, 1]


def test_split_window_of_one_step_with_graded_spikes() -> None:
    """What the next engines return: a window of one logical step plus the pipeline depth, and
    graded spikes (an integer payload, 0 = no message). Counted by messages, not values; the
    payload bits are kept in memory but not written to deploy.json."""
    sizes = (2, 3)
    raster = np.array(
        [  # layer 0 | layer 1
            [3, 0, 0, 5, 0],  # row 0: layer 0 step 0; layer 1 fill (overhead)
            [0, 7, 2, 0, -1],  # row 1: layer 0 drain (overhead); layer 1 step 0
        ],
        dtype=np.int32,
    )
    w = split_window(raster, sizes, 1, depth=1, payload_bits=8)
    np.testing.assert_array_equal(w.logical, [[3, 0, 2, 0, -1]])
    assert w.spikes.tolist() == [1, 2] and w.overhead_spikes.tolist() == [1, 1]
    assert w.payload_bits.tolist() == [8, 16]
    assert w.last_counts.tolist() == [2, 0, -1]
    assert w.neuron_updates.tolist() == [2, 3] and w.overhead_neuron_updates.tolist() == [2, 3]
    counts = SpikeCounts(2)
    counts.add(w, (3, 4))
    assert counts.payload_bits.tolist() == [8, 16] and counts.synops.tolist() == [3, 8]
    assert "payload" not in json.dumps(counts.as_dict())
    with pytest.raises(ValueError, match=r"has 1 rows \(no pipeline\) or 2, not 2 \(depth 0\)"):
        split_window(raster, sizes, 1, depth=0)


# -- Lava against the same-arithmetic reference, bit for bit -----------------------------------


@pytest.mark.lava
@pytest.mark.timeout(180)
@pytest.mark.parametrize(
    ("name", "precision"),
    [
        ("steer", "float"),
        ("steer", "fixed"),
        ("steer-continuous", "fixed"),
        ("steer-continuous", "float"),
        ("steer-rate", "fixed"),
        ("steer-rate", "float"),
        ("steer-population", "fixed"),
    ],
)
def test_lava_is_bit_exact_with_the_same_arithmetic_reference(
    name: str, precision: str, excited: dict[str, tuple[LoadedRun, Path]]
) -> None:
    _, nir_path = excited[name]
    mode = "float64" if precision == "float" else "fixed"
    reference = NIRReference(nir_path, mode)
    sizes, T = reference.chain.sizes, reference.T
    env = make_policy_env(reference.manifest, None, None)
    raster_mismatches: list[int] = []
    action_mismatches: list[int] = []
    actions: set[str] = set()
    input_trains: set[bytes] = set()  # rate encoding: the host's input spike trains
    steps = episodes = 0
    try:
        with LavaSimPredictor(nir_path, mode) as lava:
            while steps < PARITY_STEPS:
                obs, _ = env.reset(seed=100 + episodes)
                episodes += 1
                done = False
                while not done and steps < PARITY_STEPS:
                    ref_window, ref_out = reference.step(obs)
                    lava_window, lava_out = lava.step(obs)
                    assert lava_window.raster.shape == (T + len(sizes) - 1, sum(sizes))
                    if reference.manifest.encoding == "rate":
                        ref_in, lava_in = (
                            reference.codec.last_input_spikes, lava.codec.last_input_spikes
                        )  # fmt: skip
                        assert ref_in is not None and lava_in is not None
                        np.testing.assert_array_equal(lava_in, ref_in)  # same seed, same draws
                        input_trains.add(ref_in.tobytes())
                    if not np.array_equal(lava_window.raster, ref_window.raster):
                        raster_mismatches.append(steps)
                    action = reference.codec.decode(ref_out)
                    lava_action = lava.codec.decode(lava_out)
                    if not np.array_equal(np.asarray(action), np.asarray(lava_action)):
                        action_mismatches.append(steps)
                    actions.add(repr(action))
                    obs, _, terminated, truncated, _ = env.step(action)
                    done = terminated or truncated
                    steps += 1
            lava_counts = lava.counts.as_dict()
    finally:
        env.close()

    assert not raster_mismatches, (
        f"{len(raster_mismatches)} of {steps} windows differ from the {mode} reference "
        f"(first at env step {raster_mismatches[0]})"
    )
    assert not action_mismatches, f"actions differ at env steps {action_mismatches[:10]}"
    ref_counts = reference.counts.as_dict()
    assert lava_counts == ref_counts
    assert ref_counts["env_steps"] == steps == PARITY_STEPS
    # the comparison is not trivial: several episodes (the Lava state carries across resets),
    # both layers spike, the pipeline's fill rows spike (masked out of the policy's counts)
    assert episodes >= 2
    assert all(x > 0 for x in ref_counts["spikes"])
    assert ref_counts["pipeline_overhead"]["spikes"][1] > 0, ref_counts
    assert sum(ref_counts["pipeline_overhead"]["spikes"]) == int(
        reference.counts.overhead_spikes.sum()
    )
    assert len(actions) >= (10 if name == "steer-continuous" else 2), actions
    if name == "steer-rate":
        assert len(input_trains) == steps  # fresh spike trains every env step
    print(f"\n{name} {precision}: {steps} env steps, {episodes} episodes, counts {ref_counts}")


@pytest.fixture(scope="module")
def cuba_policy(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny steer CubaLIF policy (alpha 0.8: a current decay fixed point holds only to
    du = 818), its second layer driven harder and its readout drawn at random (seeded) so that
    both layers spike and the actions vary; exported."""
    base = tmp_path_factory.mktemp("cuba")
    sets = ["snn.neuron=cuba", "snn.alpha=0.8"]
    run = load_run(train_tiny(base / "run", "steer", "snn", extra_sets=sets))
    policy = run.policy
    assert isinstance(policy, SNNPolicy)
    with torch.no_grad():
        policy.snn.fc2.weight.mul_(3.0)
        readout = policy.snn.readout.weight
        readout.copy_(torch.randn(readout.shape, generator=torch.Generator().manual_seed(1)))
    nir_path, _ = export_nir(run, base / "policy.nir")
    return nir_path


@pytest.mark.lava
@pytest.mark.timeout(180)
def test_lava_fixed_runs_a_cubalif_policy_bit_exact_in_closed_loop(cuba_policy: Path) -> None:
    """Lava's bit-accurate CubaLIF (its current decay from the quantised du) against the fixed
    reference, window for window over several episodes: an off-by-one in either's current
    decay shows up as differing rasters."""
    reference = NIRReference(cuba_policy, "fixed")
    assert reference.fixed is not None
    assert [layer.cuba for layer in reference.chain.layers] == [True, True]
    assert [q.du for q in reference.fixed.layers] == [818, 818]
    env = make_policy_env(reference.manifest, None, None)
    mismatches: list[int] = []
    actions: set[str] = set()
    steps = episodes = 0
    try:
        with LavaSimPredictor(reference.policy, "fixed") as lava:
            while steps < PARITY_STEPS:
                obs, _ = env.reset(seed=200 + episodes)
                episodes += 1
                done = False
                while not done and steps < PARITY_STEPS:
                    ref_window, ref_out = reference.step(obs)
                    lava_window, lava_out = lava.step(obs)
                    if not np.array_equal(lava_window.raster, ref_window.raster):
                        mismatches.append(steps)
                    np.testing.assert_array_equal(lava_out, ref_out)
                    action = reference.codec.decode(ref_out)
                    actions.add(repr(action))
                    obs, _, terminated, truncated, _ = env.step(action)
                    done = terminated or truncated
                    steps += 1
            lava_counts = lava.counts.as_dict()
    finally:
        env.close()
    assert not mismatches, (
        f"{len(mismatches)} of {steps} windows differ from the fixed reference (first at env "
        f"step {mismatches[0]})"
    )
    ref_counts = reference.counts.as_dict()
    assert lava_counts == ref_counts and ref_counts["env_steps"] == PARITY_STEPS
    assert episodes >= 2 and all(x > 0 for x in ref_counts["spikes"]), ref_counts
    assert len(actions) >= 2, actions


# -- Lava float against the torch policy -------------------------------------------------------


def _record_torch(run: LoadedRun, steps: int) -> list[tuple[np.ndarray, Any, np.ndarray]]:
    """(observation, torch action, torch spikes [T, h1 + h2]) of a closed-loop torch run."""
    policy = run.policy
    assert isinstance(policy, SNNPolicy)
    predictor = TorchPredictor(run)
    env = run.config.make_env()
    records: list[tuple[np.ndarray, Any, np.ndarray]] = []
    try:
        episode = 0
        while len(records) < steps:
            obs, _ = env.reset(seed=500 + episode)
            episode += 1
            done = False
            while not done and len(records) < steps:
                action = predictor.predict(obs)
                raw = np.asarray(obs, dtype=np.float32)[None]
                norm = normalize_obs(run.obs_rms, run.config.ppo, raw)
                with torch.no_grad():
                    _, _, (spk1, spk2) = policy.snn(torch.from_numpy(norm), None, fused=False)
                spikes = torch.cat([spk1[:, 0], spk2[:, 0]], dim=1).numpy() > 0
                records.append((np.array(obs, copy=True), action, spikes))
                obs, _, terminated, truncated, _ = env.step(action)
                done = terminated or truncated
    finally:
        env.close()
    return records


@pytest.mark.lava
@pytest.mark.timeout(180)
@pytest.mark.parametrize("name", TORCH_RUNS)
def test_lava_float_agrees_with_torch_on_recorded_observations(
    name: str, excited: dict[str, tuple[LoadedRun, Path]]
) -> None:
    run, nir_path = excited[name]
    records = _record_torch(run, TORCH_STEPS)
    same = flips = neuron_steps = 0
    flips_per_layer = np.zeros(2, dtype=np.int64)
    with LavaSimPredictor(nir_path, "float64") as lava:
        sizes = lava.chain.sizes
        for obs, torch_action, torch_spikes in records:
            window, out = lava.step(obs)
            action = lava.codec.decode(out)
            if run.policy.discrete:
                same += action == torch_action
            else:
                same += bool(np.allclose(action, torch_action, rtol=0, atol=1e-5))
            assert torch_spikes.shape == window.logical.shape
            diff = torch_spikes != window.logical
            flips += int(diff.sum())
            flips_per_layer += [int(diff[:, : sizes[0]].sum()), int(diff[:, sizes[0] :].sum())]
            neuron_steps += diff.size
    fraction = same / len(records)
    per_million = 1e6 * flips / neuron_steps
    print(
        f"\n{name}: torch vs Lava float on {len(records)} recorded observations: "
        f"{fraction:.2%} identical actions, {flips} spike flips ({flips_per_layer.tolist()} per "
        f"layer) in {neuron_steps} neuron-steps = {per_million:.1f} per million"
    )
    assert len(records) == TORCH_STEPS
    assert fraction >= 0.99
    assert lava.counts.spikes.sum() > 0
    assert flips <= 0.001 * neuron_steps  # float64 vs float32 rounding: rare threshold flips


# -- counts, without Lava ----------------------------------------------------------------------


@pytest.mark.parametrize("mode", ["float32", "float64", "fixed"])
def test_reference_counts_match_the_torch_policy(
    mode: str, excited: dict[str, tuple[LoadedRun, Path]]
) -> None:
    """The reference's spike, synop and neuron-update counts against what the snntorch policy
    itself computes on the same observations, and against the policy's layer shapes."""
    run, nir_path = excited["steer"]
    policy = run.policy
    assert isinstance(policy, SNNPolicy)
    reference = NIRReference(nir_path, mode)
    T, (h1, h2) = run.config.snn.num_steps, run.config.snn.hidden
    n_actions = policy.snn.readout.out_features
    steps = 60
    torch_spikes = np.zeros(2, dtype=np.int64)
    torch_last = np.zeros(h2, dtype=np.int64)
    ref_last = np.zeros(h2, dtype=np.int64)
    env = make_policy_env(reference.manifest, None, None)
    try:
        obs, _ = env.reset(seed=7)
        for _ in range(steps):
            window, out = reference.step(obs)
            raw = np.asarray(obs, dtype=np.float32)[None]
            norm = normalize_obs(run.obs_rms, run.config.ppo, raw)
            with torch.no_grad():
                _, _, (spk1, spk2) = policy.snn(torch.from_numpy(norm), None, fused=False)
            torch_spikes += [int(spk1.sum()), int(spk2.sum())]
            torch_last += spk2[:, 0].sum(dim=0).numpy().astype(np.int64)
            ref_last += window.last_counts  # what the readout sees
            obs, _, terminated, truncated, _ = env.step(reference.codec.decode(out))
            if terminated or truncated:
                obs, _ = env.reset(seed=8)
    finally:
        env.close()
    c = reference.counts
    assert c.env_steps == steps
    assert np.all(torch_spikes > 0)
    neuron_steps = steps * T * np.array([h1, h2])
    # float32 runs torch's order of operations; the others differ by rare threshold flips
    # (float64) or by the quantisation (fixed point)
    tolerance = {"float32": 0.0, "float64": 0.002, "fixed": 0.02}[mode]
    assert np.all(np.abs(c.spikes - torch_spikes) <= tolerance * neuron_steps), (
        c.spikes, torch_spikes
    )  # fmt: skip
    assert np.abs(ref_last - torch_last).sum() <= tolerance * neuron_steps[1]
    assert ref_last.sum() == c.spikes[1]
    np.testing.assert_array_equal(c.neuron_updates, neuron_steps)
    np.testing.assert_array_equal(c.synops, c.spikes * np.array([h2, n_actions]))
    if mode == "float32":
        np.testing.assert_array_equal(c.spikes, torch_spikes)
        np.testing.assert_array_equal(ref_last, torch_last)
        assert c.overhead_spikes.sum() == 0 and c.overhead_neuron_updates.sum() == 0
    else:  # one Dense delay: one fill/drain row per layer and env step
        np.testing.assert_array_equal(c.overhead_neuron_updates, steps * np.array([h1, h2]))
        np.testing.assert_array_equal(
            c.overhead_synops, c.overhead_spikes * np.array([h2, n_actions])
        )
    d = c.as_dict()
    assert d["spikes"] == c.spikes.tolist() and d["synops"] == c.synops.tolist()
    assert d["neuron_updates"] == neuron_steps.tolist()


@pytest.mark.lava
@pytest.mark.timeout(120)
def test_a_parity_mismatch_fails_the_deploy(
    exported: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A Lava window that differs from its same-arithmetic reference in one spike (flipped
    here, at env step 5, layer 1, after real Lava computed it) fails the command, naming the
    step and the layer; the record is kept as evidence."""
    real_step = LavaSimPredictor.step
    calls = {"n": 0}

    def step_with_one_flipped_spike(self: LavaSimPredictor, obs: Any) -> Any:
        window, out = real_step(self, obs)
        calls["n"] += 1
        if calls["n"] == 6:  # env step 5 of the deploy
            raster = window.raster.copy()
            raster[3, self.chain.sizes[0] + 2] ^= True  # layer 1, window row 3
            window = dataclasses.replace(window, raster=raster)
        return window, out

    monkeypatch.setattr(LavaSimPredictor, "step", step_with_one_flipped_spike)
    out = tmp_path / "out"
    result = CliRunner().invoke(
        app,
        ["deploy", str(exported), "--backend", "lava-sim", "--episodes", "2", "--out", str(out)],
    )
    assert result.exit_code == 4, result.output
    message = " ".join(result.output.split())
    assert "parity failure: lava-sim (fixed) differs from the numpy reference (fixed) in 1 of" in (
        message
    ), message
    assert "env step 5 (episode 0, step 5), layer 1, window row 3" in message, message
    record = json.loads((out / "deploy.json").read_text())
    assert record["parity"]["same_arithmetic_mismatched_windows"] == 1
    assert record["parity"]["first_same_arithmetic_mismatch"] == {
        "layer": 1, "row": 3, "env_step": 5, "episode": 0, "episode_step": 5,
    }  # fmt: skip
