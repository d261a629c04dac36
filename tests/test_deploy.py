"""``snnkart deploy``: bit-exact parity of Lava (float and fixed point) with the numpy reference
in closed loop, agreement with the torch policy, spike and operation counts, foreign NIR graphs,
the quantisation rules, bad input, a missing Lava, Ctrl-C and the command line."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

import dataclasses
import json
import shutil
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path
from typing import Any

import nir
import numpy as np
import pytest
import torch
from process_marks import marked_processes, shm_segments
from tiny_runs import train_tiny
from typer.testing import CliRunner

from snnkart.backends.base import split_window
from snnkart.backends.lava_params import lava_spec
from snnkart.backends.lava_sim import LavaSimPredictor, LavaWorker
from snnkart.backends.network import ChainNetwork, UnsupportedGraphError, chain_from_graph
from snnkart.backends.quantize import (
    DECAY_UNITY,
    VTH_HOST,
    VTH_MAX,
    WEIGHT_MAX,
    check_lava_compatible,
    quantize,
)
from snnkart.backends.reference import ChainSimulator, NIRReference, load_chain
from snnkart.cli import app
from snnkart.contract.manifest import manifest_path
from snnkart.contract.records import to_data
from snnkart.eval.deploy import DEPLOY_SCHEMA, make_policy_env, run_deploy
from snnkart.export.nir_export import export_nir
from snnkart.rl.policies import SNNPolicy
from snnkart.rl.ppo import normalize_obs
from snnkart.rl.trained import LoadedRun, TorchPredictor, load_run

RUNS = {
    "steer": ("steer", "snn", "discrete"),
    "steer-continuous": ("steer", "snn", "continuous"),
    "steer-rate": ("steer", "snn", "discrete"),
    "steer-population": ("steer", "snn", "discrete"),
}
RUN_SETS = {
    "steer-rate": ["snn.encoding=rate"],  # input spikes drawn on the host (PCG64)
    "steer-population": ["snn.encoding=population"],  # Gaussian receptive fields on the host
}
TORCH_RUNS = ["steer", "steer-continuous"]
PARITY_STEPS = 300
TORCH_STEPS = 200
SUBPROCESS_ENV = {**os.environ, "SDL_VIDEODRIVER": "dummy", "COLUMNS": "200", "NO_COLOR": "1"}


def _excite(run: LoadedRun) -> LoadedRun:
    """Make layer 2 fire more and more variably, with a bias large enough to drive spikes in the
    Lava pipeline's fill rows, and the readout depend on it (parity must hold for any weights).
    The rate-encoded policy's layer-2 counts rise and fall together, so its readout rows are
    drawn at random (seeded) to turn their variation into different actions."""
    policy = run.policy
    assert isinstance(policy, SNNPolicy)
    with torch.no_grad():
        policy.snn.fc2.bias.add_(0.5)
        policy.snn.fc2.weight.mul_(2.0)
        readout = policy.snn.readout.weight
        if policy.cfg.encoding == "rate":
            generator = torch.Generator().manual_seed(0)
            readout.copy_(0.5 * torch.randn(readout.shape, generator=generator))
        else:
            readout.mul_(30.0)
    return run


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Tiny trained runs (512 env steps each), trained once for the module."""
    base = tmp_path_factory.mktemp("runs")
    return {
        name: train_tiny(base / name, *spec, extra_sets=RUN_SETS.get(name, ()))
        for name, spec in RUNS.items()
    }


@pytest.fixture(scope="module")
def excited(
    runs: dict[str, Path], tmp_path_factory: pytest.TempPathFactory
) -> dict[str, tuple[LoadedRun, Path]]:
    """Each run with :func:`_excite` applied, and its export (both read-only for the tests)."""
    base = tmp_path_factory.mktemp("excited")
    out = {}
    for name in RUNS:
        run = _excite(load_run(runs[name]))
        nir_path, _ = export_nir(run, base / name / "policy.nir")
        out[name] = (run, nir_path)
    return out


@pytest.fixture(scope="module")
def exported(runs: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The unmodified discrete steer policy's ``policy.nir`` (read-only)."""
    nir_path, _ = export_nir(load_run(runs["steer"]), tmp_path_factory.mktemp("plain") / "p.nir")
    return nir_path


def _copy_export(src: Path, dst: Path) -> Path:
    dst.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(src, dst)
    shutil.copyfile(manifest_path(src), manifest_path(dst))
    return dst


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


# -- 1. Lava against the same-arithmetic reference, bit for bit -----------------------------------


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
        with LavaSimPredictor(nir_path, precision) as lava:
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


# -- 2. Lava float against the torch policy -------------------------------------------------------


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
    with LavaSimPredictor(nir_path, "float") as lava:
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


# -- 3. counts, without Lava ----------------------------------------------------------------------


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


# -- 4. a NIR graph from outside snnkart ----------------------------------------------------------

DT = 1e-3


def _snntorch_lif(n: int, tau: float, threshold: float) -> nir.LIF:
    """A LIF population as snntorch exports it: r = tau/dt (unit input gain), no leak, reset 0."""
    return nir.LIF(
        tau=np.full(n, tau),
        r=np.full(n, tau / DT),
        v_leak=np.zeros(n),
        v_threshold=np.full(n, threshold),
        v_reset=np.zeros(n),
    )


def _graph(nodes: dict[str, Any], edges: list[tuple[str, str]]) -> nir.NIRGraph:
    return nir.NIRGraph(nodes=nodes, edges=edges)


def _foreign_lif_graph() -> tuple[nir.NIRGraph, dict[str, np.ndarray]]:
    rng = np.random.default_rng(3)
    p = {
        "w1": rng.normal(0.0, 1.0, (4, 3)).astype(np.float32),
        "b1": np.array([0.5, -0.25, 0.75, 0.0], dtype=np.float32),
        "tau": np.array([4e-3, 4e-3, 2e-3, 8e-3]),  # beta 0.75, 0.75, 0.5, 0.875
        "r": np.array([8.0, 4.0, 2.0, 8.0]),  # gain dt r / tau: 2, 1, 1, 1
        "thr": np.array([1.0, 0.5, 2.0, 0.8]),
        "w2": rng.normal(0.0, 1.0, (2, 4)).astype(np.float32),
        "b2": np.array([0.1, -0.1], dtype=np.float32),
    }
    graph = _graph(
        {
            "in": nir.Input(input_type={"input": np.array([3])}),
            "fc": nir.Affine(weight=p["w1"], bias=p["b1"]),
            "lif": nir.LIF(
                tau=p["tau"],
                r=p["r"],
                v_leak=np.zeros(4),
                v_threshold=p["thr"],
                v_reset=np.zeros(4),
            ),
            "ro": nir.Affine(weight=p["w2"], bias=p["b2"]),
            "out": nir.Output(output_type={"output": np.array([2])}),
        },
        [("in", "fc"), ("fc", "lif"), ("lif", "ro"), ("ro", "out")],
    )
    return graph, p


def _hand_loop(
    current: np.ndarray, beta: np.ndarray, gain: np.ndarray, thr: np.ndarray, reset: np.ndarray
) -> tuple[np.ndarray, float]:
    """v <- beta v + gain I; spike if v > thr; then v <- reset. Returns the spikes and the
    smallest |v - thr| seen (how far the test's values stay from a rounding-sensitive tie)."""
    v = np.zeros(current.shape[1])
    out = np.zeros(current.shape, dtype=bool)
    margin = np.inf
    for t in range(current.shape[0]):
        v = beta * v + gain * current[t]
        margin = min(margin, float(np.min(np.abs(v - thr))))
        out[t] = v > thr
        v = np.where(out[t], reset, v)
    return out, margin


def test_foreign_lif_graph_runs_like_a_hand_written_loop() -> None:
    graph, p = _foreign_lif_graph()
    chain = chain_from_graph(graph, DT)
    assert chain.n_in == 3 and chain.sizes == (4,) and chain.n_out == 2
    assert chain.fan_out == (2,) and chain.readout_node == "ro"
    (layer,) = chain.layers
    assert (layer.synapse, layer.neuron) == ("fc", "lif")
    np.testing.assert_allclose(layer.beta, [0.75, 0.75, 0.5, 0.875])
    np.testing.assert_allclose(layer.gain, [2.0, 1.0, 1.0, 1.0])
    assert not layer.plain
    assert chain.readout_weight is not None and chain.readout_bias is not None
    np.testing.assert_array_equal(chain.readout_weight, p["w2"])
    np.testing.assert_array_equal(chain.readout_bias, p["b2"])

    T = 12
    x = np.array([0.8, -0.3, 0.5], dtype=np.float32)
    current = np.broadcast_to(p["w1"] @ x + p["b1"], (T, 4)).astype(np.float32)
    current = current * np.linspace(0.5, 1.5, T, dtype=np.float32)[:, None]  # varying in time
    expected, margin = _hand_loop(
        current.astype(np.float64), 1 - DT / p["tau"], DT * p["r"] / p["tau"], p["thr"], np.zeros(4)
    )
    assert margin > 1e-4, "the hand-chosen values come too close to the threshold"
    assert 0 < expected.sum() < expected.size  # some spikes, some silence
    raster = ChainSimulator(chain, T, "float32").window(current)
    assert raster.shape == (T, 4) and raster.dtype == bool
    np.testing.assert_array_equal(raster, expected)
    window = split_window(raster, chain.sizes, T)
    np.testing.assert_array_equal(window.last_counts, expected.sum(axis=0))


def test_foreign_if_graph_with_nonzero_reset() -> None:
    w = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, -0.5], [0.3, 0.3, 0.3], [-1.0, 2.0, 0.0]], np.float32)
    r = np.array([500.0, 1000.0, 250.0, 1000.0])  # gain dt r: 0.5, 1, 0.25, 1
    thr = np.array([1.0, 1.5, 0.35, 2.0])
    reset = np.array([0.0, 0.25, -0.5, 0.5])
    graph = _graph(
        {
            "in": nir.Input(input_type={"input": np.array([3])}),
            "lin": nir.Linear(weight=w),
            "if": nir.IF(r=r, v_threshold=thr, v_reset=reset),
            "out": nir.Output(output_type={"output": np.array([4])}),
        },
        [("in", "lin"), ("lin", "if"), ("if", "out")],
    )
    chain = chain_from_graph(graph, DT)
    assert chain.readout_weight is None and chain.n_out == 4 and chain.fan_out == (4,)
    np.testing.assert_array_equal(chain.layers[0].beta, np.ones(4))
    np.testing.assert_array_equal(chain.layers[0].bias, np.zeros(4))
    T = 10
    x = np.array([0.7, 0.9, 0.4], dtype=np.float32)
    current = np.broadcast_to(w @ x, (T, 4)).astype(np.float32)
    expected, margin = _hand_loop(current.astype(np.float64), np.ones(4), DT * r, thr, reset)
    assert margin > 1e-4
    assert 0 < expected.sum() < expected.size
    np.testing.assert_array_equal(ChainSimulator(chain, T, "float32").window(current), expected)
    with pytest.raises(UnsupportedGraphError, match="'if'"):
        check_lava_compatible(chain)  # v_reset != 0 (and gain != 1) has no Lava mapping


def test_foreign_two_layer_graph_float32_and_lava_pipeline_agree() -> None:
    """A plain (snntorch-style) 2-layer graph: the float32 window, a hand loop and the float64
    Lava pipeline give the same logical spikes; layer 2 sees layer 1's spikes of the same step."""
    rng = np.random.default_rng(11)
    w1 = rng.normal(0.0, 1.0, (5, 3)).astype(np.float32)
    w2 = rng.normal(0.0, 0.8, (4, 5)).astype(np.float32)
    b2 = np.array([0.3, -0.2, 0.1, 0.45], dtype=np.float32)
    tau = 4e-3  # beta 0.75
    graph = _graph(
        {
            "in": nir.Input(input_type={"input": np.array([3])}),
            "a": nir.Affine(weight=w1, bias=np.zeros(5, np.float32)),
            "n1": _snntorch_lif(5, tau, 1.0),
            "b": nir.Affine(weight=w2, bias=b2),
            "n2": _snntorch_lif(4, tau, 0.5),
            "out": nir.Output(output_type={"output": np.array([4])}),
        },
        [("in", "a"), ("a", "n1"), ("n1", "b"), ("b", "n2"), ("n2", "out")],
    )
    chain = chain_from_graph(graph, DT)
    assert chain.sizes == (5, 4) and all(layer.plain for layer in chain.layers)
    check_lava_compatible(chain)
    T = 10
    x = np.array([1.2, -0.4, 0.9], dtype=np.float32)
    current = np.ascontiguousarray(np.broadcast_to(w1 @ x, (T, 5)), dtype=np.float32)
    # hand loop, float64
    v1, v2 = np.zeros(5), np.zeros(4)
    expected = np.zeros((T, 9), dtype=bool)
    margin = np.inf
    for t in range(T):
        v1 = 0.75 * v1 + current[t]
        margin = min(margin, float(np.min(np.abs(v1 - 1.0))))
        s1 = v1 > 1.0
        v1[s1] = 0.0
        v2 = 0.75 * v2 + w2.astype(np.float64) @ s1 + b2
        margin = min(margin, float(np.min(np.abs(v2 - 0.5))))
        s2 = v2 > 0.5
        v2[s2] = 0.0
        expected[t] = np.concatenate([s1, s2])
    assert margin > 1e-4
    assert 0 < expected[:, 5:].sum() < expected[:, 5:].size
    np.testing.assert_array_equal(ChainSimulator(chain, T, "float32").window(current), expected)
    lava64 = ChainSimulator(chain, T, "float64")
    for _ in range(3):  # the pipeline's state carries across windows; each window starts fresh
        raster = lava64.window(current.astype(np.float64))
        assert raster.shape == (T + 1, 9)
        np.testing.assert_array_equal(split_window(raster, chain.sizes, T).logical, expected)


def _plain_chain_graph(sizes: tuple[int, ...], n_in: int, seed: int) -> nir.NIRGraph:
    """A snntorch-style chain of ``len(sizes)`` LIF layers (one beta and threshold per layer)
    with a linear readout, built with the ``nir`` package as another library would."""
    rng = np.random.default_rng(seed)
    nodes: dict[str, Any] = {"in": nir.Input(input_type={"input": np.array([n_in])})}
    edges, prev, fan_in = [], "in", n_in
    for i, n in enumerate(sizes):
        gain = 1.0 if i == 0 else 2.5 / np.sqrt(fan_in)
        nodes[f"fc{i}"] = nir.Affine(
            weight=rng.normal(0.0, gain, (n, fan_in)).astype(np.float32),
            bias=(rng.normal(0.1, 0.2, n) if i else np.zeros(n)).astype(np.float32),
        )  # fmt: skip
        nodes[f"lif{i}"] = _snntorch_lif(
            n, tau=[4e-3, 8e-3, 2.5e-3][i], threshold=[1.0, 0.6, 0.8][i]
        )
        edges += [(prev, f"fc{i}"), (f"fc{i}", f"lif{i}")]
        prev, fan_in = f"lif{i}", n
    nodes["ro"] = nir.Affine(
        weight=rng.normal(0.0, 1.0, (3, fan_in)).astype(np.float32), bias=np.zeros(3, np.float32)
    )
    nodes["out"] = nir.Output(output_type={"output": np.array([3])})
    edges += [(prev, "ro"), ("ro", "out")]
    return _graph(nodes, edges)


@pytest.mark.lava
@pytest.mark.timeout(120)
@pytest.mark.parametrize("precision", ["float", "fixed"])
@pytest.mark.parametrize("sizes", [(24,), (20, 16, 12)], ids=["1-layer", "3-layer"])
def test_lava_runs_foreign_chains_of_one_and_three_layers_bit_exact(
    sizes: tuple[int, ...], precision: str
) -> None:
    """Graphs of 1 and 3 LIF layers written with the ``nir`` package (training makes 2): Lava's
    LIF and Dense processes give the same-arithmetic reference's raster, window after window,
    with the pipeline depth (T + L rows) that the number of layers implies."""
    chain = chain_from_graph(_plain_chain_graph(sizes, n_in=6, seed=len(sizes)), DT)
    assert chain.sizes == sizes
    T, L = 8, len(sizes) - 1
    fixed = quantize(chain) if precision == "fixed" else None
    reference = ChainSimulator(chain, T, "float64" if fixed is None else "fixed", fixed)
    float32 = ChainSimulator(chain, T, "float32")
    rng = np.random.default_rng(5)
    first = chain.layers[0]
    windows, logical_flips, spikes = 25, 0, np.zeros(len(sizes), dtype=np.int64)
    worker = LavaWorker(lava_spec(chain, T, "float64" if fixed is None else "fixed", fixed))
    try:
        for _ in range(windows):
            x = rng.normal(0.0, 1.0, (T, chain.n_in))  # a different input at every SNN step
            current = x @ first.weight.astype(np.float64).T + first.bias
            sent = current if fixed is None else fixed.host_current(current)
            raster = worker.window(np.ascontiguousarray(sent))
            expected = reference.window(sent)
            assert raster.shape == (T + L, sum(sizes))
            np.testing.assert_array_equal(raster, expected)
            window = split_window(raster, sizes, T)
            spikes += window.spikes
            # the pipeline computes the policy's steps: its logical spikes are those of the
            # unpipelined float32 chain (torch's order), up to rare rounding or quantisation flips
            own = float32.window(current.astype(np.float32))
            logical_flips += int((window.logical != own).sum())
    finally:
        worker.close()
    neuron_steps = windows * T * sum(sizes)
    assert logical_flips <= (0.001 if fixed is None else 0.03) * neuron_steps, logical_flips
    # not trivial: every layer fires, none saturates
    assert np.all(spikes > 0.05 * windows * T * np.asarray(sizes)), spikes
    assert np.all(spikes < 0.9 * windows * T * np.asarray(sizes)), spikes


@pytest.mark.lava
@pytest.mark.timeout(120)
@pytest.mark.parametrize("how", ["close", "kill"])
def test_a_stopped_lava_worker_leaves_no_open_files_and_is_stopped_once(
    how: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """After close() or kill(), the worker's pipes and its stderr file are closed (the tail of
    its output is kept for messages), and a second kill() signals nothing: the session's id
    may be another process's by then."""
    from snnkart.backends import lava_sim

    chain = chain_from_graph(_plain_chain_graph((8,), n_in=3, seed=1), DT)
    worker = LavaWorker(lava_spec(chain, 4, "float64", None))
    worker.window(np.zeros((4, 8)))
    stops: list[int] = []
    real = lava_sim.stop_session
    monkeypatch.setattr(
        lava_sim, "stop_session", lambda sid, **kw: (stops.append(sid), real(sid, **kw))
    )
    getattr(worker, how)()
    assert worker.proc.poll() is not None
    assert worker.stderr.closed and worker.proc.stdin.closed and worker.proc.stdout.closed
    assert worker not in lava_sim._LIVE
    assert not lava_sim._session_members(worker.proc.pid)
    worker.kill()
    worker.close()
    assert stops == [worker.proc.pid], stops
    with pytest.raises(lava_sim.LavaBackendError, match="stopped"):
        worker.window(np.zeros((4, 8)))


@pytest.mark.parametrize("kind", ["CubaLI", "Delay"])
def test_foreign_graph_with_unsupported_node_is_refused(kind: str) -> None:
    nodes: dict[str, Any] = {
        "in": nir.Input(input_type={"input": np.array([3])}),
        "fc": nir.Affine(weight=np.ones((4, 3), np.float32), bias=np.zeros(4, np.float32)),
        "out": nir.Output(output_type={"output": np.array([4])}),
    }
    if kind == "CubaLI":  # a non-spiking readout
        nodes["odd"] = nir.CubaLI(
            tau_syn=np.full(4, 2e-3), tau_mem=np.full(4, 4e-3), r=np.full(4, 4.0),
            v_leak=np.zeros(4),
        )  # fmt: skip
        edges = [("in", "fc"), ("fc", "odd"), ("odd", "out")]
    else:
        nodes["odd"] = nir.Delay(delay=np.full(3, 2e-3))
        nodes["lif"] = nir.LIF(
            tau=np.full(4, 4e-3), r=np.full(4, 4.0), v_leak=np.zeros(4), v_threshold=np.ones(4)
        )
        edges = [("in", "odd"), ("odd", "fc"), ("fc", "lif"), ("lif", "out")]
    with pytest.raises(UnsupportedGraphError) as info:
        chain_from_graph(_graph(nodes, edges), DT)
    assert kind in str(info.value) and "'odd'" in str(info.value)


# -- 5. quantisation ------------------------------------------------------------------------------


def _with_layer(chain: ChainNetwork, i: int, **changes: Any) -> ChainNetwork:
    layers = list(chain.layers)
    layers[i] = dataclasses.replace(layers[i], **changes)
    return dataclasses.replace(chain, layers=tuple(layers))


def _check_fixed(chain: ChainNetwork) -> None:
    """Every quantisation rule, for every layer of ``chain``."""
    fixed = quantize(chain)
    assert len(fixed.layers) == len(chain.layers)
    for i, (layer, q) in enumerate(zip(chain.layers, fixed.layers, strict=True)):
        beta = float(layer.beta[0])
        assert q.dv == round((1 - beta) * DECAY_UNITY), (i, beta)
        assert q.du == 4095
        assert 1 <= q.vth <= VTH_MAX
        assert 0 <= q.bias_exp <= 7
        assert q.bias_mant.dtype.kind == "i" and np.all(np.abs(q.bias_mant) <= 4095)
        theta = float(layer.threshold[0])
        if i == 0:
            assert q.weight is None and q.vth == VTH_HOST and q.scale == VTH_HOST / theta
            assert np.all(q.bias_mant == 0)
            continue
        assert q.weight is not None and q.weight.dtype.kind == "i"
        assert np.all(q.weight % 2 == 0)
        assert q.weight.min() >= -256 and q.weight.max() <= WEIGHT_MAX
        exact = layer.weight.astype(np.float64) * q.scale
        assert np.max(np.abs(q.weight - exact)) <= 1.0 + 1e-9  # nearest even integer
        assert q.vth == max(round(theta * q.scale), 1)
        target = layer.bias.astype(np.float64) * q.scale * 64
        err = np.abs(q.effective_bias - target)
        bound = (2 ** (q.bias_exp - 1) if q.bias_exp else 0) + 0.5  # rounding of the mantissa
        assert np.all(err <= bound), (i, err.max(), q.bias_exp)


def test_quantize_exported_policy(excited: dict[str, tuple[LoadedRun, Path]]) -> None:
    for name in RUNS:
        chain, manifest = load_chain(excited[name][1])
        _check_fixed(chain)
        q = quantize(chain).layers[1]
        assert q.weight is not None and int(np.abs(q.weight).max()) == WEIGHT_MAX
        assert q.dv == round((1 - manifest.layers[1].beta) * DECAY_UNITY) == 410  # beta 0.9


def test_quantize_edge_cases(exported: Path) -> None:
    chain, _ = load_chain(exported)
    layer = chain.layers[1]
    # large biases need an exponent
    big_bias = _with_layer(chain, 1, bias=np.linspace(-6.0, 6.0, layer.size).astype(np.float32))
    _check_fixed(big_bias)
    assert quantize(big_bias).layers[1].bias_exp > 0
    # tiny weights against the threshold: vth is capped at 17 bits, the weights lose resolution
    tiny = _with_layer(
        chain, 1, weight=(layer.weight * 1e-4).astype(np.float32), bias=np.zeros_like(layer.bias)
    )
    q = quantize(tiny).layers[1]
    assert q.vth == VTH_MAX and q.scale == VTH_MAX / float(layer.threshold[0])
    _check_fixed(tiny)
    for beta in (0.001, 0.5, 0.9, 0.95, 0.999):
        _check_fixed(_with_layer(chain, 0, beta=np.full(chain.sizes[0], beta)))
        _check_fixed(_with_layer(chain, 1, beta=np.full(layer.size, beta)))
    for theta in (0.25, 1.0, 3.0):
        _check_fixed(_with_layer(chain, 1, threshold=np.full(layer.size, theta)))
    # beta = 0 needs dv = 4096, one more than 12 bits hold: the largest decay is used
    assert quantize(_with_layer(chain, 1, beta=np.zeros(layer.size))).layers[1].dv == 4095


@pytest.mark.parametrize("field", ["beta", "threshold"])
def test_quantize_refuses_non_uniform_neurons(field: str, exported: Path) -> None:
    chain, _ = load_chain(exported)
    n = chain.sizes[1]
    values = np.linspace(0.5, 0.9, n) if field == "beta" else np.linspace(0.5, 1.5, n)
    bad = _with_layer(chain, 1, **{field: values})
    with pytest.raises(UnsupportedGraphError, match="non-uniform") as info:
        quantize(bad)
    assert repr(chain.layers[1].neuron) in str(info.value)  # names the LIF node ('3')
    assert ("decay" if field == "beta" else "threshold") in str(info.value)


# -- 6. bad input on the command line -------------------------------------------------------------


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
    _copy_export(plain, target)
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


# -- 7. Lava missing ------------------------------------------------------------------------------


@pytest.mark.lava
@pytest.mark.timeout(120)
def test_deploy_without_lava_fails_clearly(exported: Path, tmp_path: Path) -> None:
    block = tmp_path / "block"
    (block / "lava").mkdir(parents=True)
    (block / "lava" / "__init__.py").write_text('raise ImportError("blocked for the test")\n')
    env = dict(SUBPROCESS_ENV)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(block), env.get("PYTHONPATH")) if p)
    out = tmp_path / "out"
    args = ["deploy", str(exported), "--backend", "lava-sim", "--episodes", "1", "--out", str(out)]
    t0 = time.perf_counter()
    result = subprocess.run(
        [sys.executable, "-m", "snnkart.cli", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=90,
    )
    elapsed = time.perf_counter() - t0
    assert result.returncode != 0, result.stdout
    err = " ".join(result.stderr.split())
    assert "Traceback" not in result.stderr, result.stderr
    assert "error:" in err and "Lava" in err and "Python 3.10" in err, result.stderr
    assert "blocked for the test" in err, result.stderr  # the cause is passed on
    assert not (out / "deploy.json").exists()
    assert elapsed < 60


# -- 8. Ctrl-C to the process group mid-episode ---------------------------------------------------


@pytest.mark.lava
@pytest.mark.timeout(120)
def test_sigint_to_the_process_group_stops_everything(exported: Path, tmp_path: Path) -> None:
    mark = uuid.uuid4().hex
    shm_before = shm_segments()
    out = tmp_path / "out"
    args = [
        "deploy",
        str(exported),
        "--backend",
        "lava-sim",
        "--episodes",
        "500",
        "--out",
        str(out),
    ]
    proc = subprocess.Popen(
        [sys.executable, "-m", "snnkart.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env={**SUBPROCESS_ENV, "SNNKART_TEST_MARK": mark},
        start_new_session=True,
        # Ctrl-C as in a terminal's foreground job, even if the suite runs with SIGINT ignored
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            procs = marked_processes(mark)
            if any("lava_worker" in cmd for _, cmd in procs) and len(procs) >= 4:
                break  # the worker and its Lava runtime processes are up
            assert proc.poll() is None, proc.communicate()
            time.sleep(0.2)
        else:
            pytest.fail(f"the Lava worker did not start: {marked_processes(mark)}")
        time.sleep(3.0)  # ~250 env steps: well into the deploy, in the middle of an episode
        assert proc.poll() is None, "the deploy ended before it could be interrupted"
        assert len(shm_segments() - shm_before) > 0  # Lava's shared memory exists while it runs
        os.killpg(proc.pid, signal.SIGINT)
        t0 = time.monotonic()
        stdout, stderr = proc.communicate(timeout=10)
        stopped = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode != 0, (stdout, stderr)
    assert stopped < 10
    assert not (out / "deploy.json").exists()  # no partial record
    deadline = time.monotonic() + 3
    while time.monotonic() < deadline and (marked_processes(mark) or shm_segments() - shm_before):
        time.sleep(0.1)
    assert marked_processes(mark) == [], "processes of the deploy survived Ctrl-C"
    assert shm_segments() - shm_before == set(), "Lava's shared memory was left in /dev/shm"
    print(f"\nSIGINT: exit code {proc.returncode} after {stopped:.2f} s; {stderr.decode()[-300:]}")


# -- 9. the command line, successful runs ---------------------------------------------------------


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
    assert record["schema"] == DEPLOY_SCHEMA == "snnkart/deploy/v1"
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
    ref = to_data(run_deploy(exported, "nir-ref", "fixed", episodes=1))
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
    direct = to_data(run_deploy(exported, "nir-ref", "float32", episodes=2))
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


# -- quantisation: a bias the 13-bit mantissa cannot hold (last: it needs a fix in quantize) ---


def test_quantize_bias_fits_or_is_refused(exported: Path) -> None:
    """A bias the 13-bit mantissa cannot hold at the chosen scale (small weights, bias half the
    threshold) must be represented (a smaller scale) or refused, not silently saturated: the
    fixed-point network would otherwise spike differently from the float one."""
    chain, _ = load_chain(exported)
    layer = chain.layers[1]
    weight = (layer.weight / np.abs(layer.weight).max() * 0.01).astype(np.float32)
    weak = _with_layer(chain, 1, weight=weight, bias=np.full(layer.size, 0.5, np.float32))
    try:
        fixed = quantize(weak)
    except UnsupportedGraphError as exc:
        assert "bias" in str(exc) and "'3'" in str(exc)
        return
    q = fixed.layers[1]
    represented = q.effective_bias / (q.scale * 64)  # the bias the fixed-point network adds
    assert np.all(np.abs(q.bias_mant) <= 4095), q.bias_mant
    np.testing.assert_allclose(represented, 0.5, rtol=0.01, err_msg="the bias was saturated")
    _check_fixed(weak)


def test_backend_registry_names_one_arithmetic_per_precision(exported: Path) -> None:
    from snnkart.backends.base import arithmetic_for, open_backend
    from snnkart.errors import DeployError

    assert arithmetic_for("lava-sim", "float") == "float64"
    assert arithmetic_for("lava-sim", "fixed") == "fixed"
    assert arithmetic_for("nir-ref", "float") == "float64"
    assert arithmetic_for("nir-ref", "float32") == "float32"
    with pytest.raises(DeployError, match="--precision for lava-sim is float or fixed"):
        arithmetic_for("lava-sim", "float32")
    with pytest.raises(DeployError, match="unknown backend 'loihi'"):
        arithmetic_for("loihi", "fixed")
    with open_backend(exported, "nir-ref", "float", seed=3) as backend:
        assert (backend.name, backend.arithmetic) == ("nir-ref", "float64")
        assert backend.fixed is None and backend.counts.env_steps == 0
