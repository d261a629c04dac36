"""NeuroBench's closed-loop metrics (snnkart.contract.neurobench): hand-computed cases, the risk's
rounding, and a comparison with NeuroBench's own code.

NeuroBench's RewardScore is only on its ``Closed_Loop_Benchmark`` / ``2025_GC`` branches, not
in the released package, so :func:`neurobench_reward_score` below is its formula copied from
github.com/NeuroBench/neurobench ``2025_GC`` @ c8dfd473df2182427c75d8221ea443ccef249fe0,
``neurobench/metrics/workload/closed_loop_metrics.py`` lines 20-37 (without the plot). The
other metrics are compared with the released ``neurobench`` 2.3.0 (whose metric files equal
``2025_GC``'s): ``scripts/setup.sh`` installs it with the dev extra, without its dependencies
(its metrics need only torch, snntorch and numpy); elsewhere those tests skip as optional.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from snnkart.contract.neurobench import (
    activation_sparsity,
    connection_sparsity,
    footprint,
    is_spike_input,
    reward_score,
    risk_episodes,
    synaptic_operations,
)

NO_NEUROBENCH = "optional: neurobench (scripts/setup.sh installs it with the dev extra)"


def neurobench_reward_score(rewards: list[float]) -> dict[str, float]:
    """NeuroBench's ``RewardScore.compute`` (2025_GC @ c8dfd47, closed_loop_metrics.py 20-37)."""
    avg = np.mean(rewards)
    std = np.std(rewards)
    sorted_rewards = sorted(rewards)
    num_lowest = int(len(sorted_rewards) * 0.05)
    lowest_rewards = sorted_rewards[:num_lowest]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # "Mean of empty slice" below 20
        risk = np.mean(lowest_rewards)
    return {"avg": avg, "std": std, "risk": risk}


# --- RewardScore -------------------------------------------------------------------------


def test_reward_score_by_hand() -> None:
    # returns 1..20 in any order: mean 10.5; population variance (n^2 - 1) / 12 = 33.25, so
    # std = 5.7663 (ddof 1 would give sqrt(35) = 5.9161); 20 episodes -> int(20 * 0.05) = 1
    # worst episode -> risk = 1.
    returns = [7, 3, 20, 1, 15, 9, 12, 2, 18, 5, 11, 4, 16, 8, 19, 6, 14, 10, 17, 13]
    score = reward_score(returns)
    assert score.mean == 10.5
    assert score.std == pytest.approx(math.sqrt(33.25), abs=1e-12)
    assert (score.risk, score.risk_episodes, score.episodes) == (1.0, 1, 20)


@pytest.mark.parametrize(
    ("episodes", "worst"), [(1, 0), (19, 0), (20, 1), (21, 1), (39, 1), (40, 2), (100, 5)]
)
def test_risk_rounds_the_count_down(episodes: int, worst: int) -> None:
    # Returns 0..n-1 shuffled: the k worst are 0..k-1, mean (k - 1) / 2; k = int(0.05 n),
    # rounded down and never raised to 1, so below 20 episodes NeuroBench's risk is the mean of
    # no episode: NaN.
    returns = np.random.default_rng(episodes).permutation(episodes).astype(float)
    score = reward_score(returns)
    assert risk_episodes(episodes) == score.risk_episodes == worst
    if worst == 0:
        assert math.isnan(score.risk)
    else:
        assert score.risk == (worst - 1) / 2


def test_risk_count_is_a_floor_of_n_over_20_for_every_n() -> None:
    # int(n * 0.05) could differ from n // 20 by float rounding; it does not up to 10^5.
    assert all(risk_episodes(n) == n // 20 for n in range(100_001))


@pytest.mark.parametrize("episodes", [1, 5, 19, 20, 21, 37, 50, 100, 257])
def test_reward_score_equals_neurobench_formula(episodes: int) -> None:
    rng = np.random.default_rng(episodes)
    returns = rng.normal(200.0, 80.0, episodes).round(1).tolist()
    theirs = neurobench_reward_score(returns)
    ours = reward_score(returns)
    assert ours.mean == pytest.approx(float(theirs["avg"]), rel=1e-12)
    assert ours.std == pytest.approx(float(theirs["std"]), rel=1e-12)
    if math.isnan(theirs["risk"]):
        assert math.isnan(ours.risk)
    else:
        assert ours.risk == pytest.approx(float(theirs["risk"]), rel=1e-12)


def test_reward_score_needs_episodes() -> None:
    with pytest.raises(ValueError, match="non-empty"):
        reward_score([])


# --- ActivationSparsity ------------------------------------------------------------------


def test_activation_sparsity_by_hand() -> None:
    # Layers of 4 and 2 neurons, 2 env steps of T = 3: each layer evaluated 6 times, 36
    # activations in all; 6 + 3 = 9 non-zero -> (36 - 9) / 36 = 0.75.
    assert activation_sparsity([6, 3], [4, 2], env_steps=2, num_steps=3) == 0.75


def test_activation_sparsity_averages_episodes_unweighted() -> None:
    # One layer of 2 neurons, T = 1. Episode A: 1 env step, both neurons fire -> 0.0.
    # Episode B: 3 env steps, no spike -> 1.0. NeuroBench's closed loop averages the
    # episodes' values: 0.5; pooled it would be 1 - 2 / 8 = 0.75.
    assert activation_sparsity([[2], [0]], [2], env_steps=[1, 3]) == 0.5
    assert activation_sparsity([2], [2], env_steps=4) == 0.75


def test_activation_sparsity_rejects_impossible_counts() -> None:
    with pytest.raises(ValueError, match="exceeds"):
        activation_sparsity([9, 0], [4, 2], env_steps=2)
    with pytest.raises(ValueError, match="env_steps must have shape"):
        activation_sparsity([[1, 0]], [4, 2], env_steps=2)


# --- SynapticOperations -------------------------------------------------------------------


def test_is_spike_input_is_neurobench_rule() -> None:
    assert is_spike_input([0, 1, -1, 1])
    assert is_spike_input(np.zeros((2, 3)))
    assert not is_spike_input([0, 1, 0.5])
    assert not is_spike_input([2, 0])


def test_synaptic_operations_neurobench_docs_example() -> None:
    # docs/metrics/workload_metrics/synaptic_operations.rst: binarised W times binarised x,
    # [[1,0,1],[0,1,1],[1,1,0]] @ [0,1,1] = [1,2,1] -> 4 effective; all ones -> 9 dense.
    # x holds 1.3, not a spike value, so they are MACs.
    w = [[1.3, 0, -3.2], [0, 1.2, -5.1], [-1.1, 2.7, 0]]
    x = [0, 1.3, -1]
    ops = synaptic_operations([w], [np.not_equal(x, 0)], [is_spike_input(x)], env_steps=1)
    assert (ops.effective_macs, ops.effective_acs, ops.dense_ops) == (4, 0, 9)


W0 = np.array([[0.5, 0.0], [0.2, -1.0], [0.0, 0.3]])  # 2 -> 3; non-zero fan-out [2, 2]
W1 = np.array([[1.0, 0.0, 1.0], [1.0, 1.0, 0.0]])  # 3 -> 2; non-zero fan-out [2, 1, 1]
W2 = np.array([[0.7, -0.7]])  # 2 -> 1 readout; fan-out [1, 1]


def test_synaptic_operations_by_hand() -> None:
    # 3 env steps of T = 2.
    # Layer 0 (observation in, graded, fed at each SNN step: 6 calls): inputs non-zero 6 and 4
    #   times; x fan-out 2 each -> 20 MACs; dense 6 calls x 3 x 2 = 36.
    # Layer 1 (spikes in, 6 calls): inputs spiked 3, 2, 5 times; x fan-out 2, 1, 1 -> 13 ACs
    #   (the zero weights are not operations); dense 6 x 2 x 3 = 36.
    # Layer 2 (readout of rates, once per env step: 3 calls): non-zero 3 and 1 times -> 4
    #   MACs; dense 3 x 1 x 2 = 6.
    # Totals 24 MACs, 13 ACs, 78 dense; per env step / 3, per SNN step / 6.
    ops = synaptic_operations(
        [W0, W1, W2],
        [[6, 4], [3, 2, 5], [3, 1]],
        [False, True, False],
        env_steps=3,
        num_steps=2,
        calls_per_env_step=[2, 2, 1],
    )
    assert (ops.effective_macs, ops.effective_acs, ops.dense_ops) == (24, 13, 78)
    assert ops.per_env_step() == pytest.approx(
        {"effective_macs": 8, "effective_acs": 13 / 3, "dense_ops": 26}
    )
    assert ops.per_snn_step() == pytest.approx(
        {"effective_macs": 4, "effective_acs": 13 / 6, "dense_ops": 13}
    )
    assert ops.per_episode(1) == {"effective_macs": 24, "effective_acs": 13, "dense_ops": 78}


def test_synaptic_operations_layer_total_needs_uniform_fan_out() -> None:
    # Layer 0's inputs both have 2 non-zero weights: 10 non-zero inputs -> 20, as per input.
    ops = synaptic_operations([W0], [10], [False], env_steps=5)
    assert ops.effective_macs == 20
    with pytest.raises(ValueError, match="one count per input neuron"):
        synaptic_operations([W1], [10], [True], env_steps=5)
    with pytest.raises(ValueError, match="in \\[0, 5\\]"):
        synaptic_operations([W1], [[6, 0, 0]], [True], env_steps=5)


# --- Footprint and ConnectionSparsity -----------------------------------------------------


def test_footprint_by_hand() -> None:
    # float32 (3, 4) weight 48 B + float32 (4,) bias 16 B + int64 scalar buffer 8 B = 72 B.
    tensors = [np.zeros((3, 4), np.float32), np.ones(4, np.float32), np.array(0, np.int64)]
    assert footprint(tensors) == 72
    # 12 weights at 1 B (int8) and 4 biases at 4 B: 12 + 16 = 28 B; all at 0.5 B: 8 B.
    assert footprint([12, 4], [1, 4]) == 28
    assert footprint([12, 4], 0.5) == 8
    with pytest.raises(ValueError, match="give bytes_per_parameter"):
        footprint([12])


def test_connection_sparsity_pools_layers() -> None:
    # W0 has 2 zeros of 6, W1 2 of 6, W2 0 of 2 -> 4 / 14 (not the layers' mean 2/9).
    assert connection_sparsity([W0, W1, W2]) == 4 / 14
    with pytest.raises(ValueError, match="at least one weight"):
        connection_sparsity([np.zeros((0, 3))])


# --- Against NeuroBench's own implementation ----------------------------------------------


def _neurobench_loop(model, net, episode_lengths, num_steps, obs_rng):
    """Drive ``net`` as NeuroBench's closed loop does: hooks registered, the workload metrics
    run once per episode and the hooks cleared. Returns NeuroBench's per-env-step results
    (Closed_Loop_Benchmark: ``data[0]`` has one entry per env step), its per-episode synops
    (2025_GC: a one-element dummy ``data[0]``) and every layer's inputs and outputs."""
    import torch
    from neurobench.metrics.manager.workload_manager import WorkloadMetricManager
    from neurobench.metrics.workload import ActivationSparsity, SynapticOperations

    manager = WorkloadMetricManager([ActivationSparsity, SynapticOperations])
    per_episode = SynapticOperations()
    model.register_hooks()
    manager.initialize_metrics()
    seen: list[dict[str, list[np.ndarray]]] = []
    with torch.no_grad():
        for length in episode_lengths:
            record: dict[str, list[np.ndarray]] = {}
            if hasattr(net, "reset"):
                net.reset()
            for _ in range(length):
                obs = obs_rng.normal(0.0, 1.0, (1, 3)).astype(np.float32)
                obs[0, 2] *= obs_rng.random() < 0.5  # a zero input now and then
                for _ in range(num_steps):
                    for k, v in net(torch.from_numpy(obs)).items():
                        record.setdefault(k, []).append(v.numpy().copy())
            data = (torch.zeros(length), torch.zeros(1))
            manager.run_metrics(model, None, data, batch_size=1, dataset_len=len(episode_lengths))
            per_episode(model, None, (torch.zeros(1), torch.zeros(1)))
            model.reset_hooks()
            seen.append(record)
    model.cleanup_hooks()
    return dict(manager.results), per_episode.compute(), seen


def _net(kind: str):
    """A 3 -> 5 -> 2 net with zero weights: ReLU (ANN) or snnTorch Leaky (SNN)."""
    import snntorch as snn
    import torch

    torch.manual_seed(3)

    class Net(torch.nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.fc0, self.fc1 = torch.nn.Linear(3, 5), torch.nn.Linear(5, 2)
            with torch.no_grad():
                self.fc0.weight[0, 1] = self.fc0.weight[3, 0] = self.fc1.weight[1, 4] = 0.0
                self.fc0.weight.mul_(3.0)
            spiking = kind == "snn"
            self.act0 = snn.Leaky(beta=0.8) if spiking else torch.nn.ReLU()
            self.act1 = snn.Leaky(beta=0.8) if spiking else None

        def reset(self) -> None:
            for act in (self.act0, self.act1):
                if hasattr(act, "reset_mem"):
                    act.reset_mem()

        def forward(self, x):
            a0 = self.act0(self.fc0(x))
            a0 = a0[0] if isinstance(a0, tuple) else a0
            y = self.fc1(a0)
            a1 = self.act1(y)[0] if self.act1 is not None else None
            out = {"x0": x, "x1": a0, "y": y}
            return out if a1 is None else {**out, "a1": a1}

    return Net()


@pytest.mark.parametrize(("kind", "num_steps"), [("ann", 1), ("snn", 3)])
def test_against_neurobench(kind: str, num_steps: int) -> None:
    pytest.importorskip("neurobench", reason=NO_NEUROBENCH)
    from neurobench.metrics.static import ConnectionSparsity, Footprint
    from neurobench.models import SNNTorchModel, TorchModel

    net = _net(kind)
    model = SNNTorchModel(net) if kind == "snn" else TorchModel(net)
    tensors = [p.detach().numpy() for p in net.parameters()] + [b.numpy() for b in net.buffers()]
    assert footprint(tensors) == Footprint()(model)
    weights = [net.fc0.weight.detach().numpy(), net.fc1.weight.detach().numpy()]
    assert round(connection_sparsity(weights), 4) == ConnectionSparsity()(model)

    lengths = [4, 2, 6]
    theirs, theirs_per_episode, seen = _neurobench_loop(
        model, net, lengths, num_steps, np.random.default_rng(0)
    )
    outputs = ["x1", "a1"] if kind == "snn" else ["x1"]
    counts = [[sum(np.count_nonzero(v) for v in r[k]) for k in outputs] for r in seen]
    sizes = [5, 2] if kind == "snn" else [5]
    ours_sparsity = activation_sparsity(counts, sizes, lengths, num_steps)
    assert ours_sparsity == pytest.approx(theirs["ActivationSparsity"], abs=1e-12)

    everything = {k: np.concatenate([v for r in seen for v in r[k]]) for k in ("x0", "x1")}
    per_input = [np.count_nonzero(everything[k], axis=0) for k in ("x0", "x1")]
    spikes = [is_spike_input(everything["x0"]), is_spike_input(everything["x1"])]
    assert spikes == [False, kind == "snn"]
    ops = synaptic_operations(weights, per_input, spikes, sum(lengths), num_steps)
    nb = theirs["SynapticOperations"]
    assert ops.effective_acs > 0 if kind == "snn" else ops.effective_acs == 0
    assert ops.per_env_step() == pytest.approx(
        {"effective_macs": nb["Effective_MACs"], "effective_acs": nb["Effective_ACs"],
         "dense_ops": nb["Dense"]}, rel=1e-12
    )  # fmt: skip
    nb = theirs_per_episode
    assert ops.per_episode(len(lengths)) == pytest.approx(
        {"effective_macs": nb["Effective_MACs"], "effective_acs": nb["Effective_ACs"],
         "dense_ops": nb["Dense"]}, rel=1e-12
    )  # fmt: skip
