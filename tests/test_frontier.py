"""The temporal-sparsity frontier study: its plan (every policy kind, the converted ANN trained
as a ReLU ANN) and the conversion on the fly that its evaluation (and ``snnkart eval
--sigma-delta``) uses."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import pytest
from tiny_runs import train_tiny
from typer.testing import CliRunner

from snnkart.app.study_eval import converted, eval_backend
from snnkart.app.study_run import load_study, plan
from snnkart.cli import app
from snnkart.contract.deploy_record import DeployRecord
from snnkart.energy.sigma_delta_counts import SigmaDeltaCounts
from snnkart.report.frontier import frontier
from snnkart.report.study_record import StudyRecord

ROOT = Path(__file__).resolve().parents[1]


def test_the_frontier_plans_every_kind_on_three_reporting_seeds() -> None:
    runs = plan(load_study(ROOT / "studies" / "frontier.toml"))
    assert len(runs) == 99
    kinds = {(r.policy, r.variant) for r in runs}
    assert ("snn", "stateful_t1") in kinds and ("sdnn", "p0.3_w32") in kinds
    assert ("ann-sd", "") in kinds and ("ann", "") in kinds
    for r in runs:
        cfg = r.spec.config
        assert r.seed in (101, 102, 103) and r.track == "small_S"
        assert (cfg.policy, cfg.ann.activation) == {"ann-sd": ("ann", "relu"),
                                                    "ann": ("ann", "tanh")}.get(
            r.policy, (r.policy, "tanh"))  # fmt: skip
        assert converted(r) == (r.policy == "ann-sd")
        assert eval_backend(r) == ("torch" if r.policy == "ann" else "nir-ref fixed")
        assert cfg.sdnn.calibration_target == 0.99
    stateful = [r for r in runs if r.variant.startswith("stateful")]
    assert stateful and all(r.spec.config.snn.stateful for r in stateful)


def test_eval_converts_a_relu_ann_run_with_sigma_delta(tmp_path: Path) -> None:
    """``eval RUN --backend nir-ref --sigma-delta`` runs the converted sigma-delta network
    (its counts are the sigma-delta ones); without ``--sigma-delta`` the ANN is refused, and
    ``--sigma-delta`` on torch is a one-line error naming the fix."""
    run = train_tiny(tmp_path / "ann", "grid", "ann", extra_sets=["ann.activation=relu",
                                                                  "sdnn.calibration_episodes=1"])  # fmt: skip
    out = tmp_path / "eval"
    result = CliRunner().invoke(app, ["eval", str(run), "--backend", "nir-ref", "--episodes",
                                      "1", "--sigma-delta", "--out", str(out)])  # fmt: skip
    assert result.exit_code == 0, result.output
    record = DeployRecord.read(out / "deploy.json")
    assert record.counts.sigma_delta is not None and record.counts.env_steps > 0
    plain = CliRunner().invoke(app, ["eval", str(run), "--backend", "nir-ref", "--episodes",
                                     "1", "--out", str(tmp_path / "plain")])  # fmt: skip
    assert plain.exit_code != 0
    torch_eval = CliRunner().invoke(app, ["eval", str(run), "--sigma-delta"])
    assert torch_eval.exit_code != 0 and "--backend nir-ref" in torch_eval.output


@pytest.mark.timeout(600)
def test_a_tiny_frontier_records_sigma_delta_counts_and_is_decided_per_env(
    tmp_path: Path,
) -> None:
    """A study of ann, ann-sd, sdnn and a stateful LIF on grid: the sigma-delta runs carry their
    counts per env step in study.json (equal to their deploy.json's), the frontier prices every
    point against the env's ANN and says one sentence per env."""
    from test_study import TINY, _study

    cfg = tmp_path / "frontier.toml"
    cfg.write_text(
        'schema = "snnkart/study-config/v1"\ndata = "tuning"\nenvs = ["grid"]\n'
        'policies = ["ann", "ann-sd", "sdnn", "snn"]\nseeds = [1]\nsteps = 2048\n'
        f"finishes = 1\neval_episodes = 2\ndeploy_episodes = 0\nsets = {json.dumps(TINY)}\n"
        '[variants]\n"snn:stateful" = ["snn.stateful=true", "snn.num_steps=1"]\n'
        '"sdnn:w16" = ["sdnn.hidden=[16, 16]", "sdnn.calibration_episodes=1"]\n'
    )
    out = tmp_path / "out"
    data = _study(cfg, out)
    runs = {r["name"]: r for r in data["runs"]}
    sd = runs["small_S-grid-sdnn-w16-s1"]
    deploy = DeployRecord.read(out / "runs" / sd["name"] / "study-eval-nir-ref-fixed/deploy.json")
    assert sd["sigma_delta_counts"] == json.loads(
        json.dumps(asdict(SigmaDeltaCounts.of_deploy(deploy)))
    )
    assert runs["small_S-grid-ann-sd-s1"]["sigma_delta_counts"]["sizes"] == [64, 64]
    assert "sigma_delta_counts" not in runs["small_S-grid-snn-stateful-s1"]
    summary = frontier(StudyRecord.read(out / "study.json"))
    names = {(p["policy"], p["variant"]) for p in summary["points"]}
    assert names == {("ann-sd", ""), ("sdnn", "w16"), ("snn", "stateful")}
    grid = summary["envs"]["grid"]
    assert grid["ann_success"] == runs["small_S-grid-ann-s1"]["eval_success_rate"]
    assert grid["ann_widths"][1:3] == [64, 64] and grid["verdict"].startswith("grid: ")
    for p in summary["points"]:
        assert p["keeps_accuracy"] == (p["success"] >= 0.95 * grid["ann_success"])
        assert p["goal"] == (p["keeps_accuracy"] and p["energy_goal"])
