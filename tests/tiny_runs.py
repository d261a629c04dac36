"""Tiny trained runs (a few hundred PPO steps) for the export and deployment tests."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from snnkart.rl.config import load_config
from snnkart.rl.ppo import Trainer

TINY = [
    "ppo.num_envs=2",
    "ppo.rollout_steps=128",
    "ppo.update_epochs=1",
    "ppo.num_minibatches=2",
    "run.tensorboard=false",
]


def train_tiny(
    run_dir: Path,
    env: str,
    policy: str,
    action_mode: str = "discrete",
    total_steps: int = 512,
    extra_sets: Sequence[str] = (),
    track: str = "small_S",
) -> Path:
    """Train ``policy`` on ``env``/``track`` for ``total_steps`` steps into ``run_dir``."""
    cfg = load_config(
        overrides={
            "env": env,
            "policy": policy,
            "total_steps": total_steps,
            "action_mode": action_mode,
            "track": track,
        },
        sets=[*TINY, *extra_sets],
    )
    trainer = Trainer(cfg, run_dir)
    try:
        trainer.train()
    finally:
        trainer.close()
    return run_dir
