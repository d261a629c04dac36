"""Any gymnasium env end to end (issue 45's acceptance): a tiny run trained, evaluated from its
checkpoint, exported to NIR, read back, and deployed on Lava's simulated Loihi in fixed point
with 0 mismatched env steps against the reference: CartPole-v1 (Discrete actions), Pendulum-v1
(Box actions, a sigma-delta policy), an env of the tests' own by entry point (Dict
observations, Box actions) and one with MultiDiscrete actions (one categorical over the joint
actions). Then the refusals: another env's spaces, and a kart-only flag."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from snnkart.app.evaluate import run_eval
from snnkart.app.reporter import Silent
from snnkart.backends.loading import open_policy
from snnkart.contract.deploy_record import DeployRecord
from snnkart.contract.eval_record import EvalRecord
from snnkart.errors import DeployError, UsageError
from snnkart.eval.closed_loop import run_deploy
from snnkart.eval.request import DeployRequest
from snnkart.export.nir_export import export_nir
from snnkart.rl.config import TrainConfig
from snnkart.rl.ppo import train
from snnkart.rl.trained import load_run

pytest.importorskip("lava", reason="optional: lava-nc (the lava extra)")

ROOT = Path(__file__).resolve().parents[1]
TINY = {"total_steps": 512, "ppo": {"num_envs": 2, "rollout_steps": 128, "num_minibatches": 2}}


def _trained(tmp_path: Path, env: str, policy: str) -> Path:
    run_dir = tmp_path / "run"
    train(TrainConfig.model_validate({**TINY, "env": env, "policy": policy}), run_dir)
    return run_dir


@pytest.mark.timeout(600)
@pytest.mark.parametrize(
    ("env", "policy", "action_mode", "threshold"),
    [("CartPole-v1", "snn", "discrete", 475.0), ("Pendulum-v1", "sdnn", "continuous", None),
     ("my_envs:MyDictEnv", "snn", "continuous", None), ("my_envs:PickEnv", "snn", "discrete", None)],
)  # fmt: skip
def test_train_eval_export_deploy_fixed_bit_exact(
    env: str, policy: str, action_mode: str, threshold: float | None, tmp_path: Path
) -> None:
    run_dir = _trained(tmp_path, env, policy)
    record = run_eval(run_dir, 2, 7, None, False, None, tmp_path / "eval.json", Silent())
    data = json.loads((tmp_path / "eval.json").read_text())
    assert EvalRecord.read(tmp_path / "eval.json") == record
    assert "track" not in data and "success_rate" not in data["summary"]  # no kart keys
    assert "finished" not in data["episodes"][0] and data["env"] == env
    assert record.summary.reward_threshold == threshold
    assert (record.summary.solved is None) == (threshold is None)
    nir_file, _ = export_nir(load_run(run_dir), tmp_path / "policy.nir")
    opened = open_policy(nir_file)  # read back from the two files alone
    assert opened.manifest.env["env"] == env and opened.manifest.track is None
    assert opened.manifest.action_mode == action_mode
    request = DeployRequest(nir_file, "lava-sim", "fixed", 1, 11, out=tmp_path / "deploy")
    deployed = run_deploy(request)
    assert deployed.parity.env_steps > 0
    assert deployed.parity.same_arithmetic_mismatched_windows == 0
    assert deployed.parity.same_arithmetic_mismatched_actions == 0
    assert DeployRecord.read(tmp_path / "deploy" / "deploy.json").env.track is None


@pytest.mark.timeout(300)
def test_a_policy_is_refused_on_an_env_with_other_spaces(tmp_path: Path) -> None:
    run_dir = _trained(tmp_path, "CartPole-v1", "snn")
    nir_file, _ = export_nir(load_run(run_dir), tmp_path / "policy.nir")
    request = DeployRequest(nir_file, "nir-ref", "fixed", 1, 0, env="Acrobot-v1")
    with pytest.raises(DeployError, match=r"not the one the policy was trained on.*observation"):
        run_deploy(request)
    with pytest.raises(DeployError, match="--track is for the kart envs"):
        run_deploy(DeployRequest(nir_file, "nir-ref", "fixed", 1, 0, track="small_S"))
    with pytest.raises(UsageError, match="--track is for the kart envs"):
        run_eval(run_dir, 1, 0, None, False, None, None, Silent(), track="small_S")


@pytest.mark.timeout(300)
def test_replay_of_a_gymnasium_run_points_to_eval_video(tmp_path: Path) -> None:
    from snnkart.errors import ReplayError
    from snnkart.eval.ghosts import load_ghosts

    run_dir = _trained(tmp_path, "CartPole-v1", "ann")
    with pytest.raises(ReplayError, match=r"gymnasium env.*--video"):
        load_ghosts(run_dir)


@pytest.mark.timeout(600)
@pytest.mark.parametrize(
    ("env", "policy", "hz", "mark"),
    [("CartPole-v1", "snn", 50.0, "return >= the env's 475"),
     ("Pendulum-v1", "sdnn", 30.0, "none: Pendulum-v1 has no reward_threshold")],
)  # fmt: skip
def test_the_energy_report_prices_a_gymnasium_deployment_at_the_envs_rate(
    env: str, policy: str, hz: float, mark: str, tmp_path: Path
) -> None:
    """Static power over the env's own control period (render_fps), the task judged against
    the env's reward_threshold (per episode) or not at all; --control-hz overrides the rate."""
    import jsonschema

    from snnkart.app.report import build_report, run_report

    run_dir = _trained(tmp_path, env, policy)
    nir_file, _ = export_nir(load_run(run_dir), tmp_path / "policy.nir")
    run_deploy(DeployRequest(nir_file, "nir-ref", "fixed", 2, 0, out=tmp_path / "deploy"))
    deployed = DeployRecord.read(tmp_path / "deploy" / "deploy.json")
    assert deployed.env.control_hz == hz
    report = run_report(tmp_path / "deploy", None, None, None, Silent())
    schema = json.loads((ROOT / "snnkart/report/report.schema.json").read_text())
    jsonschema.validate(json.loads((tmp_path / "deploy" / "report.json").read_text()), schema)
    assert report["control"] == {"period_s": 1 / hz, "from": report["control"]["from"],
                                 "pass_mark": mark}  # fmt: skip
    assert "render_fps" in report["control"]["from"]
    rows = report["pricing"] if policy == "sdnn" else report["comparisons"]
    if policy == "snn":  # static power x the period, a term of the verdict
        assert {r["static"]["control_period_s"] for r in rows} == {1 / hz}
    page = (tmp_path / "deploy" / "report.md").read_text()
    if mark.startswith("none"):
        assert report["drives"] is None and "nothing judges" in page
    else:  # a 512-step CartPole policy falls over long before 475
        success = sum(e.episode_return >= 475 for e in deployed.episodes) / 2
        assert report["snn"]["task"]["success_rate"] == success and report["drives"] is False
        assert "does not do its task" in page
    again = build_report(tmp_path / "deploy", None, None, control_hz=5.0)
    assert again["control"]["period_s"] == 0.2 and again["control"]["from"] == "--control-hz 5"


@pytest.mark.timeout(600)
def test_report_ann_drives_the_users_ann_run_on_the_deployments_episodes(tmp_path: Path) -> None:
    """--ann on a gymnasium deployment: the ANN run (float and int8) driven on the deployment's
    episodes, its success the share of episodes reaching the env's reward_threshold (20 here);
    an ANN run of another env is refused."""
    from snnkart.app.report import build_report
    from snnkart.errors import ReportError

    env = "my_envs:CartPole20-v0"
    snn_dir, ann_dir = (
        _trained(tmp_path / "snn", env, "snn"),
        _trained(tmp_path / "ann", env, "ann"),
    )
    nir_file, _ = export_nir(load_run(snn_dir), tmp_path / "policy.nir")
    run_deploy(DeployRequest(nir_file, "nir-ref", "fixed", 6, 40, out=tmp_path / "deploy"))
    report = build_report(tmp_path / "deploy", ann_dir, None)
    task = report["ann"]["run"]["task"]  # type: ignore[index]
    by_hand = run_eval(ann_dir, 6, 40, None, False, None, None, Silent())
    share = sum(e.episode_return >= 20.0 for e in by_hand.episodes) / 6
    assert task["success_rate"] == share and task["mean_return"] == by_hand.summary.mean_return
    assert task["int8"]["success_rate"] is not None and task["int8"]["episodes"] == 6
    other = _trained(tmp_path / "other", "CartPole-v1", "ann")
    with pytest.raises(ReportError, match="compare policies of the same env"):
        build_report(tmp_path / "deploy", other, None)


@pytest.mark.timeout(300)
def test_the_report_of_an_env_without_a_rate_asks_for_one(tmp_path: Path) -> None:
    from snnkart.app.report import control_period
    from snnkart.errors import ReportError

    run_dir = _trained(tmp_path, "my_envs:TwoStepEnv", "snn")
    nir_file, _ = export_nir(load_run(run_dir), tmp_path / "policy.nir")
    run_deploy(DeployRequest(nir_file, "nir-ref", "fixed", 1, 0, out=tmp_path / "deploy"))
    record = DeployRecord.read(tmp_path / "deploy" / "deploy.json")
    with pytest.raises(ReportError, match=r"states no control rate.*pass --control-hz"):
        control_period(record, None)
    with pytest.raises(ReportError, match="--control-hz must be positive"):
        control_period(record, 0.0)
