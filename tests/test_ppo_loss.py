"""The PPO minibatch loss against hand-computed numbers: the ratio clipping (a sample pushed
out of the clip range in the direction its advantage favours gives the clipped term and no
gradient) and advantage normalisation over each minibatch.

The golden runs never clip (their ``clipfrac`` is 0.0 throughout), so only these tests see
the clipping."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import torch

from snnkart.rl.buffer import Batch
from snnkart.rl.config import load_config
from snnkart.rl.ppo import Trainer
from snnkart.rl.ppo_loss import clipped_surrogate

EPS = 0.2


def _log_probs(ratios: list[float]) -> tuple[torch.Tensor, torch.Tensor]:
    """Current log-probs (all 0, with a gradient) and stored ones giving ``ratios``."""
    new = torch.zeros(len(ratios), dtype=torch.float64, requires_grad=True)
    old = -torch.log(torch.tensor(ratios, dtype=torch.float64))
    return new, old


def test_a_ratio_beyond_the_clip_range_gives_the_clipped_loss_and_no_gradient() -> None:
    # ratio 1.5, advantage +2: min(1.5 * 2, 1.2 * 2) = 2.4 is the clipped term; constant.
    # ratio 1.1, advantage +1: inside the range, the term is 1.1 * 1, gradient 1.1.
    # ratio 0.5, advantage +1: below the range, but clipping it (0.8) would be the optimistic
    # bound; the pessimistic one, 0.5, is kept and has a gradient.
    new, old = _log_probs([1.5, 1.1, 0.5])
    adv = torch.tensor([2.0, 1.0, 1.0], dtype=torch.float64)
    loss, ratio, logratio = clipped_surrogate(new, old, adv, EPS, norm_adv=False)
    torch.testing.assert_close(ratio, torch.tensor([1.5, 1.1, 0.5], dtype=torch.float64))
    torch.testing.assert_close(logratio, ratio.log())
    assert loss.item() == pytest.approx(-(1.2 * 2 + 1.1 * 1 + 0.5 * 1) / 3, abs=1e-12)
    loss.backward()
    assert new.grad is not None
    # d/d log_prob of -A * r / 3 is -A * r / 3
    assert new.grad.tolist() == pytest.approx([0.0, -1.1 / 3, -0.5 / 3], abs=1e-12)


def test_a_negative_advantage_is_clipped_below_the_range() -> None:
    new, old = _log_probs([0.5, 1.5])
    adv = torch.tensor([-1.0, -1.0], dtype=torch.float64)
    loss, _, _ = clipped_surrogate(new, old, adv, EPS, norm_adv=False)
    assert loss.item() == pytest.approx((0.8 + 1.5) / 2, abs=1e-12)
    loss.backward()
    assert new.grad is not None
    assert new.grad.tolist() == pytest.approx([0.0, 1.5 / 2], abs=1e-12)


def test_advantages_are_normalised_over_the_minibatch_given() -> None:
    # advantages [2, 1]: mean 1.5, sample std sqrt(0.5), so A = [+1/sqrt(2), -1/sqrt(2)]
    a = 1 / math.sqrt(2)
    new, old = _log_probs([1.5, 1.1])
    loss, _, _ = clipped_surrogate(new, old, torch.tensor([2.0, 1.0]).double(), EPS, True)
    assert loss.item() == pytest.approx((-a * 1.2 + a * 1.1) / 2, abs=1e-7)
    loss.backward()
    assert new.grad is not None
    assert new.grad.tolist() == pytest.approx([0.0, a * 1.1 / 2], abs=1e-7)
    # the same minibatch with its advantages moved and scaled: the same loss
    shifted, _, _ = clipped_surrogate(new, old, torch.tensor([120.0, 110.0]).double(), EPS, True)
    assert shifted.item() == pytest.approx(loss.item(), abs=1e-7)


def test_the_trainers_minibatch_loss_normalises_each_minibatch(tmp_path: Path) -> None:
    """A real rollout's batch, before any update (every ratio is 1): the surrogate of a
    minibatch is then minus the mean of its normalised advantages, which is 0 when they are
    normalised over that minibatch, and not when over the whole batch or not at all."""
    cfg = load_config(
        overrides={"env": "grid", "policy": "ann", "total_steps": 128, "track": "small_S"},
        sets=["ppo.num_envs=2", "ppo.num_steps=64", "ppo.num_minibatches=2"],
    )
    trainer = Trainer(cfg, tmp_path / "run")
    batches: list[Batch] = []
    real_update = trainer.update

    def update(b: Batch) -> dict[str, float]:
        batches.append(b)
        return real_update(b)

    trainer.update = update  # type: ignore[method-assign]
    try:
        state = {k: v.clone() for k, v in trainer.policy.state_dict().items()}
        trainer.train()
        trainer.policy.load_state_dict(state)  # the policy that collected the rollout
        (b,) = batches
        whole = (b.advantages - b.advantages.mean()) / b.advantages.std()
        for start in (0, 64):
            mb = b.rows(start, start + 64)
            losses, ratio, _ = trainer._minibatch_loss(mb)
            torch.testing.assert_close(ratio, torch.ones_like(ratio), rtol=0, atol=1e-5)
            # the test can tell: over the whole batch, or raw, the mean is far from 0
            assert abs(whole[start : start + 64].mean().item()) > 1e-3
            assert abs(mb.advantages.mean().item()) > 1e-3
            assert abs(losses["policy"].item()) < 1e-5, losses["policy"].item()
    finally:
        trainer.close()
