"""A resume keeps the run it continues: its own length and schedules, whatever the defaults
or the command line's config say; extending it is explicit (``--steps N``), said in the
output and recorded in ``config.toml``."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from snnkart.cli import app
from snnkart.rl.config import load_config
from snnkart.rl.ppo import Trainer

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

TINY = ["ppo.num_envs=2", "ppo.rollout_steps=64", "ppo.update_epochs=1",
        "ppo.num_minibatches=2", "run.tensorboard=false", "ppo.learning_rate=1e-3"]  # fmt: skip
BATCH = 2 * 64
LR = 1e-3


class _Stopped(Exception):
    """A run ended from outside after an iteration, its checkpoint written (as a crash or a
    killed job leaves it)."""


def _metrics(run_dir: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in (run_dir / "metrics.jsonl").read_text().splitlines()]


def _interrupted_run(run_dir: Path, iterations: int, after: int) -> None:
    """A run of ``iterations`` iterations stopped after ``after`` of them."""
    cfg = load_config(
        overrides={"env": "grid", "policy": "ann", "total_steps": iterations * BATCH}, sets=TINY
    )

    def stop(record: dict[str, Any]) -> None:
        if record["iteration"] == after:
            raise _Stopped

    trainer = Trainer(cfg, run_dir)
    try:
        with pytest.raises(_Stopped):
            trainer.train(stop, save_every_iteration=True)
    finally:
        trainer.close()


def _train(*args: str) -> str:
    result = CliRunner().invoke(app, ["train", *args])
    assert result.exit_code == 0, result.output
    return result.output


@pytest.mark.timeout(300)
def test_resume_without_steps_keeps_the_runs_length_and_its_schedule(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    _interrupted_run(run_dir, iterations=4, after=2)
    trainer = Trainer(load_config(), run_dir, resume=True)  # the defaults say 300,000 steps
    try:
        assert (trainer.cfg.total_steps, trainer.num_iterations) == (4 * BATCH, 4)
    finally:
        trainer.close()
    output = _train("--resume", "--out", str(run_dir))
    records = _metrics(run_dir)
    assert [r["global_step"] for r in records] == [BATCH * k for k in (1, 2, 3, 4)]
    saved = tomllib.loads((run_dir / "config.toml").read_text())
    assert saved["total_steps"] == 4 * BATCH
    # the learning rate goes on annealing over 4 iterations, as if never interrupted
    rates = [r["charts/learning_rate"] for r in records]
    assert rates == pytest.approx([LR * (1 - k / 4) for k in range(4)])
    assert "the run was" not in output  # nothing was extended


@pytest.mark.timeout(300)
def test_resume_with_steps_extends_the_run_and_says_so(tmp_path: Path) -> None:
    run_dir = tmp_path / "run"
    _interrupted_run(run_dir, iterations=4, after=2)
    output = _train("--resume", "--steps", str(6 * BATCH), "--out", str(run_dir))
    assert f"the run was {4 * BATCH:,} steps long; it is now {6 * BATCH:,}" in " ".join(
        output.split()
    )
    assert [r["global_step"] for r in _metrics(run_dir)][-1] == 6 * BATCH
    assert tomllib.loads((run_dir / "config.toml").read_text())["total_steps"] == 6 * BATCH


@pytest.mark.timeout(120)
def test_steps_that_are_not_whole_rollouts_are_rounded_up_aloud(tmp_path: Path) -> None:
    sets = [a for s in TINY for a in ("--set", s)]
    output = _train("--env", "grid", "--policy", "ann", "--steps", str(BATCH + 1), *sets,
                    "--out", str(tmp_path / "run"))  # fmt: skip
    assert f"rounded up to whole rollouts: {2 * BATCH:,}" in " ".join(output.split())
