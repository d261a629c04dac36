"""Track files: the built-in tracks, validation errors that name problem and place, round trips."""

from __future__ import annotations

import dataclasses
import importlib.util
import math
from importlib import resources
from pathlib import Path

import pytest

from snnkart.envs.grid import GridEnv
from snnkart.envs.tracks import BUILTIN_TRACKS, Track, TrackError, load_track, parse_track

UPSTREAM_DIR = Path(__file__).resolve().parent / "data" / "tracks-upstream"
"""The original project's track files, vendored with their licence (see its README.md)."""
CONVERTER = Path(__file__).resolve().parents[1] / "scripts" / "convert_upstream_tracks.py"

# A valid 400 x 400 px box; tests below break one thing at a time.
VALID = """\
schema = "snnkart/track/v1"
name = "box"
time_limit_s = 20.0

[spawn]
position = [300, 300]
heading_deg = 0
jitter = 10

[[walls]]
points = [[100, 100], [500, 100], [500, 500], [100, 500], [100, 100]]

[[checkpoints]]
a = [100, 200]
b = [500, 200]
"""


def builtin_text(name: str) -> str:
    return resources.files("snnkart.tracks").joinpath(f"{name}.toml").read_text("utf-8")


def assert_same_geometry(a: Track, b: Track) -> None:
    """Walls, checkpoints and spawn equal exactly (not approximately)."""
    assert a.walls == b.walls
    assert a.checkpoints == b.checkpoints
    assert a.spawn_position == b.spawn_position
    assert a.spawn_heading == b.spawn_heading
    assert a.spawn_jitter == b.spawn_jitter


# -- loading ------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", BUILTIN_TRACKS)
def test_builtin_tracks_load(name):
    """Both built-in tracks load by name, with walls, a finish line and a spawn clear of walls."""
    track = load_track(name)
    assert track.name == name
    assert len(track.walls) >= 1 and len(track.checkpoints) >= 1
    assert track.segments.shape[1] == 4 and len(track.segments) > 0
    assert track.spawn_jitter == 20.0
    assert track.time_limit_s > 0
    assert name in track.source


def test_builtin_names():
    """The issue's two built-in tracks are big_S and small_S."""
    assert set(BUILTIN_TRACKS) == {"big_S", "small_S"}


def test_user_track_loads_by_path(tmp_path):
    """A valid TOML file is loaded by path (str or Path) and drives an env."""
    path = tmp_path / "my_box.toml"
    path.write_text(VALID, encoding="utf-8")
    for ref in (path, str(path)):
        track = load_track(ref)
        assert track.name == "box"
        assert track.source == str(path)
        assert track.spawn_position == (300.0, 300.0)
        assert track.walls == (((100, 100), (500, 100), (500, 500), (100, 500), (100, 100)),)
    env = GridEnv(track=str(path))
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)


def test_track_name_defaults_to_file_stem(tmp_path):
    """Without a ``name`` key the track is named after its file."""
    path = tmp_path / "nameless.toml"
    path.write_text(VALID.replace('name = "box"\n', ""), encoding="utf-8")
    assert load_track(path).name == "nameless"


# -- validation errors --------------------------------------------------------------------------


def parse_error(text: str, source: str = "t.toml") -> str:
    """Parse ``text``; return the TrackError message (fails if none is raised)."""
    with pytest.raises(TrackError) as excinfo:
        parse_track(text, source=source)
    return str(excinfo.value)


def test_track_error_is_a_value_error():
    """Callers can catch track problems as ValueError."""
    assert issubclass(TrackError, ValueError)


def test_malformed_toml_names_the_line():
    """Broken TOML syntax: the message says so and gives the line."""
    msg = parse_error(VALID.replace("time_limit_s = 20.0", "time_limit_s = = 20.0"))
    assert "t.toml" in msg
    assert "not valid TOML" in msg
    assert "line 3" in msg


def test_non_numeric_coordinate_names_the_point():
    """A string where a number belongs: the message names walls[0].points[1]."""
    msg = parse_error(VALID.replace("[500, 100], [500, 500]", '["500", 100], [500, 500]'))
    assert "walls[0].points[1]" in msg
    assert "expected a number" in msg
    assert "'500'" in msg


def test_bool_is_not_a_number():
    """``true`` is rejected as a coordinate even though Python's bool is an int."""
    msg = parse_error(VALID.replace("position = [300, 300]", "position = [true, 300]"))
    assert "spawn.position[0]" in msg


def test_missing_checkpoints_is_a_missing_finish_line():
    """A track without [[checkpoints]] has no finish line."""
    text = VALID.split("[[checkpoints]]")[0]
    msg = parse_error(text)
    assert "checkpoints" in msg
    assert "missing finish line" in msg


def test_missing_walls():
    """A track without [[walls]] is rejected naming ``walls``."""
    text = VALID.replace(
        "[[walls]]\npoints = [[100, 100], [500, 100], [500, 500], [100, 500], [100, 100]]\n", ""
    )
    msg = parse_error(text)
    assert "walls" in msg and "missing" in msg


def test_wall_with_one_point():
    """A wall polyline needs two points; the message names the wall."""
    text = VALID + "\n[[walls]]\npoints = [[300, 450]]\n"
    msg = parse_error(text)
    assert "walls[1].points" in msg
    assert "too few points" in msg


def test_spawn_touching_a_wall():
    """A spawn 15 px from a wall (kart radius 19.2 px) is rejected, naming spawn.position."""
    text = VALID.replace("position = [300, 300]", "position = [300, 485]")
    msg = parse_error(text.replace("jitter = 10", "jitter = 0"))
    assert "spawn.position" in msg
    assert "inside or touching a wall" in msg


def test_spawn_jitter_box_reaching_a_wall():
    """The spawn is clear, but the jitter box lets the kart touch a wall: rejected."""
    text = VALID.replace("position = [300, 300]", "position = [300, 460]")
    parse_track(text.replace("jitter = 10", "jitter = 0"))  # 40 px clearance: fine
    msg = parse_error(text.replace("jitter = 10", "jitter = 25"))
    assert "inside or touching a wall" in msg


def test_original_small_s_spawn_is_rejected():
    """The original's small_S spawn (300, 450) with jitter 20 can overlap the back wall."""
    text = builtin_text("small_S")
    assert "position = [330, 450]" in text
    msg = parse_error(text.replace("position = [330, 450]", "position = [300, 450]"), "small_S")
    assert "spawn.position" in msg
    assert "inside or touching a wall" in msg


def test_spawn_touching_a_checkpoint():
    """A kart that would spawn on a checkpoint is rejected."""
    msg = parse_error(VALID.replace("position = [300, 300]", "position = [300, 215]"))
    assert "spawn.position" in msg
    assert "checkpoints[0]" in msg


def test_checkpoint_that_does_not_span_the_track():
    """A checkpoint end 100 px from every wall: a kart could drive around it."""
    msg = parse_error(VALID.replace("b = [500, 200]", "b = [400, 200]"))
    assert "checkpoints[0].b" in msg
    assert "does not span the track" in msg


def test_degenerate_checkpoint():
    """A checkpoint whose two ends coincide is rejected."""
    msg = parse_error(VALID.replace("b = [500, 200]", "b = [100, 200]"))
    assert "checkpoints[0]" in msg and "same point" in msg


def test_unsupported_schema_and_scale():
    """Another schema version or another pixel scale is refused with the expected value."""
    msg = parse_error(VALID.replace("snnkart/track/v1", "snnkart/track/v9"))
    assert "snnkart/track/v9" in msg and "snnkart/track/v1" in msg
    msg = parse_error(VALID.replace("time_limit_s", "pixels_per_metre = 50\ntime_limit_s"))
    assert "pixels_per_metre" in msg and "100.0" in msg


def test_missing_file_path():
    """A name that is neither built-in nor a file: the message lists the built-in tracks."""
    with pytest.raises(TrackError, match="neither a built-in track") as excinfo:
        load_track("no/such/track.toml")
    assert "big_S" in str(excinfo.value) and "small_S" in str(excinfo.value)


def test_error_in_a_file_names_the_file(tmp_path):
    """Errors in a track file carry its path."""
    path = tmp_path / "bad.toml"
    path.write_text(VALID.replace("b = [500, 200]", "b = [400, 200]"), encoding="utf-8")
    with pytest.raises(TrackError) as excinfo:
        load_track(path)
    assert str(path) in str(excinfo.value)


def test_env_rejects_invalid_track_file(tmp_path):
    """Constructing an env with an invalid track fails with the TrackError."""
    path = tmp_path / "bad.toml"
    path.write_text(VALID.split("[[checkpoints]]")[0], encoding="utf-8")
    with pytest.raises(TrackError, match="missing finish line"):
        GridEnv(track=path)


# -- round trips --------------------------------------------------------------------------------


@pytest.mark.parametrize("name", BUILTIN_TRACKS)
def test_builtin_track_toml_round_trip(name):
    """Track.to_toml() parses back to the same walls, checkpoints and spawn."""
    track = load_track(name)
    again = parse_track(track.to_toml(attribution="round trip\nsecond line"), source="rt")
    assert_same_geometry(track, again)
    assert again.name == track.name
    assert again.time_limit_s == track.time_limit_s
    assert again.description == track.description


def test_round_trip_keeps_fractional_coordinates_and_heading(tmp_path):
    """Non-integer coordinates and a heading survive to_toml() -> file -> load_track exactly."""
    text = (
        VALID.replace("[500, 100]", "[500.25, 100.125]")
        .replace("heading_deg = 0", "heading_deg = 37.5")
        .replace("jitter = 10", "jitter = 7.5")
    )
    track = parse_track(text)
    assert math.degrees(track.spawn_heading) == pytest.approx(37.5)
    path = tmp_path / "rt.toml"
    path.write_text(track.to_toml(), encoding="utf-8")
    assert_same_geometry(track, load_track(path))


@pytest.mark.parametrize(
    "text",
    ['the "fast" one', "C:\\tracks\\new", "two\nlines"],
    ids=["double-quote", "backslash", "newline"],
)
@pytest.mark.parametrize("field", ["name", "description"])
def test_round_trip_escapes_text(field, text):
    """Names and descriptions with quotes, backslashes or newlines (all valid in a TOML
    string) survive to_toml() -> parse_track unchanged, instead of breaking the file."""
    track = dataclasses.replace(load_track("small_S"), **{field: text})
    again = parse_track(track.to_toml(), source="rt")
    assert getattr(again, field) == text
    assert_same_geometry(track, again)


# -- the shipped tracks come from the upstream files ----------------------------------------------


def load_converter():
    spec = importlib.util.spec_from_file_location("convert_upstream_tracks", CONVERTER)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("name", BUILTIN_TRACKS)
def test_builtin_tracks_match_upstream_conversion(name):
    """Converting the original kart-simulator files reproduces the shipped geometry exactly."""
    converted = load_converter().convert(UPSTREAM_DIR, name)
    shipped = load_track(name)
    assert_same_geometry(converted, shipped)
    assert converted.time_limit_s == shipped.time_limit_s
    # and the converted track passes validation as it is
    assert_same_geometry(converted, parse_track(converted.to_toml(), source=name))
