"""Environment speed: steps/s of each env on big_S without rendering, single and vectorised.

Also measures, side by side in the same run, the compiled LIDAR against per-ray pymunk
``segment_query_first`` calls on the same space and rays (the fastest pure-pymunk way; the
original used the slower all-hits ``segment_query``), checks that both give the same distances,
and prints the ratio. Results go to ``benchmarks/results/bench_env-<commit>.json``.

    python -m benchmarks.bench_env [--steps 20000] [--vector-envs 8]

Target (issue 2): >= 10,000 steps/s for one steer env from ``gymnasium.make`` at default
settings on one core (the original managed about 110 steps/s).
"""

from __future__ import annotations

import argparse
import json
import math
import time

import gymnasium as gym
import numpy as np
import pymunk

import snnkart  # noqa: F401  (registers the envs)
from benchmarks.common import add_out_argument, machine_info, output_path
from snnkart.envs import ENV_IDS
from snnkart.envs.lidar import cast_rays


def steps_per_second(env: gym.Env, steps: int, seed: int = 0) -> float:
    env.reset(seed=seed)
    env.action_space.seed(seed)
    actions = [env.action_space.sample() for _ in range(steps)]
    start = time.perf_counter()
    for a in actions:
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - start)


def vector_steps_per_second(env_id: str, n_envs: int, steps: int) -> float:
    envs = gym.vector.SyncVectorEnv([lambda: gym.make(env_id, track="big_S")] * n_envs)
    envs.reset(seed=0)
    envs.action_space.seed(0)
    actions = [envs.action_space.sample() for _ in range(steps // n_envs)]
    start = time.perf_counter()
    for a in actions:
        envs.step(a)
    rate = len(actions) * n_envs / (time.perf_counter() - start)
    envs.close()
    return rate


def lidar_side_by_side(n_rays: int, queries: int) -> dict[str, float]:
    """Compiled ray casting vs pymunk per-ray queries at random poses inside big_S."""
    env = gym.make(ENV_IDS["steer"], track="big_S").unwrapped
    space: pymunk.Space = env._space
    segments = env._segments
    rng = np.random.default_rng(1)
    xmin, ymin, xmax, ymax = env.track.bounds
    poses = np.column_stack(
        [
            rng.uniform(xmin, xmax, queries),
            rng.uniform(ymin, ymax, queries),
            rng.uniform(-math.pi, math.pi, queries),
        ]
    )
    offsets = -math.pi + np.arange(n_rays) * (2 * math.pi / n_rays)
    rng_px = 300.0
    out = np.empty(n_rays)
    wall_filter = pymunk.ShapeFilter(mask=0b010)

    start = time.perf_counter()
    for x, y, h in poses:
        cast_rays(x, y, offsets + h, segments, rng_px, out)
    compiled = (time.perf_counter() - start) / queries

    worst = 0.0
    start = time.perf_counter()
    for x, y, h in poses:
        for k, a in enumerate(offsets + h):
            hit = space.segment_query_first(
                (x, y), (x + rng_px * math.cos(a), y + rng_px * math.sin(a)), 0.0, wall_filter
            )
            d = 1.0 if hit is None else hit.alpha
            out[k] = d
    pymunk_time = (time.perf_counter() - start) / queries
    ref = np.empty(n_rays)
    for x, y, h in poses[:200]:
        cast_rays(x, y, offsets + h, segments, rng_px, ref)
        for k, a in enumerate(offsets + h):
            hit = space.segment_query_first(
                (x, y), (x + rng_px * math.cos(a), y + rng_px * math.sin(a)), 0.0, wall_filter
            )
            worst = max(worst, abs(ref[k] - (1.0 if hit is None else hit.alpha)))
    env.close()
    return {
        "n_rays": n_rays,
        "compiled_us_per_scan": compiled * 1e6,
        "pymunk_us_per_scan": pymunk_time * 1e6,
        "speedup": pymunk_time / compiled,
        "max_abs_difference": worst,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=20000)
    parser.add_argument("--vector-envs", type=int, default=8)
    add_out_argument(parser)
    args = parser.parse_args()

    results: dict[str, object] = {"machine": machine_info(), "steps": args.steps}
    # Warm up (numba compile / cache load, pymunk) outside the timings.
    steps_per_second(gym.make(ENV_IDS["steer"], track="big_S"), 500)
    per_env = {}
    for name, env_id in ENV_IDS.items():
        single = steps_per_second(gym.make(env_id, track="big_S"), args.steps)
        vector = vector_steps_per_second(env_id, args.vector_envs, args.steps)
        per_env[name] = {"single_steps_per_s": single, "sync_vector_steps_per_s": vector}
        print(
            f"{name:7s} single {single:9.0f} steps/s   sync-vector x{args.vector_envs} "
            f"{vector:9.0f} steps/s"
        )
    results["envs"] = per_env
    steer = per_env["steer"]["single_steps_per_s"]
    results["target_steer_steps_per_s"] = 10000
    results["steer_vs_target"] = steer / 10000
    results["steer_vs_original_110"] = steer / 110
    print(
        f"steer single vs target 10,000: {steer / 10000:.2f}x; vs the original's ~110 steps/s: "
        f"{steer / 110:.0f}x"
    )
    for n in (16, 59):
        lid = lidar_side_by_side(n, 2000)
        results[f"lidar_{n}_rays"] = lid
        print(
            f"LIDAR {n} rays: compiled {lid['compiled_us_per_scan']:.1f} us, pymunk queries "
            f"{lid['pymunk_us_per_scan']:.1f} us per scan -> {lid['speedup']:.1f}x "
            f"(max |difference| {lid['max_abs_difference']:.2e})"
        )
    path = output_path("bench_env", args.out)
    path.write_text(json.dumps(results, indent=2) + "\n")
    print(f"results written to {path}")


if __name__ == "__main__":
    main()
