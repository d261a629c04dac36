"""The ``snnkart track`` workflows: generate a track file from a seed, and draw a track with
its checkpoints, spawn and route field (:mod:`snnkart.envs.trackgen`,
:mod:`snnkart.report.track_figure`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from snnkart.envs import make, resolve_env_name
from snnkart.envs.trackgen import generated_toml
from snnkart.envs.tracks import load_track, parse_track
from snnkart.errors import TrackError
from snnkart.io import write_bytes, write_text


def generate_track_file(
    seed: int, kind: str, length_m: float | None, width_m: float | None, out: Path
) -> str:
    """Write the track generated from ``seed`` to ``out``; return its name."""
    text = generated_toml(seed, kind, length_m, width_m)
    track = parse_track(text, source=str(out))
    write_text(out, text)
    return track.name


def show_track(track: str | Path, env: str, checkpoint: int, out: Path) -> str:
    """Draw ``track`` (a name or file) with the route field to checkpoint line ``checkpoint``
    as ``env`` computes it, into the PNG ``out``; return the track's name."""
    from snnkart.report.track_figure import track_png

    loaded = load_track(track)
    n = len(loaded.checkpoints)
    if not -n <= checkpoint < n:
        raise TrackError(
            f"{loaded.source}: no checkpoint {checkpoint}; it has {n} (0..{n - 1}, the last is "
            "the finish line)"
        )
    kart: Any = make(resolve_env_name(env), track=loaded).unwrapped
    try:
        png = track_png(loaded, kart.route_field, checkpoint % n, kart.env_name)
    finally:
        kart.close()
    write_bytes(out, png)
    return loaded.name
