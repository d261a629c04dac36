"""Make the small pretrained policies the tests drive with.

    .venv/bin/python scripts/make_test_policy.py [--steps 300000] [--work runs/test-policy]
    .venv/bin/python scripts/make_test_policy.py --env gazebo --work runs/test-policy-gazebo
    .venv/bin/python scripts/make_test_policy.py --policy ann --steps 150000 --work runs/test-ann

Trains a small_S SNN (or ANN) with the defaults (seed 1, no TensorBoard, no trajectories), then
writes ``tests/data/policies/ENV-POLICY/`` with its ``config.toml`` and its latest checkpoint
without the optimizer state (the tests only evaluate it), about 120 kB: ``grid-snn`` for
``tests/test_fixed_point.py``, ``gazebo-snn`` for the ROS bridge's tests, ``grid-ann`` for the
int8 ANN's (``tests/test_ann_int8.py``). About 1-2 minutes.
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
    parser.add_argument("--policy", default="snn", help="snn (default) or ann")
    args = parser.parse_args()
    dest = POLICIES / f"{args.env}-{args.policy}"
    torch.set_num_threads(1)
    if not (args.work / "checkpoint.pt").is_file():
        cfg = load_config(
            overrides={"env": args.env, "policy": args.policy, "track": "small_S", "seed": 1,
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
