"""NeuroBench's closed-loop metrics as pure functions over plain arrays (no torch).

NeuroBench (Yik et al., Nat. Commun. 16:1545, 2025) measures its metrics with forward hooks on
a torch model. A deployed snnkart policy has no torch model, but its eval and deploy records
hold what those hooks would see, summed: so each metric here takes the weight matrices, the
per-layer counts of non-zero values over ``env_steps`` env steps and the ``num_steps`` (T) SNN
steps per env step, and computes what NeuroBench's code computes, with the same conventions.

Sources: NeuroBench's ``2025_GC`` and ``Closed_Loop_Benchmark`` branches (the closed-loop code
is not on ``main`` nor in the released package 2.3.0, whose static and workload metrics are those
of ``2025_GC``); the commits and files read are in docs/decisions.md#neurobench-metric-sources.

Sharp edges:

- Only dense (``out x in``) connection layers, as ``torch.nn.Linear`` / NIR ``Affine`` store
  them; NeuroBench's rules for convolutions and recurrent cells are not reproduced.
- NeuroBench tests per call whether a layer's input is spikes (:func:`is_spike_input`); from
  counts that test cannot be made, so the caller says per layer whether its input is spikes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

RISK_FRACTION = 0.05
"""The share of episodes, worst first, whose mean return is NeuroBench's ``risk``."""


@dataclass(frozen=True)
class RewardScore:
    """Episode returns summarised as NeuroBench's RewardScore: ``mean``, ``std`` (ddof 0),
    ``risk`` (the mean return of the ``risk_episodes`` worst episodes; NaN when that is 0)."""

    mean: float
    std: float
    risk: float
    episodes: int
    risk_episodes: int


def risk_episodes(episodes: int) -> int:
    """How many of ``episodes`` episodes NeuroBench's ``risk`` averages: ``int(n * 0.05)``,
    5 % rounded down, so 0 below 20 episodes, 1 for 20 to 39, 5 for 100."""
    if episodes < 0:
        raise ValueError(f"episodes must be >= 0, got {episodes}")
    return int(episodes * RISK_FRACTION)


def reward_score(returns: ArrayLike) -> RewardScore:
    """NeuroBench's RewardScore of one return per episode.

    NeuroBench (``2025_GC``, ``closed_loop_metrics.py`` lines 20-37; the same on
    ``Closed_Loop_Benchmark``, ``data_metrics.py`` lines 354-371)::

        avg = np.mean(self.rewards)
        std = np.std(self.rewards)
        sorted_rewards = sorted(self.rewards)
        num_lowest = int(len(sorted_rewards) * 0.05)
        lowest_rewards = sorted_rewards[:num_lowest]
        risk = np.mean(lowest_rewards)

    ``self.rewards`` holds one entry per interaction (episode): its summed reward
    (``Closed_Loop_Benchmark`` ``benchmark.py`` line 203, ``data = [torch.tensor(times),
    reward_tot]``). So ``std`` is the population standard deviation (``np.std``, ddof 0), and
    ``risk`` is the mean of the ``int(0.05 n)`` lowest returns: rounded down, never raised to
    one, so with fewer than 20 episodes NeuroBench's ``risk`` is the mean of an empty list,
    NaN. Here it is NaN too (without numpy's warning); ``risk_episodes`` says how many
    episodes it averaged.

    Args:
        returns: ``(episodes,)`` episode returns (the sum of the env's rewards), at least one.
    """
    r = np.asarray(returns, dtype=np.float64)
    if r.ndim != 1 or r.size == 0:
        raise ValueError(f"returns must be a non-empty 1-D array, got shape {r.shape}")
    k = risk_episodes(r.size)
    risk = float(np.mean(np.sort(r)[:k])) if k else float("nan")
    return RewardScore(float(np.mean(r)), float(np.std(r)), risk, int(r.size), k)


def activation_sparsity(
    nonzero_counts: ArrayLike,
    neurons_per_layer: Sequence[int],
    env_steps: int | ArrayLike,
    num_steps: int = 1,
) -> float:
    """NeuroBench's ActivationSparsity: the share of zero outputs of the activation layers.

    NeuroBench (``2025_GC``, ``activation_sparsity.py`` lines 33-55; docs
    ``activation_sparsity.rst``): "the number of zero activations over the total number of
    activations, over all layers, timesteps, samples in data"::

        spike_num, neuro_num = torch.count_nonzero(spikes).item(), torch.numel(spikes)
        ...
        sparsity = (total_neuro_num - total_spike_num) / total_neuro_num

    summed over the outputs its hooks saw on every forward call of every activation module
    (``nn.ReLU``, ``nn.Sigmoid`` and snnTorch's ``SpikingNeuron``: not ``nn.Tanh``; a model
    with none of them gets 0.0). In the closed loop the metric is computed once per episode
    and the episodes' values are averaged, unweighted by their lengths (``2025_GC``
    ``benchmark_closed_loop.py`` lines 173-179 with ``batch_size=1``, ``dataset_len =
    nr_interactions``, and ``workload_manager.py`` line 149: ``results[name] += (result *
    batch_size) / dataset_len``; ``Closed_Loop_Benchmark`` ``benchmark.py`` line 218).

    Args:
        nonzero_counts: non-zero outputs (spikes, or non-zero ReLU outputs) per activation
            layer, summed over its evaluations: ``(layers,)`` for one pool, or ``(episodes,
            layers)``, one row per episode.
        neurons_per_layer: ``(layers,)`` neurons in each activation layer.
        env_steps: env steps the counts cover: an int for ``(layers,)`` counts, one per
            episode (``(episodes,)``) for ``(episodes, layers)`` counts.
        num_steps: evaluations of each layer per env step (T SNN steps; 1 for an ANN).

    Returns:
        The sparsity in [0, 1]: for ``(layers,)`` counts ``1 - sum(counts) / (sum(neurons)
        env_steps T)``; for ``(episodes, layers)`` the mean of that over the episodes.
    """
    counts = np.asarray(nonzero_counts, dtype=np.float64)
    neurons = np.asarray(neurons_per_layer, dtype=np.float64)
    steps = np.asarray(env_steps, dtype=np.float64)
    if counts.ndim not in (1, 2) or counts.shape[-1] != neurons.size or neurons.ndim != 1:
        raise ValueError(
            f"nonzero_counts must be (layers,) or (episodes, layers) with layers = "
            f"{neurons.size} (neurons_per_layer), got shape {counts.shape}"
        )
    if steps.shape != counts.shape[:-1]:
        raise ValueError(
            f"env_steps must have shape {counts.shape[:-1]} (one per row of nonzero_counts), "
            f"got {steps.shape}"
        )
    total = neurons.sum() * steps * num_steps
    if np.any(total <= 0) or np.any(neurons <= 0) or np.any(counts < 0):
        raise ValueError("neurons, env_steps and num_steps must be positive, counts >= 0")
    if np.any(counts > neurons * (steps * num_steps)[..., None]):
        raise ValueError("a layer's non-zero count exceeds its neurons x env_steps x num_steps")
    per_episode = 1.0 - counts.sum(axis=-1) / total
    return float(np.mean(per_episode))


def is_spike_input(values: ArrayLike) -> bool:
    """NeuroBench's test for a layer's input being spikes (its operations ACs, not MACs): every
    entry is -1, 0 or 1 (``2025_GC``, ``neurobench/metrics/utils/layers/input.py`` lines
    54-55: ``if len(inputs[(inputs != 0) & (inputs != 1) & (inputs != -1)]) == 0: spiking =
    True``). It is made per forward call, on that call's whole input."""
    v = np.asarray(values)
    return bool(np.all((v == 0) | (v == 1) | (v == -1)))


@dataclass(frozen=True)
class SynapticOperations:
    """NeuroBench's SynapticOperations summed over ``env_steps`` env steps: effective MACs
    (non-spike inputs), effective ACs (spike inputs) and dense operations (every input and
    weight, zero or not); biases are not counted. :meth:`per_env_step` divides as
    NeuroBench's closed loop does."""

    effective_macs: float
    effective_acs: float
    dense_ops: float
    env_steps: int
    num_steps: int

    def _per(self, n: float) -> dict[str, float]:
        return {
            "effective_macs": self.effective_macs / n,
            "effective_acs": self.effective_acs / n,
            "dense_ops": self.dense_ops / n,
        }

    def per_env_step(self) -> dict[str, float]:
        """Per env step (one inference, its T SNN steps together): NeuroBench's normalisation
        on ``Closed_Loop_Benchmark`` (``total_samples += data[0].size(0)`` with ``data[0]``
        one entry per env step of the episode)."""
        return self._per(self.env_steps)

    def per_snn_step(self) -> dict[str, float]:
        """Per SNN step: :meth:`per_env_step` over T (``num_steps``)."""
        return self._per(self.env_steps * self.num_steps)

    def per_episode(self, episodes: int) -> dict[str, float]:
        """Per episode: what ``2025_GC``'s ``BenchmarkClosedLoop`` reports, since it passes a
        one-element dummy ``data[0]`` once per episode (``benchmark_closed_loop.py`` line 171)."""
        if episodes <= 0:
            raise ValueError(f"episodes must be positive, got {episodes}")
        return self._per(episodes)


def _effective(weight: np.ndarray, counts: np.ndarray, calls: int, layer: int) -> float:
    """Non-zero inputs x their non-zero fan-out: ``sum_j counts_j * #{i: W_ij != 0}``, for
    counts over ``calls`` forward calls of the layer."""
    if weight.ndim != 2:
        raise ValueError(f"layer {layer}: weight must be (out, in), got shape {weight.shape}")
    limit = calls * (1 if counts.ndim == 1 else weight.shape[1])
    if np.any(counts < 0) or np.any(counts > limit):
        raise ValueError(
            f"layer {layer}: input counts must be in [0, {limit}] ({calls} calls of "
            f"{weight.shape[1]} inputs)"
        )
    fan_out = np.count_nonzero(weight, axis=0).astype(np.float64)  # (in,)
    if counts.ndim == 1:
        if counts.shape != fan_out.shape:
            raise ValueError(
                f"layer {layer}: per-input counts have shape {counts.shape}, its weight "
                f"{weight.shape} needs ({weight.shape[1]},)"
            )
        return float(counts @ fan_out)
    if np.any(fan_out != fan_out[0]):
        raise ValueError(
            f"layer {layer}: its inputs' non-zero fan-outs differ (zero weights), so a "
            "layer total cannot give NeuroBench's count: pass one count per input neuron"
        )
    return float(counts) * float(fan_out[0])


def synaptic_operations(
    weights: Sequence[ArrayLike],
    input_counts: Sequence[ArrayLike],
    spike_inputs: Sequence[bool],
    env_steps: int,
    num_steps: int = 1,
    calls_per_env_step: Sequence[int] | None = None,
) -> SynapticOperations:
    """NeuroBench's SynapticOperations of dense connection layers over ``env_steps`` env steps.

    NeuroBench (``2025_GC``, ``synaptic_operations.py`` lines 55-94, ``macs.py`` lines 7-21 and
    178-198; docs ``synaptic_operations.rst``): on each forward call of each connection layer,
    its weights and input are binarised (non-zero -> 1) and the layer re-run with its bias set
    to zero ("bias is not considered as a synaptic operation"); the sum of that output is the
    call's effective operations, ACs if the input was spikes (:func:`is_spike_input`), else
    MACs. Dense operations re-run it with every weight and input set to 1 (zero weights
    included). "Eff_MACs and Eff_ACs only count effective synaptic operations by disregarding
    zero activations ... and zero connections". For a dense layer ``y = W x`` one call is
    ``sum_j [x_j != 0] * #{i: W_ij != 0}`` effective and ``out * in`` dense operations.

    Args:
        weights: per connection layer, its ``(out, in)`` weight matrix (every layer that runs
            in the forward pass counts: NeuroBench's cartpole nets include the critic head).
        input_counts: per layer, the non-zero entries of its input summed over all its calls in
            the ``env_steps`` env steps: ``(in,)``, one count per input neuron (exact), or one
            total (exact only if every input has the same number of non-zero weights).
        spike_inputs: per layer, whether its input is spikes (ACs) or graded (MACs):
            observations, rates, ReLU outputs and sigma-delta messages are graded.
        env_steps: env steps (inferences) the counts cover.
        num_steps: T, the SNN steps per env step (1 for an ANN).
        calls_per_env_step: per layer, its forward calls per env step; default T for every
            layer (e.g. 1 for a readout applied once to the spike rates).
    """
    n = len(weights)
    calls = [num_steps] * n if calls_per_env_step is None else list(calls_per_env_step)
    if not (len(input_counts) == len(spike_inputs) == len(calls) == n) or n == 0:
        raise ValueError(
            f"weights ({n}), input_counts ({len(input_counts)}), spike_inputs "
            f"({len(spike_inputs)}) and calls_per_env_step ({len(calls)}) need one entry per "
            "layer, at least one"
        )
    if env_steps <= 0 or num_steps <= 0 or min(calls) <= 0:
        raise ValueError("env_steps, num_steps and calls_per_env_step must be positive")
    macs = acs = dense = 0.0
    for k, (w, c, spikes, per_step) in enumerate(
        zip(weights, input_counts, spike_inputs, calls, strict=True)
    ):
        weight, layer_calls = np.asarray(w), env_steps * per_step
        ops = _effective(weight, np.asarray(c, dtype=np.float64), layer_calls, k)
        acs, macs = (acs + ops, macs) if spikes else (acs, macs + ops)
        dense += float(layer_calls) * weight.size
    return SynapticOperations(macs, acs, dense, env_steps, num_steps)


def footprint(
    parameters: Sequence[ArrayLike | int],
    bytes_per_parameter: float | Sequence[float] | None = None,
) -> float:
    """NeuroBench's Footprint: the bytes of a model's parameters and buffers.

    NeuroBench (``2025_GC``, ``neurobench/metrics/static/footprint.py`` lines 17-25)::

        for param in model.__net__().parameters():
            param_size += param.numel() * param.element_size()
        for buffer in model.__net__().buffers():
            buffer_size += buffer.numel() * buffer.element_size()
        return param_size + buffer_size

    Everything counts: weights (zero ones too), biases, neuron parameters (snnTorch's
    ``beta``, ``threshold``, ... are buffers or parameters) and any state buffer.

    Args:
        parameters: per tensor, an array (its size) or a parameter count.
        bytes_per_parameter: bytes of one entry, one for all or one per tensor; ``None`` takes
            each array's own item size (then every entry must be an array).

    Returns:
        Bytes (a float: sub-byte precisions give fractions).
    """
    n = len(parameters)
    per: list[float | None]
    if bytes_per_parameter is None or isinstance(bytes_per_parameter, (int, float)):
        per = [None if bytes_per_parameter is None else float(bytes_per_parameter)] * n
    else:
        per = [float(b) for b in bytes_per_parameter]
        if len(per) != n:
            raise ValueError(f"bytes_per_parameter has {len(per)} entries for {n} tensors")
    total = 0.0
    for k, (p, b) in enumerate(zip(parameters, per, strict=True)):
        if isinstance(p, (int, np.integer)):
            if b is None:
                raise ValueError(f"tensor {k} is a count ({p}): give bytes_per_parameter")
            total += int(p) * b
        else:
            a = np.asarray(p)
            total += a.size * (a.itemsize if b is None else b)
    return total


def connection_sparsity(weights: Sequence[ArrayLike]) -> float:
    """NeuroBench's ConnectionSparsity: zero weights over all weights, pooled over layers.

    NeuroBench (``2025_GC``, ``neurobench/metrics/static/connection_sparsity.py`` lines 46-49
    and 116; docs ``connection_sparsity.rst``: ":math:`\\frac{\\sum_l m_l}{\\sum_l n_l}`,
    where :math:`m_l` is the number of zero-valued weights and :math:`n_l` is the total
    weights")::

        count_zeros = torch.sum(module.weight == 0)
        count_weights = module.weight.numel()
        ...
        return round((count_zeros / count_weights).item(), 4)

    For Linear and Conv layers only ``weight`` counts, not the bias (for RNN layers and cells
    NeuroBench counts the biases too). NeuroBench rounds to 4 decimals; this does not.

    Args:
        weights: the connection layers' weight arrays (any shape), at least one entry in all.
    """
    arrays = [np.asarray(w) for w in weights]
    size = sum(a.size for a in arrays)
    if size == 0:
        raise ValueError("connection_sparsity needs at least one weight")
    return sum(a.size - np.count_nonzero(a) for a in arrays) / size


__all__ = [
    "RISK_FRACTION",
    "RewardScore",
    "SynapticOperations",
    "activation_sparsity",
    "connection_sparsity",
    "footprint",
    "is_spike_input",
    "reward_score",
    "risk_episodes",
    "synaptic_operations",
]
