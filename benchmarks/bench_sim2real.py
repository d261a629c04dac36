"""Sim-to-real robustness: success under LIDAR noise, beam dropout and actuation delay of a
gazebo SNN trained without them against one trained with them, side by side in one run.

Both train on small_S with the defaults (seed 1, the same steps); the robust one with
``env_config.sim2real`` = NOISE. Each is evaluated (torch, deterministic, the same seeded
episodes) in the clean env and in the noisy one.

    python -m benchmarks.bench_sim2real [--steps 300000] [--episodes 50]

Results go to ``benchmarks/results/bench_sim2real-<commit>.json``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import torch

from benchmarks.common import add_out_argument, machine_info, output_path
from snnkart.eval.episodes import EvalSummary, run_episodes
from snnkart.rl.config import load_config
from snnkart.rl.ppo import Trainer
from snnkart.rl.trained import TorchPredictor, load_run

NOISE = {"lidar_noise_m": 0.03, "beam_dropout": 0.1, "action_delay_steps": 2}


def train(run_dir: Path, steps: int, noisy: bool) -> Path:
    if (run_dir / "checkpoint.pt").is_file():
        return run_dir
    sets = ["run.tensorboard=false", "run.trajectories=false"]
    if noisy:
        sets += [f"env_config.sim2real.{k}={v}" for k, v in NOISE.items()]
    cfg = load_config(overrides={"env": "gazebo", "policy": "snn", "track": "small_S",
                                 "seed": 1, "total_steps": steps}, sets=sets)  # fmt: skip
    trainer = Trainer(cfg, run_dir)
    try:
        trainer.train()
    finally:
        trainer.close()
    return run_dir


def evaluate(run_dir: Path, noisy: bool, episodes: int, seed: int) -> dict:
    run = load_run(run_dir)
    env_config = {k: v for k, v in run.config.env_config.items() if k != "sim2real"}
    if noisy:
        env_config["sim2real"] = NOISE
    cfg = run.config.model_copy(update={"env_config": env_config})
    env = cfg.make_env(track=run.track)
    try:
        summary = EvalSummary.of(run_episodes(env, TorchPredictor(run), episodes, seed=seed))
    finally:
        env.close()
    return {"success": summary.success_rate, "crashes": summary.crashes,
            "mean_lap_time": summary.mean_lap_time}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--seed", type=int, default=10_000)
    parser.add_argument("--work", type=Path, default=Path("runs/bench_sim2real"))
    add_out_argument(parser)
    args = parser.parse_args()
    torch.set_num_threads(1)
    results = {}
    for name, noisy in (("trained clean", False), ("trained with noise", True)):
        run_dir = train(args.work / name.replace(" ", "-"), args.steps, noisy)
        results[name] = {
            "clean env": evaluate(run_dir, False, args.episodes, args.seed),
            "noisy env": evaluate(run_dir, True, args.episodes, args.seed),
        }
        print(name, results[name])
    out = output_path("bench_sim2real", args.out)
    out.write_text(json.dumps({"machine": machine_info(), "noise": NOISE, "steps": args.steps,
                               "episodes": args.episodes, "results": results},
                              indent=2) + "\n")  # fmt: skip
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
