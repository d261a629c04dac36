"""Renderer (rgb_array and human under SDL's dummy driver) and keyboard play loop."""

from __future__ import annotations

import os

os.environ["SDL_VIDEODRIVER"] = "dummy"  # before anything imports pygame

import math

import numpy as np
import pytest

import snnkart
from snnkart.cli.play import Keys, gazebo_action, grid_action, run_play, steer_action
from snnkart.envs.constants import KART_RADIUS_PX

pytestmark = pytest.mark.render

ENVS = ("grid", "gazebo", "steer")
FORWARD = {"grid": 4, "gazebo": 1, "steer": 7}  # right / accelerate / throttle+straight


def kart_pixels(frame: np.ndarray, position: tuple[float, float], scale: float) -> tuple[int, int]:
    """(kart-coloured pixels within the kart's box, kart-coloured pixels elsewhere)."""
    from snnkart.envs.render import KART

    mask = np.all(frame == np.asarray(KART, dtype=np.uint8), axis=2)
    r = KART_RADIUS_PX * scale + 2
    cx, cy = position[0] * scale, position[1] * scale
    ys, xs = np.nonzero(mask)
    inside = (np.abs(xs - cx) <= r) & (np.abs(ys - cy) <= r)
    return int(inside.sum()), int((~inside).sum())


@pytest.mark.parametrize(("name", "scale"), [("grid", 0.5), ("gazebo", 0.8), ("steer", 1.0)])
def test_rgb_array_frame_shows_the_kart(name: str, scale: float) -> None:
    env = snnkart.make(
        name, track="small_S", render_mode="rgb_array", config={"render_scale": scale}
    )
    env.reset(seed=1)
    for _ in range(20):
        env.step(FORWARD[name])
    frame = env.render()
    env.close()

    assert isinstance(frame, np.ndarray)
    assert frame.dtype == np.uint8
    assert frame.shape == (round(1000 * scale), round(1360 * scale), 3)
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 10
    position = env.unwrapped.position
    assert position != env.unwrapped.track.spawn_position
    inside, elsewhere = kart_pixels(frame, position, scale)
    disc = math.pi * (KART_RADIUS_PX * scale) ** 2
    assert inside > 0.6 * disc  # the disc minus its outline and heading mark
    assert elsewhere == 0


def test_human_render_under_dummy_driver() -> None:
    import pygame

    env = snnkart.make("steer", track="small_S", render_mode="human")
    env.reset(seed=0)  # renders the first frame
    assert env.render() is None
    window = pygame.display.get_surface()
    assert window.get_size() == (round(1360 * 0.8), 800)
    assert pygame.display.get_caption()[0] == "snnkart — steer on small_S"
    frame = pygame.surfarray.array3d(window).transpose(1, 0, 2)
    inside, elsewhere = kart_pixels(frame, env.unwrapped.position, 0.8)
    assert inside > 0 and elsewhere == 0
    renderer = env.unwrapped._renderer
    env.close()
    assert not pygame.display.get_init()
    renderer.close()  # a second close is harmless
    env.close()


def test_key_mappings() -> None:
    none = Keys(w=False, a=False, s=False, d=False, space=False)
    assert [grid_action(none), gazebo_action(none), steer_action(none)] == [0, 0, 4]
    w, a, s, d = (none._replace(**{k: True}) for k in "wasd")
    space = none._replace(space=True)
    assert [grid_action(k) for k in (w, s, a, d, space)] == [1, 2, 3, 4, 0]
    assert [gazebo_action(k) for k in (w, s, space, a, d)] == [1, 2, 2, 3, 4]
    # later keys win: D > A > S > W (grid), D > A > brake > W (gazebo)
    assert grid_action(none._replace(w=True, s=True)) == 2
    assert grid_action(none._replace(a=True, d=True)) == 4
    assert gazebo_action(none._replace(w=True, space=True)) == 2
    assert gazebo_action(none._replace(s=True, a=True)) == 3
    # steer: 3 * throttle (0 brake, 1 coast, 2 throttle) + steer (0 left, 1 straight, 2 right)
    assert steer_action(w._replace(a=True)) == 6
    assert steer_action(w._replace(d=True)) == 8
    assert steer_action(w._replace(space=True, d=True)) == 2  # brake wins over throttle
    assert steer_action(s._replace(a=True, d=True)) == 1  # both steer keys: straight


@pytest.mark.parametrize("name", ENVS)
def test_run_play_stops_after_max_steps(name: str) -> None:
    steps: list[int] = []
    episodes = run_play(name, "small_S", max_steps=30, seed=0, on_step=steps.append)
    assert steps == list(range(30))
    assert episodes == 0


def test_escape_quits_play() -> None:
    import pygame

    steps: list[int] = []

    def press_escape_at_5(step: int) -> None:
        steps.append(step)
        if step == 5:
            pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=pygame.K_ESCAPE))

    assert run_play("gazebo", "small_S", max_steps=30, on_step=press_escape_at_5) == 0
    assert steps == list(range(6))
    assert not pygame.display.get_init()


def test_play_reports_an_ended_episode(capsys: pytest.CaptureFixture[str]) -> None:
    # No key held: the grid kart stands still until the stand-still limit (200 steps) ends it.
    assert run_play("grid", "small_S", max_steps=205, seed=0) == 1
    assert "stood still too long, return -" in capsys.readouterr().out
