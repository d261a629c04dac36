"""Training speed: snnkart PPO (ANN and SNN at T=8) against Stable-Baselines3 PPO, one run.

All three train on steer/small_S with the same hyperparameters and the same schedules: 8 envs x
256 steps, 10 epochs, 8 minibatches, 128-128 tanh MLPs for the ANN and both critics,
observation normalisation, and the learning rate and entropy coefficient annealed linearly to
zero over the run as snnkart does by default. SB3 gets the learning rate through a schedule
callable and the entropy coefficient (a plain float in its PPO) from a callback at each rollout
start. Every hyperparameter of both sides, as each library reports it back, and the learning
rate and entropy coefficient each update used, go into the JSON; ``same_hyperparameters`` lists
any difference (tested in ``tests/test_benchmarks.py``). One torch thread, one run after the
other in this process; rollout and update time are timed separately. Targets (issue 3):
snnkart ANN >= SB3 PPO; SNN (T=8) >= 0.7x the ANN.

    python -m benchmarks.bench_train [--iterations 10] [--num-steps 256] [--out FILE]

Results go to ``benchmarks/results/bench_train-<commit>.json`` unless ``--out`` says otherwise.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import torch

from benchmarks.common import add_out_argument, machine_info, output_path
from snnkart.envs import ENV_IDS
from snnkart.rl.config import TrainConfig, load_config
from snnkart.rl.ppo import Trainer

ENV, TRACK, SEED = "steer", "small_S", 1


def settings(num_steps: int) -> list[str]:
    return [
        "ppo.num_envs=8",
        f"ppo.rollout_steps={num_steps}",
        "ppo.update_epochs=10",
        "ppo.num_minibatches=8",
        "ppo.learning_rate=3e-4",
        "ppo.ent_coef=0.01",
        "ann.hidden=[128, 128]",  # the same network as SB3's MlpPolicy below
        "run.tensorboard=false",
        "run.trajectories=false",
        "run.checkpoint_every=1000",
    ]


def config(policy: str, iterations: int, num_steps: int) -> TrainConfig:
    return load_config(
        overrides={"env": ENV, "track": TRACK, "policy": policy, "seed": SEED,
                   "total_steps": iterations * 8 * num_steps},
        sets=settings(num_steps),
    )  # fmt: skip


def shared_hyperparameters(cfg: TrainConfig) -> dict[str, Any]:
    """snnkart's settings under the names ``sb3_hyperparameters`` reads back from SB3."""
    p = cfg.ppo
    return {
        "n_envs": p.num_envs,
        "n_steps": p.rollout_steps,
        "minibatch_size": p.num_envs * p.rollout_steps // p.num_minibatches,
        "n_epochs": p.update_epochs,
        "gamma": p.gamma,
        "gae_lambda": p.gae_lambda,
        "clip_range": p.clip_coef,
        "clip_range_vf": None if not p.clip_vloss else p.clip_coef,
        "vf_coef": p.vf_coef,
        "max_grad_norm": p.max_grad_norm,
        "normalize_advantage": p.norm_adv,
        "target_kl": p.target_kl,
        "adam_eps": 1e-5,  # snnkart.rl.ppo.Trainer's optimizer
        "orthogonal_init": True,
        "actor_hidden": list(cfg.ann.hidden),
        "critic_hidden": list(cfg.ann.hidden),
        "activation": "Tanh",
        "norm_obs": p.norm_obs,
        "clip_obs": p.clip_obs,
        "obs_norm_epsilon": 1e-8,
        "norm_reward": False,
        "initial_learning_rate": p.learning_rate,
        "learning_rate_schedule": "linear to 0" if p.anneal_lr else "constant",
        "initial_ent_coef": p.ent_coef,
        "ent_coef_schedule": "linear to 0" if p.anneal_ent else "constant",
        "action_space": repr(gym.make(ENV_IDS[cfg.env], track=cfg.track,
                                      action_mode=cfg.action_mode).action_space),
    }  # fmt: skip


def snnkart_run(policy: str, iterations: int, num_steps: int) -> dict[str, Any]:
    cfg = config(policy, iterations, num_steps)
    tmp = Path(tempfile.mkdtemp(prefix="bench_train_"))
    records: list[dict[str, Any]] = []
    try:
        trainer = Trainer(cfg, tmp / "run")
        start = time.perf_counter()
        trainer.train(records.append)
        total = time.perf_counter() - start
        trainer.close()
    finally:
        shutil.rmtree(tmp)
    steps = cfg.batch_size
    rollout = sum(steps / r["charts/rollout_SPS"] for r in records)
    update = sum(r["charts/update_seconds"] for r in records)
    n = len(records) * steps
    return {
        "steps": n, "seconds": total, "steps_per_s": n / total,
        "rollout_steps_per_s": n / rollout, "update_seconds_per_iteration": update / len(records),
        "hyperparameters": shared_hyperparameters(cfg),
        "config": cfg.model_dump(mode="json"),
        "learning_rate_per_iteration": [r["charts/learning_rate"] for r in records],
        "ent_coef_per_iteration": [r["charts/ent_coef"] for r in records],
    }  # fmt: skip


def sb3_hyperparameters(model: Any, venv: Any) -> dict[str, Any]:
    """What SB3 will use, read back from its own objects (not from the arguments given)."""
    policy = model.policy
    arch = policy.net_arch
    return {
        "n_envs": model.n_envs,
        "n_steps": model.n_steps,
        "minibatch_size": model.batch_size,
        "n_epochs": model.n_epochs,
        "gamma": model.gamma,
        "gae_lambda": model.gae_lambda,
        "clip_range": model.clip_range(1.0),
        "clip_range_vf": None if model.clip_range_vf is None else model.clip_range_vf(1.0),
        "vf_coef": model.vf_coef,
        "max_grad_norm": model.max_grad_norm,
        "normalize_advantage": model.normalize_advantage,
        "target_kl": model.target_kl,
        "adam_eps": policy.optimizer.defaults["eps"],
        "orthogonal_init": policy.ortho_init,
        "actor_hidden": list(arch["pi"]),
        "critic_hidden": list(arch["vf"]),
        "activation": policy.activation_fn.__name__,
        "norm_obs": venv.norm_obs,
        "clip_obs": venv.clip_obs,
        "obs_norm_epsilon": venv.epsilon,
        "norm_reward": venv.norm_reward,
    }


def sb3_run(cfg: TrainConfig, iterations: int) -> dict[str, Any]:
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecNormalize

    p = cfg.ppo
    n = iterations  # snnkart: frac = 1 - (i - 1) / n for iteration i = 1..n, at its start

    def frac(iteration: int) -> float:
        return 1.0 - (iteration - 1) / n

    def learning_rate(progress_remaining: float) -> float:
        # SB3 asks after the rollout of iteration i, with progress_remaining = 1 - i / n
        # (and once with 1.0 when it builds the optimizer).
        i = max(1, round((1.0 - progress_remaining) * n))
        return (frac(i) if p.anneal_lr else 1.0) * p.learning_rate

    class Schedules(BaseCallback):
        """Sets the entropy coefficient at each rollout start, times rollouts, and records
        what each update used."""

        def __init__(self) -> None:
            super().__init__()
            self.rollout = 0.0
            self.t0 = 0.0
            self.lr: list[float] = []
            self.ent: list[float] = []

        def record(self) -> None:  # the values the update just done used
            self.lr.append(self.model.policy.optimizer.param_groups[0]["lr"])
            self.ent.append(self.model.ent_coef)

        def _on_rollout_start(self) -> None:
            iteration = self.model.num_timesteps // (p.num_envs * p.rollout_steps) + 1
            if iteration > 1:
                self.record()
            self.model.ent_coef = (frac(iteration) if p.anneal_ent else 1.0) * p.ent_coef
            self.t0 = time.perf_counter()

        def _on_rollout_end(self) -> None:
            self.rollout += time.perf_counter() - self.t0

        def _on_step(self) -> bool:
            return True

    venv = VecNormalize(
        make_vec_env(lambda: gym.make(ENV_IDS[cfg.env], track=cfg.track,
                                      action_mode=cfg.action_mode),
                     n_envs=p.num_envs, seed=cfg.seed),
        norm_obs=p.norm_obs, norm_reward=False, clip_obs=p.clip_obs,
    )  # fmt: skip
    model = PPO(
        "MlpPolicy", venv, n_steps=p.rollout_steps, batch_size=cfg.batch_size // p.num_minibatches,
        n_epochs=p.update_epochs, learning_rate=learning_rate, gamma=p.gamma,
        gae_lambda=p.gae_lambda, clip_range=p.clip_coef, ent_coef=p.ent_coef,
        vf_coef=p.vf_coef, max_grad_norm=p.max_grad_norm, normalize_advantage=p.norm_adv,
        target_kl=p.target_kl, seed=cfg.seed, device="cpu", verbose=0,
        policy_kwargs={"net_arch": {"pi": list(cfg.ann.hidden), "vf": list(cfg.ann.hidden)},
                       "activation_fn": torch.nn.Tanh},
    )  # fmt: skip
    hyper = sb3_hyperparameters(model, venv)
    schedules = Schedules()
    start = time.perf_counter()
    model.learn(total_timesteps=iterations * cfg.batch_size, callback=schedules)
    total = time.perf_counter() - start
    schedules.record()  # the last update
    steps = model.num_timesteps
    lr, ent = schedules.lr, schedules.ent
    hyper |= {
        "initial_learning_rate": lr[0],
        "learning_rate_schedule": "linear to 0" if _linear_to_zero(lr) else "constant"
        if len(set(lr)) == 1 else "other",
        "initial_ent_coef": ent[0],
        "ent_coef_schedule": "linear to 0" if _linear_to_zero(ent) else "constant"
        if len(set(ent)) == 1 else "other",
        "action_space": repr(venv.action_space),
    }  # fmt: skip
    return {
        "steps": steps, "seconds": total, "steps_per_s": steps / total,
        "rollout_steps_per_s": steps / schedules.rollout,
        "update_seconds_per_iteration": (total - schedules.rollout) / iterations,
        "hyperparameters": hyper,
        "stable_baselines3": __import__("stable_baselines3").__version__,
        "learning_rate_per_iteration": lr,
        "ent_coef_per_iteration": ent,
    }  # fmt: skip


def _linear_to_zero(values: list[float]) -> bool:
    """``values[i] = values[0] * (1 - i / n)`` for a run of n iterations."""
    n = len(values)
    return n > 1 and values[0] > 0 and all(
        math.isclose(v, values[0] * (1 - i / n), rel_tol=1e-9, abs_tol=1e-15)
        for i, v in enumerate(values)
    )  # fmt: skip


def differences(ours: dict[str, Any], theirs: dict[str, Any]) -> dict[str, list[Any]]:
    """Every hyperparameter or per-iteration value where the two sides differ."""
    out: dict[str, list[Any]] = {}
    keys = sorted(set(ours["hyperparameters"]) | set(theirs["hyperparameters"]))
    for k in keys:
        a, b = (
            ours["hyperparameters"].get(k, "<absent>"),
            theirs["hyperparameters"].get(k, "<absent>"),
        )
        same = (
            math.isclose(a, b, rel_tol=1e-12)
            if isinstance(a, float) and isinstance(b, float)
            else a == b
        )
        if not same:
            out[k] = [a, b]
    for k in ("learning_rate_per_iteration", "ent_coef_per_iteration"):
        a, b = ours[k], theirs[k]
        if len(a) != len(b) or not all(math.isclose(x, y, rel_tol=1e-9, abs_tol=1e-15)
                                       for x, y in zip(a, b, strict=True)):  # fmt: skip
            out[k] = [a, b]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=10)
    parser.add_argument("--num-steps", type=int, default=256, help="rollout steps per env")
    add_out_argument(parser)
    args = parser.parse_args()
    torch.set_num_threads(1)
    results: dict[str, Any] = {
        "machine": machine_info(), "iterations": args.iterations, "num_steps": args.num_steps,
        "env": ENV, "track": TRACK, "seed": SEED,
    }  # fmt: skip
    ann_cfg = config("ann", args.iterations, args.num_steps)
    for name, fn in (
        ("snnkart_ann", lambda: snnkart_run("ann", args.iterations, args.num_steps)),
        ("snnkart_snn_T8", lambda: snnkart_run("snn", args.iterations, args.num_steps)),
        ("sb3_ppo", lambda: sb3_run(ann_cfg, args.iterations)),
    ):
        r = fn()
        results[name] = r
        print(f"{name:15s} {r['steps_per_s']:7.0f} steps/s  (rollout {r['rollout_steps_per_s']:7.0f} "
              f"steps/s, update {r['update_seconds_per_iteration']:.2f} s/iteration)")  # fmt: skip
    diff = differences(results["snnkart_ann"], results["sb3_ppo"])
    results["same_hyperparameters"] = not diff
    results["hyperparameter_differences"] = diff
    print("hyperparameters and schedules, snnkart ANN vs SB3: "
          + ("identical" if not diff else f"DIFFERENT in {sorted(diff)}"))  # fmt: skip
    ann, snn, sb3 = (
        results[k]["steps_per_s"] for k in ("snnkart_ann", "snnkart_snn_T8", "sb3_ppo")
    )
    results["ann_vs_sb3"] = ann / sb3
    results["snn_vs_ann"] = snn / ann
    print(f"snnkart ANN / SB3 PPO: {ann / sb3:.2f}x (target >= 1)")
    print(f"snnkart SNN (T=8) / ANN: {snn / ann:.2f}x (target >= 0.7)")
    path = output_path("bench_train", args.out)
    path.write_text(json.dumps(results, indent=2) + "\n")
    print(f"results written to {path}")


if __name__ == "__main__":
    main()
