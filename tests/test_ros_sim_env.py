"""``snnkart ros sim --policy``: the simulator runs the env the driving policy was trained for,
and refuses another track before ROS starts (no rosmaster needed): the driver would compute
its checkpoint features on the policy's track, silently wrong on another one."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from tiny_runs import train_tiny
from typer.testing import CliRunner

from snnkart.app.ros_bridge import sim_env
from snnkart.cli import app
from snnkart.envs.spec import env_spec, spec_hash
from snnkart.errors import DeployError
from snnkart.export.nir_export import export_nir
from snnkart.rl.trained import load_run

POLICIES = Path(__file__).parent / "data" / "policies"
GAZEBO = POLICIES / "gazebo-snn"  # trained on small_S


def _trained_hash(run_dir: Path) -> str:
    return json.loads((run_dir / "checkpoint.json").read_text())["env_spec_hash"]


def test_another_track_than_the_policys_is_refused_in_one_line(tmp_path: Path) -> None:
    out = tmp_path / "sim.json"
    result = CliRunner().invoke(
        app, ["ros", "sim", "--policy", str(GAZEBO), "--track", "big_S", "--out", str(out)]
    )
    assert result.exit_code == 2, result.output
    (line,) = result.output.strip().splitlines()
    assert line.startswith("error: --track big_S is not the track") and "(small_S)" in line
    assert "drop --track" in line and not out.exists()
    nir_file, _ = export_nir(load_run(GAZEBO), tmp_path / "policy.nir")
    with pytest.raises(DeployError, match=r"--track big_S is not the track .*\(small_S\)"):
        sim_env(nir_file, "big_S")


def test_the_sim_runs_the_env_the_policy_was_trained_for(tmp_path: Path) -> None:
    env = sim_env(GAZEBO, "small_S")  # its own track, named: accepted
    try:
        assert spec_hash(env_spec(env.unwrapped)) == _trained_hash(GAZEBO)
    finally:
        env.close()
    # a non-default env config (8 LIDAR rays) comes with the policy, as the driver sees it
    run = train_tiny(tmp_path / "rays", "gazebo", "snn", total_steps=256,
                     extra_sets=["env_config.lidar.n_rays=8"])  # fmt: skip
    for policy in (run, export_nir(load_run(run), tmp_path / "rays.nir")[0]):
        env = sim_env(policy, None)
        try:
            assert spec_hash(env_spec(env.unwrapped)) == _trained_hash(run)
            assert env.observation_space.shape[0] == load_run(run).meta["env_spec"]["obs_dim"]
        finally:
            env.close()


def test_a_policy_for_another_env_is_refused() -> None:
    with pytest.raises(DeployError, match="trained on the grid env; the ROS bridge drives"):
        sim_env(POLICIES / "grid-snn", None)
