"""Make the small pretrained policy that ``tests/test_fixed_point.py`` drives with.

    .venv/bin/python scripts/make_test_policy.py [--steps 300000] [--work runs/test-policy]

Trains a grid/small_S SNN with the defaults (seed 1, no TensorBoard, no trajectories), then
writes ``tests/data/policies/grid-snn/`` with its ``config.toml`` and its latest checkpoint
without the optimizer state (the tests only evaluate it), about 120 kB. Takes about 2 minutes.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import torch

from snnkart.rl.checkpoint import load_checkpoint, save_checkpoint
from snnkart.rl.config import load_config
from snnkart.rl.ppo import Trainer

DEST = Path(__file__).resolve().parents[1] / "tests" / "data" / "policies" / "grid-snn"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--work", type=Path, default=Path("runs/test-policy"))
    args = parser.parse_args()
    torch.set_num_threads(1)
    if not (args.work / "checkpoint.pt").is_file():
        cfg = load_config(
            overrides={"env": "grid", "policy": "snn", "track": "small_S", "seed": 1,
                       "total_steps": args.steps},
            sets=["run.tensorboard=false", "run.trajectories=false"],
        )  # fmt: skip
        trainer = Trainer(cfg, args.work)
        try:
            trainer.train()
        finally:
            trainer.close()
    state, meta = load_checkpoint(args.work / "checkpoint.pt")
    state.pop("optimizer", None)
    DEST.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(args.work / "config.toml", DEST / "config.toml")
    save_checkpoint(
        DEST / "checkpoint.pt",
        state,
        {k: v for k, v in meta.items() if k not in ("schema", "versions")},
    )
    print(f"wrote {DEST} (step {meta['global_step']:,})")


if __name__ == "__main__":
    main()
