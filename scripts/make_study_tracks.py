"""Write the study's held-out tracks (``benchmarks/tracks/*.toml``) from centrelines.

Each track is a corridor of constant width around a centreline, built by
:mod:`snnkart.envs.trackgen` (the package's generator uses the same code). These tracks exist
to measure whether training
defaults generalise: nobody tunes on them (issue 17).

It also writes the generalisation study's reporting tracks, generated from the committed seed
list ``snnkart.envs.trackgen.REPORTING_SEEDS``, to ``benchmarks/tracks/generated/``.

    python scripts/make_study_tracks.py            # rewrites benchmarks/tracks/*.toml
"""

from __future__ import annotations

from pathlib import Path

from snnkart.envs.trackgen import KINDS, REPORTING_SEEDS, Design, generated_toml, track_toml

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "tracks"


DESIGNS = [
    Design(
        "ring",
        "a square ring: four 90-degree left corners, 1.2 m corridors, one lap (a user's first "
        "track in issue 17, where a steer SNN seed learned to stand still)",
        [(0, 0), (5, 0), (5, -5), (0, -5)],
        1.2,
        closed=True,
    ),
    Design(
        "zigzag",
        "sharp corners: a 60-degree right, a 120-degree left and a 60-degree right turn, "
        "1.0 m corridors",
        [(0, 0), (2.2, 0), (3.6, 2.4), (5.0, 0.0), (7.2, 0.0)],
        1.0,
    ),
    Design(
        "hairpins",
        "two U-turns of two 90-degree corners each, long straights, wide 1.6 m corridors",
        [(0, 0), (6, 0), (6, 2.6), (0, 2.6), (0, 5.2), (4, 5.2)],
        1.6,
    ),
    Design(
        "bends",
        "gentle 45-degree bends turning right through 180 degrees, 1.3 m corridors",
        [(0, 0), (3, 0), (5.1, 2.1), (5.1, 5.1), (3.0, 7.2), (0.0, 7.2)],
        1.3,
    ),
]


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    for design in DESIGNS:
        path = OUT / f"{design.name}.toml"
        path.write_text(track_toml(design))
        print(f"wrote {path.relative_to(ROOT)}")
    (OUT / "generated").mkdir(exist_ok=True)
    for seed in REPORTING_SEEDS:
        kind = KINDS[seed % 2]
        path = OUT / "generated" / f"{kind}-{seed}.toml"
        path.write_text(generated_toml(seed, kind))
        print(f"wrote {path.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
