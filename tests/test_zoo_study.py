"""A zoo study end to end at a tiny budget (snnkart's ANN and SB3 PPO on CartPole-v1, two
seeds), its resumability, its statistics against hand computation, and its config's refusals."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from snnkart.app.report import build_report
from snnkart.app.reporter import Silent
from snnkart.app.zoo_study import (
    ZooStudyConfig,
    ZooStudyRecord,
    load_zoo_config,
    run_zoo_study,
)
from snnkart.errors import ConfigError
from snnkart.report.zoo_record import bootstrap_iqm, iqm

CONFIG = """schema = "snnkart/zoo-study-config/v1"
name = "tiny"
data = "tuning"
env = "CartPole-v1"
policies = ["ann", "sb3"]
seeds = [1, 2]
steps = 512
eval_episodes = 2
eval_seed = 10000
deploy_episodes = 1
"""


def test_iqm_is_the_mean_of_the_middle_half_as_scipy_trims_it() -> None:
    assert iqm(np.array([0.0, 1.0, 2.0, 3.0, 100.0])) == pytest.approx(2.0)  # cuts 1 each end
    assert iqm(np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 1000.0])) == pytest.approx(4.5)
    assert iqm(np.array([3.0, 5.0])) == pytest.approx(4.0)  # int(0.5) = 0 cut
    low, high = bootstrap_iqm([1.0, 2.0, 3.0, 4.0, 5.0])
    assert 1.0 <= low < 3.0 < high <= 5.0


@pytest.mark.timeout(600)
def test_a_tiny_zoo_study_trains_scores_and_resumes(tmp_path: Path) -> None:
    pytest.importorskip("stable_baselines3", reason="optional: stable-baselines3 (the bench extra)")
    (tmp_path / "tiny.toml").write_text(CONFIG)
    cfg = load_zoo_config(tmp_path / "tiny.toml")
    assert cfg is not None
    record = run_zoo_study(cfg, tmp_path / "out", Silent())
    assert ZooStudyRecord.read(tmp_path / "out/zoo-study.json") == record
    assert [(r.policy, r.seed) for r in record.runs] == [
        ("ann", 1),
        ("ann", 2),
        ("sb3", 1),
        ("sb3", 2),
    ]
    assert all(r.global_step >= 512 and r.summary.episodes == 2 for r in record.runs)
    ann = record.scores[0]
    assert ann.policy == "ann" and ann.normalised == pytest.approx(1.0)
    assert ann.mean == pytest.approx(np.mean([r.summary.mean_return for r in record.runs[:2]]))
    assert record.reward_threshold == 475.0 and ann.solved_seeds is not None
    assert "Stable-Baselines3 PPO" in (tmp_path / "out/zoo-study.md").read_text()
    assert record.deployed == [] and record.commit  # no spiking kind in this study
    stamp = (tmp_path / "out/ann-s1/checkpoint.pt").stat().st_mtime
    again = run_zoo_study(cfg, tmp_path / "out", Silent())  # every run reused
    assert (tmp_path / "out/ann-s1/checkpoint.pt").stat().st_mtime == stamp
    assert again.scores == record.scores


@pytest.mark.parametrize(
    ("change", "words"),
    [
        ('data = "tuning"', 'data = "reporting"'),
        ('policies = ["ann", "sb3"]', 'policies = ["dqn"]'),
    ],
)
def test_a_bad_zoo_config_is_refused(tmp_path: Path, change: str, words: str) -> None:
    (tmp_path / "bad.toml").write_text(CONFIG.replace(change, words))
    match = "seeds 101 and up" if "reporting" in words else "policies are"
    with pytest.raises(ConfigError, match=match):
        ZooStudyConfig.read(tmp_path / "bad.toml")


ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize(
    "path", sorted((ROOT / "studies/zoo").glob("*.toml")), ids=lambda p: p.stem
)
def test_the_committed_zoo_studies_load_on_reporting_seeds(path: Path) -> None:
    from snnkart.rl.zoo import zoo_settings

    cfg = ZooStudyConfig.read(path)
    assert cfg.data == "reporting" and min(cfg.seeds) >= 101
    assert set(cfg.policies) == {"ann", "snn", "sdnn", "sb3"}
    assert zoo_settings(cfg.env).values["n_timesteps"]


@pytest.mark.timeout(600)
def test_a_zoo_studys_spiking_seed_deploys_bit_exact_on_lava(tmp_path: Path) -> None:
    pytest.importorskip("lava", reason="optional: lava-nc (the lava extra)")
    (tmp_path / "tiny.toml").write_text(
        CONFIG.replace('["ann", "sb3"]', '["snn"]').replace("[1, 2]", "[3]")
    )
    cfg = load_zoo_config(tmp_path / "tiny.toml")
    assert cfg is not None
    record = run_zoo_study(cfg, tmp_path / "out", Silent())
    (deployed,) = record.deployed
    assert deployed.policy == "snn" and deployed.seed == 3 and deployed.env_steps > 0
    assert deployed.mismatched_windows == 0 and deployed.mismatched_actions == 0
    assert record.scores[0].normalised is None  # no ANN in the study: nothing to normalise by
    assert "on lava-sim fixed" in (tmp_path / "out/zoo-study.md").read_text()
    # its energy is the one snnkart report gives the same deployment: Loihi 2 against the int8
    # ANN of the deployed widths, the same joint sample
    e = deployed.energy
    assert e is not None and (e.chip, e.baseline) == ("loihi2", "horowitz45_int8")
    report = build_report(Path(deployed.deploy_dir), None, None)
    (row,) = [
        c
        for c in report["comparisons"]  # type: ignore[attr-defined]
        if (c["snn_profile"], c["ann"], c["ann_profile"]) == (e.chip, "same_width", e.baseline)
    ]
    assert report["ann"]["same_width"]["label"] == e.ann == "ANN 64-64 (same widths)"  # type: ignore[index]
    macs = sum(t["count"] for t in row["ann_terms"] if t["op"] == "mac")
    assert macs == 4 * 64 + 64 * 64 + 64 * 2  # CartPole's 4 inputs, the zoo's 64-64, 2 actions
    assert row["uncertainty"]["ratio"]["median"] == pytest.approx(e.ratio.median)
    assert row["uncertainty"]["ann_pj"]["p95"] == pytest.approx(e.ann_pj.p95)
    assert f"{e.ratio.median:.3g}x" in (tmp_path / "out/zoo-study.md").read_text()


@pytest.mark.timeout(600)
def test_a_study_of_a_users_own_env_on_snnkarts_settings(tmp_path: Path) -> None:
    """An env the zoo has no entry for (the suite's PickEnv, by entry point, MultiDiscrete
    actions) studied with snnkart's defaults; SB3 is refused there (not like for like)."""
    text = (
        CONFIG.replace('"CartPole-v1"', '"my_envs:PickEnv"')
        .replace('["ann", "sb3"]', '["ann", "snn"]')
        .replace("[1, 2]", "[1]")
        .replace("deploy_episodes = 1", 'deploy_episodes = 1\nsettings = "snnkart"')
    )
    (tmp_path / "own.toml").write_text(text)
    cfg = load_zoo_config(tmp_path / "own.toml")
    assert cfg is not None
    record = run_zoo_study(cfg, tmp_path / "out", Silent())
    assert [r.policy for r in record.runs] == ["ann", "snn"] and record.unexpressible == []
    assert record.zoo["key"] == "snnkart's defaults" and 0 < record.random_return < 20
    (deployed,) = record.deployed
    assert deployed.mismatched_windows == 0 and deployed.energy is not None
    assert "PPO settings: snnkart's defaults" in (tmp_path / "out/zoo-study.md").read_text()
    (tmp_path / "sb3.toml").write_text(text.replace('["ann", "snn"]', '["ann", "sb3"]'))
    with pytest.raises(ConfigError, match='drop "sb3"'):
        load_zoo_config(tmp_path / "sb3.toml")


def test_the_published_cartpole_study_solves_on_every_seed_and_deploys_bit_exact() -> None:
    """docs/zoo.md's CartPole-v1 claim: every kind (and SB3) reaches gymnasium's threshold on
    every reporting seed, and each spiking kind's deployed seed is bit-exact on Lava."""
    record = ZooStudyRecord.read(ROOT / "docs/zoo/cartpole.json")
    assert record.data == "reporting" and not record.commit.endswith("-dirty")
    assert {s.policy for s in record.scores} == {"ann", "snn", "sdnn", "sb3"}
    for s in record.scores:
        assert len(s.returns) == 5 and s.solved_seeds == 5, s.policy
    assert {d.policy for d in record.deployed} == {"snn", "sdnn"}
    assert all(d.mismatched_windows == 0 and d.mismatched_actions == 0 for d in record.deployed)


def test_no_score_is_normalised_where_the_ann_does_not_beat_a_random_policy() -> None:
    """(mean - random) / (ANN - random) with the ANN below random flips every sign: a winner
    would read as below the ANN. Undefined, so left out, in the record and the table."""
    from types import SimpleNamespace

    from snnkart.report.zoo_record import scores

    def run(policy: str, seed: int, mean: float) -> Any:
        return SimpleNamespace(policy=policy, seed=seed, wall_s=1.0, steps_per_s=10.0,
                               summary=SimpleNamespace(mean_return=mean))  # fmt: skip

    below = scores([run("ann", 1, -90.0), run("sb3", 1, 80.0)], floor=-30.0, threshold=None)
    assert [s.normalised for s in below] == [None, None]
    above = scores([run("ann", 1, 70.0), run("sb3", 1, 80.0)], floor=-30.0, threshold=None)
    assert [s.normalised for s in above] == [1.0, 1.1]
