"""``policy = "sdnn"``: its config, the fake-quantised actor equal to the integer chain Lava runs
at zero thresholds, gradients through the straight-through estimators, and the message penalty
computed from each step's previous observation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from tiny_runs import TINY

from snnkart.backends.sigma_delta import (
    SigmaDeltaChain,
    input_integers,
    readout_value,
    relu_network,
    spec_from_block,
)
from snnkart.errors import ConfigError
from snnkart.export.calibrate import AffineLayers
from snnkart.export.sigma_delta_export import zero_block
from snnkart.rl.buffer import RolloutBuffer
from snnkart.rl.config import load_config
from snnkart.rl.kinds import kind
from snnkart.rl.kinds.base import PolicySpace
from snnkart.rl.policies import SDNNPolicy
from snnkart.rl.ppo import Trainer
from snnkart.rl.rollout import IterationStats
from snnkart.rl.sigma_delta import lava_weights
from snnkart.rl.sigma_delta_config import SDNNConfig

CLIP = 10.0


def _policy(seed: int = 0, n_in: int = 9, n_out: int = 4, hidden: tuple[int, ...] = (12, 10)):
    """An untrained sdnn policy with biases and a readout large enough to matter."""
    torch.manual_seed(seed)
    cfg = load_config(sets=["policy=sdnn", f"sdnn.hidden={list(hidden)}", f"ppo.clip_obs={CLIP}"])
    space = PolicySpace(n_in, n_out, True, np.zeros(n_in), np.ones(n_in))
    policy = kind("sdnn").build(cfg, space)
    assert isinstance(policy, SDNNPolicy)
    with torch.no_grad():
        for fc in policy.sdnn.affine_layers():
            fc.bias.uniform_(-0.5, 0.5)
        policy.sdnn.readout.weight.mul_(50.0)
    return policy


def _layers(policy: SDNNPolicy) -> AffineLayers:
    fcs = policy.sdnn.affine_layers()
    return AffineLayers(
        [fc.weight.detach().numpy().copy() for fc in fcs],
        [fc.bias.detach().numpy().copy() for fc in fcs],
    )


@pytest.mark.parametrize(
    ("sets", "match"),
    [
        (["sdnn.hidden=[]"], "sdnn.hidden"),
        (["sdnn.hidden=[64, 0]"], "sdnn.hidden"),
        (["sdnn.weight_bits=16"], "weight_bits"),
        (["sdnn.input_bits=1"], "input_bits"),
        (["sdnn.calibration_target=0"], "calibration_target"),
        (["sdnn.message_penalty=-1"], "message_penalty"),
        (["sdnn.message_penalty_warmup=2"], "message_penalty_warmup"),
        (["sdnn.calibration_episodes=0"], "calibration_episodes"),
        (["sdnn.thresholds=1"], "unknown key 'sdnn.thresholds'"),
    ],
)
def test_config_refuses_invalid_sdnn_values(sets: list[str], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        load_config(sets=["policy=sdnn", *sets])


def test_config_defaults() -> None:
    cfg = load_config(sets=["policy=sdnn"])
    assert cfg.policy == "sdnn"
    assert cfg.sdnn == SDNNConfig()
    assert (cfg.sdnn.hidden, cfg.sdnn.input_bits, cfg.sdnn.weight_bits) == ((64, 64), 8, 8)
    assert cfg.sdnn.message_penalty == 0.0 and cfg.sdnn.calibration_target == 0.95
    for env in ("grid", "gazebo", "steer"):  # the ANN's per-env settings and critic width
        sdnn, ann = (load_config(overrides={"env": env, "policy": k}) for k in ("sdnn", "ann"))
        assert (sdnn.ppo, sdnn.ann.hidden) == (ann.ppo, ann.ann.hidden)


def test_torch_actor_equals_the_integer_chain_at_zero_thresholds() -> None:
    """The actor's readout and every hidden integer, against the chain the export's block
    builds (spec_from_block, input_integers, block.rows held Lava steps, readout_value)."""
    policy = _policy()
    rng = np.random.default_rng(1)
    z = np.clip(rng.normal(0, 3, (40, 9)), -CLIP, CLIP).astype(np.float32)
    z[5] = z[4]  # an unchanged observation sends no input message
    with torch.no_grad():
        out, hidden = policy.sdnn(torch.from_numpy(z))
    net = _layers(policy)
    block = zero_block(net, CLIP, 8, "sdnn")
    assert [block.input_scale, *(la.act_scale for la in block.layers), block.out_scale] == (
        policy.sdnn.units()
    )
    spec = spec_from_block(block, net.weights, net.biases, "fixed")
    chain = SigmaDeltaChain(spec)
    for k, zk in enumerate(z):
        q = input_integers(block, zk)
        for _ in range(block.rows):
            sigma = chain.step(q)
        for layer, h in enumerate(hidden):
            np.testing.assert_array_equal(chain.enc[layer + 1].act, h[k].numpy())
        got = readout_value(block, sigma, net.biases[-1], "fixed")
        np.testing.assert_allclose(out[k].numpy(), got, rtol=1e-6, atol=1e-7)
    qs = input_integers(block, z)
    ref = readout_value(block, relu_network(spec, qs), net.biases[-1], "fixed")
    np.testing.assert_allclose(out.numpy(), ref, rtol=1e-6, atol=1e-7)
    assert np.abs(ref).max() > 0.1  # the readout is not trivially small


def test_lava_weights_match_lavas_clip_and_truncation() -> None:
    from snnkart.backends.sigma_delta import lava_fixed_weights

    rng = np.random.default_rng(2)
    for q in (
        rng.integers(-300, 300, (6, 7)),
        rng.integers(0, 300, (6, 7)),
        -rng.integers(0, 300, (6, 7)),
    ):
        got = lava_weights(torch.from_numpy(q.astype(np.float64)))
        np.testing.assert_array_equal(got.numpy().astype(np.int64), lava_fixed_weights(q))


def test_straight_through_gradients_reach_every_layer() -> None:
    policy = _policy()
    z = torch.randn(32, 9) * 2
    out, hidden = policy.sdnn(z)
    (out.square().sum() + sum(h.mean() for h in hidden)).backward()
    for fc in policy.sdnn.affine_layers():
        assert fc.weight.grad is not None and fc.bias.grad is not None
        assert torch.isfinite(fc.weight.grad).all()
        assert fc.weight.grad.abs().sum() > 0 and fc.bias.grad.abs().sum() > 0


def test_message_penalty_lowers_the_proxy() -> None:
    """Minimising the proxy alone on a toy pair of consecutive observations lowers it, and the
    messages sent at thresholds of a quarter of each layer's mean activation with it."""
    policy = _policy(hidden=(16, 16))
    x_before = torch.randn(64, 9)
    x_now = x_before + 0.5 * torch.randn(64, 9)

    def messages() -> float:
        with torch.no_grad():
            now, before = policy.sdnn(x_now)[1], policy.sdnn(x_before)[1]
        return sum(float(((a - b).abs() >= 0.25 * a.mean()).double().mean())
                   for a, b in zip(now, before, strict=True))  # fmt: skip

    first = float(policy.message_proxy(x_now, x_before).detach())
    messages_first = messages()
    opt = torch.optim.Adam(policy.sdnn.parameters(), lr=1e-2)
    for _ in range(60):
        opt.zero_grad()
        policy.message_proxy(x_now, x_before).backward()
        opt.step()
    assert float(policy.message_proxy(x_now, x_before).detach()) < 0.5 * first
    assert messages() < 0.7 * messages_first
    assert float(policy.message_proxy(x_now, x_now).detach()) == 0.0


def test_rollout_stores_each_steps_previous_observation(tmp_path: Path) -> None:
    """buffer.previous[t] is the observation of step t - 1 of the same episode, and step t's
    own at an episode's first step (un-normalised observations make this exact)."""
    cfg = load_config(
        overrides={"env": "grid", "policy": "sdnn", "total_steps": 256, "track": "small_S"},
        sets=[*TINY, "ppo.norm_obs=false", "sdnn.hidden=[8]", "ppo.rollout_steps=200"],
    )
    trainer = Trainer(cfg, tmp_path / "run")
    try:
        buf = trainer._allocate()
        trainer.rollout.reset(seed=3)
        stats = IterationStats()
        done = trainer.rollout.collect(
            trainer.policy, trainer.obs_rms, buf, trainer.progress, stats, lambda: False
        )
        _check_loss_adds_the_penalty(trainer, buf)
    finally:
        trainer.close()
    assert done and buf.previous is not None
    prev, raw, ends = buf.previous.numpy(), buf.raw.numpy(), buf.ends.numpy()
    np.testing.assert_array_equal(prev[0], raw[0])
    starts = ends[:-1] > 0
    assert starts.any() and not starts.all()  # both kinds of step are checked
    np.testing.assert_array_equal(prev[1:][~starts], raw[:-1][~starts])
    np.testing.assert_array_equal(prev[1:][starts], raw[1:][starts])
    assert len(stats.kind["messages"]) == 200 and stats.kind["messages"][0].shape == (2,)


def test_training_logs_the_penalty_and_message_rates(tmp_path: Path) -> None:
    import json

    cfg = load_config(
        overrides={"env": "grid", "policy": "sdnn", "total_steps": 512, "track": "small_S"},
        sets=[*TINY, "sdnn.hidden=[16, 16]", "sdnn.message_penalty=0.1",
              "sdnn.message_penalty_warmup=1.0"],
    )  # fmt: skip
    trainer = Trainer(cfg, tmp_path / "run")
    try:
        trainer.train()
    finally:
        trainer.close()
    records = [json.loads(x) for x in (tmp_path / "run/metrics.jsonl").read_text().splitlines()]
    assert [r["sdnn/message_penalty"] for r in records] == [0.0, 0.05]  # the warm-up ramp
    for r in records:
        assert 0.0 < r["sdnn/message_rate_layer1"] <= 1.0
        assert 0.0 < r["sdnn/message_rate_input"] <= 1.0
        assert r["losses/message_proxy"] > 0.0


def _check_loss_adds_the_penalty(trainer: Trainer, buf: RolloutBuffer) -> None:
    """The minibatch loss is PPO's plus ``message_penalty`` times the proxy of (obs, previous)."""
    assert buf.previous is not None
    zeros = torch.zeros_like(buf.rewards)
    mb = buf.flat(zeros, zeros)
    trainer.penalty_weights = {"messages": 0.5}
    parts, _, _ = trainer._minibatch_loss(mb)
    p = trainer.cfg.ppo
    ppo = parts["policy"] - trainer.ent_coef * parts["entropy"] + p.vf_coef * parts["value"]
    proxy = trainer.policy.message_proxy(mb.obs, mb.previous)
    assert float(proxy.detach()) > 0.0
    torch.testing.assert_close(parts["messages"], proxy)
    torch.testing.assert_close(parts["loss"], ppo + 0.5 * proxy)
