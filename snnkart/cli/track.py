"""``snnkart track ...``: commands on track files: ``generate``, ``show`` and ``edit`` (the
track editor)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from snnkart.cli.guard import fail, guard

track_app = typer.Typer(help="Generate, edit and draw tracks.", no_args_is_help=True)


@track_app.command("generate")
def generate(
    seed: Annotated[
        int, typer.Option("--seed", help="generator seed (the same seed, the same file)")
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="the track file to write (.toml)")],
    kind: Annotated[
        str, typer.Option("--kind", help="loop (a closed circuit, one lap) or course (A to B)")
    ] = "loop",
    length_m: Annotated[
        float | None,
        typer.Option(
            "--length-m",
            help="centreline length: loop 14..20 m, course 12..18 m (default: from the seed)",
        ),
    ] = None,
    width_m: Annotated[
        float | None,
        typer.Option("--width-m", help="corridor width, 1..2 m (default: from the seed)"),
    ] = None,
) -> None:
    """Write a generated track (walls, checkpoints, spawn) in the track TOML format: corners
    the steer car and the gazebo robot can take, inside the renderer's 10 m world."""
    from snnkart.app.tracks import generate_track_file

    name = guard(lambda: generate_track_file(seed, kind, length_m, width_m, out))
    typer.echo(f"wrote {out} ({name}); try it: snnkart track show {out} -o track.png")


@track_app.command("show")
def show(
    track: Annotated[str, typer.Argument(help="built-in track (big_S, small_S) or a track file")],
    out: Annotated[Path, typer.Option("--out", "-o", help="the picture to write (.png)")],
    env: Annotated[
        str,
        typer.Option(
            "--env", "-e", help="whose geometry the route keeps to: grid, gazebo or steer"
        ),
    ] = "steer",
    checkpoint: Annotated[
        int,
        typer.Option("--checkpoint", help="the route field to this checkpoint line (-1: finish)"),
    ] = 0,
) -> None:
    """Draw a track: walls, checkpoints (finish in red), spawn with heading and jitter box,
    and the geodesic route field (distance and direction along the drivable route)."""
    from snnkart.app.tracks import show_track

    name = guard(lambda: show_track(track, env, checkpoint, out))
    typer.echo(f"wrote {out} ({name}, {env} geometry)")


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
