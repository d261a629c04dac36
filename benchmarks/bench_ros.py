"""ROS control-loop latency: message in -> Twist out, per backend, side by side in one run.

The bridge pair (``snnkart ros sim --lock-step`` and ``snnkart ros drive``) over a rosmaster
on loopback drives one seeded episode of the pretrained gazebo SNN
(``tests/data/policies/gazebo-snn``) on each backend: torch (the trained policy), nir-ref fixed
and lava-sim fixed (its export), in lock-step. Per backend: the node's median and
95th-percentile time from the (scan, odom) pair to the published Twist, the steps, the lap
time, and the wall-clock per simulated step (the round trip through ROS included); and the
torch policy in real time (60 steps per second) over several runs (real time is not
repeatable): how many finish, their lap times, and the driver's commands per simulated step.

    python -m benchmarks.bench_ros [--policy DIR] [--real-time-runs N]

Results go to ``benchmarks/results/bench_ros-<commit>.json``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from benchmarks.common import add_out_argument, machine_info, output_path
from snnkart.ros.master import ros_env, rosmaster

POLICY = Path(__file__).resolve().parents[1] / "tests" / "data" / "policies" / "gazebo-snn"
SNNKART = str(Path(sys.executable).with_name("snnkart"))


def bridge(policy: Path, backend: str, seed: int, work: Path, mode: str = "--lock-step") -> dict:
    out = work / f"sim-{backend}{mode}.json"
    with rosmaster() as uri:
        env = ros_env(uri)
        sim = subprocess.Popen([SNNKART, "ros", "sim", "--policy", str(policy), mode,
                                "--seed", str(seed),
                                "--out", str(out)], env=env, text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
        drive = subprocess.run([SNNKART, "ros", "drive", str(policy), "--backend", backend,
                                mode, "--max-seconds", "300", "--timeout", "20"],
                               env=env, text=True, capture_output=True, timeout=400)  # fmt: skip
        sim.communicate(timeout=60)
    if drive.returncode != 0:
        raise SystemExit(f"{backend}: {drive.stderr[-1000:]}")
    record = json.loads(out.read_text())
    node = json.loads(drive.stdout.strip().splitlines()[-1])
    return {
        "steps": record["steps"],
        "ended": record["ended"],
        "lap_time_s": record["lap_time"],
        "latency_ms_median": node["latency_ms_median"],
        "latency_ms_p95": node["latency_ms_p95"],
        "commands_per_step": node["commands"] / max(record["steps"], 1),
        "wall_ms_per_step": 1000 * record["wall_seconds"] / max(record["steps"], 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", type=Path, default=POLICY)
    parser.add_argument("--seed", type=int, default=10_000)
    parser.add_argument("--real-time-runs", type=int, default=5)
    add_out_argument(parser)
    args = parser.parse_args()
    from snnkart.export.nir_export import export_nir
    from snnkart.rl.trained import load_run

    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        nir_path, _ = export_nir(load_run(args.policy), work / "policy.nir")
        for backend, policy in (("torch", args.policy), ("nir-ref", nir_path),
                                ("lava-sim", nir_path)):  # fmt: skip
            results[backend] = bridge(policy, backend, args.seed, work)
            print(backend, results[backend])
        runs = [bridge(args.policy, "torch", args.seed, work, "--real-time")
                for _ in range(args.real_time_runs)]  # fmt: skip
        laps = [r["lap_time_s"] for r in runs if r["ended"] == "finished"]
        real_time = {"runs": runs, "finished": f"{len(laps)}/{len(runs)}",
                     "lap_time_s_min_max": [min(laps), max(laps)] if laps else None}  # fmt: skip
        print("torch in real time", real_time)
    base = results["torch"]["latency_ms_median"]
    ratios = {k: v["latency_ms_median"] / base for k, v in results.items()}
    out = output_path("bench_ros", args.out)
    out.write_text(json.dumps({"machine": machine_info(), "policy": str(args.policy),
                               "seed": args.seed, "backends": results,
                               "torch_real_time": real_time,
                               "latency_vs_torch": ratios}, indent=2) + "\n")  # fmt: skip
    print(f"wrote {out}; median latency relative to torch: {ratios}")


if __name__ == "__main__":
    main()
