"""The early-stop rule (``stop`` in the train config): a run that has learned stops at the
second passing check and stays stopped; the checks change nothing else the run computes."""

from __future__ import annotations

import json
from pathlib import Path

import torch
from tiny_runs import TINY

from snnkart.app.launch import RunSpec, complete
from snnkart.rl.config import load_config
from snnkart.rl.normalise import RunningMeanStd
from snnkart.rl.ppo import Trainer

FIXTURE = Path(__file__).resolve().parent / "data" / "policies" / "grid-snn"
STEPS = 8 * 256  # 8 iterations of 2 envs x 128 steps


def _trainer(run_dir: Path, stop: list[str], lr: str = "0.001") -> Trainer:
    """A grid SNN run that starts from the committed policy that drives small_S."""
    cfg = load_config(
        overrides={"env": "grid", "policy": "snn", "total_steps": STEPS},
        sets=[*TINY, f"ppo.learning_rate={lr}", "run.trajectories=false", *stop],
    )
    trainer = Trainer(cfg, run_dir)
    state = torch.load(FIXTURE / "checkpoint.pt", weights_only=False)
    trainer.policy.load_state_dict(state["policy"])
    trainer.obs_rms = RunningMeanStd.from_state(state["obs_rms"])
    return trainer


def _train(trainer: Trainer) -> None:
    try:
        trainer.train()
    finally:
        trainer.close()


def _metrics(run_dir: Path) -> list[dict[str, object]]:
    return [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]


RULE = ["stop.finishes=1", "stop.every=256", "stop.episodes=4", "stop.success=0.5"]


def test_a_run_that_drives_stops_at_the_second_passing_check_and_stays_stopped(
    tmp_path: Path,
) -> None:
    run = tmp_path / "run"
    trainer = _trainer(run, [*RULE, "stop.checks=2"], lr="0")
    _train(trainer)
    rows = _metrics(run)
    checks = [r["stop/eval_success"] for r in rows if "stop/eval_success" in r]
    assert len(checks) == 2 and min(checks) >= 0.5  # type: ignore[type-var]
    assert rows[-1]["stop/streak"] == 2
    meta = json.loads((run / "checkpoint.json").read_text())
    assert meta["stopped_early"] is True and meta["global_step"] < STEPS
    assert complete(run, RunSpec("run", trainer.cfg))

    resumed = Trainer(trainer.cfg, run, resume=True)  # a launcher's resume trains nothing more
    _train(resumed)
    assert len(_metrics(run)) == len(rows)


def test_an_untrained_policy_is_never_stopped(tmp_path: Path) -> None:
    run = tmp_path / "run"
    cfg = load_config(
        overrides={"env": "grid", "policy": "ann", "total_steps": 4 * 256},
        sets=[*TINY, "run.trajectories=false", *RULE],
    )
    trainer = Trainer(cfg, run)
    trainer.progress.finishes = 1  # checks run, and fail: it cannot drive yet
    _train(trainer)
    checks = [r["stop/eval_success"] for r in _metrics(run) if "stop/eval_success" in r]
    assert checks == [0.0] * 3  # none after the last iteration: the run ends there anyway
    assert json.loads((run / "checkpoint.json").read_text())["stopped_early"] is False


def test_the_checks_change_nothing_the_run_computes(tmp_path: Path) -> None:
    checked = _trainer(tmp_path / "checked", [*RULE, "stop.checks=100"])
    _train(checked)
    plain = _trainer(tmp_path / "plain", [])
    _train(plain)
    rows = _metrics(tmp_path / "checked")
    assert sum("stop/eval_success" in r for r in rows) >= 6  # the checks ran
    keys = ("charts/episodic_return", "charts/cumulative_finishes", "losses/policy_loss")
    assert [[r.get(k) for k in keys] for r in rows] == [
        [r.get(k) for k in keys] for r in _metrics(tmp_path / "plain")
    ]
    for name, value in checked.policy.state_dict().items():
        assert torch.equal(value, plain.policy.state_dict()[name]), name
