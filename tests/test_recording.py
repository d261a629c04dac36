"""Expert recordings (snnkart/recording/v1): file round trip, replay to the same trajectory,
refusal of another env, and the two ways to make one (play --record, record --driver)."""

from __future__ import annotations

import os

os.environ["SDL_VIDEODRIVER"] = "dummy"  # before anything imports pygame

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from snnkart.envs.recording import (
    ARRAYS,
    Recording,
    RecordingError,
    replay_observations,
    returns_to_go,
)
from snnkart.envs.spec import env_spec, make_env
from snnkart.eval.expert import record_driver

SNNKART = str(Path(sys.executable).parent / "snnkart")


@pytest.mark.parametrize(("env", "mode"), [("grid", "discrete"), ("steer", "continuous")])
def test_a_driver_recording_replays_to_the_same_trajectory(
    tmp_path: Path, env: str, mode: str
) -> None:
    rec = record_driver(env, "small_S", episodes=2, seed=5, action_mode=mode)
    loaded = Recording.load(rec.save(tmp_path / "d.npz"))
    assert loaded.meta == rec.meta
    for name in ARRAYS:
        np.testing.assert_array_equal(getattr(loaded, name), getattr(rec, name), err_msg=name)
    assert loaded.seeds.tolist() == [5, 6]
    assert loaded.meta["env_spec"]["action_mode"] == mode
    assert len(loaded.obs) == sum(e["length"] for e in loaded.meta["episodes"]) > 100
    ends = np.flatnonzero(loaded.terminated | loaded.truncated)
    assert (ends + 1).tolist() == [*loaded.episode_starts[1:].tolist(), len(loaded.obs)]
    replayed = replay_observations(loaded, make_env(env, "small_S", action_mode=mode))
    np.testing.assert_array_equal(replayed, loaded.obs)
    assert len(np.unique(loaded.obs[:, -1])) > 10  # the kart moved: not a trivial trajectory


def test_returns_to_go_by_hand() -> None:
    rewards = np.array([1.0, 2.0, 3.0, 10.0, 20.0], dtype=np.float32)
    got = returns_to_go(rewards, np.array([0, 3]), gamma=0.5)
    np.testing.assert_allclose(got, [1 + 0.5 * (2 + 0.5 * 3), 2 + 0.5 * 3, 3, 10 + 0.5 * 20, 20])


def test_a_recording_of_another_env_or_layout_is_refused(tmp_path: Path) -> None:
    rec = Recording.load(record_driver("grid", "small_S", episodes=1).save(tmp_path / "g.npz"))
    cases = [
        ("steer", None, "env grid vs steer"),
        ("grid", {"lidar": {"n_rays": 8}}, "observation layout (lidar[16],"),
        ("grid", {"reward": {"finish": 5.0}}, "env config differs in reward.finish"),
    ]
    for env, config, expected in cases:
        with pytest.raises(RecordingError) as caught:
            replay_observations(rec, make_env(env, "small_S", config=config))
        message = str(caught.value)
        assert expected in message and "\n" not in message, message
    with pytest.raises(RecordingError, match="track small_S vs big_S"):
        rec.check(env_spec(make_env("grid", "big_S").unwrapped))
    rec.check(env_spec(make_env("grid", "big_S").unwrapped), any_track=True)  # cloning may


def test_a_file_that_is_not_a_recording_is_refused(tmp_path: Path) -> None:
    np.savez(tmp_path / "x.npz", obs=np.zeros(3))
    with pytest.raises(RecordingError, match="is not a snnkart recording"):
        Recording.load(tmp_path / "x.npz")
    with pytest.raises(RecordingError, match="does not exist"):
        Recording.load(tmp_path / "missing.npz")


def test_play_records_what_the_player_did_and_it_replays(tmp_path: Path) -> None:
    import pygame

    from snnkart.cli.play import run_play

    def keys(step: int) -> None:
        if step == 50:  # R: restart mid-episode
            pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=pygame.K_r))

    out = tmp_path / "play.npz"
    run_play("grid", "small_S", max_steps=300, seed=3, on_step=keys, record=out)
    rec = Recording.load(out)
    assert rec.meta["driver"] == "human"
    assert [e["end"] for e in rec.meta["episodes"]] == ["restarted", "stood_still", "stopped"]
    assert [e["length"] for e in rec.meta["episodes"]] == [50, 200, 50]
    assert rec.seeds[0] == 3 and len(set(rec.seeds.tolist())) == 3
    assert rec.truncated[49] and not rec.terminated[49] and rec.terminated[249]
    np.testing.assert_array_equal(replay_observations(rec, make_env("grid", "small_S")), rec.obs)


def test_record_command_writes_a_recording(tmp_path: Path) -> None:
    out = tmp_path / "d.npz"
    result = subprocess.run(
        [SNNKART, "record", "--env", "grid", "--track", "small_S", "--episodes", "2", "-o", str(out)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "2 episodes, 2 finished" in result.stdout
    assert Recording.load(out).episodes == 2
    bad = subprocess.run(
        [SNNKART, "record", "--driver", "pursuitt", "-o", str(out)], capture_output=True, text=True
    )
    assert bad.returncode == 2 and "did you mean 'pursuit'" in bad.stderr
