"""``replay`` shows whole training episodes, counted as training counts them, each from its
reset pose; ``replay --compare`` ends each kart on its terminal step, the clock on the longest
episode's own end time."""

from __future__ import annotations

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")  # before anything imports pygame

import json
from pathlib import Path

import numpy as np
import pytest

from snnkart.app.replay import _race, run_replay
from snnkart.app.reporter import Silent
from snnkart.envs.constants import DT
from snnkart.eval.episodes import run_episodes
from snnkart.eval.ghosts import Racer, load_ghosts, race_frames
from snnkart.rl.config import load_config
from snnkart.rl.ppo import Trainer
from snnkart.rl.trained import TorchPredictor, load_run

ENVS, STEPS = 4, 128  # per rollout
SETS = [f"ppo.num_envs={ENVS}", f"ppo.rollout_steps={STEPS}", "ppo.update_epochs=1",
        "ppo.num_minibatches=2", "ppo.start_spread=0", "run.tensorboard=false"]  # fmt: skip


def _train(run_dir: Path, iterations: int, resume: bool) -> None:
    cfg = load_config(overrides={"env": "grid", "policy": "ann",
                                 "total_steps": iterations * ENVS * STEPS}, sets=SETS)  # fmt: skip
    trainer = Trainer(cfg, run_dir, resume=resume, total_steps=cfg.total_steps if resume else None)
    try:
        trainer.train()
    finally:
        trainer.close()


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three iterations, then a resume (which resets the envs) to five."""
    run_dir = tmp_path_factory.mktemp("replay") / "run"
    _train(run_dir, 3, resume=False)
    _train(run_dir, 5, resume=True)
    return run_dir


def test_replay_counts_the_episodes_training_counted(run: Path, tmp_path: Path) -> None:
    """As many episodes as metrics.jsonl counts, per iteration, with training's mean length;
    the episodes cut by the resume and by the end are named as left out."""
    records = [json.loads(line) for line in (run / "metrics.jsonl").read_text().splitlines()]
    lines = Silent()
    counts = run_replay(run, "all", tmp_path / "all.gif", 8, lines)
    assert counts["episodes"] == sum(r["charts/episodes"] for r in records) > ENVS
    assert counts["begun_before"] == 0
    assert ENVS < counts["unfinished"] <= 2 * ENVS  # at the resume and at the end
    assert f"replaying {counts['episodes']} episodes" in lines.messages[0]
    assert f"{counts['unfinished']} unfinished episodes" in lines.messages[1]
    ghosts = load_ghosts(run).ghosts
    for r in records:
        steps = [len(g.positions) - 1 for g in ghosts if g.iteration == r["iteration"]]
        assert len(steps) == r["charts/episodes"], r["iteration"]
        if steps:
            assert np.mean(steps) == pytest.approx(r["charts/episodic_length"])


def test_every_replayed_episode_starts_at_its_reset_pose(run: Path) -> None:
    """Every first pose is a spawn pose (start_spread 0: the spawn and its jitter), and the first
    episode of each env starts exactly where a fresh env reset with that env's seed stands."""
    cfg = load_run(run).config
    ghosts = load_ghosts(run).ghosts
    firsts = np.array([g.positions[0] for g in ghosts])
    env = cfg.make_env().unwrapped
    spawn, jitter = np.array(env.track.spawn_position), env.track.spawn_jitter
    assert (np.abs(firsts - spawn) <= jitter + 1e-3).all()
    for i in range(ENVS):  # gymnasium seeds env i of a vector env with seed + i
        env.reset(seed=cfg.seed + i)
        assert np.isclose(firsts, env.position, atol=1e-3).all(axis=1).any(), i
    env.close()


def test_compare_ends_each_kart_on_its_terminal_step(run: Path) -> None:
    """A racer's path runs from its reset pose to its terminal pose, one pose per step; the last
    frame shows every kart at its terminal pose and the longest episode's own end time."""
    seed = 10_000
    (racer,), _ = _race([run], seed, None)
    policy = load_run(run)
    env = policy.config.make_env(track=policy.track)
    (alone,) = run_episodes(env, TorchPredictor(policy, seed=seed), 1, seed)
    end_pose = env.unwrapped.position
    env.reset(seed=seed)
    assert len(racer.positions) == alone.length + 1
    assert np.allclose(racer.positions[0], env.unwrapped.position, atol=1e-3)
    assert np.allclose(racer.positions[-1], end_pose, atol=1e-3)
    env.close()

    end = 4 * (len(racer.positions) // 8) + 2  # not a multiple of --every
    short = Racer("short", "ANN grid", racer.positions[: end + 1], "crashed")
    frames = list(race_frames([racer, short], every=4))
    assert frames[-1].lines[0] == ("time", f"{alone.length * DT:.2f} s")
    assert np.allclose(frames[-1].positions, [racer.positions[-1], short.positions[-1]])
    (at_end,) = [f for f in frames if f.lines[0] == ("time", f"{end * DT:.2f} s")]
    assert np.allclose(at_end.positions[1], short.positions[-1])
    assert at_end.lines[4][1] == "crashed"  # its outcome, from its terminal step on


def test_replay_help_says_what_is_left_out() -> None:
    from typer.testing import CliRunner

    from snnkart.cli import app

    result = CliRunner().invoke(app, ["replay", "--help"], env={"COLUMNS": "200"})
    assert result.exit_code == 0
    assert "episodes unfinished when training stopped or resumed are not shown" in result.output
