"""The main job, measured: ``snnkart demo`` run as a user runs it, its results gathered in one JSON.

It trains the grid/small_S SNN (300k steps, seed 101: ``snnkart.app.pipeline.DEMO_SEED``), scores
the torch policy and its fixed-point twin on the same seeded episodes, exports to NIR and drives
the kart on Lava in fixed point and in float with every env step checked against the numpy
reference. The JSON keeps what docs/deployment.md quotes from it: training speed and first finish,
success of torch vs fixed point, Lava's parity with the reference, its agreement with the float32
policy, and ms per env step.

    python -m benchmarks.bench_main_job [--steps 400000] [--lava-episodes 5]
                                        [--eval-episodes 50] [--runs DIR] [--from-run RUN]
                                        [--out FILE]

``--from-run`` copies a trained run in as the demo's first stage (which then skips training).
Results go to ``benchmarks/results/bench_main_job-<commit>.json`` unless ``--out`` says otherwise.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from benchmarks.common import add_out_argument, machine_info, output_path, training_seconds

ROOT = Path(__file__).resolve().parents[1]


def training_speed(run_dir: Path) -> dict[str, Any]:
    """Env steps per second of training, from the run's per-iteration metrics."""
    timed = training_seconds(run_dir)
    if timed is None:
        return {"steps_per_s": None, "note": "no metrics.jsonl (a run copied in with --from-run)"}
    meta = json.loads((run_dir / "checkpoint.json").read_text())
    return {"steps_per_s": meta["global_step"] / timed[0], "iterations": timed[1]}


def deploy_summary(path: Path) -> dict[str, Any]:
    record = json.loads(path.read_text())
    parity, timing, summary = record["parity"], record["timing"], record["summary"]
    return {
        "episodes": summary["episodes"],
        "success_rate": summary["success_rate"],
        "env_steps": parity["env_steps"],
        "same_arithmetic_reference": parity["same_arithmetic_reference"],
        "mismatched_windows": parity["same_arithmetic_mismatched_windows"],
        "mismatched_actions": parity["same_arithmetic_mismatched_actions"],
        "float32_identical_action_fraction": parity["float32_identical_action_fraction"],
        "float32_spike_flips_per_million_neuron_steps": parity[
            "float32_spike_flips_per_million_neuron_steps"
        ],
        "ms_per_env_step": timing["ms_per_env_step"],
        "startup_s": timing["startup_s"],
        "spikes_per_env_step": [s / parity["env_steps"] for s in record["counts"]["spikes"]],
    }


def report_summary(path: Path) -> dict[str, Any]:
    """The energy report's headline: each SNN profile against the ANN run on each digital one."""
    report = json.loads(path.read_text())
    ann = report["ann"].get("run") or report["ann"]["same_width"]
    return {
        "drives": report["drives"],
        "snn_success_rate": report["snn"]["task"]["success_rate"],
        "ann_success_rate": (ann["task"] or {}).get("success_rate"),
        "ann_widths": ann["widths"],
        "synops_per_inference": sum(report["snn"]["per_inference"]["synops_chip"]),
        "spikes_per_inference": sum(report["snn"]["per_inference"]["spikes"]),
        "nj_per_inference": {
            f"{c['snn_profile']} vs {c['ann_profile']}": [c["snn_pj"] / 1e3, c["ann_pj"] / 1e3]
            for c in report["comparisons"]
            if c["ann"] == ("run" if "run" in report["ann"] else "same_width")
        },
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--ann-steps", type=int, default=300_000)
    parser.add_argument("--lava-episodes", type=int, default=20)
    parser.add_argument("--eval-episodes", type=int, default=50)
    parser.add_argument("--runs", type=Path, default=ROOT / "runs" / "bench_main_job")
    parser.add_argument("--from-run", type=Path, help="a trained grid SNN run to start from")
    add_out_argument(parser)
    args = parser.parse_args()

    out = args.runs
    if args.from_run is not None:
        if out.exists():
            raise SystemExit(f"{out} exists; --from-run needs a fresh --runs directory")
        shutil.copytree(args.from_run, out / "snn")
    command = [sys.executable, "-m", "snnkart.cli", "demo", "--out", str(out),
               "--steps", str(args.steps), "--ann-steps", str(args.ann_steps),
               "--lava-episodes", str(args.lava_episodes),
               "--eval-episodes", str(args.eval_episodes)]  # fmt: skip
    start = time.perf_counter()
    subprocess.run(command, check=True, cwd=ROOT)
    wall = time.perf_counter() - start

    meta = json.loads((out / "snn" / "checkpoint.json").read_text())
    quant = json.loads((out / "quantization.json").read_text())
    results = {
        "machine": machine_info(),
        "command": ["snnkart", *command[3:]],
        "from_run": str(args.from_run) if args.from_run else None,
        "wall_s": wall,
        "training": {
            "global_step": meta["global_step"],
            "first_finish_step": meta["first_finish_step"],
            "finishes": meta["finishes"],
            **training_speed(out / "snn"),
        },
        "torch_vs_fixed_point": {
            "episodes": quant["episodes"],
            "first_seed": quant["first_seed"],
            "torch_success_rate": quant["torch"]["success_rate"],
            "fixed_point_success_rate": quant["fixed_reference"]["success_rate"],
        },
        "lava": {
            precision: deploy_summary(out / f"deploy-lava-sim-{precision}" / "deploy.json")
            for precision in ("fixed", "float")
        },
        "report": report_summary(out / "report" / "report.json"),
    }
    q, lava = results["torch_vs_fixed_point"], results["lava"]
    print(f"training: {meta['global_step']:,} steps, first finish at {meta['first_finish_step']:,}")
    print(f"success on {q['episodes']} episodes: torch {q['torch_success_rate']:.0%}, "
          f"fixed point {q['fixed_point_success_rate']:.0%}")  # fmt: skip
    for precision, row in lava.items():
        print(f"Lava {precision}: {row['mismatched_windows']} of {row['env_steps']} env steps differ "
              f"from the reference; {row['float32_identical_action_fraction']:.1%} of actions as "
              f"float32; {row['ms_per_env_step']:.1f} ms per env step")  # fmt: skip
    path = output_path("bench_main_job", args.out)
    path.write_text(json.dumps(results, indent=2) + "\n")
    print(f"results written to {path}")


if __name__ == "__main__":
    main()
