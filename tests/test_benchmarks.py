"""Every benchmark runs, at tiny sizes, and what it measures side by side is like for like.
(Learning and sparsity are studies now, ``studies/learning.toml`` and ``studies/sparsity.toml``,
tested with ``snnkart study`` in tests/test_study*.py.)

The benchmarks are not run in full here (that is minutes to hours); these smoke runs keep them
from rotting and check the claims their ratios rest on: the same hyperparameters and schedules
for snnkart and Stable-Baselines3, the compiled LIDAR equal to pymunk's queries, Lava's actions
equal to the reference's, and each result traced to a machine, a commit and a policy.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import torch

ROOT = Path(__file__).resolve().parents[1]
FIXTURE = ROOT / "tests" / "data" / "policies" / "grid-snn"


def run_benchmark(name: str, *args: str, timeout: float) -> None:
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy"}
    result = subprocess.run(
        [sys.executable, "-m", f"benchmarks.{name}", *args],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr


def check_machine(results: dict) -> None:
    machine = results["machine"]
    assert machine["commit"] and machine["commit"] != "unknown"
    assert machine["cores"] >= 1 and machine["python"].startswith("3.")


@pytest.mark.timeout(240)
def test_bench_train_gives_sb3_the_same_hyperparameters_and_schedules(tmp_path, monkeypatch):
    pytest.importorskip("stable_baselines3", reason="optional: pip install -e '.[bench]'")
    from benchmarks import bench_train

    out = tmp_path / "train.json"
    threads = torch.get_num_threads()
    monkeypatch.setattr(
        sys, "argv", ["bench_train", "--iterations", "3", "--num-steps", "32", "--out", str(out)]
    )
    try:
        bench_train.main()
    finally:
        torch.set_num_threads(threads)
    results = json.loads(out.read_text())
    check_machine(results)
    ours, sb3 = results["snnkart_ann"], results["sb3_ppo"]
    # Read back from SB3's own objects, not from the arguments the benchmark passed.
    assert results["hyperparameter_differences"] == {}
    assert results["same_hyperparameters"] is True
    assert ours["hyperparameters"] == sb3["hyperparameters"]
    # The schedules each update used: annealed linearly to zero, the same on both sides.
    assert sb3["learning_rate_per_iteration"] == pytest.approx([3e-4, 2e-4, 1e-4], rel=1e-9)
    assert ours["learning_rate_per_iteration"] == pytest.approx([3e-4, 2e-4, 1e-4], rel=1e-9)
    assert sb3["ent_coef_per_iteration"] == pytest.approx([0.01, 0.01 * 2 / 3, 0.01 / 3])
    assert ours["ent_coef_per_iteration"] == pytest.approx(sb3["ent_coef_per_iteration"])
    for side in ("snnkart_ann", "snnkart_snn_T8", "sb3_ppo"):
        assert results[side]["steps"] == 3 * 8 * 32
    assert results["ann_vs_sb3"] == pytest.approx(ours["steps_per_s"] / sb3["steps_per_s"])


def test_bench_train_names_a_difference():
    """The comparison itself can fail: a constant learning rate on one side is reported."""
    from benchmarks.bench_train import differences

    a = {"hyperparameters": {"gamma": 0.995, "n_steps": 256},
         "learning_rate_per_iteration": [3e-4, 2e-4], "ent_coef_per_iteration": [0.01, 0.005]}  # fmt: skip
    b = {"hyperparameters": {"gamma": 0.99, "n_steps": 256},
         "learning_rate_per_iteration": [3e-4, 3e-4], "ent_coef_per_iteration": [0.01, 0.005]}  # fmt: skip
    assert set(differences(a, b)) == {"gamma", "learning_rate_per_iteration"}
    assert differences(a, a) == {}


@pytest.mark.timeout(120)
def test_bench_env_runs_and_its_lidar_equals_pymunk(tmp_path):
    out = tmp_path / "env.json"
    run_benchmark("bench_env", "--steps", "300", "--vector-envs", "2", "--out", str(out),
                  timeout=110)  # fmt: skip
    results = json.loads(out.read_text())
    check_machine(results)
    assert set(results["envs"]) == {"grid", "gazebo", "steer"}
    for rays in (16, 59):
        lidar = results[f"lidar_{rays}_rays"]
        assert lidar["max_abs_difference"] < 1e-9  # the compiled scan is pymunk's, faster
        assert lidar["speedup"] == pytest.approx(
            lidar["pymunk_us_per_scan"] / lidar["compiled_us_per_scan"]
        )


@pytest.mark.lava
@pytest.mark.timeout(150)
def test_bench_deploy_runs_and_lava_acts_as_the_reference(tmp_path):
    out = tmp_path / "deploy.json"
    run_benchmark("bench_deploy", "--run", str(FIXTURE), "--steps", "40", "--out", str(out),
                  timeout=140)  # fmt: skip
    results = json.loads(out.read_text())
    check_machine(results)
    policy = results["policy"]
    assert policy["run"] == str(FIXTURE) and policy["env"] == "grid"
    assert policy["global_step"] > 0 and policy["checkpoint_versions"]
    backends = results["backends"]
    for lava in ("lava-sim float", "lava-sim fixed"):
        assert backends[lava]["identical_actions_to_reference"] == 1.0
        assert backends[lava]["ms_per_env_step"] > 0


@pytest.mark.lava
@pytest.mark.timeout(240)
def test_bench_main_job_runs_the_demo_end_to_end(tmp_path):
    """The README's main job (``snnkart demo``) on the committed driving policy: all six
    stages run, Lava matches the reference on every env step, the energy report is written
    against a (briefly trained) ANN baseline, and the numbers are gathered."""
    out = tmp_path / "main_job.json"
    run_benchmark(
        "bench_main_job", "--steps", "1000", "--ann-steps", "2048", "--lava-episodes", "1",
        "--eval-episodes", "5",
        "--runs", str(tmp_path / "demo"), "--from-run", str(FIXTURE), "--out", str(out),
        timeout=230,
    )  # fmt: skip
    results = json.loads(out.read_text())
    check_machine(results)
    report = results["report"]
    assert report["drives"] and report["ann_widths"] == [21, 64, 64, 5]
    assert report["ann_success_rate"] is not None and report["synops_per_inference"] > 0
    assert "loihi1 vs horowitz45_fp32_sram" in report["nj_per_inference"]
    assert (tmp_path / "demo" / "report" / "report.html").is_file()
    assert (
        results["training"]["global_step"]
        == json.loads((FIXTURE / "checkpoint.json").read_text())["global_step"]
    )  # the demo reused the run instead of training
    quant = results["torch_vs_fixed_point"]
    assert quant["episodes"] == 5
    assert quant["torch_success_rate"] >= 0.8 and quant["fixed_point_success_rate"] >= 0.8
    for precision, episodes in (("fixed", 1), ("float", 2)):
        lava = results["lava"][precision]
        assert lava["episodes"] == episodes and lava["env_steps"] > 100
        assert lava["mismatched_windows"] == 0 and lava["mismatched_actions"] == 0
        assert lava["float32_identical_action_fraction"] >= 0.95


@pytest.mark.timeout(300)
def test_bench_ros_measures_every_backend_over_a_real_rosmaster(tmp_path):
    import shutil

    if shutil.which("rosmaster") is None:
        pytest.skip("optional: ROS 1 is not installed (apt-get install python3-rospy ...)")
    out = tmp_path / "ros.json"
    run_benchmark("bench_ros", "--out", str(out), "--real-time-runs", "2", timeout=280)
    results = json.loads(out.read_text())
    check_machine(results)
    assert set(results["backends"]) == {"torch", "nir-ref", "lava-sim"}
    for backend in results["backends"].values():
        assert backend["ended"] == "finished" and backend["latency_ms_median"] > 0
    assert results["latency_vs_torch"]["torch"] == 1.0
    real_time = results["torch_real_time"]
    # in real time the trajectory depends on which ticks the machine's load drops, and the
    # small test policy may then crash (1 of 2 once, beside a two-run study and the suite):
    # at least one run finishes, and every run ends as an episode ends
    assert len(real_time["runs"]) == 2 and real_time["finished"] in ("1/2", "2/2"), real_time
    assert {r["ended"] for r in real_time["runs"]} <= {"finished", "crashed", "ended"}
    # a control loop that sleeps after acting runs at 0.75 commands per step whatever the load;
    # the fixed-grid loop at 0.95-0.98 alone and 0.91-0.93 beside a Lava deploy (the suite
    # must pass while another snnkart job runs), where a busy moment may drop a few more ticks
    rates = [r["commands_per_step"] for r in real_time["runs"]]
    assert all(rate > 0.85 for rate in rates), rates


def test_bench_sim2real_trains_both_and_evaluates_each_in_both_envs(tmp_path):
    out = tmp_path / "s2r.json"
    run_benchmark("bench_sim2real", "--steps", "1024", "--episodes", "2", "--work",
                  str(tmp_path / "runs"), "--out", str(out), timeout=240)  # fmt: skip
    results = json.loads(out.read_text())
    check_machine(results)
    assert set(results["results"]) == {"trained clean", "trained with noise"}
    for by_env in results["results"].values():
        assert set(by_env) == {"clean env", "noisy env"}
    noisy = tmp_path / "runs" / "trained-with-noise" / "config.toml"
    assert "action_delay_steps = 2" in noisy.read_text()
