"""Deployment speed: time per env step of one exported SNN policy (T=8) on every backend, side by
side in one run, on the same recorded observations.

Backends: the torch policy (snntorch modules, one thread), the numpy NIR reference in its three
arithmetics (float32 torch order, float64 Lava order, fixed point), and Lava's simulated Loihi
(float and fixed; one long non-blocking run, one message each way per env step through the
host bridge). Lava's start-up (compile, runtime, first step) is timed apart. Target (issue 4):
Lava fixed at most 20 s per 1,000 env steps at T=8.

    python -m benchmarks.bench_deploy [--run RUN_DIR] [--steps 1000]

Without ``--run`` a tiny SNN is trained for 2,048 steps (speed does not depend on training).
Results go to ``benchmarks/results/bench_deploy-<commit>.json``.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from benchmarks.common import add_out_argument, machine_info, output_path
from snnkart.backends.reference import NIRReference
from snnkart.backends.registry import open_backend
from snnkart.export.nir_export import export_nir
from snnkart.rl.config import load_config
from snnkart.rl.ppo import Trainer
from snnkart.rl.trained import TorchPredictor, load_run


def record_observations(run: Any, steps: int, seed: int = 0) -> list[np.ndarray]:
    """Observations of a closed-loop run of the torch policy (episodes back to back)."""
    env = run.config.make_env(track=run.track)
    predictor = TorchPredictor(run, seed=seed)
    obs_list: list[np.ndarray] = []
    try:
        obs, _ = env.reset(seed=seed)
        while len(obs_list) < steps:
            obs_list.append(obs)
            obs, _, terminated, truncated, _ = env.step(predictor.predict(obs))
            if terminated or truncated:
                obs, _ = env.reset()
    finally:
        env.close()
    return obs_list


def time_predictor(predictor: Any, observations: list[np.ndarray]) -> tuple[float, list[Any]]:
    actions = []
    t0 = time.perf_counter()
    for obs in observations:
        actions.append(predictor.predict(obs))
    return time.perf_counter() - t0, actions


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--run", type=Path, help="a trained SNN run (default: train a tiny one)")
    parser.add_argument("--steps", type=int, default=1000)
    add_out_argument(parser)
    args = parser.parse_args()
    torch.set_num_threads(1)

    with tempfile.TemporaryDirectory(prefix="bench-deploy-") as tmp:
        run_dir = args.run
        if run_dir is None:
            run_dir = Path(tmp) / "run"
            cfg = load_config(
                overrides={"env": "steer", "policy": "snn", "total_steps": 2048},
                sets=["ppo.num_envs=2", "ppo.rollout_steps=512", "run.tensorboard=false"],
            )
            trainer = Trainer(cfg, run_dir)
            try:
                trainer.train()
            finally:
                trainer.close()
        run = load_run(run_dir)
        nir_path, _ = export_nir(run, Path(tmp) / "policy.nir")
        observations = record_observations(run, args.steps)
        n = len(observations)
        rows: dict[str, dict[str, Any]] = {}
        actions: dict[str, list[Any]] = {}

        seconds, actions["torch"] = time_predictor(TorchPredictor(run), observations)
        rows["torch"] = {"seconds": seconds}
        for mode in ("float32", "float64", "fixed"):
            seconds, actions[f"nir-ref {mode}"] = time_predictor(
                NIRReference(nir_path, mode), observations
            )
            rows[f"nir-ref {mode}"] = {"seconds": seconds}
        for precision in ("float", "fixed"):
            t0 = time.perf_counter()
            lava = open_backend(nir_path, "lava-sim", precision)
            try:
                lava.predict(observations[0])  # the first step includes Lava's warm-up
                startup = time.perf_counter() - t0
                seconds, acts = time_predictor(lava, observations[1:])
            finally:
                lava.close()
            actions[f"lava-sim {precision}"] = [None, *acts]
            rows[f"lava-sim {precision}"] = {
                "seconds": seconds * n / (n - 1),
                "startup_s": startup,
            }

    torch_s = rows["torch"]["seconds"]
    ref = {"lava-sim float": "nir-ref float64", "lava-sim fixed": "nir-ref fixed"}
    print(f"{n} env steps at T={run.config.snn.num_steps}, policy {run.config.env}/"
          f"{run.config.track} ({run.config.snn.hidden})")  # fmt: skip
    print(f"{'backend':<18}{'ms/step':>9}{'x torch':>9}  notes")
    for name, row in rows.items():
        row["ms_per_env_step"] = 1000 * row["seconds"] / n  # = s per 1000 env steps
        row["ratio_to_torch"] = row["seconds"] / torch_s
        note = ""
        if name in ref:
            same = sum(
                a == b for a, b in zip(actions[name][1:], actions[ref[name]][1:], strict=True)
            )  # fmt: skip
            row["identical_actions_to_reference"] = same / (n - 1)
            note = f"start-up {row['startup_s']:.2f} s; actions = {ref[name]}: {same}/{n - 1}"
        print(f"{name:<18}{row['ms_per_env_step']:>9.2f}"
              f"{row['ratio_to_torch']:>9.1f}  {note}")  # fmt: skip
    target = rows["lava-sim fixed"]["ms_per_env_step"]  # ms per step = s per 1000 steps
    print(f"target: Lava fixed <= 20 s per 1000 env steps: {target:.1f} s "
          f"({'met' if target <= 20 else 'NOT met'})")  # fmt: skip
    out = output_path("bench_deploy", args.out)
    out.write_text(json.dumps({
        "machine": machine_info(),
        "env_steps": n,
        "num_steps_T": run.config.snn.num_steps,
        "hidden": list(run.config.snn.hidden),
        "policy": {  # which policy was timed: the run, its checkpoint and what made it
            "run": str(args.run) if args.run is not None else "tiny run trained by the benchmark",
            "env": run.config.env,
            "track": run.track.name if run.track is not None else run.config.track,
            "global_step": run.meta.get("global_step"),
            "checkpoint_versions": run.meta.get("versions"),
            "env_spec_hash": run.meta.get("env_spec_hash"),
        },
        "io_pattern": "host bridge process, one non-blocking RunSteps per session, one message "
                      "each way per env step (current in, spike raster out), LIFReset/Dense "
                      "library processes",
        "backends": rows,
    }, indent=2) + "\n")  # fmt: skip
    print(f"results written to {out}")


if __name__ == "__main__":
    main()
