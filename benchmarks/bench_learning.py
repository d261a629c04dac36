"""Learning, not just running: ANN and SNN on small_S in every env, several seeds.

For each env x policy x seed this trains with the default settings for ``--steps`` env steps
(``snnkart train``), then evaluates the final deterministic policy on 20 seeded episodes
(``snnkart eval``). It records the step of the first finished training episode and the
evaluation success rate. Targets (issue 3): first finish within 200,000 steps and at least
80 % evaluation success by 300,000 steps, for 3 of 3 seeds, ANN and SNN, every env.

Runs go two at a time (one torch thread each, 2 cores). Results are appended to the JSON
file after every run, so an interrupted benchmark keeps what it measured.

    python -m benchmarks.bench_learning [--envs grid gazebo steer] [--policies ann snn]
                                        [--seeds 1 2 3] [--steps 300000] [--jobs 2]
                                        [--eval-episodes 20] [--out FILE]
                                        [--set ppo.ent_coef=0.02 ...]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from benchmarks.common import add_out_argument, git_commit, machine_info, output_path

ROOT = Path(__file__).resolve().parents[1]
SNNKART = [sys.executable, "-m", "snnkart.cli"]


def one_run(
    env: str, policy: str, seed: int, steps: int, runs: Path, sets: list[str], episodes: int = 20
) -> dict[str, Any]:
    run_dir = runs / f"{env}-{policy}-s{seed}"
    # Resume an interrupted run only if the same code made it; set an older one aside.
    marker = run_dir / "bench_commit"
    commit = git_commit()
    if run_dir.exists() and (not marker.is_file() or marker.read_text().strip() != commit):
        old = marker.read_text().strip() if marker.is_file() else "unknown"
        run_dir.rename(run_dir.with_name(f"{run_dir.name}.{old}.{int(time.time())}"))
    run_dir.mkdir(parents=True, exist_ok=True)
    marker.write_text(commit + "\n")
    start = time.perf_counter()
    subprocess.run(
        [*SNNKART, "train", "--env", env, "--policy", policy, "--track", "small_S",
         "--seed", str(seed), "--steps", str(steps), "--out", str(run_dir)]
        + [arg for kv in sets for arg in ("--set", kv)]
        + (["--resume"] if (run_dir / "config.toml").exists() else []),
        check=True, cwd=ROOT, capture_output=True, text=True,
    )  # fmt: skip
    train_seconds = time.perf_counter() - start
    subprocess.run(
        [*SNNKART, "eval", str(run_dir), "--episodes", str(episodes), "--seed", "10000"],
        check=True, cwd=ROOT, capture_output=True, text=True,
    )  # fmt: skip
    evaluation = json.loads((run_dir / "eval.json").read_text())["summary"]
    meta = json.loads((run_dir / "checkpoint.json").read_text())
    first = meta["first_finish_step"]
    return {
        "env": env,
        "policy": policy,
        "seed": seed,
        "steps": meta["global_step"],
        "first_finish_step": None if first < 0 else first,
        "training_finishes": meta["finishes"],
        "training_episodes": meta["episodes"],
        "eval_success_rate": evaluation["success_rate"],
        "eval_mean_lap_time": evaluation["mean_lap_time"],
        "eval_crashes": evaluation["crashes"],
        "train_seconds": train_seconds,
        "first_finish_within_200k": first >= 0 and first <= 200_000,
        "eval_success_at_least_80pct": evaluation["success_rate"] >= 0.8,
        "run_dir": str(run_dir),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", nargs="+", default=["grid", "gazebo", "steer"])
    parser.add_argument("--policies", nargs="+", default=["ann", "snn"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    parser.add_argument("--steps", type=int, default=300_000)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--eval-episodes", type=int, default=20)
    parser.add_argument("--runs", type=Path, default=ROOT / "runs" / "bench_learning")
    parser.add_argument(
        "--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
        help="a non-default setting for every run (snnkart train --set), recorded in the JSON",
    )  # fmt: skip
    add_out_argument(parser)
    args = parser.parse_args()

    path = output_path("bench_learning", args.out)
    results: dict[str, Any] = {
        "machine": machine_info(),
        "steps": args.steps,
        "settings": args.sets,
        "eval_episodes": args.eval_episodes,
        "runs": [],
    }
    jobs = [(e, p, s) for e in args.envs for p in args.policies for s in args.seeds]
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        futures = [
            pool.submit(one_run, e, p, s, args.steps, args.runs, args.sets, args.eval_episodes)
            for e, p, s in jobs
        ]
        for fut in futures:
            r = fut.result()
            results["runs"].append(r)
            path.write_text(json.dumps(results, indent=2) + "\n")
            first = r["first_finish_step"]
            print(
                f"{r['env']:6s} {r['policy']} seed {r['seed']}: first finish "
                f"{'never' if first is None else f'{first:,}'}, eval success "
                f"{r['eval_success_rate']:.0%}, {r['train_seconds']:.0f} s",
                flush=True,
            )
    print("\nsummary (runs meeting the target / runs):")
    for e in args.envs:
        for p in args.policies:
            rs = [r for r in results["runs"] if r["env"] == e and r["policy"] == p]
            ff = sum(r["first_finish_within_200k"] for r in rs)
            ok = sum(r["eval_success_at_least_80pct"] for r in rs)
            print(f"  {e:6s} {p}: first finish <= 200k {ff}/{len(rs)}, eval >= 80 % {ok}/{len(rs)}")
    print(f"results written to {path}")


if __name__ == "__main__":
    main()
