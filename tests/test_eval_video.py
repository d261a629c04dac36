"""``snnkart eval --video``: the filmed frames (last step, banner, counter, zoom), MP4 and its
install hint, and ``snnkart play``'s key help and stand-still message."""

from __future__ import annotations

import os

os.environ["SDL_VIDEODRIVER"] = "dummy"  # before anything imports pygame

import sys
from pathlib import Path
from typing import Any, cast

import numpy as np
import pytest

from snnkart.envs import make
from snnkart.envs.base import KartEnv
from snnkart.envs.overlay import VIEW_MARGIN_PX
from snnkart.envs.render import WORLD_SIZE_PX
from snnkart.errors import UsageError
from snnkart.eval.drivers import ScriptedDriver, drive_episode
from snnkart.eval.episodes import run_episodes
from snnkart.eval.video import BANNER_FRAMES, Film, check_video_path, video_writer

pytestmark = pytest.mark.render


class Frames:
    """A video writer that keeps the frames in memory."""

    def __init__(self) -> None:
        self.frames: list[np.ndarray] = []

    def append_data(self, frame: np.ndarray) -> None:
        self.frames.append(frame)


def kart_env() -> KartEnv:
    return cast(KartEnv, make("steer", track="small_S", render_mode="rgb_array").unwrapped)


def film(seed: int, episodes: int, filmed: int) -> tuple[Frames, list[Any]]:
    env = kart_env()
    frames = Frames()
    shot = Film(env, frames, episodes, seed, filmed)
    results = run_episodes(env, ScriptedDriver(env), episodes, seed, shot.on_step, shot.on_episode)
    env.close()
    return frames, results


def test_last_frame_shows_the_final_step_and_return() -> None:
    # Seed 1's lap ends on an odd step, which the every-second-step frames never drew.
    frames, (result,) = film(seed=1, episodes=1, filmed=1)
    assert result.finished and result.length % 2 == 1
    env = kart_env()
    drive_episode(env, seed=1)
    final = env.render()  # the final step as the renderer draws it: its panel shows the return
    assert final is not None and env.episode_return == result.episode_return
    panel = final[:, round(WORLD_SIZE_PX * env.config.render_scale) :]
    last = frames.frames[-1]
    assert np.array_equal(last[:, -panel.shape[1] :], panel)
    # the banner is held over the final frame; the frame before it is an earlier step
    assert all(np.array_equal(f, last) for f in frames.frames[-BANNER_FRAMES:])
    assert not np.array_equal(frames.frames[-BANNER_FRAMES - 1][:, -panel.shape[1] :], panel)


def test_only_the_first_episodes_are_filmed_and_the_view_is_zoomed() -> None:
    frames, results = film(seed=0, episodes=3, filmed=1)
    assert len(results) == 3
    assert len(frames.frames) == results[0].length // 2 + BANNER_FRAMES
    env = kart_env()
    env.reset(seed=0)
    raw = env.render()
    assert raw is not None
    track_px = round(WORLD_SIZE_PX * env.config.render_scale)
    view_px = frames.frames[0].shape[1] - (raw.shape[1] - track_px)
    xmin, _, xmax, _ = env.track.bounds
    crop_px = (xmax - xmin + 2 * VIEW_MARGIN_PX) * env.config.render_scale
    # small_S fills a third of the world's width: shown at full height it is about twice as big
    assert frames.frames[0].shape[0] == raw.shape[0] and view_px < track_px
    assert view_px / crop_px > 1.8


def test_counter_names_the_episode_and_seed() -> None:
    frames, _ = film(seed=5, episodes=2, filmed=2)
    # the counter box, top left, differs between the two episodes' frames (seed 5 / seed 6)
    first, last = frames.frames[0], frames.frames[-1]
    assert not np.array_equal(first[:30, :200], last[:30, :200])


def test_mp4_is_written(tmp_path: Path) -> None:
    pytest.importorskip("imageio_ffmpeg")
    import imageio.v2 as imageio

    frames, _ = film(seed=1, episodes=1, filmed=1)
    out = tmp_path / "lap.mp4"
    with video_writer(out, fps=30) as writer:
        for frame in frames.frames[-20:]:
            writer.append_data(frame)
    assert b"ftyp" in out.read_bytes()[:64]  # an MP4 container, not a GIF named .mp4
    read = imageio.mimread(out, format="FFMPEG", memtest=False)
    assert len(read) == 20 and read[0].shape == frames.frames[-1].shape


def test_mp4_without_ffmpeg_gives_an_install_hint(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # as if not installed
    with pytest.raises(UsageError) as caught:
        check_video_path(Path("lap.mp4"))
    message = str(caught.value)
    assert "\n" not in message and "pip install 'snnkart[video]'" in message
    check_video_path(Path("lap.gif"))  # GIFs need no ffmpeg


def test_play_says_standing_still_once_per_spell(capsys: pytest.CaptureFixture[str]) -> None:
    from snnkart.cli.play import run_play

    # No key held: the grid kart stands still (200 steps) twice; only the first is printed.
    assert run_play("grid", "small_S", max_steps=405, seed=0) == 2
    assert capsys.readouterr().out.count("stood still too long") == 1


def test_play_shows_its_keys_in_the_window() -> None:
    import pygame

    from snnkart.cli.play import run_play

    bottoms: list[np.ndarray] = []

    def grab(step: int) -> None:
        if step == 3:
            surface = pygame.display.get_surface()
            bottoms.append(pygame.surfarray.array3d(surface)[:300, -20:].copy())

    run_play("grid", "small_S", max_steps=5, seed=0, on_step=grab)
    from snnkart.envs.render import TEXT

    assert np.any(np.all(bottoms[0] == np.asarray(TEXT, dtype=np.uint8), axis=2))


def test_eval_scores_all_episodes_and_films_the_first(tmp_path: Path) -> None:
    import json

    from typer.testing import CliRunner

    from snnkart.cli import app

    fixture = Path(__file__).parent / "data" / "policies" / "grid-snn"
    gif, out = tmp_path / "eval.gif", tmp_path / "eval.json"
    args = ["eval", str(fixture), "--episodes", "2", "--video", str(gif), "--out", str(out)]
    result = CliRunner().invoke(app, [*args, "--video-episodes", "1"])
    assert result.exit_code == 0, result.output
    episodes = json.loads(out.read_text())["episodes"]
    assert len(episodes) == 2
    from PIL import Image

    # one frame per second step of the first episode only, then the banner: the GIF writer
    # keeps repeated frames as one frame shown BANNER_FRAMES times as long
    with Image.open(gif) as image:
        durations = []
        for k in range(image.n_frames):
            image.seek(k)
            durations.append(image.info["duration"])
    assert len(durations) == episodes[0]["length"] // 2 + 1
    assert durations[-1] >= (BANNER_FRAMES - 1) * durations[0]  # GIF times are centiseconds
