"""``snnkart track edit``'s window under SDL's dummy video driver: pygame mouse and key events
posted to its queue draw the expected file and save it with Ctrl+S; a committed track opened
and saved unedited is the same file; the command refuses a broken file in one line."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from snnkart.cli import app

pygame = pytest.importorskip("pygame")
from snnkart.cli.track_editor import SCALE, EditorWindow  # noqa: E402
from snnkart.envs.track_edit import EditedTrack, TrackEditor, read_track_file  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
EXPECTED = (ROOT / "tests/data/editor/corridor.toml").read_text()


@pytest.fixture
def window(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[EditorWindow]:
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    win = EditorWindow(TrackEditor(EditedTrack(name="corridor")), tmp_path / "corridor.toml")
    yield win
    pygame.quit()


def screen(x: float, y: float) -> tuple[int, int]:
    return (round(x * SCALE), round(y * SCALE))


def post_key(key: int, mod: int = 0) -> None:
    pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=key, mod=mod))


def post_mouse(kind: int, x: float, y: float, button: int = 1) -> None:
    if kind == pygame.MOUSEMOTION:
        event = pygame.event.Event(kind, pos=screen(x, y), rel=(0, 0), buttons=(1, 0, 0))
    else:
        event = pygame.event.Event(kind, pos=screen(x, y), button=button)
    pygame.event.post(event)


def post_line(a: tuple[float, float], b: tuple[float, float]) -> None:
    post_mouse(pygame.MOUSEBUTTONDOWN, *a)
    post_mouse(pygame.MOUSEMOTION, *b)
    post_mouse(pygame.MOUSEBUTTONUP, *b)


def test_events_draw_and_save_the_expected_file(window: EditorWindow, tmp_path: Path) -> None:
    post_key(pygame.K_g)  # a 10 px grid: at 0.75 screen px per track px a mouse can't hit 150
    post_key(pygame.K_w)
    for x, y in [(500, 100), (100, 100), (100, 200), (500, 200)]:
        post_mouse(pygame.MOUSEBUTTONDOWN, x, y)
        post_mouse(pygame.MOUSEBUTTONUP, x, y)
    post_mouse(pygame.MOUSEBUTTONDOWN, 500, 200, button=3)  # ends the wall: the next click
    post_mouse(pygame.MOUSEBUTTONDOWN, 800, 800)  # starts a wall of one point, dropped below
    post_mouse(pygame.MOUSEBUTTONUP, 800, 800)
    post_key(pygame.K_s)  # the spawn, facing east, then moved
    post_mouse(pygame.MOUSEBUTTONDOWN, 141, 141)
    post_mouse(pygame.MOUSEMOTION, 141, 241)
    window.pump()
    assert window.editor.state.heading_deg == 90  # the drag aims the kart as it goes
    post_mouse(pygame.MOUSEMOTION, 241, 141)
    post_mouse(pygame.MOUSEBUTTONUP, 241, 141)
    post_key(pygame.K_m)
    post_line((141, 141), (150, 150))
    post_key(pygame.K_c)
    post_line((300, 100), (300, 200))
    post_line((600, 100), (700, 200))  # a stray checkpoint: the loader refuses it ...
    window.pump()
    assert window.editor.error is not None and "does not span the track" in window.editor.error
    pygame.image.save(window.screen, str(tmp_path / "invalid.png"))
    post_key(pygame.K_z, pygame.KMOD_LCTRL)  # ... and undo takes it back
    post_line((440, 100), (440, 200))
    post_key(pygame.K_m)  # move the finish line's ends onto x = 450
    post_line((441, 101), (450, 100))
    post_line((441, 199), (450, 200))
    post_key(pygame.K_s, pygame.KMOD_LCTRL)
    window.pump()
    pygame.image.save(window.screen, str(tmp_path / "saved.png"))
    assert window.editor.error is None, window.editor.error
    assert window.message == f"saved {window.path}"
    assert window.path.read_text() == EXPECTED
    post_key(pygame.K_ESCAPE)
    window.pump()
    assert not window.running


def test_quitting_with_unsaved_changes_asks_twice(window: EditorWindow) -> None:
    post_key(pygame.K_w)
    post_mouse(pygame.MOUSEBUTTONDOWN, 100, 100)
    post_key(pygame.K_ESCAPE)
    window.pump()
    assert window.running and window.message.startswith("unsaved changes: Esc again")
    post_key(pygame.K_g)  # another key in between: the next Esc asks again
    post_key(pygame.K_ESCAPE)
    window.pump()
    assert window.running
    pygame.event.post(pygame.event.Event(pygame.QUIT))
    window.pump()
    assert not window.running


def test_a_committed_track_opened_and_saved_is_the_same_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    path = tmp_path / "small_S.toml"
    shutil.copy(ROOT / "snnkart/tracks/small_S.toml", path)
    before = path.read_bytes()
    path.write_text("")  # saving must write it all again
    window = EditorWindow(TrackEditor(read_track_file(ROOT / "snnkart/tracks/small_S.toml")), path)
    try:
        post_key(pygame.K_s, pygame.KMOD_CTRL)
        window.pump()
    finally:
        pygame.quit()
    assert path.read_bytes() == before


def test_the_command_refuses_a_broken_file(tmp_path: Path) -> None:
    broken = tmp_path / "broken.toml"
    broken.write_text('schema = "snnkart/track/v1"\n[spawn]\nposition = [1, 2]\n')
    result = CliRunner().invoke(app, ["track", "edit", str(broken)])
    assert result.exit_code == 2
    assert "walls: missing" in result.output and "start a new one" in result.output
