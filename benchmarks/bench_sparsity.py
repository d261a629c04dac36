"""Find the sparse spiking policy: success against synaptic operations over T, width and the
firing-rate penalty, several seeds per point.

Each point is a set of ``snnkart train --set`` overrides on top of the env's SNN defaults. Each
run trains for ``--steps`` env steps, is exported to NIR and deployed on the numpy reference
in fixed point (bit-exact with Lava's fixed-point models, see tests/test_deploy.py) on
``--episodes`` seeded episodes; the benchmark records the deployment's success, lap time and
its counts per env step (spikes, synaptic operations and neuron updates per layer). Energy is
not computed here: ``snnkart report`` prices these counts with the hardware profiles, so a
changed price needs no rerun.

Runs go ``--jobs`` at a time (one torch thread each). Results are written after every run, and
a run whose deploy.json exists is not trained again (resumable).

    python -m benchmarks.bench_sparsity [--env grid] [--points default t4 ...] [--seeds 1 2 3]
                                        [--steps 300000] [--jobs 2] [--episodes 50] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from benchmarks.common import add_out_argument, git_commit, machine_info, output_path

ROOT = Path(__file__).resolve().parents[1]
SNNKART = [sys.executable, "-m", "snnkart.cli"]

POINTS: dict[str, list[str]] = {
    "default": [],  # T = 8, 64-64, no penalty: the dense reference
    "t4": ["snn.num_steps=4"],
    "t4-r0.02": ["snn.num_steps=4", "snn.rate_reg=0.02"],
    "t4-r0.05": ["snn.num_steps=4", "snn.rate_reg=0.05"],
    "t4-r0.1": ["snn.num_steps=4", "snn.rate_reg=0.1"],
    "t2-r0.05": ["snn.num_steps=2", "snn.rate_reg=0.05"],
    "t8-r0.05": ["snn.rate_reg=0.05"],
    "t4-r0.05-w32": ["snn.num_steps=4", "snn.rate_reg=0.05", "snn.hidden=[32, 32]"],
    "t4-r0.1-warm": ["snn.num_steps=4", "snn.rate_reg=0.1", "snn.rate_reg_warmup=0.5"],
    "t4-r0.2-warm": ["snn.num_steps=4", "snn.rate_reg=0.2", "snn.rate_reg_warmup=0.5"],
}
"""Named points of the sweep: ``snnkart train --set`` overrides."""


def _snnkart(*args: str, cwd: Path = ROOT) -> None:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    result = subprocess.run([*SNNKART, *args], cwd=cwd, capture_output=True, text=True, env=env)
    if result.returncode != 0:
        raise RuntimeError(f"snnkart {' '.join(args)} failed:\n{result.stderr[-3000:]}")


def one_run(
    env: str, point: str, seed: int, steps: int, episodes: int, runs: Path
) -> dict[str, Any]:
    run_dir = runs / f"{env}-{point}-s{seed}"
    deploy_dir = run_dir / "deploy-fixed"
    start = time.perf_counter()
    if not (deploy_dir / "deploy.json").is_file():
        sets = [arg for kv in POINTS[point] for arg in ("--set", kv)]
        resume = ["--resume"] if (run_dir / "checkpoint.json").is_file() else []
        _snnkart("train", "--env", env, "--policy", "snn", "--track", "small_S",
                 "--seed", str(seed), "--steps", str(steps), "--out", str(run_dir),
                 *sets, *resume)  # fmt: skip
        _snnkart("export", "--nir", str(run_dir), "--out", str(run_dir / "policy.nir"))
        _snnkart("deploy", str(run_dir / "policy.nir"), "--backend", "nir-ref",
                 "--precision", "fixed", "--episodes", str(episodes), "--seed", "10000",
                 "--out", str(deploy_dir))  # fmt: skip
    seconds = time.perf_counter() - start
    record = json.loads((deploy_dir / "deploy.json").read_text())
    meta = json.loads((run_dir / "checkpoint.json").read_text())
    counts, summary = record["counts"], record["summary"]
    n = max(counts["env_steps"], 1)
    first = meta.get("first_finish_step", -1)
    return {
        "env": env,
        "point": point,
        "settings": POINTS[point],
        "seed": seed,
        "steps": meta["global_step"],
        "first_finish_step": None if first is None or first < 0 else first,
        "num_steps": record["manifest"]["num_steps"],
        "sizes": [layer["size"] for layer in record["manifest"]["layers"]],
        "network": record["network"],
        "precision": record["precision"],
        "success_rate": summary["success_rate"],
        "mean_lap_time": summary["mean_lap_time"],
        "mean_return": summary["mean_return"],
        "env_steps": counts["env_steps"],
        "spikes_per_step": [s / n for s in counts["spikes"]],
        "synops_per_step": [s / n for s in counts["synops"]],
        "neuron_updates_per_step": [s / n for s in counts["neuron_updates"]],
        "seconds": seconds,
        "deploy_json": str(deploy_dir / "deploy.json"),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="grid")
    parser.add_argument("--points", nargs="+", default=list(POINTS), choices=list(POINTS))
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--runs", type=Path, default=ROOT / "runs" / "bench_sparsity")
    add_out_argument(parser)
    args = parser.parse_args()

    path = output_path("bench_sparsity", args.out)
    results: dict[str, Any] = {
        "benchmark": "bench_sparsity",
        "commit": git_commit(),
        "machine": machine_info(),
        "env": args.env,
        "track": "small_S",
        "steps": args.steps,
        "deploy": {
            "backend": "nir-ref",
            "precision": "fixed",
            "episodes": args.episodes,
            "first_seed": 10000,
        },
        "points": {p: POINTS[p] for p in args.points},
        "runs": [],
    }
    jobs = [(p, s) for p in args.points for s in args.seeds]
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        futures = [
            pool.submit(one_run, args.env, p, s, args.steps, args.episodes, args.runs)
            for p, s in jobs
        ]
        for fut in futures:
            r = fut.result()
            results["runs"].append(r)
            path.write_text(json.dumps(results, indent=2) + "\n")
            print(
                f"{r['point']:14s} seed {r['seed']}: success {r['success_rate']:.0%}, "
                f"synops/step {sum(r['synops_per_step']):,.0f}, "
                f"spikes/step {sum(r['spikes_per_step']):,.1f}, {r['seconds']:.0f} s",
                flush=True,
            )
    print(f"results written to {path}")


if __name__ == "__main__":
    main()
