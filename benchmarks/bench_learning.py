"""Learning, not just running: ANN and SNN on small_S (or other tracks) in every env, several seeds.

For each env x policy x seed this trains with the default settings for ``--steps`` env steps
(``snnkart train``), then evaluates the final deterministic policy on 20 seeded episodes
(``snnkart eval``). It records the step of the first finished training episode and the
evaluation success rate. Targets (issue 3): first finish within 200,000 steps and at least
80 % evaluation success by 300,000 steps, for 3 of 3 seeds, ANN and SNN, every env.

Runs go through the launcher's local process pool (``snnkart.app.launch.LocalPool``: one
torch thread each, ``--jobs`` at a time; finished runs are reused and interrupted ones
resumed), then each is evaluated; results are written to the JSON after every evaluation.

    python -m benchmarks.bench_learning [--envs grid gazebo steer] [--policies ann snn]
                                        [--seeds 1 2 3] [--tracks small_S FILE.toml ...]
                                        [--steps 300000] [--jobs 2]
                                        [--eval-episodes 20] [--out FILE]
                                        [--set ppo.ent_coef=0.02 ...]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from benchmarks.common import add_out_argument, git_commit, machine_info, output_path

ROOT = Path(__file__).resolve().parents[1]
SNNKART = [sys.executable, "-m", "snnkart.cli"]


def _set_aside_foreign(run_dir: Path, commit: str) -> None:
    """Resume an interrupted run only if the same code made it; set an older one aside."""
    marker = run_dir / "bench_commit"
    if run_dir.exists() and (not marker.is_file() or marker.read_text().strip() != commit):
        old = marker.read_text().strip() if marker.is_file() else "unknown"
        run_dir.rename(run_dir.with_name(f"{run_dir.name}.{old}.{int(time.time())}"))
    run_dir.mkdir(parents=True, exist_ok=True)
    marker.write_text(commit + "\n")


def evaluate(
    result: Any, env: str, policy: str, seed: int, episodes: int, track: str = "small_S"
) -> dict[str, Any]:
    """Score a trained run on seeded episodes (``snnkart eval``) and make its record."""
    run_dir = Path(result.run_dir)
    subprocess.run(
        [*SNNKART, "eval", str(run_dir), "--episodes", str(episodes), "--seed", "10000"],
        check=True, cwd=ROOT, capture_output=True, text=True,
    )  # fmt: skip
    evaluation = json.loads((run_dir / "eval.json").read_text())["summary"]
    first = result.first_finish_step
    return {
        "env": env,
        "track": track,
        "policy": policy,
        "seed": seed,
        "steps": result.global_step,
        "first_finish_step": first,
        "training_finishes": result.finishes,
        "training_episodes": result.episodes,
        "eval_success_rate": evaluation["success_rate"],
        "eval_mean_lap_time": evaluation["mean_lap_time"],
        "eval_crashes": evaluation["crashes"],
        "train_seconds": result.seconds,
        "first_finish_within_200k": first is not None and first <= 200_000,
        "eval_success_at_least_80pct": evaluation["success_rate"] >= 0.8,
        "run_dir": str(run_dir),
    }


def _run_name(track: str, env: str, policy: str, seed: int) -> str:
    prefix = "" if track == "small_S" else f"{Path(track).stem}-"
    return f"{prefix}{env}-{policy}-s{seed}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--envs", nargs="+", default=["grid", "gazebo", "steer"])
    parser.add_argument("--policies", nargs="+", default=["ann", "snn"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    parser.add_argument(
        "--tracks", nargs="+", default=["small_S"],
        help="built-in track names or TOML files (e.g. benchmarks/tracks/*.toml)",
    )  # fmt: skip
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
    from snnkart.app.launch import LocalPool, RunSpec
    from snnkart.app.reporter import Silent
    from snnkart.rl.config import load_config

    jobs = [(t, e, p, s) for t in args.tracks for e in args.envs for p in args.policies
            for s in args.seeds]  # fmt: skip
    commit = git_commit()
    specs = []
    for t, e, p, seed in jobs:
        name = _run_name(t, e, p, seed)
        _set_aside_foreign(args.runs / name, commit)
        config = load_config(overrides={"env": e, "policy": p, "track": t, "seed": seed,
                                        "total_steps": args.steps}, sets=args.sets)  # fmt: skip
        specs.append(RunSpec(name, config))
    start = time.perf_counter()
    trained = LocalPool(args.runs, jobs=args.jobs).run(specs, Silent())
    train_wall = time.perf_counter() - start
    for (t, e, p, seed), result in zip(jobs, trained, strict=True):
        if result.status not in ("done", "reused"):
            raise SystemExit(f"{result.name}: {result.status} ({result.error})")
        r = evaluate(result, e, p, seed, args.eval_episodes, t)
        results["runs"].append(r)
        path.write_text(json.dumps(results, indent=2) + "\n")
        first = r["first_finish_step"]
        print(
            f"{Path(t).stem} {r['env']:6s} {r['policy']} seed {r['seed']}: first finish "
            f"{'never' if first is None else f'{first:,}'}, eval success "
            f"{r['eval_success_rate']:.0%}, {r['train_seconds']:.0f} s",
            flush=True,
        )
    # The study's wall-clock (issue 16's target: the 30-run small_S study within 45 minutes on
    # two cores); meaningful only when no run was reused from an earlier invocation.
    results["wall_clock"] = {
        "train_seconds": train_wall,
        "eval_seconds": time.perf_counter() - start - train_wall,
        "total_seconds": time.perf_counter() - start,
        "jobs": args.jobs,
        "runs": len(trained),
        "runs_reused": sum(r.status == "reused" for r in trained),
    }
    path.write_text(json.dumps(results, indent=2) + "\n")
    w = results["wall_clock"]
    print(
        f"wall-clock: {w['total_seconds'] / 60:.1f} min for {w['runs']} runs "
        f"({w['train_seconds'] / 60:.1f} training on {args.jobs} jobs, "
        f"{w['eval_seconds'] / 60:.1f} evaluation; {w['runs_reused']} reused)"
    )
    print("\nsummary (runs meeting the target / runs):")
    for t in args.tracks:
        for e in args.envs:
            for p in args.policies:
                rs = [r for r in results["runs"]
                      if r["track"] == t and r["env"] == e and r["policy"] == p]  # fmt: skip
                ff = sum(r["first_finish_within_200k"] for r in rs)
                ok = sum(r["eval_success_at_least_80pct"] for r in rs)
                anyf = sum(r["first_finish_step"] is not None for r in rs)
                print(f"  {Path(t).stem} {e:6s} {p}: first finish {anyf}/{len(rs)}, within 200k "
                      f"{ff}/{len(rs)}, eval >= 80 % {ok}/{len(rs)}")  # fmt: skip
    print(f"results written to {path}")


if __name__ == "__main__":
    main()
