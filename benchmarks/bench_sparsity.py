"""Find the sparse spiking policy: success against synaptic operations over T, width and the
firing-rate penalty, several seeds per point.

Each point is a set of ``snnkart train --set`` overrides on top of the env's SNN defaults. Each
run trains for ``--steps`` env steps, is exported to NIR and deployed on the numpy reference
in fixed point (bit-exact with Lava's fixed-point models, see tests/test_deploy.py) on
``--episodes`` seeded episodes; the benchmark records the deployment's success, lap time and
its counts per env step (spikes, synaptic operations and neuron updates per layer). Energy is
not computed here: ``snnkart report`` prices these counts with the hardware profiles, so a
changed price needs no rerun.

Training runs on the launcher's local pool (``snnkart.app.launch.LocalPool``: ``--jobs`` at a
time, one torch thread each, finished runs reused and interrupted ones resumed); each run is
then exported and deployed. Results are written after every run, and a run whose deploy.json
exists is neither trained nor deployed again.

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
from pathlib import Path
from typing import Any

from benchmarks.common import (
    add_out_argument,
    git_commit,
    machine_info,
    output_path,
    training_seconds,
)

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
HOST = "horowitz45_fp32_sram"
"""The digital profile pricing the SNN's host work in the summary."""


def _snnkart(*args: str, cwd: Path = ROOT) -> None:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    result = subprocess.run([*SNNKART, *args], cwd=cwd, capture_output=True, text=True, env=env)
    if result.returncode != 0:
        raise RuntimeError(f"snnkart {' '.join(args)} failed:\n{result.stderr[-3000:]}")


def _name(env: str, point: str, seed: int) -> str:
    return f"{env}-{point}-s{seed}"


def train_all(env: str, jobs: list[tuple[str, int]], steps: int, runs: Path, workers: int) -> None:
    """Train every (point, seed) not yet deployed on the launcher's local pool (one torch
    thread each, ``workers`` at a time; finished runs are reused, interrupted ones resumed)."""
    from snnkart.app.launch import LocalPool, RunSpec
    from snnkart.app.reporter import Silent
    from snnkart.rl.config import load_config

    specs = [
        RunSpec(
            _name(env, point, seed),
            load_config(
                overrides={
                    "env": env,
                    "policy": "snn",
                    "track": "small_S",
                    "seed": seed,
                    "total_steps": steps,
                },
                sets=POINTS[point],
            ),
        )
        for point, seed in jobs
        if not (runs / _name(env, point, seed) / "deploy-fixed" / "deploy.json").is_file()
    ]
    for result in LocalPool(runs, jobs=workers).run(specs, Silent()):
        if result.status not in ("done", "reused"):
            raise SystemExit(f"{result.name}: {result.status} ({result.error})")


def one_run(env: str, point: str, seed: int, episodes: int, runs: Path) -> dict[str, Any]:
    """Export and deploy a trained run (unless deployed already); its record."""
    run_dir = runs / _name(env, point, seed)
    deploy_dir = run_dir / "deploy-fixed"
    start = time.perf_counter()
    if not (deploy_dir / "deploy.json").is_file():
        _snnkart("export", "--nir", str(run_dir), "--out", str(run_dir / "policy.nir"))
        _snnkart("deploy", str(run_dir / "policy.nir"), "--backend", "nir-ref",
                 "--precision", "fixed", "--episodes", str(episodes), "--seed", "10000",
                 "--out", str(deploy_dir))  # fmt: skip
    seconds = time.perf_counter() - start  # 0-ish when the run was deployed already
    timed = training_seconds(run_dir)
    train_seconds = timed[0] if timed else None
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
        "overhead_spikes_per_step": [s / n for s in counts["pipeline_overhead"]["spikes"]],
        "overhead_synops_per_step": [s / n for s in counts["pipeline_overhead"]["synops"]],
        "overhead_neuron_updates_per_step": [
            s / n for s in counts["pipeline_overhead"]["neuron_updates"]
        ],
        "encoding": record["manifest"]["encoding"],
        "action_mode": record["manifest"]["action_mode"],
        "seconds": seconds,
        "train_seconds": train_seconds,
        "deploy_json": str(deploy_dir / "deploy.json"),
    }


def summarise(results: dict[str, Any]) -> dict[str, Any]:
    """Per point, over its seeds: success and counts (median, min, max); the energy per
    inference on each neuromorphic profile with the host work on each digital profile
    (``nj_per_inference[chip][digital]``, median over seeds) against the 64-64 and the
    same-width ANN on that digital profile; and whether the point meets the issue's goal
    against the dense default: >= 95 % of its success, >= 10x fewer synaptic ops, T <= 4."""
    import statistics

    from snnkart.energy.counts import AnnCounts, SnnCounts
    from snnkart.energy.pricing import ann_terms, snn_terms, total
    from snnkart.energy.profiles import DEFAULT_CHIPS, DEFAULT_DIGITAL, load_profile

    chips = [load_profile(n) for n in DEFAULT_CHIPS]
    digital = [load_profile(n) for n in DEFAULT_DIGITAL]

    def spread(values: list[float]) -> dict[str, float]:
        return {"median": statistics.median(values), "min": min(values), "max": max(values)}

    def nj(runs: list[dict[str, Any]], chip: Any, host: Any) -> float:
        return statistics.median(total(snn_terms(SnnCounts.of_sweep(r), chip, host)) / 1e3
                                 for r in runs)  # fmt: skip

    net = results["runs"][0]["network"]
    ann_nj = {d.name: total(ann_terms(AnnCounts((net["n_in"], 64, 64, net["n_out"])), d)) / 1e3
              for d in digital}  # fmt: skip
    points: dict[str, Any] = {}
    for name in dict.fromkeys(r["point"] for r in results["runs"]):
        runs = [r for r in results["runs"] if r["point"] == name]
        same = AnnCounts((net["n_in"], *runs[0]["sizes"], net["n_out"]))
        energies = {c.name: {d.name: nj(runs, c, d) for d in digital} for c in chips}
        same_nj = {d.name: total(ann_terms(same, d)) / 1e3 for d in digital}
        points[name] = {
            "settings": runs[0]["settings"], "num_steps": runs[0]["num_steps"],
            "sizes": runs[0]["sizes"], "seeds": [r["seed"] for r in runs],
            "success_rate": spread([r["success_rate"] for r in runs]),
            "synops_per_inference": spread([sum(r["synops_per_step"][:-1]) for r in runs]),
            "spikes_per_inference": spread([sum(r["spikes_per_step"]) for r in runs]),
            "nj_per_inference": energies,
            "ann_same_width_nj_per_inference": same_nj,
            "ratio_vs_ann_same_width": {f"{c} vs {d}": e / same_nj[d] for c, row in energies.items()
                                        for d, e in row.items()},
            "ratio_vs_ann_64_64": {f"{c} vs {d}": e / ann_nj[d] for c, row in energies.items()
                                   for d, e in row.items()},
        }  # fmt: skip
    dense = points.get("default")
    for p in points.values():
        if dense:
            p["meets_goal"] = (
                p["success_rate"]["median"] >= 0.95 * dense["success_rate"]["median"]
                and p["synops_per_inference"]["median"] * 10
                <= dense["synops_per_inference"]["median"]
                and p["num_steps"] <= 4
            )
    return {"host_profile": "the ANN's digital profile", "ann_64_64_nj_per_inference": ann_nj,
            "points": points}  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="grid")
    parser.add_argument("--points", nargs="+", default=list(POINTS), choices=list(POINTS))
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--runs", type=Path, default=ROOT / "runs" / "bench_sparsity")
    parser.add_argument(
        "--summarise",
        type=Path,
        metavar="JSON",
        help="only add the per-point summary (with energies) to a results file",
    )
    add_out_argument(parser)
    args = parser.parse_args()
    if args.summarise is not None:
        data = json.loads(args.summarise.read_text())
        data["summary"] = summarise(data)
        data["summary_commit"] = git_commit()
        args.summarise.write_text(json.dumps(data, indent=2) + "\n")
        _print_summary(data["summary"])
        return

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
    train_all(args.env, jobs, args.steps, args.runs, args.jobs)
    for p, seed in jobs:
        r = one_run(args.env, p, seed, args.episodes, args.runs)
        results["runs"].append(r)
        path.write_text(json.dumps(results, indent=2) + "\n")
        print(
            f"{r['point']:14s} seed {r['seed']}: success {r['success_rate']:.0%}, "
            f"synops/step {sum(r['synops_per_step']):,.0f}, "
            f"spikes/step {sum(r['spikes_per_step']):,.1f}, trained in {r['train_seconds']:.0f} s",
            flush=True,
        )
    results["summary"] = summarise(results)
    path.write_text(json.dumps(results, indent=2) + "\n")
    _print_summary(results["summary"])
    print(f"results written to {path}")


def _print_summary(summary: dict[str, Any]) -> None:
    ann = summary["ann_64_64_nj_per_inference"]
    print("ANN 64-64 nJ/inference: " + ", ".join(f"{k} {v:.3g}" for k, v in ann.items()))
    for name, p in summary["points"].items():
        s, syn = p["success_rate"], p["synops_per_inference"]
        print(f"{name:14s} success {s['median']:.0%} ({s['min']:.0%}-{s['max']:.0%}), synops "
              f"{syn['median']:,.0f}, loihi1 {p['nj_per_inference']['loihi1'][HOST]:.3g} nJ "
              f"({p['ratio_vs_ann_same_width']['loihi1 vs horowitz45_fp32_sram']:.2f}x the "
              "same-width fp32+SRAM ANN), "
              f"goal {'met' if p.get('meets_goal') else 'not met'}")  # fmt: skip


if __name__ == "__main__":
    main()
