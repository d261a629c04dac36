"""The track editor's model (:mod:`snnkart.envs.track_edit`), driven by mouse and key events:
a track drawn by events is the expected file, the loader's own messages come live, undo
goes back, and a committed track loaded and saved unedited is the same file byte for byte."""

from __future__ import annotations

from pathlib import Path

import pytest

from snnkart.envs.track_edit import EditedTrack, TrackEditor, read_track_file
from snnkart.envs.tracks import load_track
from snnkart.errors import TrackError

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = [ROOT / "snnkart/tracks/small_S.toml", ROOT / "snnkart/tracks/big_S.toml"]
EXPECTED = (ROOT / "tests/data/editor/corridor.toml").read_text()
"""The file :func:`draw_corridor` draws."""


def click(ed: TrackEditor, x: float, y: float, button: int = 1) -> None:
    ed.press((x, y), button)
    ed.release((x, y), button)


def line(ed: TrackEditor, a: tuple[float, float], b: tuple[float, float]) -> None:
    ed.press(a)
    ed.drag(((a[0] + b[0]) / 2, (a[1] + b[1]) / 2))
    ed.release(b)


def draw_corridor(ed: TrackEditor) -> None:
    """A U-shaped wall, a checkpoint and the finish line, the spawn facing east (the points a
    little off the pixel grid, which the editor snaps to)."""
    ed.key("w")
    for x, y in [(500.2, 99.7), (100, 100), (99.6, 200.4)]:
        click(ed, x, y)
    click(ed, 500, 200)
    ed.key("return")
    ed.key("c")
    line(ed, (300, 100), (300, 200))
    line(ed, (450, 100), (450, 200))
    ed.key("s")
    line(ed, (150, 150), (250, 150.4))


def test_a_track_drawn_by_events_is_the_expected_file(tmp_path: Path) -> None:
    ed = TrackEditor(EditedTrack(name="corridor"))
    draw_corridor(ed)
    assert ed.error is None
    ed.save(tmp_path / "corridor.toml")
    assert (tmp_path / "corridor.toml").read_text() == EXPECTED
    assert load_track(tmp_path / "corridor.toml").checkpoints[-1].a == (450, 100)


@pytest.mark.parametrize("path", COMMITTED, ids=lambda p: p.name)
def test_a_committed_track_saved_unedited_is_the_same_file(path: Path, tmp_path: Path) -> None:
    ed = TrackEditor(read_track_file(path))
    assert ed.error is None
    ed.save(tmp_path / path.name)
    assert (tmp_path / path.name).read_bytes() == path.read_bytes()


def test_the_loader_s_messages_come_live_and_undo_goes_back() -> None:
    ed = TrackEditor(EditedTrack(name="corridor"))
    assert ed.error is not None and "no spawn yet" in ed.error
    draw_corridor(ed)
    ed.key("c")
    line(ed, (600, 150), (700, 150))  # far from any wall: a kart can drive around it
    assert ed.error is not None
    assert "checkpoints[2].a: finish line does not span the track" in ed.error
    with pytest.raises(TrackError, match="not saved: corridor: checkpoints"):
        ed.save(Path("never-written.toml"))
    ed.key("z", ctrl=True)
    assert ed.error is None and ed.state.to_toml() == EXPECTED
    ed.key("s")
    click(ed, 110, 150)  # the kart would touch the back wall
    assert ed.error is not None and "spawn.position" in ed.error and "touching a wall" in ed.error
    ed.key("z", ctrl=True)
    assert ed.state.to_toml() == EXPECTED


def test_move_delete_and_grid() -> None:
    ed = TrackEditor(EditedTrack(name="corridor"))
    draw_corridor(ed)
    ed.key("m")
    line(ed, (303, 104), (320.4, 99))  # within reach of checkpoint 0's end a: moved
    assert ed.state.checkpoints[0] == [(320, 99), (300, 200)]
    line(ed, (148, 152), (160, 150))  # the spawn
    assert ed.state.spawn == (160, 150) and ed.state.heading_deg == 0
    ed.delete((451, 199))  # the finish line goes
    assert len(ed.state.checkpoints) == 1
    ed.delete((500, 101))  # a wall's end point
    assert ed.state.walls[0][0] == (100, 100)
    for _ in range(4):
        ed.key("z", ctrl=True)
    assert ed.state.to_toml() == EXPECTED
    ed.key("g")
    assert ed.snap((104.9, 96)) == (100, 100)
    ed.key("w")
    click(ed, 10, 10)
    ed.key("c")  # a wall of one point is dropped when the tool changes
    assert ed.state.to_toml() == EXPECTED


def test_the_spawn_heading_is_written_in_whole_degrees(tmp_path: Path) -> None:
    ed = TrackEditor(EditedTrack(name="corridor"))
    draw_corridor(ed)
    ed.key("s")
    line(ed, (150, 150), (240, 110))  # up and to the right: -24 degrees
    assert ed.error is None and ed.state.heading_deg == -24
    ed.save(tmp_path / "t.toml")
    assert "heading_deg = -24  #" in (tmp_path / "t.toml").read_text()
