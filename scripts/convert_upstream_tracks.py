"""Convert the original kart-simulator's track files into snnkart's TOML track format.

Usage: python scripts/convert_upstream_tracks.py ../shared/tracks-upstream snnkart/tracks

Writes big_S.toml (shapes.txt + sectors.txt) and small_S.toml (boxes.txt + sectors_box.txt).
The geometry is copied unchanged; only the spawn of small_S moves from the original's
(300, 450), which let 29 % of spawns overlap the back wall, to (330, 450).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

from snnkart.envs.tracks import Checkpoint, Track, parse_track, parse_upstream_polylines

ATTRIBUTION = """\
{name}: {what}
Geometry converted from the kart-simulator project by NotEnoughSnow
(github.com/NotEnoughSnow/kart-simulator, branch main_line @ ea7d18c, files {files}),
licensed under the Apache License 2.0; see LICENSE-tracks.txt beside this file.
Converted by scripts/convert_upstream_tracks.py; {change}"""

TRACKS = {
    "big_S": dict(
        walls="shapes.txt",
        sectors="sectors.txt",
        spawn=(180.0, 100.0),
        time_limit_s=90.0,
        what="the original's large circuit: one clockwise lap from the top-left straight",
        change="spawn (180, 100) heading east as in the original.",
    ),
    "small_S": dict(
        walls="boxes.txt",
        sectors="sectors_box.txt",
        spawn=(330.0, 450.0),
        time_limit_s=30.0,
        what="the original's small S-curve: three corridors joined right, then left",
        change="spawn moved from (300, 450) to (330, 450), clear of the back wall.",
    ),
}


def convert(upstream: Path, name: str) -> Track:
    spec = TRACKS[name]
    walls = parse_upstream_polylines((upstream / spec["walls"]).read_text(), spec["walls"])
    sectors = parse_upstream_polylines((upstream / spec["sectors"]).read_text(), spec["sectors"])
    return Track(
        name=name,
        walls=tuple(tuple(line) for line in walls),
        checkpoints=tuple(Checkpoint(s[0], s[1]) for s in sectors),
        spawn_position=spec["spawn"],
        spawn_heading=0.0 * math.pi,
        spawn_jitter=20.0,
        time_limit_s=spec["time_limit_s"],
        description=spec["what"],
    )


def main(upstream: str, out_dir: str) -> None:
    for name, spec in TRACKS.items():
        track = convert(Path(upstream), name)
        files = f"{spec['walls']} + {spec['sectors']}"
        text = track.to_toml(ATTRIBUTION.format(name=name, files=files, **spec))
        parse_track(text, source=name)  # validate before writing
        Path(out_dir, f"{name}.toml").write_text(text, encoding="utf-8")
        print(f"wrote {out_dir}/{name}.toml")


if __name__ == "__main__":
    main(*sys.argv[1:3])
