"""Make the small pretrained policies the tests drive with.

    .venv/bin/python scripts/make_test_policy.py [--steps 300000] [--work runs/test-policy]
    .venv/bin/python scripts/make_test_policy.py --env gazebo --work runs/test-policy-gazebo

Trains a small_S SNN with the defaults (seed 1, no TensorBoard, no trajectories), then writes
``tests/data/policies/ENV-snn/`` with its ``config.toml`` and its latest checkpoint without the
optimizer state (the tests only evaluate it), about 120 kB: ``grid-snn`` for
``tests/test_fixed_point.py``, ``gazebo-snn`` for the ROS bridge's tests. About 1-2 minutes.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import torch

from snnkart.rl.checkpoint import load_checkpoint, save_checkpoint
from snnkart.rl.config import load_config
from snnkart.rl.ppo import Trainer

POLICIES = Path(__file__).resolve().parents[1] / "tests" / "data" / "policies"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--work", type=Path, default=Path("runs/test-policy"))
    parser.add_argument("--env", default="grid", help="grid (default) or gazebo")
    args = parser.parse_args()
    dest = POLICIES / f"{args.env}-snn"
    torch.set_num_threads(1)
    if not (args.work / "checkpoint.pt").is_file():
        cfg = load_config(
            overrides={"env": args.env, "policy": "snn", "track": "small_S", "seed": 1,
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
    dest.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(args.work / "config.toml", dest / "config.toml")
    save_checkpoint(
        dest / "checkpoint.pt",
        state,
        {k: v for k, v in meta.items() if k not in ("schema", "versions")},
    )
    print(f"wrote {dest} (step {meta['global_step']:,})")


if __name__ == "__main__":
    main()
