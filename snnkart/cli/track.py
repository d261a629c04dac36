"""``snnkart track ...``: commands on track files (``track edit``: the track editor)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from snnkart.cli.guard import fail

track_app = typer.Typer(help="Draw and edit track files.", no_args_is_help=True)


@track_app.command("edit")
def edit(
    file: Annotated[
        Path,
        typer.Argument(help="the track file to edit, or to create when it does not exist"),
    ] = Path("track.toml"),
) -> None:
    """Draw walls, checkpoints and the spawn with the mouse; the loader checks the track live.

    Keys: W wall, C checkpoint, S spawn, M move, Delete removes the point under the mouse, G a
    10 px grid, Ctrl+Z undo, Ctrl+S save (only a track the loader accepts), Esc quit."""
    from snnkart.cli.track_editor import EditorWindow
    from snnkart.envs.track_edit import EditedTrack, TrackEditor, read_track_file
    from snnkart.errors import TrackError

    try:
        state = read_track_file(file) if file.exists() else EditedTrack(name=file.stem)
    except (TrackError, OSError, UnicodeDecodeError) as exc:
        fail(f"{exc}; fix the file in a text editor or start a new one")
    EditorWindow(TrackEditor(state), file).run()
