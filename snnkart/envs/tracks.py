"""Race tracks: loading, validation and the built-in ``big_S`` and ``small_S``.

A track is a human-editable TOML file (schema ``snnkart/track/v1``)::

    schema = "snnkart/track/v1"
    name = "my_track"
    pixels_per_metre = 100.0      # coordinates are pixels, x right, y down; 100 px = 1 m
    time_limit_s = 30.0           # episode time limit (truncation) at the default speed scale

    [spawn]
    position = [330.0, 450.0]     # kart centre, px
    heading_deg = 0.0             # 0 = +x (east); positive turns clockwise on screen
    jitter = 20.0                 # uniform offset in [-jitter, +jitter] px on each axis

    [[walls]]                     # one open polyline per table; add the first point again to close it
    points = [[277, 566], [448, 566], [448, 497]]

    [[checkpoints]]               # in driving order; the LAST checkpoint is the finish line
    a = [444, 496]
    b = [560, 404]

Validation rejects, with the file and the offending entry named: malformed TOML or numbers,
a wall with fewer than two points, no checkpoints (no finish line), a checkpoint whose ends are
not both within one kart diameter of a wall (so a kart could drive around it), and a spawn
whose jitter box lets the kart touch a wall.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from snnkart.envs.constants import KART_RADIUS_PX, PIXELS_PER_METRE
from snnkart.envs.geometry import box_segment_distance, point_segment_distance
from snnkart.errors import TrackError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised on 3.10
    import tomli as tomllib

TRACK_SCHEMA = "snnkart/track/v1"
BUILTIN_TRACKS = ("big_S", "small_S")
RANDOM_TRACK = "random"
"""The track name that asks an env for a new generated track at every reset
(:mod:`snnkart.envs.trackgen`); ``load_track`` gives its stand-in, ``tracks/random.toml``."""
RANDOM_DESCRIPTION = "a new generated track at every reset, drawn from the reset's seed"


@dataclass(frozen=True)
class Checkpoint:
    """A checkpoint line from ``a`` to ``b`` (px). The kart passes it by touching it."""

    a: tuple[float, float]
    b: tuple[float, float]

    @property
    def midpoint(self) -> tuple[float, float]:
        """The midpoint (the original's shaping goal; snnkart measures geodesic progress)."""
        return ((self.a[0] + self.b[0]) / 2.0, (self.a[1] + self.b[1]) / 2.0)


@dataclass(frozen=True)
class Track:
    """A validated track. All coordinates in px (y down); see the module docstring."""

    name: str
    walls: tuple[tuple[tuple[float, float], ...], ...]
    checkpoints: tuple[Checkpoint, ...]
    spawn_position: tuple[float, float]
    spawn_heading: float  # radians, clockwise on screen from +x
    spawn_jitter: float  # px
    time_limit_s: float
    source: str = "<memory>"
    description: str = ""
    segments: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        segs = [
            (p[0], p[1], q[0], q[1])
            for line in self.walls
            for p, q in itertools.pairwise(line)
            if p != q
        ]
        object.__setattr__(self, "segments", np.asarray(segs, dtype=np.float64).reshape(-1, 4))

    @property
    def finish(self) -> Checkpoint:
        return self.checkpoints[-1]

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of walls and checkpoints, px."""
        pts = [p for line in self.walls for p in line]
        pts += [c.a for c in self.checkpoints] + [c.b for c in self.checkpoints]
        xs, ys = zip(*pts, strict=True)
        return min(xs), min(ys), max(xs), max(ys)

    def to_toml(self, attribution: str = "") -> str:
        """Serialise to the documented TOML format (comments included)."""
        lines = [f"# {line}".rstrip() for line in attribution.splitlines()] if attribution else []
        lines += [
            f'schema = "{TRACK_SCHEMA}"',
            f"name = {json.dumps(self.name)}",
            f"description = {json.dumps(self.description)}",
            f"pixels_per_metre = {PIXELS_PER_METRE}  # x right, y down, px",
            f"time_limit_s = {self.time_limit_s}  # episode truncation at the default speed scale",
            "",
            "[spawn]",
            f"position = [{_num(self.spawn_position[0])}, {_num(self.spawn_position[1])}]  # px",
            f"heading_deg = {_num(math.degrees(self.spawn_heading))}"
            "  # 0 = +x (east), clockwise on screen",
            f"jitter = {_num(self.spawn_jitter)}  # px, uniform per axis",
        ]
        for line in self.walls:
            pts = ", ".join(f"[{_num(x)}, {_num(y)}]" for x, y in line)
            lines += ["", "[[walls]]", f"points = [{pts}]"]
        for i, cp in enumerate(self.checkpoints):
            tag = "  # finish line" if i == len(self.checkpoints) - 1 else ""
            lines += [
                "",
                f"[[checkpoints]]{tag}",
                f"a = [{_num(cp.a[0])}, {_num(cp.a[1])}]",
                f"b = [{_num(cp.b[0])}, {_num(cp.b[1])}]",
            ]
        return "\n".join(lines) + "\n"


def _num(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else repr(float(x))


def load_track(track: str | Path | Track) -> Track:
    """Load a built-in track by name (``big_S``, ``small_S``), a track file by path, or for
    ``random`` the stand-in of random tracks (see :func:`is_random`)."""
    if isinstance(track, Track):
        return track
    name = str(track)
    if name in (*BUILTIN_TRACKS, RANDOM_TRACK):
        text = resources.files("snnkart.tracks").joinpath(f"{name}.toml").read_text("utf-8")
        return parse_track(text, source=f"built-in track {name!r}")
    path = Path(name).expanduser()
    if not path.is_file():
        raise TrackError(
            f"track {name!r} is neither a built-in track ({', '.join(BUILTIN_TRACKS)}) "
            f"nor an existing file; check the name or the path"
        )
    try:
        text = path.read_text("utf-8")
    except UnicodeDecodeError as exc:
        raise TrackError(f"{path}: not a text file ({exc}); a track is a TOML file") from exc
    return parse_track(text, source=str(path))


def short_name(track: str) -> str:
    """A track as studies and results name it: a built-in's (or ``random``'s) name, a track
    file's stem (``benchmarks/tracks/ring.toml`` is ``ring``)."""
    return Path(track).stem if track.endswith(".toml") else track


def track_sha256(track: Track) -> str:
    """The content hash of a track's geometry (of its canonical TOML text)."""
    return hashlib.sha256(track.to_toml().encode()).hexdigest()


def is_random(track: str | Path | Track) -> bool:
    """Whether ``track`` asks for random tracks: the name ``random`` or its stand-in track (as
    a checkpoint or manifest embeds it)."""
    if isinstance(track, Track):
        return track.name == RANDOM_TRACK and track.description == RANDOM_DESCRIPTION
    return str(track) == RANDOM_TRACK


def is_builtin(given: str | Path) -> bool:
    return str(given) in BUILTIN_TRACKS


def embed_track(track: Track, given: str | Path) -> dict[str, str]:
    """A track as checkpoints and NIR manifests carry it: its name, how the user named it
    (a built-in name, or the file path as given), its content hash and its validated TOML, so
    a policy's track can be rebuilt on any machine without the original file."""
    return {
        "name": track.name,
        "given": str(given),
        "sha256": track_sha256(track),
        "toml": track.to_toml(),
    }


def embedded_track(record: Mapping[str, object], where: str) -> Track:
    """Rebuild a track from :func:`embed_track`'s record (``where`` names the file it is in)."""
    try:
        text = record["toml"]
        if not isinstance(text, str):
            raise TypeError(f"its toml is a {type(text).__name__}, not text")
        track = parse_track(text, source=f"track {record['name']!r} embedded in {where}")
    except (KeyError, TypeError) as exc:
        raise TrackError(f"{where}: malformed embedded track ({exc})") from exc
    if track_sha256(track) != record.get("sha256"):
        raise TrackError(f"{where}: the embedded track does not match its hash (edited by hand?)")
    return track


def track_label(name: str, given: str | Path | None) -> str:
    """How messages name a track: its name, and for a file the path as the user gave it."""
    if given is None or is_builtin(given) or str(given) == name:
        return name
    return f"{name} ({given})"


def parse_track(text: str, source: str = "<string>") -> Track:
    """Parse and validate the TOML text of a track; see the module docstring for the format."""
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise TrackError(f"{source}: not valid TOML: {exc}") from exc
    where = _Where(source)
    schema = raw.get("schema", TRACK_SCHEMA)
    if schema != TRACK_SCHEMA:
        raise TrackError(
            f"{source}: schema {schema!r} is not supported (expected {TRACK_SCHEMA!r})"
        )
    ppm = _number(raw.get("pixels_per_metre", PIXELS_PER_METRE), where("pixels_per_metre"))
    if ppm != PIXELS_PER_METRE:
        raise TrackError(
            f"{where('pixels_per_metre')}: {ppm} is not supported; tracks use "
            f"{PIXELS_PER_METRE} px per metre (scale the coordinates instead)"
        )
    walls = _walls(raw.get("walls"), where)
    checkpoints = _checkpoints(raw.get("checkpoints"), where)
    spawn = _table(raw.get("spawn"), where("spawn"))
    pos = _point(spawn.get("position"), where("spawn.position"))
    heading = math.radians(_number(spawn.get("heading_deg", 0.0), where("spawn.heading_deg")))
    jitter = _number(spawn.get("jitter", 0.0), where("spawn.jitter"))
    if jitter < 0:
        raise TrackError(f"{where('spawn.jitter')}: must be >= 0, got {jitter}")
    time_limit = _number(raw.get("time_limit_s", 60.0), where("time_limit_s"))
    if time_limit <= 0:
        raise TrackError(f"{where('time_limit_s')}: must be > 0, got {time_limit}")
    track = Track(
        name=str(raw.get("name", Path(source).stem)),
        walls=tuple(walls),
        checkpoints=tuple(checkpoints),
        spawn_position=pos,
        spawn_heading=heading,
        spawn_jitter=jitter,
        time_limit_s=time_limit,
        source=source,
        description=str(raw.get("description", "")),
    )
    _validate_geometry(track, where)
    return track


def _walls(walls_raw: Any, where: _Where) -> list[tuple[tuple[float, float], ...]]:
    if not isinstance(walls_raw, list) or not walls_raw:
        raise TrackError(f"{where('walls')}: missing; add at least one [[walls]] table with points")
    walls = []
    for i, w in enumerate(walls_raw):
        pts = _points(_table(w, where(f"walls[{i}]")).get("points"), where(f"walls[{i}].points"))
        if len(pts) < 2:
            raise TrackError(
                f"{where(f'walls[{i}].points')}: too few points ({len(pts)}); "
                "a wall polyline needs at least 2"
            )
        walls.append(tuple(pts))
    return walls


def _checkpoints(cps_raw: Any, where: _Where) -> list[Checkpoint]:
    if not isinstance(cps_raw, list) or not cps_raw:
        raise TrackError(
            f"{where('checkpoints')}: missing finish line; add at least one [[checkpoints]] "
            "table (the last one is the finish line)"
        )
    checkpoints = []
    for i, c in enumerate(cps_raw):
        tbl = _table(c, where(f"checkpoints[{i}]"))
        a = _point(tbl.get("a"), where(f"checkpoints[{i}].a"))
        b = _point(tbl.get("b"), where(f"checkpoints[{i}].b"))
        if a == b:
            raise TrackError(f"{where(f'checkpoints[{i}]')}: a and b are the same point")
        checkpoints.append(Checkpoint(a, b))
    return checkpoints


def _validate_geometry(track: Track, where: _Where) -> None:
    segs = track.segments
    if len(segs) == 0:
        raise TrackError(f"{where('walls')}: all wall points coincide; no wall segment left")
    reach = 2.0 * KART_RADIUS_PX
    for i, cp in enumerate(track.checkpoints):
        for end in ("a", "b"):
            p = getattr(cp, end)
            gap = float(point_segment_distance(p, segs).min())
            if gap >= reach:
                kind = "finish line" if i == len(track.checkpoints) - 1 else "checkpoint"
                raise TrackError(
                    f"{where(f'checkpoints[{i}].{end}')}: {kind} does not span the track: its end "
                    f"{list(p)} is {gap:.1f} px from the nearest wall, so a kart "
                    f"({reach:.1f} px wide) can drive around it; move the end onto a wall"
                )
    # The whole jitter box must keep the kart clear of every wall.
    clearance = box_segment_distance(track.spawn_position, track.spawn_jitter, segs)
    if clearance <= KART_RADIUS_PX:
        raise TrackError(
            f"{where('spawn.position')}: the spawn {list(track.spawn_position)} is inside or "
            f"touching a wall: with the spawn jitter (+-{track.spawn_jitter} px per axis) the "
            f"kart centre can come within {clearance:.1f} px of a wall, less than the kart "
            f"radius ({KART_RADIUS_PX} px); move the spawn or reduce the jitter"
        )
    cp_segs = np.asarray([[*c.a, *c.b] for c in track.checkpoints], dtype=np.float64)
    for i in range(len(cp_segs)):
        gap = box_segment_distance(track.spawn_position, track.spawn_jitter, cp_segs[i : i + 1])
        if gap <= KART_RADIUS_PX:
            raise TrackError(
                f"{where('spawn.position')}: the kart can spawn touching checkpoints[{i}] "
                f"({gap:.1f} px away); move the spawn or the checkpoint"
            )


class _Where:
    def __init__(self, source: str) -> None:
        self.source = source

    def __call__(self, key: str) -> str:
        return f"{self.source}: {key}"


def _table(value: object, where: str) -> dict[str, object]:
    if not isinstance(value, dict):
        raise TrackError(f"{where}: expected a table, got {value!r}")
    return value


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TrackError(f"{where}: expected a number, got {value!r}")
    if not math.isfinite(value):
        raise TrackError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


def _point(value: Any, where: str) -> tuple[float, float]:
    if not isinstance(value, list) or len(value) != 2:
        raise TrackError(f"{where}: expected a point [x, y] of two numbers, got {value!r}")
    return (_number(value[0], f"{where}[0]"), _number(value[1], f"{where}[1]"))


def _points(value: Any, where: str) -> list[tuple[float, float]]:
    if not isinstance(value, list):
        raise TrackError(f"{where}: expected a list of points [[x, y], ...], got {value!r}")
    return [_point(p, f"{where}[{j}]") for j, p in enumerate(value)]


def parse_upstream_polylines(text: str, source: str) -> list[list[tuple[float, float]]]:
    """Read the original kart-simulator's track text: CR-separated CSV rows of ``"(x, y)"``."""
    import ast
    import csv

    rows = []
    for k, row in enumerate(csv.reader(text.splitlines())):
        if not row:
            continue
        pts = []
        for field_ in row:
            try:
                x, y = ast.literal_eval(field_)
            except (ValueError, SyntaxError, TypeError) as exc:
                raise TrackError(f"{source}: record {k + 1}: malformed point {field_!r}") from exc
            pts.append((float(x), float(y)))
        rows.append(pts)
    return rows
