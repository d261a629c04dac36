"""The track editor's model: a track being drawn, edited by mouse and key events (no pygame).

``snnkart track edit`` (:mod:`snnkart.cli.track_editor`) turns pygame events into calls of
:class:`TrackEditor` in track coordinates (px, x right, y down) and draws :attr:`TrackEditor.state`;
the tests drive the same calls. One tool is active at a time:

============  ===  =====================================================================
tool          key  mouse
============  ===  =====================================================================
``wall``      W    a left click adds a point to the wall being drawn (the first starts it);
                   Enter or a right click ends it
``checkpoint`` C   press at one end, release at the other; checkpoints are driven in the
                   order drawn, the last is the finish line
``spawn``     S    press at the kart's position, release in the direction it faces
``move``      M    drag a wall point, a checkpoint end or the spawn; Delete removes the
                   point or checkpoint under the mouse
============  ===  =====================================================================

Ctrl+Z undoes the last change; points snap to whole pixels (G: to a 10 px grid). The track is
validated after every change by the loader itself (:func:`snnkart.envs.tracks.parse_track`):
:attr:`TrackEditor.error` is its message, or ``None`` for a valid track, which :meth:`save`
writes in the loader's format; the comment lines heading a loaded file are kept.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path

from snnkart.envs.tracks import Checkpoint, Track, parse_track
from snnkart.errors import TrackError

Point = tuple[float, float]
TOOLS = {"w": "wall", "c": "checkpoint", "s": "spawn", "m": "move"}
PICK_RADIUS_PX = 8.0
"""How close (px) a press must be to a point for the move tool to take it."""
GRID_PX = 10.0
"""The coarse snap (G toggles it); otherwise points snap to whole pixels."""
MIN_HEADING_DRAG_PX = 5.0
"""A spawn release closer than this to the press keeps the heading as it was."""


@dataclass
class EditedTrack:
    """The editable geometry and settings of a track (a :class:`Track` before validation)."""

    name: str
    walls: list[list[Point]] = field(default_factory=list)
    checkpoints: list[list[Point]] = field(default_factory=list)  # [a, b] each
    spawn: Point | None = None
    heading_deg: float = 0.0
    jitter: float = 0.0
    time_limit_s: float = 30.0
    description: str = ""
    header: str = ""  # the comment lines heading the file, without their "# "

    @classmethod
    def from_track(cls, track: Track, header: str = "") -> EditedTrack:
        return cls(
            name=track.name,
            walls=[list(w) for w in track.walls],
            checkpoints=[[c.a, c.b] for c in track.checkpoints],
            spawn=track.spawn_position,
            heading_deg=math.degrees(track.spawn_heading),
            jitter=track.spawn_jitter,
            time_limit_s=track.time_limit_s,
            description=track.description,
            header=header,
        )

    def to_toml(self) -> str:
        """The track file's text, in :meth:`Track.to_toml`'s format (whether valid or not)."""
        track = Track(
            name=self.name,
            walls=tuple(tuple(w) for w in self.walls),
            checkpoints=tuple(Checkpoint(a, b) for a, b in self.checkpoints),
            spawn_position=self.spawn if self.spawn is not None else (0.0, 0.0),
            spawn_heading=_exact_radians(self.heading_deg),
            spawn_jitter=self.jitter,
            time_limit_s=self.time_limit_s,
            description=self.description,
        )
        return track.to_toml(attribution=self.header)


def _exact_radians(deg: float) -> float:
    """Radians that :func:`math.degrees` turns back into ``deg`` exactly (so the file says
    ``heading_deg = 45``, not ``44.99999999999999``), else ``math.radians(deg)``."""
    rad = math.radians(deg)
    for direction in (math.inf, -math.inf):
        r = rad
        for _ in range(4):
            if math.degrees(r) == deg:
                return r
            r = math.nextafter(r, direction)
    return rad


def read_track_file(path: Path) -> EditedTrack:
    """A track file to edit: validated by the loader, its heading comment lines kept."""
    text = path.read_text("utf-8")
    comments = []
    for line in text.splitlines():
        if not line.startswith("#"):
            break
        comments.append(line[2:] if line.startswith("# ") else line[1:])
    return EditedTrack.from_track(parse_track(text, source=str(path)), "\n".join(comments))


class TrackEditor:
    """Edits one :class:`EditedTrack` by mouse and key events; see the module docstring."""

    def __init__(self, track: EditedTrack) -> None:
        self.state = track
        self.tool = "wall"
        self.grid = False
        self.drawing: list[Point] | None = None  # the wall being drawn (part of state.walls)
        self.pressed: Point | None = None  # checkpoint and spawn tools: where the press was
        self.held: tuple[str, int, int] | None = None  # the move tool's point: kind, i, j
        self.history: list[EditedTrack] = []
        self.error: str | None = None
        self.validate()

    # -- events ---------------------------------------------------------------------------

    def key(self, name: str, ctrl: bool = False) -> None:
        """A key press: ``name`` is the key's lower-case name (``"w"``, ``"return"``, ...)."""
        if ctrl and name == "z":
            self.undo()
        elif name in TOOLS and not ctrl:
            self.finish_wall()
            self.tool = TOOLS[name]
        elif name == "g":
            self.grid = not self.grid
        elif name in ("return", "enter"):
            self.finish_wall()

    def press(self, pos: Point, button: int = 1) -> None:
        """A mouse button goes down at ``pos`` (1 left, 3 right)."""
        p = self.snap(pos)
        if button == 3:
            self.finish_wall()
        elif button != 1:
            return
        elif self.tool == "wall":
            self._add_wall_point(p)
        elif self.tool in ("checkpoint", "spawn"):
            self.pressed = p
            if self.tool == "spawn":
                self._change()
                self.state.spawn = p
        elif self.tool == "move":
            self.held = self.pick(pos)
            if self.held is not None:
                self._change()

    def drag(self, pos: Point) -> None:
        """The mouse moves with the left button down."""
        if self.tool == "move" and self.held is not None:
            self._set_point(self.held, self.snap(pos))
        elif self.tool == "spawn" and self.pressed is not None:
            self._aim(pos)

    def release(self, pos: Point, button: int = 1) -> None:
        """The left mouse button goes up at ``pos``."""
        if button != 1:
            return
        p = self.snap(pos)
        if self.tool == "checkpoint" and self.pressed is not None and p != self.pressed:
            self._change()
            self.state.checkpoints.append([self.pressed, p])
        elif self.tool == "spawn" and self.pressed is not None:
            self._aim(pos)
        elif self.tool == "move" and self.held is not None:
            self._set_point(self.held, p)
        self.pressed, self.held = None, None
        self.validate()

    def delete(self, pos: Point) -> None:
        """Remove the wall point (a wall left with one point goes) or checkpoint at ``pos``."""
        hit = self.pick(pos)
        if hit is None or hit[0] == "spawn":
            return
        self._change()
        kind, i, j = hit
        if kind == "checkpoint":
            del self.state.checkpoints[i]
        else:
            del self.state.walls[i][j]
            if len(self.state.walls[i]) < 2:
                del self.state.walls[i]
        self.validate()

    def undo(self) -> None:
        """Go back to the state before the last change (nothing happens with no change left)."""
        self.drawing = None
        if self.history:
            self.state = self.history.pop()
        self.validate()

    # -- queries --------------------------------------------------------------------------

    def snap(self, pos: Point) -> Point:
        step = GRID_PX if self.grid else 1.0
        return (round(pos[0] / step) * step, round(pos[1] / step) * step)

    def pick(self, pos: Point) -> tuple[str, int, int] | None:
        """The point nearest ``pos`` within :data:`PICK_RADIUS_PX`: ("wall", wall, point),
        ("checkpoint", checkpoint, 0 for a or 1 for b) or ("spawn", 0, 0)."""
        candidates = [("spawn", 0, 0, self.state.spawn)] if self.state.spawn else []
        candidates += [
            ("checkpoint", i, j, end)
            for i, cp in enumerate(self.state.checkpoints)
            for j, end in enumerate(cp)
        ]
        candidates += [
            ("wall", i, j, p) for i, wall in enumerate(self.state.walls) for j, p in enumerate(wall)
        ]
        best = min(candidates, key=lambda c: math.dist(pos, c[3]), default=None)
        if best is None or math.dist(pos, best[3]) > PICK_RADIUS_PX:
            return None
        return best[0], best[1], best[2]

    def validate(self) -> str | None:
        """Check the track with the loader; keep and return its message (None: valid)."""
        if self.state.spawn is None:
            self.error = "no spawn yet: choose the spawn tool (S) and press where the kart starts"
        else:
            try:
                parse_track(self.state.to_toml(), source=self.state.name)
                self.error = None
            except TrackError as exc:
                self.error = str(exc)
        return self.error

    def save(self, path: Path) -> None:
        """Write the track file; refuse (with the loader's message) while it is invalid."""
        if self.validate() is not None:
            raise TrackError(f"not saved: {self.error}")
        path.write_text(self.state.to_toml(), "utf-8")

    # -- changes --------------------------------------------------------------------------

    def finish_wall(self) -> None:
        """End the wall being drawn; a wall of a single point is dropped."""
        if self.drawing is not None and len(self.drawing) < 2:
            self.state.walls.remove(self.drawing)
        self.drawing = None
        self.validate()

    def _add_wall_point(self, p: Point) -> None:
        self._change()
        if self.drawing is None:
            self.drawing = [p]
            self.state.walls.append(self.drawing)
        elif p != self.drawing[-1]:
            self.drawing.append(p)
        self.validate()

    def _aim(self, pos: Point) -> None:
        spawn, pos = self.state.spawn, self.snap(pos)
        if spawn is not None and math.dist(spawn, pos) >= MIN_HEADING_DRAG_PX:
            self.state.heading_deg = float(
                round(math.degrees(math.atan2(pos[1] - spawn[1], pos[0] - spawn[0])))
            )

    def _set_point(self, hit: tuple[str, int, int], p: Point) -> None:
        kind, i, j = hit
        if kind == "spawn":
            self.state.spawn = p
        elif kind == "checkpoint":
            self.state.checkpoints[i][j] = p
        else:
            self.state.walls[i][j] = p

    def _change(self) -> None:
        """Remember the state before a change, for :meth:`undo`."""
        saved = copy.deepcopy(self.state)
        self.history.append(saved)
        if self.drawing is not None:  # keep drawing into the live copy's open wall
            self.drawing = self.state.walls[-1]
