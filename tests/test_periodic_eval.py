"""Periodic evaluation and the best checkpoint (``eval`` in the train config), choosing a
run's checkpoint by name (``--checkpoint best|latest|STEP``), and the resolved env config a
run's ``config.toml`` carries (issue 32)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
import torch
from tiny_runs import TINY, train_tiny
from typer.testing import CliRunner

import snnkart
from snnkart.cli import app
from snnkart.envs.spec import env_spec, spec_hash
from snnkart.errors import CheckpointError, ConfigError
from snnkart.rl.checkpoint import load_checkpoint
from snnkart.rl.config import load_config, read_run_config
from snnkart.rl.normalise import RunningMeanStd
from snnkart.rl.periodic_eval import score_key
from snnkart.rl.ppo import Trainer
from snnkart.rl.run_dir import checkpoint_path

pytestmark = pytest.mark.xdist_group(
    "periodic_eval"
)  # one worker builds the module's fixtures once

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

FIXTURE = Path(__file__).resolve().parent / "data" / "policies" / "grid-snn"
STEPS = 8 * 256  # 8 iterations of 2 envs x 128 steps
EVAL = ["eval.every_steps=256", "eval.episodes=3"]
TIMING = {"charts/SPS", "charts/rollout_SPS", "charts/update_seconds"}


def _trainer(run_dir: Path, sets: list[str]) -> Trainer:
    """A grid SNN run that starts from the committed policy that drives small_S (so its
    evaluations score differently as training moves it)."""
    cfg = load_config(
        overrides={"env": "grid", "policy": "snn", "total_steps": STEPS},
        sets=[*TINY, "ppo.learning_rate=0.003", "run.trajectories=false", *sets],
    )
    trainer = Trainer(cfg, run_dir)
    state = torch.load(FIXTURE / "checkpoint.pt", weights_only=False)
    trainer.policy.load_state_dict(state["policy"])
    trainer.obs_rms = RunningMeanStd.from_state(state["obs_rms"])
    try:
        trainer.train()
    finally:
        trainer.close()
    return trainer


def _metrics(run_dir: Path) -> list[dict[str, object]]:
    return [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]


@pytest.fixture(scope="session")  # built once per worker, whatever runs between its tests
def evaluated(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Trainer]:
    run = tmp_path_factory.mktemp("evaluated") / "run"
    return run, _trainer(run, [*EVAL, "run.checkpoint_every=1"])


def test_periodic_evaluation_changes_nothing_training_computes(
    evaluated: tuple[Path, Trainer], tmp_path: Path
) -> None:
    run, trainer = evaluated
    plain = _trainer(tmp_path / "plain", ["run.checkpoint_every=1"])
    rows = _metrics(run)
    assert sum("eval/mean_return" in r for r in rows) == STEPS // 256  # every iteration
    without_evals = [
        json.dumps({k: v for k, v in r.items() if k not in TIMING and not k.startswith("eval/")})
        for r in rows
    ]  # as JSON text, so that NaN equals NaN
    assert without_evals == [
        json.dumps({k: v for k, v in r.items() if k not in TIMING})
        for r in _metrics(tmp_path / "plain")
    ]
    for name, value in trainer.policy.state_dict().items():
        assert torch.equal(value, plain.policy.state_dict()[name]), name
    assert not (tmp_path / "plain" / "best.pt").exists()


def test_the_best_checkpoint_is_the_best_recorded_evaluation(
    evaluated: tuple[Path, Trainer],
) -> None:
    run, trainer = evaluated
    evals = [
        (r["iteration"], {"success_rate": r["eval/success_rate"],
                          "mean_return": r["eval/mean_return"]}, r["eval/best"])
        for r in _metrics(run)
    ]  # fmt: skip
    assert len({score_key(s) for _, s, _ in evals}) > 1  # the scores moved: a real choice
    best_it, best, _ = max(evals, key=lambda e: (score_key(e[1]), -e[0]))  # the first of the best
    meta = json.loads((run / "best.json").read_text())
    assert meta["iteration"] == best_it and meta["eval"]["mean_return"] == best["mean_return"]
    # eval/best marks exactly the evaluations that beat every earlier one
    marks = [score_key(s) > max([score_key(p) for _, p, _ in evals[:k]], default=(-1e9, -1e9))
             for k, (_, s, _) in enumerate(evals)]  # fmt: skip
    assert [b for _, _, b in evals] == marks
    # best.pt holds the policy of that iteration (its history checkpoint)
    best_state, _ = load_checkpoint(run / "best.pt")
    history, _ = load_checkpoint(run / "checkpoints" / f"iter_{best_it:06d}.pt")
    for name, value in history["policy"].items():
        assert torch.equal(value, best_state["policy"][name]), name
    # evaluated again on the same seeds, it scores what was recorded
    cfg = trainer.cfg.eval
    record = snnkart.evaluate(run, episodes=cfg.episodes, seed=cfg.seed, checkpoint="best",
                              out=run / "best-eval.json")  # fmt: skip
    assert record.summary.success_rate == best["success_rate"]
    assert record.summary.mean_return == pytest.approx(best["mean_return"], rel=1e-9)
    # a resumed run compares with that best, not from scratch
    resumed = Trainer(trainer.cfg, run, resume=True)
    try:
        assert resumed.evals.best == meta["eval"]
    finally:
        resumed.close()


def _eval(*args: str) -> tuple[int, str]:
    result = CliRunner().invoke(app, ["eval", *args, "--episodes", "1"])
    return result.exit_code, result.output


def test_eval_takes_best_latest_or_a_step_and_says_what_is_missing(tmp_path: Path) -> None:
    run = train_tiny(tmp_path / "run", "grid", "ann", total_steps=768,
                     extra_sets=["run.checkpoint_every=2"])  # fmt: skip
    code, out = _eval(str(run), "--checkpoint", "best")
    assert code == 2
    assert ("error: no best checkpoint: this run was trained without periodic evaluation "
            "(set eval.every_steps)") in out  # fmt: skip
    code, out = _eval(str(run), "--checkpoint", "300")
    assert code == 2 and "no checkpoint at step 300" in out and "steps 512, 768" in out
    for which, expected in (("512", "checkpoints/iter_000002.pt"), ("latest", "checkpoint.pt"),
                            (str(run / "checkpoint.pt"), "checkpoint.pt")):  # fmt: skip
        code, out = _eval(str(run), "--checkpoint", which, "--out", str(tmp_path / "e.json"))
        assert code == 0, out
        record = json.loads((tmp_path / "e.json").read_text())
        assert record["checkpoint"] == str(run / expected), which
    assert checkpoint_path(run) == checkpoint_path(run, "latest") == run / "checkpoint.pt"
    # on, but not reached yet
    late = train_tiny(tmp_path / "late", "grid", "ann", total_steps=256,
                      extra_sets=["eval.every_steps=5000"])  # fmt: skip
    with pytest.raises(CheckpointError, match=r"no best checkpoint .* yet.*step 5000"):
        snnkart.load_policy(late, checkpoint="best")


def test_the_eval_keys_are_known_to_the_config() -> None:
    assert load_config(sets=["eval.every_steps=1000"]).eval.every_steps == 1000
    assert load_config().eval.every_steps == 0  # off by default
    with pytest.raises(ConfigError, match=r"eval\.every_steps"):
        load_config(sets=["eval.every_step=1000"])


def test_config_toml_writes_the_resolved_env_config_and_makes_the_same_env(
    tmp_path: Path,
) -> None:
    run = train_tiny(tmp_path / "run", "gazebo", "snn", total_steps=256,
                     extra_sets=["env_config.physics.preset=turtlebot3",
                                 "env_config.reward.heading=0.25"])  # fmt: skip
    saved = tomllib.loads((run / "config.toml").read_text())["env_config"]
    assert saved["lidar"]["n_rays"] == 16 and saved["reward"]["stall"] == 0.01  # defaults
    assert saved["physics"]["max_linear_m_s"] == 0.22  # the preset's value, written out
    assert saved["reward"]["heading"] == 0.25
    meta = json.loads((run / "checkpoint.json").read_text())
    # the file alone makes the env trained in: as a new config, and as the run's own
    for cfg in (load_config(run / "config.toml"), read_run_config(run)):
        env = cfg.make_env()
        try:
            assert spec_hash(env_spec(env.unwrapped)) == meta["env_spec_hash"]  # type: ignore[arg-type]
        finally:
            env.close()
    resumed = Trainer(load_config(), run, resume=True, total_steps=512)
    try:
        resumed.train()
    finally:
        resumed.close()
    assert json.loads((run / "checkpoint.json").read_text())["global_step"] == 512


def test_best_means_more_laps_first_then_a_higher_return() -> None:
    laps = {"success_rate": 0.9, "mean_return": 5.0}
    assert score_key(laps) > score_key({"success_rate": 0.8, "mean_return": 15.0})
    assert score_key(laps) < score_key({"success_rate": 0.9, "mean_return": 5.5})
