"""Training speed: snnkart PPO (ANN and SNN at T=8) against Stable-Baselines3 PPO, one run.

All three train on steer/small_S with the same hyperparameters (8 envs x 256 steps, 10 epochs,
8 minibatches, 128-128 tanh MLPs for the ANN and both critics, observation normalisation),
one torch thread, one after the other in this process. Rollout and update time are timed
separately. Targets (issue 3): snnkart ANN >= SB3 PPO; SNN (T=8) >= 0.7x the ANN.

    python -m benchmarks.bench_train [--iterations 10]

Results go to ``benchmarks/results/bench_train-<commit>.json``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import torch

from benchmarks.common import machine_info, results_path
from snnkart.envs import ENV_IDS
from snnkart.rl.config import load_config
from snnkart.rl.ppo import Trainer

SETS = [
    "ppo.num_envs=8",
    "ppo.num_steps=256",
    "ppo.update_epochs=10",
    "ppo.num_minibatches=8",
    "ppo.learning_rate=3e-4",
    "ppo.ent_coef=0.01",
    "ann.hidden=[128, 128]",  # the same network as SB3's MlpPolicy below
    "run.tensorboard=false",
    "run.trajectories=false",
    "run.checkpoint_every=1000",
]


def snnkart_run(policy: str, iterations: int) -> dict[str, float]:
    cfg = load_config(
        overrides={"env": "steer", "track": "small_S", "policy": policy,
                   "total_steps": iterations * 2048, "seed": 1},
        sets=SETS,
    )  # fmt: skip
    tmp = Path(tempfile.mkdtemp(prefix="bench_train_"))
    trainer = Trainer(cfg, tmp / "run")
    rollout = update = 0.0
    records: list[dict[str, Any]] = []

    def on_iteration(r: dict[str, Any]) -> None:
        records.append(r)

    start = time.perf_counter()
    trainer.train(on_iteration)
    total = time.perf_counter() - start
    trainer.close()
    shutil.rmtree(tmp)
    steps = cfg.batch_size
    for r in records:
        rollout += steps / r["charts/rollout_SPS"]
        update += r["charts/update_seconds"]
    n = len(records) * steps
    return {"steps": n, "seconds": total, "steps_per_s": n / total,
            "rollout_steps_per_s": n / rollout, "update_seconds_per_iteration": update / len(records)}  # fmt: skip


def sb3_run(iterations: int) -> dict[str, float]:
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    class Timer(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.rollout = 0.0
            self.t0 = 0.0

        def _on_rollout_start(self) -> None:
            self.t0 = time.perf_counter()

        def _on_rollout_end(self) -> None:
            self.rollout += time.perf_counter() - self.t0

        def _on_step(self) -> bool:
            return True

    venv = VecNormalize(
        make_vec_env(lambda: gym.make(ENV_IDS["steer"], track="small_S"), n_envs=8, seed=1),
        norm_obs=True, norm_reward=False, clip_obs=10.0,
    )  # fmt: skip
    model = PPO(
        "MlpPolicy", venv, n_steps=256, batch_size=256, n_epochs=10, learning_rate=3e-4,
        gamma=0.995, gae_lambda=0.95, clip_range=0.2, ent_coef=0.01, vf_coef=0.5,
        max_grad_norm=0.5, seed=1, device="cpu", verbose=0,
        policy_kwargs={"net_arch": {"pi": [128, 128], "vf": [128, 128]}, "activation_fn": torch.nn.Tanh},
    )  # fmt: skip
    timer = Timer()
    start = time.perf_counter()
    model.learn(total_timesteps=iterations * 2048, callback=timer)
    total = time.perf_counter() - start
    n = model.num_timesteps
    return {"steps": n, "seconds": total, "steps_per_s": n / total,
            "rollout_steps_per_s": n / timer.rollout,
            "update_seconds_per_iteration": (total - timer.rollout) / iterations}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=10)
    args = parser.parse_args()
    torch.set_num_threads(1)
    results: dict[str, Any] = {"machine": machine_info(), "iterations": args.iterations}
    for name, fn in (
        ("snnkart_ann", lambda: snnkart_run("ann", args.iterations)),
        ("snnkart_snn_T8", lambda: snnkart_run("snn", args.iterations)),
        ("sb3_ppo", lambda: sb3_run(args.iterations)),
    ):
        r = fn()
        results[name] = r
        print(f"{name:15s} {r['steps_per_s']:7.0f} steps/s  (rollout {r['rollout_steps_per_s']:7.0f} "
              f"steps/s, update {r['update_seconds_per_iteration']:.2f} s/iteration)")  # fmt: skip
    ann, snn, sb3 = (
        results[k]["steps_per_s"] for k in ("snnkart_ann", "snnkart_snn_T8", "sb3_ppo")
    )
    results["ann_vs_sb3"] = ann / sb3
    results["snn_vs_ann"] = snn / ann
    print(f"snnkart ANN / SB3 PPO: {ann / sb3:.2f}x (target >= 1)")
    print(f"snnkart SNN (T=8) / ANN: {snn / ann:.2f}x (target >= 0.7)")
    path = results_path("bench_train")
    path.write_text(json.dumps(results, indent=2) + "\n")
    print(f"results written to {path}")


if __name__ == "__main__":
    main()
