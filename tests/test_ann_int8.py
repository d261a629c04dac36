"""The ANN quantised to int8 (snnkart.rl.int8) and measured on the deployment's episodes
(snnkart.eval.ann_int8): the integer forward pass against hand-computed integers, the
quantisation rules against hand-derived scales, its error against the float actor on a trained
policy, and the evaluation on the deployment's own seeds."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

from snnkart.contract.deploy_record import DeployRecord
from snnkart.eval.ann_int8 import (
    Int8Predictor,
    calibration_seeds,
    int8_task,
    normalised,
    record_observations,
    task_on,
)
from snnkart.eval.episodes import run_episodes
from snnkart.rl.int8 import (
    Int8Layer,
    Int8Mlp,
    actor_params,
    fixed_multiplier,
    quantise_mlp,
    tanh_table,
)
from snnkart.rl.trained import LoadedRun, load_run

ROOT = Path(__file__).resolve().parents[1]
ANN = ROOT / "tests/data/policies/grid-ann"
DEPLOY = ROOT / "tests/data/records/deploy-nir-ref-fixed.json"


def _tiny() -> Int8Mlp:
    """2 -> 2 (tanh) -> 2 with integers chosen by hand."""
    hidden = Int8Layer(
        weight=np.array([[2, -1], [1, 3]], np.int8), bias=np.array([10, -5], np.int32),
        in_scale=0.1, weight_scale=0.01, pre_scale=0.01,
        multiplier=2**30, shift=31,  # M / 2**k = 0.5 = in_scale * weight_scale / pre_scale
        table=tanh_table(0.01, 0.01),
    )  # fmt: skip
    out = Int8Layer(
        weight=np.array([[1, -2], [3, 1]], np.int8), bias=np.array([0, 7], np.int32),
        in_scale=0.01, weight_scale=0.01, pre_scale=None, multiplier=0, shift=0, table=None,
    )  # fmt: skip
    return Int8Mlp((hidden, out))


def test_int8_forward_pass_equals_a_hand_computation() -> None:
    net = _tiny()
    z = np.array([[0.5, -0.3]])
    x0 = net.quantise_input(z)
    assert x0.tolist() == [[5, -3]]  # 0.5 / 0.1, -0.3 / 0.1
    hidden = net.layers[0]
    acc = hidden.accumulate(x0)
    assert acc.tolist() == [[23, -9]]  # 2*5 + 1*3 + 10, 5 - 9 - 5
    pre = hidden.requantise(acc)
    assert pre.tolist() == [[12, -4]]  # 23 * 0.5 = 11.5 -> 12, -9 * 0.5 = -4.5 -> -4 (half up)
    x1 = hidden.activate(pre)
    assert x1.tolist() == [[12, -4]]  # rint(100 tanh(0.12)) = rint(11.94), rint(-4.00)
    assert net.accumulator(z).tolist() == [[20, 39]]  # 12 + 8 + 0, 36 - 4 + 7
    assert net.act(z, discrete=True).tolist() == [1]
    assert net.act(z, discrete=False) == pytest.approx(np.array([[0.002, 0.0039]]))
    # saturation: an input beyond the calibrated range is clipped to ±127
    assert net.quantise_input(np.array([[100.0, -100.0]])).tolist() == [[127, -127]]


def test_the_tanh_table_by_hand() -> None:
    table = tanh_table(0.01, 0.01)
    assert table.shape == (255,) and table.dtype == np.int8
    assert (table[127 + 10], table[127 + 50], table[127 - 30]) == (10, 46, -29)
    assert (table[0], table[127], table[254]) == (-85, 0, 85)  # rint(100 tanh(±1.27))


def test_fixed_multiplier_is_31_bits_and_exact_for_powers_of_two() -> None:
    assert fixed_multiplier(0.5) == (2**30, 31)
    m, k = fixed_multiplier(0.00874985)
    assert 2**30 <= m < 2**31 and m / 2**k == pytest.approx(0.00874985, rel=2**-30)


def test_quantisation_rules_by_hand() -> None:
    """Symmetric per-tensor scales (max|v| / 127), int8 weights, int32 bias at s_in s_w."""
    w1, b1 = np.array([[0.5, -1.27], [1.0, 0.25]]), np.array([0.01, -0.02])
    w2, b2 = np.array([[0.254, -0.127], [0.0, 0.0635]]), np.array([0.003, 0.0])
    calibration = np.array([[1.27, -0.635], [-1.27, 0.0]])
    net = quantise_mlp([(w1, b1), (w2, b2)], calibration)
    first, last = net.layers
    assert first.in_scale == pytest.approx(0.01)  # max|z| = 1.27
    assert first.weight_scale == pytest.approx(0.01)  # max|W1| = 1.27
    assert first.weight.tolist() == [[50, -127], [100, 25]]
    assert first.bias.tolist() == [100, -200]  # b1 / (0.01 * 0.01)
    # pre-activations: W1 z + b1 = [1.45145, 1.09125] and [-0.625, -1.29]; max 1.45145
    assert first.pre_scale == pytest.approx(1.45145 / 127)
    assert first.multiplier / 2**first.shift == pytest.approx(1e-4 / (1.45145 / 127))
    assert last.in_scale == pytest.approx(np.tanh(1.45145) / 127)
    assert last.weight_scale == pytest.approx(0.002)  # 0.254 / 127
    assert last.weight.tolist() == [[127, -64], [0, 32]]  # -63.5 -> -64, 31.75 -> 32
    assert last.bias.tolist() == [round(0.003 / (last.in_scale * 0.002)), 0]
    assert first.table is not None and int(first.table[254]) == 127  # tanh(max pre) -> 127


def _float_actor(params: list[tuple[np.ndarray, np.ndarray]], z: np.ndarray) -> np.ndarray:
    x = np.asarray(z, np.float64)
    for i, (w, b) in enumerate(params):
        x = x @ w.T + b
        if i < len(params) - 1:
            x = np.tanh(x)
    return x


def test_int8_error_is_a_few_quantisation_steps_and_shrinks_with_the_step() -> None:
    """On inputs inside the calibrated range the logits are off by a few steps; widening the
    calibrated input range 4x (steps 4x coarser) makes the error grow."""
    rng = np.random.default_rng(0)
    params = [(rng.normal(0, 0.3, (16, 8)), rng.normal(0, 0.1, 16)),
              (rng.normal(0, 0.3, (16, 16)), rng.normal(0, 0.1, 16)),
              (rng.normal(0, 0.3, (4, 16)), rng.normal(0, 0.1, 4))]  # fmt: skip
    z = np.clip(rng.normal(0, 1, (2000, 8)), -3, 3)
    exact = _float_actor(params, z)
    spread = np.abs(exact).max()

    def error(calibration: np.ndarray) -> np.ndarray:
        net = quantise_mlp(params, calibration)
        return np.abs(net.accumulator(z) * net.out_scale - exact)  # type: ignore[no-any-return]

    fine, coarse = error(z), error(np.vstack([z, np.full((1, 8), 12.0)]))
    assert fine.max() < 0.05 * spread and fine.mean() < 0.01 * spread
    assert coarse.mean() > 2 * fine.mean()


@pytest.fixture(scope="module")
def ann() -> LoadedRun:
    return load_run(ANN)


def _make_env(run: LoadedRun) -> Any:
    return lambda: run.config.make_env(track=run.track)


def test_int8_agrees_with_the_float_actor_on_recorded_observations(ann: LoadedRun) -> None:
    observations = record_observations(ann, _make_env(ann), calibration_seeds(10_000, 5))
    held_out = record_observations(ann, _make_env(ann), range(30_000, 30_003))
    net = quantise_mlp(actor_params(ann.policy.actor), observations)
    logits = _float_actor(actor_params(ann.policy.actor), held_out)
    agree = (net.act(held_out, discrete=True) == logits.argmax(-1)).mean()
    assert agree >= 0.97, f"int8 agrees with float on only {agree:.1%} of observations"


class _Seeds(gym.Wrapper):  # type: ignore[type-arg]
    """The real env, noting the seed of every reset."""

    def __init__(self, env: Any, seeds: list[int]) -> None:
        super().__init__(env)
        self.seeds = seeds

    def reset(self, **kwargs: Any) -> Any:
        self.seeds.append(kwargs["seed"])
        return self.env.reset(**kwargs)


def test_int8_calibrates_on_other_seeds_and_drives_the_evaluations(ann: LoadedRun) -> None:
    seeds: list[int] = []
    task = int8_task(ann, lambda: _Seeds(_make_env(ann)(), seeds), 500, 3, calibration_episodes=2)
    assert seeds == [503, 504, 500, 501, 502]  # calibration first, none of the evaluation's
    assert task["calibration"]["first_seed"] == 503 and task["first_seed"] == 500
    assert 0.95 <= task["action_agreement"] <= 1


class _Both:
    """The int8 actor driving, the float actor's argmax asked on the same observation."""

    def __init__(self, run: LoadedRun, net: Int8Mlp) -> None:
        self.run, self.net = run, net
        self.same: list[bool] = []

    def reset(self) -> None:
        pass

    def predict(self, obs: np.ndarray) -> int:
        import torch

        z = normalised(self.run, obs)[None]
        action = int(self.net.act(z, discrete=True)[0])
        with torch.no_grad():
            reference = int(self.run.policy.actor(torch.from_numpy(z)).argmax(-1)[0])
        self.same.append(action == reference)
        return action


def test_action_agreement_counts_the_steps_where_float_and_int8_agree(ann: LoadedRun) -> None:
    """A deliberately coarse int8 actor (input steps 30x too wide) disagrees on some steps;
    the predictor counts them as the float actor's argmax, asked here, does."""
    observations = record_observations(ann, _make_env(ann), range(40_000, 40_001))
    coarse = quantise_mlp(actor_params(ann.policy.actor), 30 * observations)
    predictor, both = Int8Predictor(ann, coarse, 0), _Both(ann, coarse)
    for policy in (predictor, both):
        env = _make_env(ann)()
        try:
            run_episodes(env, policy, 1, 40_001)
        finally:
            env.close()
    assert predictor.steps == len(both.same)
    assert predictor.agreement == pytest.approx(np.mean(both.same))
    assert 0 < predictor.agreement < 1  # type: ignore[operator]


def test_report_measures_int8_on_the_deployments_episodes(ann: LoadedRun) -> None:
    """The report's int8 result is the int8 policy's on the deployment's seeds: driven again
    here from the record's first seed, it returns the same episodes."""
    from snnkart.app.report import _ann_run

    record = DeployRecord.read(DEPLOY)
    episodes = len(record.episodes)
    _, task = _ann_run(ANN, record)
    int8 = task["int8"]
    assert (int8["first_seed"], int8["episodes"]) == (record.first_seed, episodes)
    observations = record_observations(
        ann, _make_env(ann), calibration_seeds(record.first_seed, episodes)
    )
    both = _Both(ann, quantise_mlp(actor_params(ann.policy.actor), observations))
    env = _make_env(ann)()
    try:
        results = run_episodes(env, both, episodes, record.first_seed)
    finally:
        env.close()
    assert int8["mean_return"] == pytest.approx(np.mean([r.episode_return for r in results]))
    assert int8["steps_per_episode"] == np.mean([r.length for r in results])
    assert int8["action_agreement"] == pytest.approx(np.mean(both.same))
    assert task_on(task, "horowitz45_int8") is int8 and task_on(task, "horowitz45_fp32") is task
