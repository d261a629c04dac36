"""The results protocol (docs/results.md): which training seeds and tracks are tuning data, on
which defaults may be chosen, and which are reporting data, which no choice may touch.

Every study config declares one (``data = "tuning"`` or ``data = "reporting"``) and may use only
that kind's seeds and tracks; :func:`check_study_data` refuses a mix, naming the seed or track.
A track is known by its name (a built-in) or its file's stem (``benchmarks/tracks/ring.toml`` is
the ring).
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from snnkart.envs.trackgen import reporting_track_names

DataKind = Literal["tuning", "reporting"]
"""What a study's runs are for: choosing defaults, or the published numbers."""

TUNING_SEEDS = range(1, 101)
"""Training seeds 1-100: free to tune on."""
FIRST_REPORTING_SEED = 101
"""Training seeds 101 and up: reporting only."""
TUNING_TRACKS: tuple[str, ...] = ("small_S", "big_S", "ring", "hairpins")
"""The tracks defaults were (or may be) chosen on."""
REPORTING_TRACKS: tuple[str, ...] = ("zigzag", "bends", *reporting_track_names())
"""The tracks no choice has touched: zigzag, bends, and the generated tracks of the committed
seed list ``snnkart.envs.trackgen.REPORTING_SEEDS`` (``benchmarks/tracks/generated/``), which
``track="random"`` never draws."""


def track_name(track: str) -> str:
    """A built-in track's name, or a track file's stem."""
    return Path(track).stem if track.endswith(".toml") else track


def data_problem(kind: DataKind, seeds: list[int], tracks: list[str]) -> str | None:
    """What in ``seeds`` and ``tracks`` is not ``kind`` data, in one line; None when all is."""
    if kind == "tuning":
        seed = next((s for s in seeds if s not in TUNING_SEEDS), None)
        allowed, seed_rule = TUNING_TRACKS, "1-100"
    else:
        seed = next((s for s in seeds if s < FIRST_REPORTING_SEED), None)
        allowed, seed_rule = REPORTING_TRACKS, f"{FIRST_REPORTING_SEED} and up"
    if seed is not None:
        return f"seed {seed} is not {kind} data ({kind} studies use seeds {seed_rule})"
    track = next((t for t in tracks if track_name(t) not in allowed), None)
    if track is not None:
        return (
            f"track {track!r} is not {kind} data ({kind} studies use the tracks "
            f"{', '.join(allowed)})"
        )
    return None
