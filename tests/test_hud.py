"""The HUD of the snnkart windows (human mode under SDL's dummy driver): each element where
its layout says, the indicators following the last action, and P's screenshot."""

from __future__ import annotations

import os

os.environ["SDL_VIDEODRIVER"] = "dummy"  # before anything imports pygame

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

import snnkart

pytestmark = pytest.mark.render


def window_frame() -> np.ndarray:
    import pygame

    return pygame.surfarray.array3d(pygame.display.get_surface()).transpose(1, 0, 2)


def count(frame: np.ndarray, rect: Any, colour: tuple[int, int, int]) -> int:
    """Pixels of exactly ``colour`` inside ``rect``."""
    part = frame[rect.top : rect.bottom, rect.left : rect.right]
    return int(np.all(part == np.asarray(colour, dtype=np.uint8), axis=2).sum())


def drive(action: int, steps: int = 12) -> tuple[np.ndarray, Any]:
    env = snnkart.make("steer", track="small_S", render_mode="human")
    env.reset(seed=0)
    for _ in range(steps):
        env.step(action)
    frame = window_frame()
    hud = env.unwrapped._renderer._hud
    env.close()
    return frame, hud


@pytest.mark.parametrize(("action", "forward", "right"), [(8, True, True), (0, False, False)])
def test_each_element_is_where_the_layout_says(action: int, forward: bool, right: bool) -> None:
    """steer's action 8 is throttle+right, 0 brake+left."""
    from snnkart.envs.render import CHECKPOINT_NEXT, NEGATIVE, POSITIVE, RAY_HIT, TEXT, TEXT_DIM

    frame, hud = drive(action)
    regions = hud.layout.regions
    for name in ("text", "throttle", "brake", "steer", "lidar"):
        assert regions["box"].contains(regions[name]), name
    for k in range(7):  # every text row has its label and value in it
        row = regions["text"].copy()
        row.top, row.height = row.top + k * hud.layout.row_height, hud.layout.row_height
        assert count(frame, row, TEXT_DIM) > 5 and count(frame, row, TEXT) > 0, k
    assert (count(frame, regions["throttle"], POSITIVE) > 100) is forward
    assert (count(frame, regions["brake"], NEGATIVE) > 100) is not forward
    steer = regions["steer"]
    left, right_half = steer.copy(), steer.copy()
    left.width = right_half.width = steer.width // 2
    right_half.left = steer.centerx + 1
    assert (count(frame, right_half, CHECKPOINT_NEXT) > 20) is right
    assert (count(frame, left, CHECKPOINT_NEXT) > 20) is not right
    assert count(frame, regions["lidar"], RAY_HIT) > 10  # the hit dots of the mini view


def test_the_box_avoids_the_track() -> None:
    _, hud = drive(4, steps=1)
    box = hud.layout.regions["box"]
    xmin, ymin, xmax, ymax = (0.8 * b for b in hud.env.track.bounds)
    overlap_x = max(0, min(box.right, xmax) - max(box.left, xmin))
    overlap_y = max(0, min(box.bottom, ymax) - max(box.top, ymin))
    assert overlap_x * overlap_y == 0
    from snnkart.envs.overlay import _corner

    # a track over the top left half: the box goes top right; over the left: bottom right
    assert _corner(800, 800, (200, 350), (0, 0, 500, 500), 1.0) == (600, 0)
    assert _corner(800, 800, (200, 350), (0, 0, 500, 800), 1.0) == (600, 0)
    assert _corner(800, 800, (200, 350), (0, 0, 800, 400), 1.0) == (0, 450)
    # a track over the whole view: the first corner, unless the kart is near it
    assert _corner(800, 800, (200, 350), (0, 0, 1000, 1000), 1.0, (500.0, 500.0)) == (0, 0)
    assert _corner(800, 800, (200, 350), (0, 0, 1000, 1000), 1.0, (100.0, 100.0)) == (0, 450)


def test_p_saves_a_screenshot_that_decodes(tmp_path: Path, monkeypatch: Any) -> None:
    import pygame

    monkeypatch.chdir(tmp_path)
    env = snnkart.make("gazebo", track="small_S", render_mode="human")
    env.reset(seed=0)
    pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=pygame.K_p))
    pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=pygame.K_r))
    env.step(1)
    saved = list(env.unwrapped._renderer.screenshots)
    still_queued = [e.key for e in pygame.event.get(pygame.KEYDOWN)]
    size = pygame.display.get_surface().get_size()
    env.close()
    assert len(saved) == 1 and saved[0].parent == tmp_path
    with Image.open(saved[0]) as image:
        assert image.size == size
        assert np.asarray(image.convert("RGB")).std() > 5  # a picture, not a blank
    assert still_queued == [pygame.K_r]  # play's R still reaches play's loop


def test_controls_of_each_action_kind() -> None:
    from snnkart.envs.overlay import controls

    class Stub:
        def __init__(self, mode: str, names: tuple[str, ...], action: Any) -> None:
            self.action_mode, self.ACTION_NAMES, self.last_action = mode, names, action

    gazebo = ("none", "accelerate", "brake", "left", "right")
    assert controls(Stub("discrete", gazebo, 1)) == (1.0, 0.0)
    assert controls(Stub("discrete", gazebo, 2)) == (-1.0, 0.0)
    assert controls(Stub("discrete", gazebo, 3)) == (0.0, -1.0)
    assert controls(Stub("discrete", ("brake+right",), 0)) == (-1.0, 1.0)
    assert controls(Stub("continuous", (), np.array([0.5, -2.0]))) == (0.5, -1.0)
    assert controls(Stub("discrete", gazebo, None)) == (0.0, 0.0)


def test_best_lap_is_the_fastest_finished_lap_shown() -> None:
    import pygame

    from snnkart.envs.overlay import ROWS, Hud
    from snnkart.eval.drivers import drive_episode

    env = snnkart.make("gazebo", track="small_S").unwrapped
    hud = Hud(env, 0.8, 800, 800)
    surface = pygame.Surface((1088, 800))
    hud(surface)
    assert hud.best_lap is None and hud._values()[ROWS.index("best lap")] == "-"
    result = drive_episode(env, seed=0)
    assert result.finished
    hud(surface)
    assert hud.best_lap == pytest.approx(env.elapsed_time)
    assert hud._values()[ROWS.index("best lap")] == f"{env.elapsed_time:.2f} s"
    best = hud.best_lap
    env.reset(seed=1)
    hud(surface)  # an unfinished episode leaves it
    assert hud.best_lap == best


def test_replay_window_shows_the_frame_rate() -> None:
    import pygame

    from snnkart.envs.render import TEXT, Renderer

    env = snnkart.make("steer", track="small_S").unwrapped
    env.reset(seed=0)
    renderer = Renderer(env, human=True)
    pad = renderer._hud.layout.pad
    for _ in range(3):
        renderer.draw_ghosts(np.array([[300.0, 500.0]]), [(200, 80, 80)], [("runs", "1")])
    frame = window_frame()
    renderer.close()
    area = pygame.Rect(pad, pad, 80, 20)
    assert count(frame, area, TEXT) > 5
    assert renderer._hud.fps > 0
